//! `motile analyze RUN_DIR`.

use crate::cli::print_table;
use crate::report::analyze::{AnalyzeOptions, analyze_run};
use anyhow::Context;
use std::path::PathBuf;

/// Arguments of `motile analyze`.
#[derive(clap::Args, Debug)]
pub struct AnalyzeArgs {
    /// Run directory (contains config.toml and snapshots/).
    pub run_dir: PathBuf,
    /// TOML file with analysis options (keys: modes, shell_width, tolerance, t_start, viscosity).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Fourier modes per dimension for particle snapshots [default: floor((L/l)/2), at least 4].
    #[arg(long)]
    pub modes: Option<usize>,
    /// Spacing of the radii of the correlation functions, in units of length [default: L/128,
    /// 64 radii in (0, L/2]].
    #[arg(long)]
    pub shell_width: Option<f64>,
    /// NUFFT tolerance [default: 1e-6].
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Start of the time-averaging window [default: 0].
    #[arg(long)]
    pub t_start: Option<f64>,
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

/// Analyse the run and print its time series.
pub fn run(a: AnalyzeArgs) -> anyhow::Result<()> {
    let mut opts = load_options(&a.config)?;
    opts.modes = a.modes.or(opts.modes);
    opts.shell_width = a.shell_width.or(opts.shell_width);
    opts.tolerance = a.tolerance.unwrap_or(opts.tolerance);
    opts.t_start = a.t_start.unwrap_or(opts.t_start);
    opts.validate()
        .map_err(|e| anyhow::anyhow!("analysis options: {e}"))?;
    let report = analyze_run(&a.run_dir, &opts)?;
    println!(
        "analysed {} {} snapshot(s); wrote {}",
        report.snapshots.len(),
        report.kind,
        a.run_dir.join("analysis").display()
    );
    print_table(&report.timeseries);
    Ok(())
}
