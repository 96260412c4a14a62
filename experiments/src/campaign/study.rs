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
use crate::report::statistics::{Estimate, MIN_SNAPSHOTS, RunStatistics, StatisticsWindow};
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::{Context, bail};
use motile_particle::model::geometry::{norm, sub};
use std::fmt::Write as _;
use std::path::Path;

/// The knobs `motile study` sweeps: name, model, default values (least to most accurate) and the
/// reference setting.
pub const KNOBS: [(&str, &str, &str, &str); 8] = [
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
    ("gmres_tolerance", "particle", "1e-2,1e-3,1e-4,1e-5", "1e-7"),
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
    /// The velocity norm's history against the reference's: max over the window of
    /// |Delta ||u||_2(t)| / max ||u||_2 (the error itself where it is not on statistics).
    pub history_error: f64,
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
    /// With `--statistics-from`: the run's statistics over the window, and each one's relative
    /// difference from the reference's (the error is their largest).
    pub statistics: Option<(RunStatistics, [f64; 4])>,
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
struct Knob<'a> {
    /// The knob's name.
    name: &'static str,
    /// The model it belongs to: "particle" or "meanfield".
    model: &'static str,
    /// The values swept by default, comma-separated, least to most accurate.
    defaults: &'static str,
    /// The reference setting (the knob's own, or the study's `--reference`).
    reference: &'a str,
}

fn knob(name: &str) -> anyhow::Result<Knob<'static>> {
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
        "gmres_tolerance" => c.hydro.gmres_tolerance = num()?,
        "hydrodynamics" => c.hydrodynamics = v.parse()?,
        "dt" => {
            c.dt = num()?;
            // The study's diagnostics (every 0.2/beta) and statistics' snapshots (every
            // 0.4/beta) must fall on whole steps.
            let per = 0.2 / c.dt;
            if (per - per.round()).abs() > 1e-9 * per {
                anyhow::bail!(
                    "study dt = {v}: the study's diagnostics every 0.2/beta need a whole number of steps; use a dt that divides 0.2 (0.2, 0.1, 0.05, 0.04, 0.025, 0.02, ...)"
                );
            }
            // The contact margin follows the step where it must: at least the 2.5 U dt two
            // rods can close in one step (the validation's bound).
            c.contact.margin = c.contact.margin.max(2.5 * c.dt);
        }
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
    /// With a statistics window: the run's statistics over it.
    statistics: Option<RunStatistics>,
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
    /// Particle knobs: compare on statistics over `[from, t_end]` instead of pathwise (the
    /// time-averaged norm, the orientation decorrelation rate, the MSD at a lag, the first zero
    /// of `Corr[Q]`); snapshots every 0.4/beta.
    pub statistics_from: Option<f64>,
    /// The reference setting (default: the knob's).
    pub reference: Option<String>,
}

/// The window of a study on statistics from `from` to `t_end`: decorrelation fitted over lags
/// 1 to 8/beta and the MSD at 4/beta, each at most a quarter of the window (so that both halves
/// of the window measure them).
pub fn statistics_window(from: f64, t_end: f64) -> StatisticsWindow {
    let quarter = 0.25 * (t_end - from);
    StatisticsWindow {
        t0: from,
        t1: t_end,
        fit_from: 1.0f64.min(0.25 * quarter),
        fit_to: 8.0f64.min(quarter),
        msd_lag: 4.0f64.min(quarter),
    }
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
    let mut knob = knob(&opts.knob)?;
    if let Some(r) = &opts.reference {
        knob.reference = r;
    }
    let accuracy = opts.accuracy;
    if !(accuracy > 0.0 && accuracy < 1.0) {
        bail!("--accuracy = {accuracy} is outside the allowed range (0, 1)");
    }
    let base = base_run(scene, opts, knob)?;
    let window = match (opts.statistics_from, &base) {
        (None, _) => None,
        (Some(from), RunConfig::Particle(c)) => {
            let t_end = opts.t_end.unwrap_or(c.t_end);
            if !(from >= 0.0 && from < t_end) {
                bail!(
                    "--statistics-from = {from} is outside the allowed range [0, {t_end}) (the window's end)"
                );
            }
            Some(statistics_window(from, t_end))
        }
        (Some(_), RunConfig::MeanField(_)) => {
            bail!(
                "--statistics-from applies to particle knobs; {} is a mean-field knob",
                knob.name
            )
        }
    };
    // Every setting's config is built and checked before anything is written.
    let settings = plan(&base, opts, knob)?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let runs: Vec<SettingRun> = settings
        .into_iter()
        .map(|setting| run_setting(setting, (knob, window), out, event))
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
fn base_run(scene: &Scene, opts: &StudyOptions, knob: Knob<'_>) -> anyhow::Result<RunConfig> {
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
fn plan(base: &RunConfig, opts: &StudyOptions, knob: Knob<'_>) -> anyhow::Result<Vec<Setting>> {
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
            let config = setting_config(base, (opts.t_end, opts.statistics_from), knob, &value)?;
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
    (t_end, statistics): (Option<f64>, Option<f64>),
    knob: Knob<'_>,
    value: &str,
) -> anyhow::Result<RunConfig> {
    Ok(match base {
        RunConfig::Particle(c) => {
            let mut c = c.clone();
            c.t_end = t_end.unwrap_or(c.t_end);
            c.vtk = false;
            // Statistics read snapshots every 0.4/beta (a whole number of steps for every dt
            // swept); pathwise errors need none but the last.
            c.snapshot_interval = if statistics.is_some() {
                0.4f64.min(c.t_end)
            } else {
                c.t_end
            };
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
    (knob, window): (Knob, Option<StatisticsWindow>),
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
    // The statistics read the snapshots after the timing.
    let outcome = outcome.and_then(|o| match window {
        Some(w) => match RunStatistics::of(&dir, &w)? {
            Some(s) => Ok(Outcome {
                statistics: Some(s),
                ..o
            }),
            None => bail!(
                "{}: fewer than {MIN_SNAPSHOTS} snapshots in t = {}-{}; the statistics need more",
                dir.display(),
                w.t0,
                w.t1
            ),
        },
        None => Ok(o),
    });
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
                    statistics: None,
                })
            })
        }
        RunConfig::MeanField(c) => meanfield::run_meanfield(c, dir, false).map(|s| Outcome {
            t: s.timeseries.column("t [mu/|sigma_a|]").unwrap_or_default(),
            u: s.timeseries
                .column("u_l2 [L |sigma_a|/mu]")
                .unwrap_or_default(),
            rods: None,
            statistics: None,
        }),
    }
}

/// Each setting's error against the reference (the last run, which must have finished).
fn study_points(runs: &[SettingRun], knob: Knob<'_>) -> anyhow::Result<Vec<StudyPoint>> {
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
            let (history_error, position_error, failure) = match &run.outcome {
                Err(e) => (f64::INFINITY, f64::INFINITY, Some(format!("{e:#}"))),
                Ok(o) => {
                    let (e, ep) = error_against(o, reference_outcome)?;
                    (e, ep, None)
                }
            };
            let statistics = match (&run.outcome, &reference_outcome.statistics) {
                (
                    Ok(Outcome {
                        statistics: Some(s),
                        ..
                    }),
                    Some(r),
                ) => Some((*s, statistics_errors(s, r))),
                _ => None,
            };
            // On statistics, the error is the largest relative difference of the four.
            let error = match &statistics {
                Some((_, e)) => e.iter().copied().fold(0.0, f64::max),
                None => history_error,
            };
            let has_flow = match &run.outcome {
                Ok(o) => o.u.iter().any(|&u| u.is_finite() && u != 0.0),
                Err(_) => true,
            };
            Ok(StudyPoint {
                value: run.setting.value.clone(),
                seconds: run.seconds,
                error,
                history_error,
                position_error,
                reference: run.setting.reference,
                failure,
                has_flow,
                statistics,
            })
        })
        .collect()
}

/// `study_<knob>.csv`.
fn write_csv(points: &[StudyPoint], knob: Knob<'_>, out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from(
        "value,reference,wall_seconds,error,history_error,position_error,failure,norm [beta L],norm_spread,decorrelation_rate [beta],rate_spread,msd [l^2],msd_spread,corr_q_zero [l],zero_spread\n",
    );
    for p in points {
        writeln!(
            csv,
            "{},{},{:.3},{:e},{:e},{:e},\"{}\",{}",
            p.value,
            p.reference,
            p.seconds,
            p.error,
            p.history_error,
            p.position_error,
            p.failure.clone().unwrap_or_default().replace('"', "'"),
            statistics_columns(p.statistics.as_ref().map(|s| &s.0))
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
    knob: Knob<'_>,
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
    let what = if opts.statistics_from.is_some() {
        "the largest relative difference of the four statistics below"
    } else {
        "max over the window of |Delta ||u||_2(t)| / max ||u||_2"
    };
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
        "# Study: {name} ({model}, scene `{}`)\n\nBase: {}. Window {window}. Error: {what}, against the reference {name} = {reference}.\n\n{verdict}\n\n| {name} | wall time (s) | error | norm history error | position error (particle) | note |\n|---|---|---|---|---|---|\n",
        scene.info.name,
        base.describe()
    );
    for p in points {
        writeln!(
            md,
            "| {}{} | {:.2} | {:.2e} | {:.2e} | {:.2e} | {} |",
            p.value,
            if p.reference { " (reference)" } else { "" },
            p.seconds,
            p.error,
            p.history_error,
            p.position_error,
            match (&p.failure, p.has_flow) {
                (Some(f), _) => f.clone(),
                (None, false) => "no flow: error 1 by construction (not charted)".into(),
                (None, true) => String::new(),
            }
        )
        .expect("string");
    }
    if let Some(w) = opts
        .statistics_from
        .map(|from| statistics_window(from, t_end.unwrap_or_else(|| base_t_end(base))))
    {
        md.push_str(&statistics_table(points, name, &w));
    }
    write_atomic(&out.join(format!("study_{name}.md")), md.as_bytes())?;
    Ok(md)
}

/// The base run's end time.
fn base_t_end(base: &RunConfig) -> f64 {
    match base {
        RunConfig::Particle(c) => c.t_end,
        RunConfig::MeanField(c) => c.t_end,
    }
}

/// A CSV row's statistics columns (NaN without statistics).
fn statistics_columns(s: Option<&RunStatistics>) -> String {
    let nan = Estimate {
        value: f64::NAN,
        spread: f64::NAN,
    };
    let all = s.map_or([nan; 4], |s| {
        [s.norm, s.decorrelation_rate, s.msd, s.corr_zeros[2]]
    });
    all.iter()
        .map(|e| format!("{:e},{:e}", e.value, e.spread))
        .collect::<Vec<_>>()
        .join(",")
}

/// The statistics of each setting and their relative differences from the reference's.
fn statistics_table(points: &[StudyPoint], name: &str, w: &StatisticsWindow) -> String {
    let mut md = format!(
        "\nStatistics over t = {}-{} (1/beta), each +- half the difference between the window's halves (the norm: +- its batch-means standard error); in brackets the relative difference from the reference's. Decorrelation rate: -d ln <p(t0 + tau).p(t0)>/d tau over tau = {}-{}/beta; MSD at tau = {}/beta; Corr[Q]'s first zero of its time average.\n\n| {name} | ||u||_2 (beta L) | decorrelation rate (beta) | MSD (l^2) | Corr[Q] zero (l) | largest difference |\n|---|---|---|---|---|---|\n",
        w.t0, w.t1, w.fit_from, w.fit_to, w.msd_lag
    );
    for p in points {
        let Some((s, e)) = &p.statistics else {
            continue;
        };
        let cell = |x: &Estimate, e: f64| {
            format!("{:.4e} +- {:.1e} [{:.1}%]", x.value, x.spread, 100.0 * e)
        };
        writeln!(
            md,
            "| {}{} | {} | {} | {} | {} | {:.1}% |",
            p.value,
            if p.reference { " (reference)" } else { "" },
            cell(&s.norm, e[0]),
            cell(&s.decorrelation_rate, e[1]),
            cell(&s.msd, e[2]),
            cell(&s.corr_zeros[2], e[3]),
            100.0 * p.error
        )
        .expect("string");
    }
    md
}

/// `study_<knob>.{png,svg}`: error against wall time of the charted settings (with a flow, a
/// finite non-zero error), the stated accuracy as a line from the cheapest charted setting to
/// the reference's wall time, and the reference (error 0 by definition, off a log axis) as a
/// vertical line at its wall time, labelled at its top.
fn write_chart(
    points: &[StudyPoint],
    knob: Knob<'_>,
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
    // The reference (error 0, off the log axis) as a vertical line at its wall time over the
    // charted errors' range, labelled at its top.
    if ref_seconds.is_finite() && !plotted.is_empty() {
        let (y_lo, y_hi) = plotted
            .iter()
            .map(|p| p.error)
            .chain([accuracy])
            .fold((f64::INFINITY, 0.0f64), |(a, b), e| (a.min(e), b.max(e)));
        series.push(Series {
            label: format!("reference {reference}: its wall time (error 0)"),
            points: vec![(ref_seconds, y_lo), (ref_seconds, y_hi)],
        });
        labels.push((ref_seconds, y_hi, format!("{reference} (reference)")));
    }
    log_chart(
        &out.join(format!("study_{name}")),
        &title,
        &format!(
            "wall time [s] ({} worker thread(s))",
            rayon::current_num_threads()
        ),
        &if points.iter().any(|p| p.statistics.is_some()) {
            format!("largest difference of the statistics vs {name} = {reference} [1]")
        } else {
            format!("error vs {name} = {reference} [1]")
        },
        &series,
        &labels,
    )?;
    Ok(())
}

/// Each statistic's relative difference from the reference's: the norm, the decorrelation
/// rate, the MSD and `Corr[Q]`'s zero (NaN compares as 1: a statistic a run could not measure).
fn statistics_errors(s: &RunStatistics, r: &RunStatistics) -> [f64; 4] {
    let rel = |a: f64, b: f64| {
        let e = (a - b).abs() / b.abs();
        if e.is_finite() { e } else { 1.0 }
    };
    [
        rel(s.norm.value, r.norm.value),
        rel(s.decorrelation_rate.value, r.decorrelation_rate.value),
        rel(s.msd.value, r.msd.value),
        rel(s.corr_zeros[2].value, r.corr_zeros[2].value),
    ]
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
