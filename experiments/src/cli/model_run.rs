//! `motile particle run` and `motile meanfield run`.

use crate::cli::progress;
use crate::run::Device;
use crate::run::meanfield::{MeanFieldRunConfig, run_meanfield};
use crate::run::particle::{ParticleRunConfig, run_particle};
use anyhow::Context;
use std::path::{Path, PathBuf};

/// Arguments of `motile <model> run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// TOML config (every key optional; docs/config.md lists them). Without it, built-in
    /// defaults.
    pub config: Option<PathBuf>,
    /// Output run directory (not needed with --dry-run).
    #[arg(long, required_unless_present = "dry_run")]
    pub out: Option<PathBuf>,
    /// Check the config as the run does before its first step (the ranges, the files its start
    /// reads, the memory it needs), print the resolved config and exit.
    #[arg(long)]
    pub dry_run: bool,
    /// Where the step runs, overriding the config's `device` (cpu or gpu; [`device_help`]).
    #[arg(long, value_enum, hide_possible_values = true, help = device_help())]
    pub device: Option<Device>,
}

/// What `motile particle run` does, its hydrodynamic levels named from
/// [`motile_particle::model::level::Hydrodynamics::ALL`].
pub fn particle_about() -> String {
    format!(
        "Run the particle model (rods, contacts, hydrodynamics {}) into a run directory",
        crate::cli::levels(|_| true)
    )
}

/// The help of `--device`: what runs on the GPU (docs/gpu.md), the levels named from
/// [`motile_particle::model::level::Hydrodynamics::ALL`].
pub fn device_help() -> String {
    format!(
        "Where the run's steps run, overriding the config's `device`: cpu (the worker threads, \
         --threads) or gpu: the whole step on one NVIDIA GPU through CUDA, for the mean-field \
         model and for the particle model at every hydrodynamic level ({}), the state resident \
         there (snapshots, diagnostics and checkpoints are written from it by the CPU). A \
         particle run on the GPU is one process (not MPI ranks) in a box at least 3 contact \
         reaches wide. gpu needs a build with `--features gpu`; a GPU request without a GPU is \
         an error, never a CPU fallback (docs/gpu.md)",
        crate::cli::levels(|_| true)
    )
}

/// The config of a run command: parsed from `path` (or the defaults), file names in it made
/// relative to the config file's folder (`resolve`), checked as the run checks it before its
/// first step (`check`: ranges, memory, the files it reads), printed and `None` on a dry run.
fn resolve_config<C: Default + serde::Serialize>(
    path: &Option<PathBuf>,
    dry_run: bool,
    parse: impl Fn(&str, &Path) -> anyhow::Result<C>,
    resolve: impl Fn(&mut C, &Path),
    overrides: impl Fn(&mut C),
    check: impl Fn(&C) -> anyhow::Result<()>,
) -> anyhow::Result<Option<C>> {
    let mut cfg = match path {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("{}: cannot read", p.display()))?;
            let mut cfg = parse(&text, p)?;
            resolve(&mut cfg, p.parent().unwrap_or(Path::new(".")));
            cfg
        }
        None => C::default(),
    };
    overrides(&mut cfg);
    check(&cfg)?;
    if dry_run {
        print!("{}", toml::to_string_pretty(&cfg)?);
        return Ok(None);
    }
    Ok(Some(cfg))
}

/// `motile particle run`.
pub fn particle(a: RunArgs) -> anyhow::Result<()> {
    let device = a.device;
    let Some(cfg) = resolve_config(
        &a.config,
        a.dry_run,
        crate::run::particle::parse_config,
        ParticleRunConfig::resolve_paths,
        |c| {
            if let Some(d) = device {
                c.device = d;
            }
        },
        // The override is checked with the rest (the GPU step needs a box of at least 3
        // contact reaches).
        |c| {
            c.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
            crate::run::particle::preflight(c)
        },
    )?
    else {
        return Ok(());
    };
    let out = a.out.context("--out DIR is required to run")?;
    let s = run_particle(&cfg, &out, progress())?;
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

/// `motile meanfield run`.
pub fn meanfield(a: RunArgs) -> anyhow::Result<()> {
    let device = a.device;
    let Some(cfg) = resolve_config(
        &a.config,
        a.dry_run,
        crate::run::meanfield::parse_config,
        MeanFieldRunConfig::resolve_paths,
        |c| {
            if let Some(d) = device {
                c.device = d;
            }
        },
        crate::run::meanfield::preflight,
    )?
    else {
        return Ok(());
    };
    let out = a.out.context("--out DIR is required to run")?;
    let s = run_meanfield(&cfg, &out, progress())?;
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
