//! `motile study KNOB`.

use crate::campaign::scene::load_scene;
use crate::campaign::study::{KNOBS, StudyOptions, study};
use std::path::PathBuf;

/// Arguments of `motile study`.
#[derive(clap::Args, Debug)]
pub struct StudyArgs {
    /// The knob ([`knob_help`]).
    #[arg(
        help = knob_help(),
        hide_possible_values = true,
        value_parser = clap::builder::PossibleValuesParser::new(KNOBS.map(|k| k.0))
    )]
    pub knob: String,
    /// Scene whose run is the base (its first run of the knob's model).
    #[arg(long, default_value = "demo")]
    pub scene: String,
    /// Values to sweep, comma-separated [default: the knob's list].
    #[arg(long, value_delimiter = ',')]
    pub values: Option<Vec<String>>,
    /// End time of each run [default: the scene run's].
    #[arg(long)]
    pub t_end: Option<f64>,
    /// Stated accuracy (relative error).
    #[arg(long, default_value_t = 1e-2)]
    pub accuracy: f64,
    /// The scene run to sweep [default: its first run of the knob's model].
    #[arg(long)]
    pub run: Option<String>,
    /// Compare on statistics over [FROM, t_end] (1/beta) instead of pathwise: the
    /// time-averaged velocity norm, the orientation decorrelation rate, the MSD at a lag and the
    /// first zero of `Corr[Q]` (particle knobs; for contact-driven runs, which do not converge
    /// pathwise).
    #[arg(long, value_name = "FROM")]
    pub statistics_from: Option<f64>,
    /// The reference setting [default: the knob's].
    #[arg(long)]
    pub reference: Option<String>,
    /// Output directory.
    #[arg(long, default_value = "runs/study")]
    pub out: PathBuf,
}

/// The help of the knob: each knob of [`KNOBS`] with its model and default values.
pub fn knob_help() -> String {
    let knobs: Vec<String> = KNOBS
        .iter()
        .map(|(name, model, values, reference)| {
            format!("{name} ({model}: {values}; reference {reference})")
        })
        .collect();
    format!("The knob: {}", knobs.join(", "))
}

/// Run the study and print its table.
pub fn run(a: StudyArgs) -> anyhow::Result<()> {
    let s = load_scene(&a.scene)?;
    let opts = StudyOptions {
        knob: a.knob.clone(),
        values: a.values,
        t_end: a.t_end,
        accuracy: a.accuracy,
        run: a.run,
        statistics_from: a.statistics_from,
        reference: a.reference,
    };
    let report = study(&s, &opts, &a.out, &mut |line| println!("{line}"))?;
    println!("{}", report.markdown);
    println!(
        "wrote {}",
        a.out.join(format!("study_{}.png", a.knob)).display()
    );
    Ok(())
}
