//! `motile compare RUN... --out DIR`.

use crate::report::compare::compare_with_table;
use motile_particle::model::level::Hydrodynamics;
use std::path::PathBuf;

/// Arguments of `motile compare`.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Run directories, or runs filed without snapshots with their `compare/` products (particle
    /// runs need a level with a flow; [`runs_help`]).
    #[arg(required = true, help = runs_help())]
    pub runs: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// An earlier series table (a `series.csv`, e.g. docs/gallery/paper_dilute_series.csv):
    /// its rows for runs not given here join `series.csv` and the saturated norm's chart.
    #[arg(long)]
    pub table: Option<PathBuf>,
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
    let report = compare_with_table(&a.runs, &a.out, a.table.as_deref())?;
    println!("wrote {}\n{}", a.out.display(), report.table);
    Ok(())
}
