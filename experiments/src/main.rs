//! `motile`: run, analyse and compare simulations of suspensions of swimming rods. This file
//! parses the command line and dispatches; each command lives in `motile_experiments::cli`.

use clap::{Parser, Subcommand};
use motile_experiments::cli;
use motile_experiments::cli::analyze::AnalyzeArgs;
use motile_experiments::cli::check_accuracy::CheckAccuracyArgs;
use motile_experiments::cli::compare::CompareArgs;
use motile_experiments::cli::demo::DemoArgs;
use motile_experiments::cli::fidelity::FidelityArgs;
use motile_experiments::cli::model_run::RunArgs;
use motile_experiments::cli::resume::ResumeArgs;
use motile_experiments::cli::scene_run::SceneArgs;
use motile_experiments::cli::stability::StabilityArgs;
use motile_experiments::cli::study::StudyArgs;
use motile_experiments::cli::theory::TheoryArgs;
use motile_experiments::io::checkpoint::Interrupted;
use motile_experiments::run::ranks;
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "motile",
    version,
    about = "Simulate and compare suspensions of swimming rods (particle and mean-field models)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    threads: Option<usize>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Compare particle and mean-field runs in mean-field units: figures, tables.
    ///
    /// Puts the runs in one unit system (docs/MODEL.md section 5) and writes into OUT up to nine
    /// figures, each as PNG and SVG: the velocity norm against time with the linear theory,
    /// the saturated norm against L/l (particle runs), the time-averaged velocity
    /// autocorrelation, |u| on the plane z = 0, the correlations of c, n (particle runs) and Q,
    /// and for particle runs the mean squared displacement and the orientation
    /// autocorrelation; norms, correlations and trajectories as CSV; summary.md and series.md
    /// (growth rates, saturated norms, correlation lengths). It prints the summary table.
    Compare(CompareArgs),
    /// Analyse a run's snapshots: correlation functions, norms, trajectory statistics.
    ///
    /// Writes <RUN_DIR>/analysis/ (timeseries.csv, correlations.{csv,png,svg}, analysis.h5)
    /// and prints the time series.
    Analyze(AnalyzeArgs),
    /// Particle model: `motile particle run [CONFIG] --out DIR`.
    Particle {
        #[command(subcommand)]
        action: ParticleAction,
    },
    /// Mean-field model: `motile meanfield run [CONFIG] --out DIR`.
    Meanfield {
        #[command(subcommand)]
        action: MeanfieldAction,
    },
    /// Run a scene (a named set of runs): `motile scenes` lists the built-in ones.
    ///
    /// A scene is a named, versioned set of particle and mean-field runs (a built-in one or a
    /// scene file), each run into OUT/RUN and analysed, all compared in OUT/compare, a summary
    /// in OUT/scene.md. Running it again resumes what is unfinished and skips what is done.
    Run(SceneArgs),
    /// List the built-in scenes: what each shows, its runs and its cost.
    Scenes,
    /// Where the methods fail (a map of short runs), or where the particle model's growth sets
    /// in (`onset`).
    ///
    /// `particle` and `meanfield`: a map of short runs, time step against volume fraction
    /// (particle) or against resolution (mean-field), each cell the run's outcome
    /// (OUT/stability_MODEL.{png,svg,csv,md}). `onset`: the growth rate of a seeded box-scale
    /// perturbation over nu against L nu for each volume fraction, beside the continuum's
    /// rate (docs/MODEL.md section 5; OUT/onset.{png,svg,csv,md}).
    Stability(StabilityArgs),
    /// Accuracy against cost: sweep one knob of a scene's run.
    ///
    /// Measures each setting's error against the most accurate one and its wall time, charts
    /// them (OUT/study_KNOB.{png,svg,csv,md}) and names the cheapest setting within the stated
    /// accuracy.
    Study(StudyArgs),
    /// Audit a particle run's fast sums against the direct Ewald sum.
    ///
    /// Evaluates the sum the run's config uses on one snapshot and the direct Ewald sum at K
    /// sampled targets, and prints the measured error of each output (and of the rod motion it
    /// gives) beside hydro.sum_tolerance (docs/accuracy.md).
    CheckAccuracy(CheckAccuracyArgs),
    /// Continue a stopped or killed run from its newest checkpoint, bit for bit.
    Resume(ResumeArgs),
    /// Pair fidelity of the hydrodynamic levels against slender-body theory.
    ///
    /// Two rods at centre distances 0.5-5 l with random orientations; each level's
    /// flow-induced velocities against slender-body theory's
    /// (OUT/pair_fidelity.{png,svg,csv,md}).
    Fidelity(FidelityArgs),
    /// The linear theory of the periodic box: growth rates, the onset box.
    ///
    /// The lowest mode's growth rate for swimmers at volume fraction nu in boxes of given
    /// sides, the onset box and the continuum's rate (docs/MODEL.md section 5b).
    Theory(TheoryArgs),
    /// The main job: both models above the instability, compared (about 3 minutes on 2 cores).
    ///
    /// Runs the `demo` scene (experiments/scenes/demo.toml): pushers above the instability in
    /// both models from one initial condition. A particle run with slender-body hydrodynamics
    /// (8 640 rods at nu = 5 in a box of 12 rod lengths, to t = 8.5/beta) in OUT/particle, the
    /// mean-field run from the same initial Q at the same zeta on a 32^3 grid in OUT/meanfield,
    /// both analysed and compared in mean-field units: figures and summary.md in OUT/compare,
    /// the scene report in OUT/scene.md. Then free swimmers checked against exact values in
    /// OUT/free_swimmers. The last lines printed say where each of these is.
    Demo(DemoArgs),
}

#[derive(Subcommand, Debug)]
enum ParticleAction {
    /// Run the particle model into a run directory (the levels are listed from the model).
    #[command(about = cli::model_run::particle_about())]
    Run(RunArgs),
}

#[derive(Subcommand, Debug)]
enum MeanfieldAction {
    /// Run the mean-field model (Q tensor, Bingham closure; defaults: the paper's case at 32^3).
    Run(RunArgs),
}

/// Run the command.
fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Compare(a) => cli::compare::run(a),
        Command::Analyze(a) => cli::analyze::run(a),
        Command::Particle {
            action: ParticleAction::Run(a),
        } => cli::model_run::particle(a),
        Command::Meanfield {
            action: MeanfieldAction::Run(a),
        } => cli::model_run::meanfield(a),
        Command::Run(a) => cli::scene_run::run(a),
        Command::Scenes => cli::scene_run::list(),
        Command::Stability(a) => cli::stability::run(a),
        Command::Study(a) => cli::study::run(a),
        Command::CheckAccuracy(a) => cli::check_accuracy::run(a),
        Command::Resume(a) => cli::resume::run(a),
        Command::Fidelity(a) => cli::fidelity::run(a),
        Command::Theory(a) => cli::theory::run(a),
        Command::Demo(a) => cli::demo::run(a),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if cli.threads == Some(0) {
        eprintln!("motile: error: --threads 0: need at least 1 worker thread");
        return ExitCode::from(2);
    }
    if let Some(t) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
    {
        eprintln!("motile: cannot start {t} threads: {e}");
        return ExitCode::from(2);
    }
    if let Err(e) = motile_experiments::io::checkpoint::install_signal_handlers() {
        eprintln!("motile: warning: cannot install SIGINT/SIGTERM handlers: {e}");
    }
    // Under mpirun: rank 0 runs the command, the other ranks follow it (run::ranks).
    #[cfg(feature = "mpi")]
    let _universe = {
        let universe = match mpi::initialize() {
            Some(u) => u,
            None => {
                eprintln!("motile: error: MPI could not be initialised");
                return ExitCode::FAILURE;
            }
        };
        let world = ranks::MpiRanks::world();
        if motile_particle::parallel::comm::Comm::size(&world) > 1 {
            let comm: &'static ranks::MpiRanks = Box::leak(Box::new(world));
            ranks::set_world(comm);
            if motile_particle::parallel::comm::Comm::rank(comm) != 0 {
                return match motile_experiments::run::particle::follow(comm) {
                    Ok(()) => ExitCode::SUCCESS,
                    Err(e) => {
                        eprintln!("motile: error: {e:#}");
                        ExitCode::FAILURE
                    }
                };
            }
        }
        universe
    };
    #[cfg(not(feature = "mpi"))]
    if let Some(n) = ranks::launched_ranks() {
        eprintln!(
            "motile: error: started as one of {n} MPI ranks, but this motile was built without the mpi feature (each rank would run the whole command into the same directory); build it with `cargo build --release --features mpi`"
        );
        return ExitCode::from(2);
    }
    let result = dispatch(cli.command);
    ranks::release();
    if let Some(comm) = ranks::world() {
        let (exchanges, values) = ranks::traffic();
        eprintln!(
            "motile: rank 0 of {}: {exchanges} exchanges, {values} values ({:.1} MB) sent to other ranks",
            comm.size(),
            values as f64 * 8e-6
        );
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if let Some(i) = e.downcast_ref::<Interrupted>() {
                eprintln!("motile: {i}");
                // The shell convention for a process ended by a signal: 128 + its number.
                return ExitCode::from((128 + i.signal).clamp(0, 255) as u8);
            }
            eprintln!("motile: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
