//! `motile compare RUN... --out DIR`.

use crate::report::compare::compare;
use motile_particle::model::level::Hydrodynamics;
use std::path::PathBuf;

/// Arguments of `motile compare`.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Run directories (particle runs need a level with a flow; [`runs_help`]).
    #[arg(required = true, help = runs_help())]
    pub runs: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
}

/// The help of the run directories: particle runs need a flow, the levels that have one named
/// from [`Hydrodynamics::ALL`].
pub fn runs_help() -> String {
    format!(
        "Run directories: mean-field runs, and particle runs with a flow (hydrodynamics {})",
        crate::cli::levels(Hydrodynamics::has_flow)
    )
}

/// Compare the runs and print the table.
pub fn run(a: CompareArgs) -> anyhow::Result<()> {
    let report = compare(&a.runs, &a.out)?;
    println!("wrote {}\n{}", a.out.display(), report.table);
    Ok(())
}
