//! `motile stability particle|meanfield|onset`.

use crate::campaign::onset::{OnsetOptions, onset};
use crate::campaign::stability::{meanfield_map, particle_map};
use crate::run::meanfield::MeanFieldRunConfig;
use crate::run::particle::ParticleRunConfig;
use motile_particle::model::level::Hydrodynamics;
use std::path::PathBuf;

/// Arguments of `motile stability`.
#[derive(clap::Args, Debug)]
pub struct StabilityArgs {
    /// What to map: the particle or the mean-field model's failures, or the particle model's
    /// onset.
    #[arg(value_parser = ["particle", "meanfield", "onset"])]
    pub model: String,
    /// Time steps (particle dt, 1/beta; mean-field dt_max), comma-separated
    /// [default: particle 0.005,0.01,0.02,0.04; mean-field 0.05,0.1,0.2,0.4,0.8; onset: the
    /// first is its step, default 0.04].
    #[arg(long, value_delimiter = ',')]
    pub dts: Option<Vec<f64>>,
    /// Particle and onset: volume fractions, comma-separated [default: particle 0.625,2,5;
    /// onset 3.75,5].
    #[arg(long, value_delimiter = ',')]
    pub fractions: Option<Vec<f64>>,
    /// Mean-field: grids, comma-separated [default: 8,16,32].
    #[arg(long, value_delimiter = ',')]
    pub grids: Option<Vec<usize>>,
    /// Particle: box side L/l.
    #[arg(long, default_value_t = 6.0)]
    pub box_length: f64,
    /// Onset: values of L nu, comma-separated [default: 30,45,60].
    #[arg(long, value_delimiter = ',')]
    pub box_nu: Option<Vec<f64>>,
    /// Onset: amplitude of the seeded perturbation [default: 0.025].
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Onset: box sides L/l, comma-separated, in place of --box-nu (a scan at fixed volume
    /// fractions, each run's lowest modes fitted for a complex rate beside the box theory;
    /// --t-end is then the end time itself).
    #[arg(long, value_delimiter = ',')]
    pub boxes: Option<Vec<f64>>,
    /// Onset with --boxes: run each box at least this many periods of its lowest mode where the
    /// box theory makes it a complex pair (2 pi/|Im sigma| each; the end time is the longer).
    #[arg(long)]
    pub periods: Option<f64>,
    /// Onset: time between snapshots (1/beta), which the rotational diffusion is measured from
    /// [default: the first and last only].
    #[arg(long)]
    pub snapshot_interval: Option<f64>,
    /// Particle and onset: the hydrodynamic level.
    #[arg(long, default_value = "sbt", value_parser = levels_parser())]
    pub hydrodynamics: Hydrodynamics,
    /// Mean-field: diffusion D (the default is the paper's).
    #[arg(long, default_value_t = 1e-4)]
    pub diffusion: f64,
    /// Mean-field: CFL number (the default is the largest allowed, so dt_max is the step until
    /// the flow is strong).
    #[arg(long, default_value_t = 2.0)]
    pub cfl: f64,
    /// End time of each run [default: particle 2, mean-field 60]; onset: end time times nu
    /// [default: 40], or with --boxes the end time.
    #[arg(long)]
    pub t_end: Option<f64>,
    /// Output directory.
    #[arg(long, default_value = "runs/stability")]
    pub out: PathBuf,
}

/// The hydrodynamic levels as clap's possible values, named from [`Hydrodynamics::ALL`].
fn levels_parser() -> impl clap::builder::TypedValueParser<Value = Hydrodynamics> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(Hydrodynamics::names())
        .try_map(|s| s.parse::<Hydrodynamics>())
}

/// Map the model's failures (or the onset) and print the table.
pub fn run(a: StabilityArgs) -> anyhow::Result<()> {
    let mut event = |line: &str| println!("{line}");
    let out = a.out;
    if a.model == "onset" {
        let d = OnsetOptions::default();
        let boxes = a.boxes.unwrap_or_default();
        let dt = a.dts.and_then(|v| v.first().copied()).unwrap_or(d.dt);
        let opts = OnsetOptions {
            fractions: a.fractions.unwrap_or(d.fractions.clone()),
            box_nu: a.box_nu.unwrap_or(d.box_nu.clone()),
            hydrodynamics: a.hydrodynamics,
            dt,
            t_end_nu: if boxes.is_empty() {
                a.t_end.unwrap_or(d.t_end_nu)
            } else {
                d.t_end_nu
            },
            t_end: if boxes.is_empty() { None } else { a.t_end },
            amplitude: a.amplitude.unwrap_or(d.amplitude),
            snapshot_interval: a.snapshot_interval,
            periods: a.periods,
            // The contact solver needs a margin of at least 2.5 U dt.
            contact_margin: (2.5 * dt > 0.1).then_some(3.0 * dt),
            boxes,
            ..d
        };
        onset(&opts, &out, &mut event)?;
        println!("{}", std::fs::read_to_string(out.join("onset.md"))?);
        println!("wrote {}", out.join("onset.png").display());
        return Ok(());
    }
    let md = match a.model.as_str() {
        "particle" => {
            let base = ParticleRunConfig {
                box_length: a.box_length,
                hydrodynamics: a.hydrodynamics,
                t_end: a.t_end.unwrap_or(2.0),
                diagnostic_interval: 0.05,
                ..ParticleRunConfig::default()
            };
            particle_map(
                &base,
                &a.dts.unwrap_or(vec![0.005, 0.01, 0.02, 0.04]),
                &a.fractions.unwrap_or(vec![0.625, 2.0, 5.0]),
                &out,
                &mut event,
            )?
            .1
        }
        "meanfield" => {
            let base = MeanFieldRunConfig {
                diffusion: a.diffusion,
                cfl: a.cfl,
                t_end: a.t_end.unwrap_or(60.0),
                mode_max: 2,
                step_retries: 0,
                diagnostic_interval: 1.0,
                ..Default::default()
            };
            meanfield_map(
                &base,
                &a.dts.unwrap_or(vec![0.05, 0.1, 0.2, 0.4, 0.8]),
                &a.grids.unwrap_or(vec![8, 16, 32]),
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
        out.join(format!("stability_{}.png", a.model)).display()
    );
    Ok(())
}
