//! `motile check-accuracy RUN_DIR`.

use crate::report::accuracy::{audit, render};
use std::path::PathBuf;

/// Arguments of `motile check-accuracy`.
#[derive(clap::Args, Debug)]
pub struct CheckAccuracyArgs {
    /// Run directory of a particle run with hydrodynamics "sbt" or "dipole".
    pub run_dir: PathBuf,
    /// Snapshot number (snapshots/snap_NNNNNN.h5) [default: the last].
    #[arg(long)]
    pub snapshot: Option<usize>,
    /// Targets of the direct sum (its cost is O(N K)).
    #[arg(long, default_value_t = 256)]
    pub targets: usize,
}

/// Audit the run's fast sums and print the measured errors.
pub fn run(a: CheckAccuracyArgs) -> anyhow::Result<()> {
    let audit = audit(&a.run_dir, a.snapshot, a.targets)?;
    print!("{}", render(&audit));
    Ok(())
}
