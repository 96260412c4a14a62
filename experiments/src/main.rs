//! `motile`: run, analyse and compare simulations of suspensions of swimming rods.

use anyhow::Context;
use clap::{Parser, Subcommand};
use motile_experiments::analyze::{AnalyzeOptions, analyze_run};
use motile_experiments::demo::DemoConfig;
use motile_experiments::particle_run::{
    ParticleRunConfig, parse_config, resume_particle, run_particle,
};
use motile_experiments::rundir::{RunDir, TimeSeries};
use motile_experiments::scene;
use motile_experiments::{compare, meanfield_run};
use std::path::PathBuf;
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
    /// Compare particle and mean-field runs in one unit system (docs/MODEL.md section 5): velocity
    /// norm against time (PNG, SVG, CSV) and a table of its time averages.
    Compare {
        /// Run directories (particle runs need hydrodynamics "dipole" or "sbt").
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Compute correlation functions, norms and trajectory statistics of a run's snapshots;
    /// writes <RUN_DIR>/analysis/ (CSV, HDF5, PNG, SVG).
    Analyze {
        /// Run directory (contains config.toml and snapshots/).
        run_dir: PathBuf,
        /// TOML file with analysis options (keys: modes, shell_width, tolerance, t_start, viscosity).
        #[arg(long)]
        config: Option<PathBuf>,
        /// Fourier modes per dimension for particle snapshots [default: floor((L/l)/2)].
        #[arg(long)]
        modes: Option<usize>,
        /// Spacing of the radii of the correlation functions, in units of length [default: L/128,
        /// 64 radii in (0, L/2]].
        #[arg(long)]
        shell_width: Option<f64>,
        /// NUFFT tolerance [default: 1e-6].
        #[arg(long)]
        tolerance: Option<f64>,
        /// Start of the time-averaging window [default: 0].
        #[arg(long)]
        t_start: Option<f64>,
    },
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
    /// Run a scene: a named, versioned set of particle and mean-field runs
    /// (`motile scenes` lists the built-in ones; or give a scene file), each analysed, all
    /// compared in OUT/compare, a summary in OUT/scene.md. Running it again resumes what is
    /// unfinished and skips what is done.
    Run {
        /// Built-in scene name (demo, dilute, paper-dilute, concentrated, meanfield) or a
        /// scene file.
        scene: String,
        /// Output directory [default: runs/SCENE (the scene's name)].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only these runs of the scene (repeatable).
        #[arg(long)]
        only: Vec<String>,
        /// Print the scene's resolved runs and exit.
        #[arg(long)]
        dry_run: bool,
        /// With --dry-run: also time a few steps of each run (at a proxy size when large)
        /// and print its estimated cost (scenes that set `estimate` print it before running).
        #[arg(long, requires = "dry_run")]
        estimate: bool,
    },
    /// List the built-in scenes.
    Scenes,
    /// Where methods fail: a map of short runs, time step against volume fraction (particle)
    /// or against resolution (mean-field), each cell the run's outcome (PNG, SVG, CSV, MD in
    /// OUT). `onset`: where the particle model starts to grow like the continuum, the growth
    /// rate of a seeded box-scale perturbation over nu against L nu for each volume fraction,
    /// beside the continuum's rate (docs/MODEL.md section 5; OUT/onset.{png,svg,csv,md}).
    Stability {
        /// "particle", "meanfield" or "onset".
        model: String,
        /// Time steps (particle dt, 1/beta; mean-field dt_max), comma-separated
        /// [default: particle 0.005,0.01,0.02,0.04; mean-field 0.05,0.1,0.2,0.4,0.8].
        #[arg(long, value_delimiter = ',')]
        dts: Option<Vec<f64>>,
        /// Particle: volume fractions [default: 0.625,2,5; onset: 3.75,5].
        #[arg(long, value_delimiter = ',')]
        fractions: Option<Vec<f64>>,
        /// Mean-field: grids [default: 8,16,32].
        #[arg(long, value_delimiter = ',')]
        grids: Option<Vec<usize>>,
        /// Particle: box side L/l [default: 6].
        #[arg(long, default_value_t = 6.0)]
        box_length: f64,
        /// Onset: values of L nu, comma-separated [default: 30,45,60].
        #[arg(long, value_delimiter = ',')]
        box_nu: Option<Vec<f64>>,
        /// Onset: amplitude of the seeded perturbation [default: 0.025].
        #[arg(long)]
        amplitude: Option<f64>,
        /// Particle and onset: hydrodynamics [default: sbt].
        #[arg(long, default_value = "sbt")]
        hydrodynamics: motile_particle::model::level::Hydrodynamics,
        /// Mean-field: diffusion D [default: 1e-4, the paper's].
        #[arg(long, default_value_t = 1e-4)]
        diffusion: f64,
        /// Mean-field: CFL number [default: 2, the largest allowed, so dt_max is the step until
        /// the flow is strong].
        #[arg(long, default_value_t = 2.0)]
        cfl: f64,
        /// End time of each run [default: particle 2, mean-field 60]; onset: end time times nu [default: 40].
        #[arg(long)]
        t_end: Option<f64>,
        /// Output directory.
        #[arg(long, default_value = "runs/stability")]
        out: PathBuf,
    },
    /// Accuracy against cost: sweep one knob of a scene's run (particle: sum_tolerance,
    /// quadrature_points, hydrodynamics, dt; mean-field: meanfield_dt, grid, closure_degree),
    /// measure each setting's error against the most accurate one and its wall time, chart
    /// them (OUT/study_KNOB.{png,svg,csv,md}) and name the cheapest setting within the
    /// stated accuracy.
    Study {
        /// The knob.
        knob: String,
        /// Scene whose run is the base (its first run of the knob's model).
        #[arg(long, default_value = "demo")]
        scene: String,
        /// Values to sweep, comma-separated [default: the knob's list].
        #[arg(long, value_delimiter = ',')]
        values: Option<Vec<String>>,
        /// End time of each run [default: the scene run's].
        #[arg(long)]
        t_end: Option<f64>,
        /// Stated accuracy (relative error) [default: 1e-2].
        #[arg(long, default_value_t = 1e-2)]
        accuracy: f64,
        /// Output directory.
        #[arg(long, default_value = "runs/study")]
        out: PathBuf,
    },
    /// Audit a particle run's fast sums: evaluate the sum its config uses on one snapshot and
    /// the direct Ewald sum at K sampled targets, and print the measured error of each output
    /// (and of the rod motion it gives) beside hydro.sum_tolerance (docs/accuracy.md).
    CheckAccuracy {
        /// Run directory of a particle run with hydrodynamics "sbt" or "dipole".
        run_dir: PathBuf,
        /// Snapshot number (snapshots/snap_NNNNNN.h5) [default: the last].
        #[arg(long)]
        snapshot: Option<usize>,
        /// Targets of the direct sum (its cost is O(N K)).
        #[arg(long, default_value_t = 256)]
        targets: usize,
    },
    /// Continue a stopped or killed run from its newest checkpoint, bit for bit.
    Resume {
        /// Run directory.
        run_dir: PathBuf,
    },
    /// The main job: a small dilute particle run (OUT/particle), a small mean-field run
    /// (OUT/meanfield), both analysed, and free swimmers checked against exact values
    /// (OUT/free_swimmers). The particle part runs slender-body hydrodynamics at 320 rods; OUT/compare has both velocity norms on one chart.
    Demo {
        /// Output run directory.
        #[arg(long, default_value = "runs/demo")]
        out: PathBuf,
        /// Box side L/l.
        #[arg(long)]
        box_length: Option<f64>,
        /// Random seed.
        #[arg(long)]
        seed: Option<u64>,
    },
}

/// Arguments of `motile <model> run`.
#[derive(clap::Args, Debug)]
struct RunArgs {
    /// TOML config (every key optional; see README). Without it, built-in defaults.
    config: Option<PathBuf>,
    /// Output run directory (not needed with --dry-run).
    #[arg(long, required_unless_present = "dry_run")]
    out: Option<PathBuf>,
    /// Print the resolved config and exit.
    #[arg(long)]
    dry_run: bool,
    /// Where the work runs, overriding the config's `device`: cpu, or gpu (a build with
    /// `--features gpu`: the whole mean-field step, or the Fourier part of the particle model's
    /// hydrodynamic sums; a GPU request without a GPU is an error, never a CPU fallback).
    #[arg(long, value_enum)]
    device: Option<meanfield_run::Device>,
}

#[derive(Subcommand, Debug)]
enum ParticleAction {
    /// Run the particle model (rods, contacts, hydrodynamics "none", "dipole" or "sbt") into a
    /// run directory.
    Run(RunArgs),
}

#[derive(Subcommand, Debug)]
enum MeanfieldAction {
    /// Run the mean-field model (Q tensor, Bingham closure; defaults: the paper's case at 32^3).
    Run(RunArgs),
}

/// The config of a run command: parsed from `path` (or the defaults), file names in it made
/// relative to the config file's folder (`resolve`), printed and `None` on a dry run.
fn resolve_config<C: Default + serde::Serialize>(
    path: &Option<PathBuf>,
    dry_run: bool,
    parse: impl Fn(&str, &std::path::Path) -> anyhow::Result<C>,
    resolve: impl Fn(&mut C, &std::path::Path),
    overrides: impl Fn(&mut C),
) -> anyhow::Result<Option<C>> {
    let mut cfg = match path {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read", p.display()))?;
            let mut cfg = parse(&text, p)?;
            resolve(&mut cfg, p.parent().unwrap_or(std::path::Path::new(".")));
            cfg
        }
        None => C::default(),
    };
    overrides(&mut cfg);
    if dry_run {
        print!("{}", toml::to_string_pretty(&cfg)?);
        return Ok(None);
    }
    Ok(Some(cfg))
}

fn load_options(config: &Option<PathBuf>) -> anyhow::Result<AnalyzeOptions> {
    match config {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read", p.display()))?;
            toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))
        }
        None => Ok(AnalyzeOptions::default()),
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Compare { runs, out } => {
            let report = compare::compare(&runs, &out)?;
            println!("wrote {}\n{}", out.display(), report.table);
            Ok(())
        }
        Command::Analyze {
            run_dir,
            config,
            modes,
            shell_width,
            tolerance,
            t_start,
        } => {
            let mut opts = load_options(&config)?;
            opts.modes = modes.or(opts.modes);
            opts.shell_width = shell_width.or(opts.shell_width);
            opts.tolerance = tolerance.unwrap_or(opts.tolerance);
            opts.t_start = t_start.unwrap_or(opts.t_start);
            opts.validate()
                .map_err(|e| anyhow::anyhow!("analysis options: {e}"))?;
            let report = analyze_run(&run_dir, &opts)?;
            println!(
                "analysed {} {} snapshot(s); wrote {}",
                report.snapshots.len(),
                report.kind,
                run_dir.join("analysis").display()
            );
            print_table(&report.timeseries);
            Ok(())
        }
        Command::Particle {
            action:
                ParticleAction::Run(RunArgs {
                    config,
                    out,
                    dry_run,
                    device,
                }),
        } => {
            let Some(cfg) = resolve_config(
                &config,
                dry_run,
                parse_config,
                ParticleRunConfig::resolve_paths,
                |c| {
                    if let Some(d) = device {
                        c.device = d;
                    }
                },
            )?
            else {
                return Ok(());
            };
            // The override is checked with the rest (a GPU needs hydrodynamic sums to run).
            cfg.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
            let out = out.context("--out DIR is required to run")?;
            let s = run_particle(
                &cfg,
                &out,
                std::io::IsTerminal::is_terminal(&std::io::stderr()),
            )?;
            println!(
                "particle run: {} rods, {} steps in {:.1} s ({:.2} steps/s); wrote {}",
                s.rods.len(),
                s.steps,
                s.seconds,
                s.steps as f64 / s.seconds,
                out.display()
            );
            Ok(())
        }
        Command::Meanfield {
            action:
                MeanfieldAction::Run(RunArgs {
                    config,
                    out,
                    dry_run,
                    device,
                }),
        } => {
            let Some(cfg) = resolve_config(
                &config,
                dry_run,
                meanfield_run::parse_config,
                meanfield_run::MeanFieldRunConfig::resolve_paths,
                |c| {
                    if let Some(d) = device {
                        c.device = d;
                    }
                },
            )?
            else {
                return Ok(());
            };
            let out = out.context("--out DIR is required to run")?;
            let s = meanfield_run::run_meanfield(
                &cfg,
                &out,
                std::io::IsTerminal::is_terminal(&std::io::stderr()),
            )?;
            let last = s.timeseries.rows.last().map(|r| r[2]).unwrap_or(f64::NAN);
            println!(
                "mean-field run: {}^3, {} steps in {:.1} s, final ||u||_2 = {last:.4e}; wrote {}",
                cfg.grid,
                s.steps,
                s.seconds,
                out.display()
            );
            Ok(())
        }
        Command::Study {
            knob,
            scene,
            values,
            t_end,
            accuracy,
            out,
        } => {
            let s = scene::load_scene(&scene)?;
            let report = motile_experiments::study::study(
                &s,
                &knob,
                values,
                t_end,
                accuracy,
                &out,
                &mut |line| println!("{line}"),
            )?;
            println!("{}", report.markdown);
            println!("wrote {}", out.join(format!("study_{knob}.png")).display());
            Ok(())
        }
        Command::Stability {
            model,
            dts,
            fractions,
            grids,
            box_length,
            box_nu,
            amplitude,
            hydrodynamics,
            diffusion,
            cfl,
            t_end,
            out,
        } => {
            use motile_experiments::stability;
            let mut event = |line: &str| println!("{line}");
            if model == "onset" {
                let d = motile_experiments::onset::OnsetOptions::default();
                let opts = motile_experiments::onset::OnsetOptions {
                    fractions: fractions.unwrap_or(d.fractions.clone()),
                    box_nu: box_nu.unwrap_or(d.box_nu.clone()),
                    hydrodynamics,
                    dt: dts.and_then(|v| v.first().copied()).unwrap_or(d.dt),
                    t_end_nu: t_end.unwrap_or(d.t_end_nu),
                    amplitude: amplitude.unwrap_or(d.amplitude),
                    ..d
                };
                motile_experiments::onset::onset(&opts, &out, &mut event)?;
                println!("{}", std::fs::read_to_string(out.join("onset.md"))?);
                println!("wrote {}", out.join("onset.png").display());
                return Ok(());
            }
            let md = match model.as_str() {
                "particle" => {
                    let base = ParticleRunConfig {
                        box_length,
                        hydrodynamics,
                        t_end: t_end.unwrap_or(2.0),
                        diagnostic_interval: 0.05,
                        ..ParticleRunConfig::default()
                    };
                    stability::particle_map(
                        &base,
                        &dts.unwrap_or(vec![0.005, 0.01, 0.02, 0.04]),
                        &fractions.unwrap_or(vec![0.625, 2.0, 5.0]),
                        &out,
                        &mut event,
                    )?
                    .1
                }
                "meanfield" => {
                    let base = meanfield_run::MeanFieldRunConfig {
                        diffusion,
                        cfl,
                        t_end: t_end.unwrap_or(60.0),
                        mode_max: 2,
                        step_retries: 0,
                        diagnostic_interval: 1.0,
                        ..Default::default()
                    };
                    stability::meanfield_map(
                        &base,
                        &dts.unwrap_or(vec![0.05, 0.1, 0.2, 0.4, 0.8]),
                        &grids.unwrap_or(vec![8, 16, 32]),
                        &out,
                        &mut event,
                    )?
                    .1
                }
                other => anyhow::bail!(
                    "stability: model \"{other}\" is not one of \"particle\", \"meanfield\", \"onset\""
                ),
            };
            println!("{md}");
            println!(
                "wrote {}",
                out.join(format!("stability_{model}.png")).display()
            );
            Ok(())
        }
        Command::CheckAccuracy {
            run_dir,
            snapshot,
            targets,
        } => {
            let audit = motile_experiments::accuracy::audit(&run_dir, snapshot, targets)?;
            print!("{}", motile_experiments::accuracy::render(&audit));
            Ok(())
        }
        Command::Scenes => {
            for (name, text) in scene::BUILTIN {
                let s = scene::parse_scene(text, name)?;
                println!("{name} (version {}): {}", s.info.version, s.info.cost);
                for (run, cfg) in &s.runs {
                    println!("    {run}: {}", cfg.describe());
                }
            }
            Ok(())
        }
        Command::Run {
            scene,
            out,
            only,
            dry_run,
            estimate,
        } => {
            let s = scene::load_scene(&scene)?;
            let out = out.unwrap_or_else(|| PathBuf::from("runs").join(&s.info.name));
            if dry_run {
                println!(
                    "scene {} (version {}) -> {}\n{}\nmodel level: {}\ncost: {}",
                    s.info.name,
                    s.info.version,
                    out.display(),
                    s.info.description.trim(),
                    s.info.level.trim(),
                    s.info.cost
                );
                let scratch =
                    std::env::temp_dir().join(format!("motile-estimate-{}", std::process::id()));
                for (run, cfg) in &s.runs {
                    if !only.is_empty() && !only.contains(run) {
                        continue;
                    }
                    println!("  {run}: {}", cfg.describe());
                    if estimate {
                        let e = motile_experiments::estimate::estimate(cfg, &scratch)?;
                        println!("    estimated cost: {}", e.describe());
                    }
                }
                return Ok(());
            }
            let report = scene::run_scene(
                &s,
                &out,
                &only,
                std::io::IsTerminal::is_terminal(&std::io::stderr()),
                &mut |line| println!("{line}"),
            )?;
            println!("{}", report.markdown);
            println!("wrote {}", out.join("scene.md").display());
            Ok(())
        }
        Command::Resume { run_dir } => {
            let model = RunDir::open(&run_dir)?.header()?.model;
            let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
            match model.as_str() {
                "particle" => {
                    let s = resume_particle(&run_dir, progress)?;
                    println!(
                        "resumed: {} steps in {:.1} s, now at step {}",
                        s.steps, s.seconds, s.final_step
                    );
                }
                "meanfield" => {
                    let s = meanfield_run::resume_meanfield(&run_dir, progress)?;
                    let t = s.timeseries.rows.last().map(|r| r[0]).unwrap_or(f64::NAN);
                    println!(
                        "resumed: {} steps in {:.1} s; last diagnostic at t = {t}",
                        s.steps, s.seconds
                    );
                }
                other => anyhow::bail!(
                    "{}: cannot resume a run of model \"{other}\" (expected \"particle\" or \"meanfield\")",
                    run_dir.display()
                ),
            }
            Ok(())
        }
        Command::Demo {
            out,
            box_length,
            seed,
        } => {
            // Part 1: the demo scene (experiments/scenes/demo.toml), both models above the
            // instability, compared in mean-field units (docs/MODEL.md section 5); part 2: free
            // swimmers against exact values. The checks live in the demo module.
            use motile_experiments::demo;
            let s = scene::load_scene("demo")?;
            let report = scene::run_scene(
                &s,
                &out,
                &[],
                std::io::IsTerminal::is_terminal(&std::io::stderr()),
                &mut |line| println!("{line}"),
            )?;
            println!("{}", demo::meanfield_bound_line(&out)?);
            println!("{}", report.markdown);
            for line in demo::DemoSummary::read(&out)?.lines() {
                println!("{line}");
            }
            let out = out.join("free_swimmers");
            let mut cfg = DemoConfig::default();
            cfg.box_length = box_length.unwrap_or(cfg.box_length);
            cfg.seed = seed.unwrap_or(cfg.seed);
            let t0 = std::time::Instant::now();
            let (table, checks) = demo::free_swimmers(&out, &cfg)?;
            print_table(&table);
            for line in checks {
                println!("{line}");
            }
            println!(
                "wrote {} in {:.1} s",
                out.display(),
                t0.elapsed().as_secs_f64()
            );
            Ok(())
        }
    }
}

fn print_table(ts: &TimeSeries) {
    println!("{}", ts.columns.join("  "));
    for r in &ts.rows {
        let cells: Vec<String> = r.iter().map(|v| format!("{v:.4e}")).collect();
        println!("{}", cells.join("  "));
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
    if let Err(e) = motile_experiments::checkpoint::install_signal_handlers() {
        eprintln!("motile: warning: cannot install SIGINT/SIGTERM handlers: {e}");
    }
    // Under mpirun: rank 0 runs the command, the other ranks follow it (run::ranks).
    #[cfg(feature = "mpi")]
    let _universe = {
        use motile_experiments::run::ranks;
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
                return match ranks::follow(comm) {
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
    if let Some(n) = motile_experiments::run::ranks::launched_ranks() {
        eprintln!(
            "motile: error: started as one of {n} MPI ranks, but this motile was built without the mpi feature (each rank would run the whole command into the same directory); build it with `cargo build --release --features mpi`"
        );
        return ExitCode::from(2);
    }
    let result = run(cli);
    motile_experiments::run::ranks::release();
    if let Some(comm) = motile_experiments::run::ranks::world() {
        let (exchanges, values) = motile_experiments::run::ranks::traffic();
        eprintln!(
            "motile: rank 0 of {}: {exchanges} exchanges, {values} values ({:.1} MB) sent to other ranks",
            comm.size(),
            values as f64 * 8e-6
        );
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if let Some(i) = e.downcast_ref::<motile_experiments::checkpoint::Interrupted>() {
                eprintln!("motile: {i}");
                // The shell convention for a process ended by a signal: 128 + its number.
                return ExitCode::from((128 + i.signal).clamp(0, 255) as u8);
            }
            eprintln!("motile: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
