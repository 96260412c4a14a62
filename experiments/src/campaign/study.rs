//! `motile study <knob>`: accuracy against cost. One knob of a scene's run is swept; each
//! setting runs over the same (short) window, its error is measured against the most accurate
//! setting, and the chart puts error against wall time and names the cheapest setting that
//! meets a stated accuracy.
//!
//! The error is the one the project's comparison is about, the same for every knob: the
//! largest difference of the velocity norm `||u||_2(t)` (particle runs: the time series'
//! `velocity_norm`, from the force density; mean-field runs: `u_l2`) from the reference run's
//! over the window, divided by the reference's largest norm. A run without a flow
//! (`hydrodynamics = "none"`) has error 1 by construction: the table lists it, the chart
//! leaves it off. Particle studies also report the RMS difference of
//! the rods' end positions from the reference's, relative to the RMS distance travelled
//! (swimming dominates it, so it is the weaker test of the flow).

use crate::campaign::run_config::RunConfig;
use crate::campaign::scene::Scene;
use crate::io::rundir::TimeSeries;
use crate::io::write_atomic;
use crate::report::plot::{Series, log_chart};
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::{Context, bail};
use motile_particle::model::geometry::{norm, sub};
use std::fmt::Write as _;
use std::path::Path;

/// The knobs `motile study` sweeps: name, model, default values (least to most accurate) and the
/// reference setting.
pub const KNOBS: [(&str, &str, &str, &str); 7] = [
    (
        "sum_tolerance",
        "particle",
        "1e-2,1e-3,1e-4,1e-5,1e-6",
        "1e-8",
    ),
    ("quadrature_points", "particle", "2,4,8", "16"),
    (
        "hydrodynamics",
        "particle",
        "none,dipole,sbt-explicit",
        "sbt",
    ),
    ("dt", "particle", "0.04,0.02,0.01,0.005", "0.0025"),
    ("meanfield_dt", "meanfield", "0.4,0.2,0.1,0.05", "0.0125"),
    ("grid", "meanfield", "8,12,16,24", "32"),
    ("closure_degree", "meanfield", "10,20,40", "80"),
];

/// One setting's result.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyPoint {
    /// The knob's value, as given.
    pub value: String,
    /// Wall seconds of the run (without analysis).
    pub seconds: f64,
    /// Relative error against the reference (0 for the reference).
    pub error: f64,
    /// Particle knobs: RMS end-position difference over the RMS distance travelled;
    /// mean-field: NaN.
    pub position_error: f64,
    /// Whether this is the reference setting.
    pub reference: bool,
    /// The run's failure, if it stopped (its error is then infinite).
    pub failure: Option<String>,
    /// Whether the run has a flow: a run without one (`hydrodynamics = "none"`) has error 1
    /// by construction, listed in the table and left off the chart.
    pub has_flow: bool,
}

/// What a study found.
#[derive(Clone, Debug)]
pub struct StudyReport {
    /// Every setting, the reference last.
    pub points: Vec<StudyPoint>,
    /// The cheapest setting whose error meets the stated accuracy, if any.
    pub cheapest: Option<StudyPoint>,
    /// Markdown summary (also `OUT/study_<knob>.md`).
    pub markdown: String,
}

/// One knob of [`KNOBS`], by name.
#[derive(Clone, Copy, Debug)]
struct Knob {
    /// The knob's name.
    name: &'static str,
    /// The model it belongs to: "particle" or "meanfield".
    model: &'static str,
    /// The values swept by default, comma-separated, least to most accurate.
    defaults: &'static str,
    /// The reference setting.
    reference: &'static str,
}

fn knob(name: &str) -> anyhow::Result<Knob> {
    KNOBS
        .iter()
        .find(|k| k.0 == name)
        .map(|&(name, model, defaults, reference)| Knob {
            name,
            model,
            defaults,
            reference,
        })
        .with_context(|| {
            let names: Vec<&str> = KNOBS.iter().map(|k| k.0).collect();
            format!("no knob \"{name}\"; knobs: {}", names.join(", "))
        })
}

fn set_particle(c: &mut ParticleRunConfig, knob: &str, v: &str) -> anyhow::Result<()> {
    let num = || -> anyhow::Result<f64> {
        v.parse::<f64>()
            .with_context(|| format!("{knob} = {v}: not a number"))
    };
    match knob {
        "sum_tolerance" => c.hydro.sum_tolerance = num()?,
        "quadrature_points" => c.hydro.quadrature_points = num()? as usize,
        "hydrodynamics" => c.hydrodynamics = v.parse()?,
        "dt" => c.dt = num()?,
        _ => unreachable!("checked knob"),
    }
    c.validate()
        .map_err(|e| anyhow::anyhow!("study {knob} = {v}: {e}"))
}

fn set_meanfield(c: &mut MeanFieldRunConfig, knob: &str, v: &str) -> anyhow::Result<()> {
    let num = || -> anyhow::Result<f64> {
        v.parse::<f64>()
            .with_context(|| format!("{knob} = {v}: not a number"))
    };
    match knob {
        "meanfield_dt" => c.dt_max = num()?,
        "grid" => c.grid = num()? as usize,
        "closure_degree" => c.closure_degree = num()? as usize,
        _ => unreachable!("checked knob"),
    }
    c.validate()
        .map_err(|e| anyhow::anyhow!("study {knob} = {v}: {e}"))
}

/// The rods' unwrapped positions at the start and the end of a particle run.
struct RodPositions {
    start: Vec<[f64; 3]>,
    end: Vec<[f64; 3]>,
}

/// What one run left to compare.
struct Outcome {
    /// Diagnostic times.
    t: Vec<f64>,
    /// The velocity norm at those times.
    u: Vec<f64>,
    /// Particle runs: the rods' start and end positions.
    rods: Option<RodPositions>,
}

/// What a study sweeps.
#[derive(Clone, Debug, Default)]
pub struct StudyOptions {
    /// The knob.
    pub knob: String,
    /// Values to sweep (default: the knob's list).
    pub values: Option<Vec<String>>,
    /// End time of each run (default: the scene run's own).
    pub t_end: Option<f64>,
    /// The stated accuracy (relative error) the cheapest setting must meet.
    pub accuracy: f64,
    /// The scene run to sweep (default: its first run of the knob's model).
    pub run: Option<String>,
}

/// One setting of the knob, its run's config built and checked.
struct Setting {
    /// The knob's value, as given.
    value: String,
    /// Whether it is the reference setting.
    reference: bool,
    /// The run's config with the value set.
    config: RunConfig,
}

/// One setting's run: its wall time and what it left (or why it stopped).
struct SettingRun {
    setting: Setting,
    seconds: f64,
    outcome: anyhow::Result<Outcome>,
}

/// Sweep `opts.knob` over its values on a run of `scene` of the knob's model, each to its end
/// time, into `out/runs/<knob>_<value>`; write `out/study_<knob>.{csv,md,png,svg}`. `event`
/// gets a line per run.
pub fn study(
    scene: &Scene,
    opts: &StudyOptions,
    out: &Path,
    event: &mut dyn FnMut(&str),
) -> anyhow::Result<StudyReport> {
    let knob = knob(&opts.knob)?;
    let accuracy = opts.accuracy;
    if !(accuracy > 0.0 && accuracy < 1.0) {
        bail!("--accuracy = {accuracy} is outside the allowed range (0, 1)");
    }
    let base = base_run(scene, opts, knob)?;
    // Every setting's config is built and checked before anything is written.
    let settings = plan(&base, opts, knob)?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let runs: Vec<SettingRun> = settings
        .into_iter()
        .map(|setting| run_setting(setting, knob, out, event))
        .collect::<anyhow::Result<_>>()?;
    let points = study_points(&runs, knob)?;
    let cheapest = points
        .iter()
        .filter(|p| !p.reference && p.error <= accuracy)
        .min_by(|a, b| a.seconds.total_cmp(&b.seconds))
        .cloned();
    write_csv(&points, knob, out)?;
    let markdown = write_markdown(scene, opts, &base, knob, &points, cheapest.as_ref(), out)?;
    write_chart(&points, knob, accuracy, cheapest.as_ref(), out)?;
    Ok(StudyReport {
        points,
        cheapest,
        markdown,
    })
}

/// The scene's run the knob is swept on: its first of the knob's model (or the one named).
fn base_run(scene: &Scene, opts: &StudyOptions, knob: Knob) -> anyhow::Result<RunConfig> {
    scene
        .runs
        .iter()
        .find(|(n, c)| c.model() == knob.model && opts.run.as_ref().is_none_or(|r| r == n))
        .map(|(_, c)| c.clone())
        .with_context(|| {
            format!(
                "scene {} has no {} run{} for the knob {}",
                scene.info.name,
                knob.model,
                opts.run
                    .as_ref()
                    .map_or(String::new(), |r| format!(" named {r}")),
                knob.name
            )
        })
}

/// The settings to run, the reference last, each with its config.
fn plan(base: &RunConfig, opts: &StudyOptions, knob: Knob) -> anyhow::Result<Vec<Setting>> {
    let mut values: Vec<String> = opts
        .values
        .clone()
        .unwrap_or_else(|| knob.defaults.split(',').map(String::from).collect());
    values.retain(|v| v != knob.reference);
    let settings = values
        .into_iter()
        .map(|v| (v, false))
        .chain([(knob.reference.to_string(), true)]);
    settings
        .map(|(value, reference)| {
            let config = setting_config(base, opts.t_end, knob, &value)?;
            Ok(Setting {
                value,
                reference,
                config,
            })
        })
        .collect()
}

/// The base run's config over the study's window (one snapshot and checkpoint at its end),
/// with the knob set to `value`.
fn setting_config(
    base: &RunConfig,
    t_end: Option<f64>,
    knob: Knob,
    value: &str,
) -> anyhow::Result<RunConfig> {
    Ok(match base {
        RunConfig::Particle(c) => {
            let mut c = c.clone();
            c.t_end = t_end.unwrap_or(c.t_end);
            c.vtk = false;
            c.snapshot_interval = c.t_end;
            c.checkpoint_interval = c.t_end;
            // Diagnostics every 0.2/beta: a whole number of steps for every dt swept.
            c.diagnostic_interval = 0.2f64.min(c.t_end);
            set_particle(&mut c, knob.name, value)?;
            RunConfig::Particle(c)
        }
        RunConfig::MeanField(c) => {
            let mut c = c.clone();
            c.t_end = t_end.unwrap_or(c.t_end);
            c.snapshot_interval = c.t_end;
            c.checkpoint_interval = c.t_end;
            set_meanfield(&mut c, knob.name, value)?;
            RunConfig::MeanField(c)
        }
    })
}

/// Run one setting into `out/runs/<knob>_<value>` (an earlier run there removed), timed.
fn run_setting(
    setting: Setting,
    knob: Knob,
    out: &Path,
    event: &mut dyn FnMut(&str),
) -> anyhow::Result<SettingRun> {
    let dir = out
        .join("runs")
        .join(format!("{}_{}", knob.name, setting.value));
    crate::io::remove_old_run(&dir)?;
    // One-time costs stay out of the timing: closure tables are built (and cached) first.
    if let RunConfig::MeanField(c) = &setting.config {
        meanfield::closure_tables(c.closure_degree)?;
    }
    let t0 = std::time::Instant::now();
    let outcome = run_outcome(&setting.config, &dir);
    let seconds = t0.elapsed().as_secs_f64();
    event(&format!(
        "{} = {}{}: {:.1} s{}",
        knob.name,
        setting.value,
        if setting.reference {
            " (reference)"
        } else {
            ""
        },
        seconds,
        match &outcome {
            Ok(_) => String::new(),
            Err(e) => format!(", stopped: {e:#}"),
        }
    ));
    Ok(SettingRun {
        setting,
        seconds,
        outcome,
    })
}

/// Run `config` into `dir` and keep what the error needs: the velocity norm against time and,
/// for particles, the rods' start and end positions.
fn run_outcome(config: &RunConfig, dir: &Path) -> anyhow::Result<Outcome> {
    match config {
        RunConfig::Particle(c) => {
            let start = particle::initial_rods(c)?.unwrapped();
            particle::run_particle(c, dir, false).and_then(|s| {
                let ts = TimeSeries::read(&dir.join("timeseries.csv"))?;
                Ok(Outcome {
                    t: ts.column("t [1/beta]").unwrap_or_default(),
                    u: ts.column("velocity_norm [beta L]").unwrap_or_default(),
                    rods: Some(RodPositions {
                        start,
                        end: s.rods.unwrapped(),
                    }),
                })
            })
        }
        RunConfig::MeanField(c) => meanfield::run_meanfield(c, dir, false).map(|s| Outcome {
            t: s.timeseries.column("t [mu/|sigma_a|]").unwrap_or_default(),
            u: s.timeseries
                .column("u_l2 [L |sigma_a|/mu]")
                .unwrap_or_default(),
            rods: None,
        }),
    }
}

/// Each setting's error against the reference (the last run, which must have finished).
fn study_points(runs: &[SettingRun], knob: Knob) -> anyhow::Result<Vec<StudyPoint>> {
    let Some(SettingRun {
        outcome: Ok(reference_outcome),
        ..
    }) = runs.last()
    else {
        let why = match runs.last() {
            Some(SettingRun {
                outcome: Err(e), ..
            }) => format!("{e:#}"),
            _ => "no runs".into(),
        };
        bail!(
            "study {}: the reference setting {} failed: {why}",
            knob.name,
            knob.reference
        );
    };
    runs.iter()
        .map(|run| {
            let (error, position_error, failure) = match &run.outcome {
                Err(e) => (f64::INFINITY, f64::INFINITY, Some(format!("{e:#}"))),
                Ok(o) => {
                    let (e, ep) = error_against(o, reference_outcome)?;
                    (e, ep, None)
                }
            };
            let has_flow = match &run.outcome {
                Ok(o) => o.u.iter().any(|&u| u.is_finite() && u != 0.0),
                Err(_) => true,
            };
            Ok(StudyPoint {
                value: run.setting.value.clone(),
                seconds: run.seconds,
                error,
                position_error,
                reference: run.setting.reference,
                failure,
                has_flow,
            })
        })
        .collect()
}

/// `study_<knob>.csv`.
fn write_csv(points: &[StudyPoint], knob: Knob, out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from("value,reference,wall_seconds,error,position_error,failure\n");
    for p in points {
        writeln!(
            csv,
            "{},{},{:.3},{:e},{:e},\"{}\"",
            p.value,
            p.reference,
            p.seconds,
            p.error,
            p.position_error,
            p.failure.clone().unwrap_or_default().replace('"', "'")
        )
        .expect("string");
    }
    write_atomic(
        &out.join(format!("study_{}.csv", knob.name)),
        csv.as_bytes(),
    )?;
    Ok(())
}

/// `study_<knob>.md` (returned too): the base, the window, the verdict and the table.
fn write_markdown(
    scene: &Scene,
    opts: &StudyOptions,
    base: &RunConfig,
    knob: Knob,
    points: &[StudyPoint],
    cheapest: Option<&StudyPoint>,
    out: &Path,
) -> anyhow::Result<String> {
    let Knob {
        name,
        model,
        reference,
        ..
    } = knob;
    let (t_end, accuracy) = (opts.t_end, opts.accuracy);
    let what = "max over the window of |Delta ||u||_2(t)| / max ||u||_2";
    let window = match base {
        RunConfig::Particle(c) => format!("t = 0 to {} (1/beta)", t_end.unwrap_or(c.t_end)),
        RunConfig::MeanField(c) => format!("t = 0 to {} (mu/|sigma_a|)", t_end.unwrap_or(c.t_end)),
    };
    let verdict = match cheapest {
        Some(p) => format!(
            "cheapest setting meeting the stated accuracy {accuracy:.0e}: **{name} = {}** (error {:.2e}, {:.1} s)",
            p.value, p.error, p.seconds
        ),
        None => {
            format!("no setting other than the reference meets the stated accuracy {accuracy:.0e}")
        }
    };
    let mut md = format!(
        "# Study: {name} ({model}, scene `{}`)\n\nBase: {}. Window {window}. Error: {what}, against the reference {name} = {reference}.\n\n{verdict}\n\n| {name} | wall time (s) | error | position error (particle) | note |\n|---|---|---|---|---|\n",
        scene.info.name,
        base.describe()
    );
    for p in points {
        writeln!(
            md,
            "| {}{} | {:.2} | {:.2e} | {:.2e} | {} |",
            p.value,
            if p.reference { " (reference)" } else { "" },
            p.seconds,
            p.error,
            p.position_error,
            match (&p.failure, p.has_flow) {
                (Some(f), _) => f.clone(),
                (None, false) => "no flow: error 1 by construction (not charted)".into(),
                (None, true) => String::new(),
            }
        )
        .expect("string");
    }
    write_atomic(&out.join(format!("study_{name}.md")), md.as_bytes())?;
    Ok(md)
}

/// `study_<knob>.{png,svg}`: error against wall time of the charted settings (with a flow, a
/// finite non-zero error), the stated accuracy as a line from the cheapest charted setting to
/// the reference's wall time, where the reference (error 0 by definition, off a log axis) is
/// labelled.
fn write_chart(
    points: &[StudyPoint],
    knob: Knob,
    accuracy: f64,
    cheapest: Option<&StudyPoint>,
    out: &Path,
) -> anyhow::Result<()> {
    let Knob {
        name, reference, ..
    } = knob;
    let plotted: Vec<&StudyPoint> = points
        .iter()
        .filter(|p| !p.reference && p.has_flow && p.error.is_finite() && p.error > 0.0)
        .collect();
    let mut series = vec![Series {
        label: format!("{name} (labels: values)"),
        points: plotted.iter().map(|p| (p.seconds, p.error)).collect(),
    }];
    let ref_seconds = points.last().map_or(f64::NAN, |p| p.seconds);
    let (t_lo, t_hi) = plotted
        .iter()
        .map(|p| p.seconds)
        .chain(ref_seconds.is_finite().then_some(ref_seconds))
        .fold((f64::INFINITY, 0.0f64), |(a, b), s| (a.min(s), b.max(s)));
    if t_hi > 0.0 && !plotted.is_empty() {
        series.push(Series {
            label: format!("stated accuracy {accuracy:.0e}"),
            points: vec![(t_lo, accuracy), (t_hi, accuracy)],
        });
    }
    let title = match cheapest {
        Some(p) => format!(
            "{name}: cheapest within {accuracy:.0e} is {} (reference {reference}: {ref_seconds:.1} s)",
            p.value
        ),
        None => format!(
            "{name}: only the reference {reference} ({ref_seconds:.1} s) is within {accuracy:.0e}"
        ),
    };
    let mut labels: Vec<(f64, f64, String)> = plotted
        .iter()
        .map(|p| (p.seconds, p.error, p.value.clone()))
        .collect();
    if ref_seconds.is_finite() && !plotted.is_empty() {
        labels.push((ref_seconds, accuracy, format!("{reference} (reference)")));
    }
    log_chart(
        &out.join(format!("study_{name}")),
        &title,
        &format!(
            "wall time [s] ({} worker thread(s))",
            rayon::current_num_threads()
        ),
        &format!("error vs {name} = {reference} [1]"),
        &series,
        &labels,
    )?;
    Ok(())
}

fn error_against(o: &Outcome, r: &Outcome) -> anyhow::Result<(f64, f64)> {
    if o.t.len() != r.t.len() || o.t.iter().zip(&r.t).any(|(a, b)| (a - b).abs() > 1e-9) {
        bail!("diagnostics at different times than the reference's; cannot compare");
    }
    let scale =
        r.u.iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
    // A run without a flow (NaN or zero norms where the reference has one) misses all of it.
    let worst =
        o.u.iter()
            .zip(&r.u)
            .filter(|(_, b)| b.is_finite())
            .map(|(a, b)| if a.is_finite() { (a - b).abs() } else { *b })
            .fold(0.0, f64::max);
    let position = match (&o.rods, &r.rods) {
        (Some(run), Some(reference)) => {
            let dx: f64 = run
                .end
                .iter()
                .zip(&reference.end)
                .map(|(a, b)| norm(sub(*a, *b)).powi(2))
                .sum();
            let travel: f64 = reference
                .end
                .iter()
                .zip(&reference.start)
                .map(|(a, b)| norm(sub(*a, *b)).powi(2))
                .sum();
            (dx / travel.max(1e-300)).sqrt()
        }
        _ => f64::NAN,
    };
    Ok((worst / scale.max(1e-300), position))
}
