//! `motile compare RUN... --out DIR`.

use crate::report::compare::compare;
use std::path::PathBuf;

/// Arguments of `motile compare`.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Run directories (particle runs need hydrodynamics "dipole" or "sbt").
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
}

/// Compare the runs and print the table.
pub fn run(a: CompareArgs) -> anyhow::Result<()> {
    let report = compare(&a.runs, &a.out)?;
    println!("wrote {}\n{}", a.out.display(), report.table);
    Ok(())
}
