//! `motile check-accuracy RUN_DIR`.

use crate::report::accuracy::{audit, render};
use motile_particle::model::level::Hydrodynamics;
use std::path::PathBuf;

/// Arguments of `motile check-accuracy`.
#[derive(clap::Args, Debug)]
pub struct CheckAccuracyArgs {
    /// Run directory of a particle run with a flow ([`run_dir_help`]).
    #[arg(help = run_dir_help())]
    pub run_dir: PathBuf,
    /// Snapshot number (snapshots/snap_NNNNNN.h5) [default: the last].
    #[arg(long)]
    pub snapshot: Option<usize>,
    /// Targets of the direct sum (its cost is O(N K)).
    #[arg(long, default_value_t = 256)]
    pub targets: usize,
}

/// The help of the run directory: a particle run whose level has fast sums, the levels named
/// from [`Hydrodynamics::ALL`].
pub fn run_dir_help() -> String {
    format!(
        "Run directory of a particle run with hydrodynamics {}",
        crate::cli::levels(Hydrodynamics::has_flow)
    )
}

/// Audit the run's fast sums and print the measured errors.
pub fn run(a: CheckAccuracyArgs) -> anyhow::Result<()> {
    let audit = audit(&a.run_dir, a.snapshot, a.targets)?;
    print!("{}", render(&audit));
    Ok(())
}
