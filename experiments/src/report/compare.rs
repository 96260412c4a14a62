//! `motile compare RUN... --out DIR` (docs/MODEL.md §5): particle and mean-field runs on one chart in
//! the mean-field unit system (the curves of [`crate::report::curves`]): the velocity norm
//! against time with its growth phases, the table of its time averages, the time-averaged
//! correlation functions, trajectory statistics and velocity slices.
//!
//! Conversions (docs/MODEL.md §5): particle time `t_mf = t_p nu / (8 eta mu)`, particle velocity
//! (reported normalised by `beta L`) `u_mf = (u_p / (beta L)) 8 eta mu / nu`; mean-field runs are
//! already in those units.

use crate::io::write_atomic;
use crate::report::compact;
use crate::report::compare_figures::CompareFigures;
use crate::report::curves::{
    AnalysisWindow, CorrCurve, CorrelationLength, NormCurve, NormStatistics, RunAnalysis,
    TrajectoryCurve, ZERO_FIELD_NORM, analyse, norm_curve_of,
};
use crate::report::opened_run::OpenedRun;
use crate::report::plot::{Chart, Series, semilog_chart};
use crate::report::series::write_series;
use crate::report::trajectory_series::{ComparedColumns, write_particle_statistics};
use anyhow::{Context, bail};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `compare` wrote.
#[derive(Clone, Debug)]
pub struct CompareReport {
    /// The runs compared, each opened once (in the order given).
    pub runs: Vec<OpenedRun>,
    /// The curves (one per run).
    pub curves: Vec<NormCurve>,
    /// Time-averaged velocity autocorrelations (runs whose snapshots carry a flow).
    pub correlations: Vec<CorrCurve>,
    /// Trajectory statistics of the particle runs.
    pub trajectories: Vec<TrajectoryCurve>,
    /// Markdown table of the time averages.
    pub table: String,
}

/// Compare `runs` and write `velocity_norm.{png,svg,csv}`, `summary.{csv,md}`,
/// `velocity_correlation.{png,svg,csv}` and, for particle runs, `msd.{png,svg}`,
/// `orientation.{png,svg}` and `trajectories.csv`, the series summary `series.{csv,md}` and
/// `saturated_norm.{png,svg}` into `out`. Time averages are over each run's saturated state
/// ([`crate::report::curves::saturated_from`]; the table and the legends say which).
///
/// Everything is written into a staging folder beside `out` first and moved into `out` only
/// when all of it succeeded: a comparison that fails (a damaged snapshot, an unreadable run)
/// leaves nothing under the final names.
pub fn compare(runs: &[PathBuf], out: &Path) -> anyhow::Result<CompareReport> {
    compare_with_table(runs, out, None)
}

/// [`compare`], with the rows of an earlier series table (`table`, e.g. the gallery's
/// `paper_dilute_series.csv`) for runs not given here added to `series.csv` and to the
/// saturated norm's chart: members whose run directories are elsewhere still count.
pub fn compare_with_table(
    runs: &[PathBuf],
    out: &Path,
    table: Option<&Path>,
) -> anyhow::Result<CompareReport> {
    if runs.is_empty() {
        bail!("compare: give at least one run directory");
    }
    let name = out
        .file_name()
        .map_or("compare".into(), |n| n.to_string_lossy().into_owned());
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent)
        .with_context(|| format!("{}: cannot create", parent.display()))?;
    let stage = parent.join(format!(".{name}.partial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&stage);
    let result = compare_into(runs, table, &stage).and_then(|report| {
        std::fs::create_dir_all(out)
            .with_context(|| format!("{}: cannot create", out.display()))?;
        for entry in std::fs::read_dir(&stage)? {
            let entry = entry?;
            let target = out.join(entry.file_name());
            std::fs::rename(entry.path(), &target)
                .with_context(|| format!("{}: cannot write", target.display()))?;
        }
        Ok(report)
    });
    let _ = std::fs::remove_dir_all(&stage);
    result
}

/// Where a run's time in mean-field units falls in its own unit.
fn own_time(c: &NormCurve, t_mf: f64) -> f64 {
    c.particle.as_ref().map_or(t_mf, |p| t_mf * p.time_unit)
}

/// The note under the summary table.
const SUMMARY_NOTE: &str = "\nTime averages are over each run's saturated state: from the later of the end of its growth phase and half the run, to its end (samples correlated over a few diagnostic intervals: the standard error comes from batch means over up to 10 contiguous blocks). Particle runs start at their sampling noise, about 1/sqrt(N) in each box mode, while the continuum starts from a seeded perturbation, so the particle curves start apart.\n";

/// [`compare`] writing straight into `out`: each run opened once, its norm curve and statistics
/// derived, then the norm's files, its snapshots' analysis, the correlation and series tables
/// and the figures.
fn compare_into(
    runs: &[PathBuf],
    earlier: Option<&Path>,
    out: &Path,
) -> anyhow::Result<CompareReport> {
    let (opened, curves) = open_runs(runs)?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let statistics: Vec<NormStatistics> = curves.iter().map(NormStatistics::of).collect();
    write_norm_csv(&curves, out)?;
    let mut table = write_summary(&curves, &statistics, out)?;
    write_norm_chart(&curves, out)?;
    let analyses = analyse_runs(&opened, &curves, &statistics)?;
    table.push_str(&write_correlation_lengths(&curves, &analyses, out)?);
    write_order_correlations(&curves, &analyses, out)?;
    let corr_u_zeros: Vec<f64> = analyses.iter().map(first_zero_of_u).collect();
    write_series(&curves, &statistics, &corr_u_zeros, earlier, out)?;
    let compared: Vec<ComparedColumns> = statistics
        .iter()
        .zip(&analyses)
        .map(|(s, a)| ComparedColumns::of(s, a))
        .collect();
    write_particle_statistics(&opened, &compared, out)?;
    table.push_str(SUMMARY_NOTE);
    write_atomic(&out.join("summary.md"), table.as_bytes())?;
    let figures = CompareFigures::collect(&curves, analyses);
    figures.write(out)?;
    Ok(CompareReport {
        runs: opened,
        curves,
        correlations: figures.correlations,
        trajectories: figures.trajectories,
        table,
    })
}

/// Open every run once and read its norm curve (in the order given; the first that fails
/// stops the comparison).
fn open_runs(runs: &[PathBuf]) -> anyhow::Result<(Vec<OpenedRun>, Vec<NormCurve>)> {
    runs.iter()
        .map(|r| {
            let run = OpenedRun::open(r)?;
            let curve = norm_curve_of(&run)?;
            Ok((run, curve))
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .map(|pairs| pairs.into_iter().unzip())
}

/// `velocity_norm.csv`: every run's norm against time, mean-field units.
fn write_norm_csv(curves: &[NormCurve], out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from("run,label,t [mu/|sigma_a|],u_l2 [L |sigma_a|/mu]\n");
    for c in curves {
        for (t, u) in c.t.iter().zip(&c.u) {
            writeln!(csv, "{},\"{}\",{t:e},{u:e}", c.run.display(), c.label).expect("string");
        }
    }
    write_atomic(&out.join("velocity_norm.csv"), csv.as_bytes())?;
    Ok(())
}

/// `summary.csv` and the time averages' table (returned: `summary.md` gets more below it).
fn write_summary(
    curves: &[NormCurve],
    statistics: &[NormStatistics],
    out: &Path,
) -> anyhow::Result<String> {
    let mut md = String::from(
        "| run | averaging window (t, mean-field units) | time-averaged velocity norm (mean-field units) | standard error | samples | growth phase (t) | growth rate over the phase (peak local rate), mean-field units | R^2, grew by | the continuum's linear theory at the run's zeta (M3; the particle box theory is in series.md) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut csv = String::from(
        "run,label,t0,t1,mean_u_l2,std_error,samples,growth_phase,growth_t0,growth_t1,growth_rate,growth_rate_std_error,peak_rate,r_squared,growth_factor,theory_rate\n",
    );
    for (c, s) in curves.iter().zip(statistics) {
        md.push_str(&summary_row(c, s));
        let (t0, t1, w) = (s.saturated_from, s.t_end, &s.average);
        let (g, phase) = s.fit_or_nan();
        writeln!(
            csv,
            "{},\"{}\",{t0:e},{t1:e},{:e},{:e},{},{phase},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            c.run.display(),
            c.label,
            w.mean,
            w.std_error,
            w.samples,
            g.t0,
            g.t1,
            g.rate,
            g.std_error,
            g.peak_rate,
            g.r_squared,
            g.growth_factor,
            c.theory_rate
        )
        .expect("string");
    }
    write_atomic(&out.join("summary.csv"), csv.as_bytes())?;
    Ok(md)
}

/// One run's row of the time averages' table.
fn summary_row(c: &NormCurve, s: &NormStatistics) -> String {
    let (window, rate, quality) = match &s.growth {
        Some((g, true)) => (
            format!("[{:.3}, {:.3}]", g.t0, g.t1),
            format!(
                "{:.4} +- {:.1e} (peak {:.4})",
                g.rate, g.std_error, g.peak_rate
            ),
            format!("{:.3}, x{:.1}", g.r_squared, g.growth_factor),
        ),
        Some((g, false)) => (
            "none".into(),
            "-".into(),
            format!(
                "no growth phase (over the run: R^2 {:.2}, x{:.2})",
                g.r_squared, g.growth_factor
            ),
        ),
        None => ("too few samples".into(), "-".into(), "-".into()),
    };
    let w = &s.average;
    format!(
        "| {} | [{:.3}, {:.3}] | {:.4e} | {:.1e} | {} | {window} | {rate} | {quality} | {:.4} |\n",
        c.label, s.saturated_from, s.t_end, w.mean, w.std_error, w.samples, c.theory_rate
    )
}

/// A linear theory's rate drawn over one run's curve.
struct TheorySlope<'a> {
    /// Index of the run (its colour).
    run: usize,
    /// The run's curve.
    curve: &'a NormCurve,
    /// The rate, mean-field units.
    rate: f64,
    /// Which theory.
    what: String,
}

/// The linear theories of each run: the box theory's Re sigma for particles (docs/MODEL.md
/// §5b), also with the rotational diffusion measured in them, M3 for the mean field.
fn theory_slopes(curves: &[NormCurve]) -> Vec<TheorySlope<'_>> {
    let mut slopes = Vec::new();
    for (run, curve) in curves.iter().enumerate() {
        let slope = |rate: f64, what: String| TheorySlope {
            run,
            curve,
            rate,
            what,
        };
        match &curve.particle {
            Some(p) => {
                if let Some(s) = p.box_theory {
                    slopes.push(slope(s.re, format!("L/l = {} box theory", p.box_length)));
                }
                if let (Some(s), Some(d)) = (p.box_theory_dr, p.rotational_diffusion) {
                    slopes.push(slope(
                        s.re,
                        format!(
                            "L/l = {} box theory, measured d_r = {d:.1e}/beta",
                            p.box_length
                        ),
                    ));
                }
            }
            None => slopes.push(slope(curve.theory_rate, "M3".to_string())),
        }
    }
    slopes
}

/// A theory's exponential from the curve's first sample until it reaches twice the largest
/// norm `u_max` (or the curve ends); `None` for a damped theory or a curve without samples.
fn theory_series(slope: &TheorySlope, u_max: f64) -> Option<Series> {
    let (c, rate) = (slope.curve, slope.rate);
    let (&t0, &u0) = (c.t.first()?, c.u.first()?);
    if rate <= 0.0 || u0 <= 0.0 {
        return None;
    }
    let t_hit = t0 + (2.0 * u_max / u0).ln() / rate;
    let t1 = t_hit.min(c.t.last().copied().unwrap_or(t0));
    Some(Series {
        label: format!("linear theory ({}): rate {rate:.3}", slope.what),
        points: (0..=20)
            .map(|k| {
                let t = t0 + (t1 - t0) * k as f64 / 20.0;
                (t, u0 * (rate * (t - t0)).exp())
            })
            .collect(),
    })
}

/// `velocity_norm.{png,svg}`: the norms on a log axis, each run's linear theory drawn as a
/// slope from its first sample.
fn write_norm_chart(curves: &[NormCurve], out: &Path) -> anyhow::Result<()> {
    let u_max = curves
        .iter()
        .flat_map(|c| c.u.iter().copied())
        .fold(0.0, f64::max);
    let theory: Vec<(Series, usize)> = theory_slopes(curves)
        .iter()
        .filter_map(|slope| Some((theory_series(slope, u_max)?, slope.run)))
        .collect();
    semilog_chart(
        &out.join("velocity_norm"),
        &Chart {
            title: "Velocity norm (particles: box-scale modes), mean-field units",
            x_label: "t [mu/|sigma_a|]",
            y_label: "||u||_2 [L |sigma_a|/mu]",
            series: curves
                .iter()
                .map(|c| Series {
                    label: match &c.particle {
                        Some(p) => format!("{} (N = {}, from its noise)", c.label, p.rods),
                        None => c.label.clone(),
                    },
                    points: c.t.iter().copied().zip(c.u.iter().copied()).collect(),
                })
                .collect(),
        },
        &theory,
    )?;
    Ok(())
}

/// Each run's snapshots analysed once: Corr[u] and the order-parameter correlations over its
/// saturated state (in its own time unit), the velocity slice nearest the latest time all runs
/// reached, trajectories.
fn analyse_runs(
    opened: &[OpenedRun],
    curves: &[NormCurve],
    statistics: &[NormStatistics],
) -> anyhow::Result<Vec<RunAnalysis>> {
    let common = curves
        .iter()
        .filter_map(|c| c.t.last().copied())
        .fold(f64::INFINITY, f64::min);
    opened
        .iter()
        .zip(curves.iter().zip(statistics))
        .map(|(run, (c, s))| {
            let window = AnalysisWindow {
                label: &c.label,
                t_start: own_time(c, s.saturated_from),
                slice_at: common.is_finite().then(|| own_time(c, common)),
            };
            if crate::report::products::is_compact(run) {
                compact::read_analysis(run, &c.label)
            } else if run.snapshot_paths.is_empty() {
                anyhow::bail!(
                    "{}: no snapshots, and no compare/ products to draw the run from",
                    run.path().display()
                )
            } else {
                analyse(run, &window)
            }
        })
        .collect()
}

/// `correlation_lengths.csv`, and the table of correlation lengths (returned, for
/// `summary.md`).
fn write_correlation_lengths(
    curves: &[NormCurve],
    analyses: &[RunAnalysis],
    out: &Path,
) -> anyhow::Result<String> {
    let mut csv = String::from("run,label,field,correlation_length [L],correlation_length [l]\n");
    let mut md = String::from(
        "\n| run | correlation lengths (first zero of the Corr averaged over the saturated state): r/L (r/l for particle runs) |\n|---|---|\n",
    );
    for (c, a) in curves.iter().zip(analyses) {
        let mut cells = Vec::new();
        for CorrelationLength { field, length: z } in &a.lengths {
            let in_l = a.particle.map_or(f64::NAN, |p| z * p.box_length);
            writeln!(
                csv,
                "{},\"{}\",{field},{z:e},{in_l:e}",
                c.run.display(),
                c.label
            )
            .expect("string");
            cells.push(if z.is_nan() {
                format!("{field}: no zero")
            } else if a.particle.is_some() {
                format!("{field}: {z:.3} ({in_l:.2})")
            } else {
                format!("{field}: {z:.3}")
            });
        }
        for field in &a.zero_fields {
            cells.push(format!(
                "{field}: identically zero (||{field}||_2 <= {ZERO_FIELD_NORM:.0e}), not plotted"
            ));
        }
        writeln!(md, "| {} | {} |", c.label, cells.join("; ")).expect("string");
    }
    write_atomic(&out.join("correlation_lengths.csv"), csv.as_bytes())?;
    Ok(md)
}

/// `order_correlations.csv`: each run's time-averaged order-parameter correlations,
/// normalised at 0, against `r / L` (what a comparison drawn from compact products reads back).
fn write_order_correlations(
    curves: &[NormCurve],
    analyses: &[RunAnalysis],
    out: &Path,
) -> anyhow::Result<()> {
    let mut csv = String::from("label,field,r/L,Corr/Corr(0) [1]\n");
    for (c, a) in curves.iter().zip(analyses) {
        for o in &a.order {
            for (r, v) in &o.points {
                writeln!(csv, "\"{}\",{},{r:e},{v:e}", c.label, o.field).expect("string");
            }
        }
    }
    write_atomic(&out.join("order_correlations.csv"), csv.as_bytes()).map_err(anyhow::Error::from)
}

/// The first zero of a run's time-averaged Corr[u] (`r / L`); NaN without one.
fn first_zero_of_u(a: &RunAnalysis) -> f64 {
    a.lengths
        .iter()
        .find(|l| l.field == "u")
        .map_or(f64::NAN, |l| l.length)
}

#[cfg(test)]
mod tests {
    use motile_particle::model::units::{DEFAULT_DIAMETER, particle_to_meanfield};

    #[test]
    fn conversions_are_the_model_ones() {
        // nu = 0.625: 8 eta / nu = 2.3454...
        let s = 8.0 * 0.183_233_6 / 0.625;
        let (t, u) = particle_to_meanfield(10.0, 0.01, 0.625, DEFAULT_DIAMETER);
        assert!(
            (t - 10.0 / s).abs() < 1e-5 && (u - 0.01 * s).abs() < 1e-7,
            "{t} {u}"
        );
    }
}
