//! The shared grid's distributed FFT alone (slabs, all-to-all transposes, rustfft/realfft), for
//! the comparison with FFTW's MPI interface in BENCHMARKS.md (`bench/fftw_mpi_round_trip.c` is
//! the same measurement over FFTW):
//!
//! ```text
//! cargo build --release -p motile-experiments --features mpi --example mpi_fft
//! mpirun -n P target/release/examples/mpi_fft [M ...]      # default 64 128
//! ```
//!
//! One thread per rank. For each grid size `M`: 10 round trips (forward, then inverse) of three
//! real fields on `M^3` (the RPY sum's three force components); prints `M`, the ranks, the
//! median seconds per round trip (the slowest rank's) and the round trip's largest relative
//! error (the largest over ranks).

use motile_experiments::run::ranks::MpiRanks;
use motile_particle::parallel::comm::Comm;
use motile_particle::parallel::slab_fft::fft_round_trip;
use std::process::ExitCode;

fn main() -> ExitCode {
    let Some(_universe) = mpi::initialize() else {
        eprintln!("mpi_fft: MPI could not be initialised");
        return ExitCode::FAILURE;
    };
    if let Err(e) = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global()
    {
        eprintln!("mpi_fft: {e}");
        return ExitCode::FAILURE;
    }
    let comm = MpiRanks::world();
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("grid sizes are whole numbers"))
        .collect();
    let sizes = if sizes.is_empty() {
        vec![64, 128]
    } else {
        sizes
    };
    if comm.rank() == 0 {
        println!("impl,ranks,M,seconds_per_round_trip,max_relative_error");
    }
    for m in sizes {
        let (seconds, error) = fft_round_trip(&comm, m, 3, 10);
        let mut worst = [seconds, error];
        comm.max(&mut worst);
        if comm.rank() == 0 {
            println!(
                "motile,{},{m},{:.6},{:.1e}",
                comm.size(),
                worst[0],
                worst[1]
            );
        }
    }
    ExitCode::SUCCESS
}
