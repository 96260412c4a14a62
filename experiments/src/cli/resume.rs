//! `motile resume RUN_DIR`.

use crate::cli::progress;
use crate::io::rundir::RunDir;
use crate::run::meanfield::resume_meanfield;
use crate::run::particle::resume_particle;
use std::path::PathBuf;

/// Arguments of `motile resume`.
#[derive(clap::Args, Debug)]
pub struct ResumeArgs {
    /// Run directory.
    pub run_dir: PathBuf,
}

/// Resume the run from its newest valid checkpoint.
pub fn run(a: ResumeArgs) -> anyhow::Result<()> {
    let run_dir = a.run_dir;
    let model = RunDir::open(&run_dir)?.header()?.model;
    match model.as_str() {
        "particle" => {
            let s = resume_particle(&run_dir, progress())?;
            println!(
                "resumed: {} steps in {:.1} s, now at step {}",
                s.steps, s.seconds, s.final_step
            );
        }
        "meanfield" => {
            let s = resume_meanfield(&run_dir, progress())?;
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
