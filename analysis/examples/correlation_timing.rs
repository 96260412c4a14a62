//! Times the velocity autocorrelation of points and velocities read from a raw file, for
//! `bench/python_boundary.py`, which times `motile.velocity_autocorrelation` on the same file's
//! data in the same session (the cost of the Python boundary).
//!
//! `correlation_timing FILE BOX_LENGTH MODES TOLERANCE REPS`: FILE holds `N` rows of six
//! little-endian f64 (x, y, z, ux, uy, uz). Prints one JSON line: the median seconds of the
//! whole call (plan, sort, type-1 NUFFT, shells) and `Corr(0)`.

use motile_analysis::correlation::{CorrelationOptions, sampled_vector_coefficients};
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    assert_eq!(
        a.len(),
        5,
        "usage: correlation_timing FILE BOX_LENGTH MODES TOLERANCE REPS"
    );
    let bytes = std::fs::read(&a[0]).expect("read the data file");
    let box_length: f64 = a[1].parse().expect("BOX_LENGTH");
    let modes: usize = a[2].parse().expect("MODES");
    let tolerance: f64 = a[3].parse().expect("TOLERANCE");
    let reps: usize = a[4].parse().expect("REPS");
    let v: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let x: Vec<[f64; 3]> = v.chunks_exact(6).map(|r| [r[0], r[1], r[2]]).collect();
    let u: Vec<[f64; 3]> = v.chunks_exact(6).map(|r| [r[3], r[4], r[5]]).collect();
    let opts = CorrelationOptions {
        modes: Some(modes),
        tolerance,
        ..CorrelationOptions::default()
    };
    let mut times = Vec::new();
    let mut c0 = 0.0;
    for _ in 0..reps {
        let t = Instant::now();
        let corr = sampled_vector_coefficients(&x, &u, box_length, &opts)
            .expect("valid input")
            .correlation(None);
        times.push(t.elapsed().as_secs_f64());
        c0 = corr.value[0];
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{{\"points\": {}, \"median_s\": {:.6}, \"corr0\": {:.17e}}}",
        x.len(),
        times[times.len() / 2],
        c0
    );
}
