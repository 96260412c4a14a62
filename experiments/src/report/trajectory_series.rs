//! The particle runs' statistics table of `motile compare` (`particle_statistics.{csv,md}`):
//! one row per particle run with snapshots, over the later half of the run (the paper averages
//! its concentrated runs over t = 100-200/beta): the time-averaged velocity norm with its
//! standard error, the orientation decorrelation rate, the MSD at a stated lag and the first
//! zeros of `Corr[c]`, `Corr[n]` and `Corr[Q]` in l and in L ([`RunStatistics`]); every row also
//! has what the comparison measured in mean-field units (the norm's time average over the
//! saturated state, the first zero of `Corr[u]`), so that the continuum's runs compared beside
//! the particles have their rows too (their particle columns NaN); and, with
//! concentrated boxes (nu > 1) of two or more sizes, the time-averaged norm against L/l on
//! log-log axes with its fitted power law and the line l/L the paper finds
//! (`norm_scaling.{png,svg}`).

use crate::io::write_atomic;
use crate::report::curves::{NormStatistics, RunAnalysis};
use crate::report::opened_run::OpenedRun;
use crate::report::pair_structure::{PairRun, write_pair_correlations};
use crate::report::plot::{Series, log_chart};
use crate::report::statistics::{
    Estimate, MIN_SNAPSHOTS, RunStatistics, StatisticsWindow, pair_correlations, window_snapshots,
};
use std::fmt::Write as _;
use std::path::Path;

/// The lag of the MSD column (1/beta).
pub const MSD_LAG: f64 = 4.0;

const CSV_HEADER: &str = "run,model,nu,L/l,rods,level,t0 [1/beta],t1 [1/beta],snapshots,mean_u_l2 [beta L],std_error,decorrelation_rate [beta],rate_spread,msd_lag [1/beta],msd [l^2],msd_spread,corr_c_zero [l],corr_n_zero [l],corr_q_zero [l],corr_q_zero_spread [l],corr_c_zero [L],corr_n_zero [L],corr_q_zero [L],mean_u_l2 [mf],std_error [mf],t0 [mf],t1 [mf],corr_u_zero [L]\n";

/// What the comparison measured of one run in mean-field units, for every run (particle or
/// continuum): the norm's time average over the saturated state with its standard error, and
/// the first zeros of its time-averaged `Corr[u]` and `Corr[Q]` (`r / L`, NaN without one).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ComparedColumns {
    /// The norm's time average (mean-field units) with its batch-means standard error.
    pub(crate) mean: f64,
    /// Its standard error.
    pub(crate) std_error: f64,
    /// The averaging window, mean-field units.
    pub(crate) t0: f64,
    /// Its end.
    pub(crate) t1: f64,
    /// Snapshots in the analysis' averaging window.
    pub(crate) snapshots: usize,
    /// First zero of the time-averaged `Corr[u]`, `r / L`.
    pub(crate) corr_u_zero: f64,
    /// First zero of the time-averaged `Corr[Q]`, `r / L`.
    pub(crate) corr_q_zero: f64,
}

impl ComparedColumns {
    /// The columns of one run from the comparison's norm statistics and analysis.
    pub(crate) fn of(s: &NormStatistics, a: &RunAnalysis) -> Self {
        let zero = |field: &str| {
            a.lengths
                .iter()
                .find(|l| l.field == field)
                .map_or(f64::NAN, |l| l.length)
        };
        Self {
            mean: s.average.mean,
            std_error: s.average.std_error,
            t0: s.saturated_from,
            t1: s.t_end,
            snapshots: a.window_count,
            corr_u_zero: zero("u"),
            corr_q_zero: zero("Q"),
        }
    }
}

/// One particle run's row.
struct Row {
    run: String,
    nu: f64,
    box_length: f64,
    rods: usize,
    level: String,
    window: StatisticsWindow,
    stats: RunStatistics,
    compared: ComparedColumns,
}

/// One continuum run's row: its name and what the comparison measured.
struct ContinuumRow {
    run: String,
    compared: ComparedColumns,
}

/// The window of a run ending at `t_end`: its later half, the decorrelation fitted over lags
/// 1-8/beta and the MSD at [`MSD_LAG`] (each at most a quarter of the window).
fn later_half(t_end: f64) -> StatisticsWindow {
    let (t0, t1) = (0.5 * t_end, t_end);
    let quarter = 0.25 * (t1 - t0);
    StatisticsWindow {
        t0,
        t1,
        fit_from: 1.0f64.min(0.25 * quarter),
        fit_to: 8.0f64.min(quarter),
        msd_lag: MSD_LAG.min(quarter),
    }
}

/// `particle_statistics.{csv,md}` of the particle runs among `opened` with at least
/// [`MIN_SNAPSHOTS`] snapshots in their later half (none: nothing written) and of the continuum
/// runs beside them (`compared`: each run's columns in mean-field units, in the order of
/// `opened`), and `norm_scaling.{png,svg}` where concentrated ones have two or more box sizes.
pub(crate) fn write_particle_statistics(
    opened: &[OpenedRun],
    compared: &[ComparedColumns],
    out: &Path,
) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    let mut continuum = Vec::new();
    let mut pair_runs = Vec::new();
    for (run, &compared) in opened.iter().zip(compared) {
        let name: String = run.path().file_name().map_or_else(
            || run.path().display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        let Some((config, _)) = run.particle() else {
            continuum.push(ContinuumRow {
                run: name,
                compared,
            });
            continue;
        };
        if run.snapshot_paths.len() < MIN_SNAPSHOTS {
            continue;
        }
        let t_end = run.column("t [1/beta]")?.last().copied().unwrap_or(0.0);
        let window = later_half(t_end);
        // The window's snapshots, read once for the statistics and the pair structure; a run
        // with too few of them has no row.
        let snaps = window_snapshots(run.path(), &window)?;
        let Some(stats) = RunStatistics::of_snapshots(run.path(), &snaps, &window)? else {
            continue;
        };
        if config.volume_fraction > 1.0 {
            pair_runs.push(PairRun {
                label: name.clone(),
                window,
                curves: pair_correlations(&snaps)?,
            });
        }
        rows.push(Row {
            run: name,
            nu: config.volume_fraction,
            box_length: config.box_length,
            rods: config.rod_count(),
            level: config.hydrodynamics.to_string(),
            window,
            stats,
            compared,
        });
    }
    if rows.is_empty() {
        return Ok(());
    }
    write_atomic(
        &out.join("particle_statistics.csv"),
        csv(&rows, &continuum).as_bytes(),
    )?;
    write_atomic(
        &out.join("particle_statistics.md"),
        markdown(&rows, &continuum).as_bytes(),
    )?;
    let concentrated: Vec<&Row> = rows.iter().filter(|r| r.nu > 1.0).collect();
    // The concentrated runs' structure at the rod scale, in l.
    write_pair_correlations(&pair_runs, out)?;
    let mut boxes: Vec<f64> = concentrated.iter().map(|r| r.box_length).collect();
    boxes.sort_by(f64::total_cmp);
    boxes.dedup();
    if boxes.len() >= 2 {
        write_norm_scaling(&concentrated, out)?;
    }
    Ok(())
}

/// The columns every row has (mean-field units): the norm's average with its standard error
/// and window, and `Corr[u]`'s first zero in L.
fn compared_csv(c: &ComparedColumns) -> String {
    format!(
        "{:e},{:e},{:e},{:e},{:e}",
        c.mean, c.std_error, c.t0, c.t1, c.corr_u_zero
    )
}

fn csv(rows: &[Row], continuum: &[ContinuumRow]) -> String {
    let mut s = String::from(CSV_HEADER);
    for r in rows {
        let z = r.stats.corr_zeros;
        writeln!(
            s,
            "{},particle,{},{},{},{},{},{},{},{:e},{:e},{:e},{:e},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{}",
            r.run,
            r.nu,
            r.box_length,
            r.rods,
            r.level,
            r.window.t0,
            r.window.t1,
            r.stats.snapshots,
            r.stats.norm.value,
            r.stats.norm.spread,
            r.stats.decorrelation_rate.value,
            r.stats.decorrelation_rate.spread,
            r.window.msd_lag,
            r.stats.msd.value,
            r.stats.msd.spread,
            z[0].value,
            z[1].value,
            z[2].value,
            z[2].spread,
            z[0].value / r.box_length,
            z[1].value / r.box_length,
            z[2].value / r.box_length,
            compared_csv(&r.compared),
        )
        .expect("string");
    }
    // The continuum has no rods, box in l, particle window or trajectories: NaN there; its
    // Corr[Q] zero in L is the comparison's.
    for c in continuum {
        let nan = |n: usize| vec!["NaN"; n].join(",");
        writeln!(
            s,
            "{},meanfield,{},continuum,{},{},{},{:e},{}",
            c.run,
            nan(3),
            nan(2),
            c.compared.snapshots,
            nan(13),
            c.compared.corr_q_zero,
            compared_csv(&c.compared),
        )
        .expect("string");
    }
    s
}

fn markdown(rows: &[Row], continuum: &[ContinuumRow]) -> String {
    let mut s = String::from(
        "# Particle runs' statistics\n\nEach particle run over the later half of its time (the paper averages its concentrated runs over t = 100-200/beta), in particle units. ||u||_2: time average with its batch-means standard error. Decorrelation rate: -d ln <p(t0 + tau).p(t0)>/d tau, least squares over the lags tau in the window's fit range, averaged over origins t0. MSD at the stated lag, averaged over origins. Zeros: first zero of each time-averaged correlation, on 2 L/l Fourier modes per axis (16-64). +-: half the difference between the window's halves (none where a half has no value: a correlation that does not cross zero within L/2 in one half). The last two columns are the comparison's, for every run in mean-field units (the continuum's too): the norm's time average over the saturated state and Corr[u]'s first zero.\n\n| run | nu | L/l | rods | level | window (1/beta) | ||u||_2 (beta L) | decorrelation rate (beta) | MSD (l^2) at lag | zeros of Corr[c], Corr[n], Corr[Q] (l) | Corr[Q] zero (L) | ||u||_2 (mean-field units) | Corr[u] zero (L) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let pm = |e: &Estimate| {
        if e.spread.is_finite() {
            format!("{:.4} +- {:.4}", e.value, e.spread)
        } else {
            format!("{:.4} (a half has none)", e.value)
        }
    };
    let compared = |c: &ComparedColumns| {
        format!(
            "{:.4e} +- {:.1e} | {:.3}",
            c.mean, c.std_error, c.corr_u_zero
        )
    };
    for r in rows {
        let z = r.stats.corr_zeros;
        writeln!(
            s,
            "| {} | {} | {} | {} | {} | {}-{} | {:.4e} +- {:.1e} | {} | {} at {} | {:.2}, {:.2}, {} | {:.3} | {} |",
            r.run,
            r.nu,
            r.box_length,
            r.rods,
            r.level,
            r.window.t0,
            r.window.t1,
            r.stats.norm.value,
            r.stats.norm.spread,
            pm(&r.stats.decorrelation_rate),
            pm(&r.stats.msd),
            r.window.msd_lag,
            z[0].value,
            z[1].value,
            pm(&z[2]),
            z[2].value / r.box_length,
            compared(&r.compared),
        )
        .expect("string");
    }
    for c in continuum {
        writeln!(
            s,
            "| {} | - | - | - | continuum | t_mf = {:.0}-{:.0} | - | - | - | - | {} | {} |",
            c.run,
            c.compared.t0,
            c.compared.t1,
            if c.compared.corr_q_zero.is_nan() {
                "none within L/2".to_string()
            } else {
                format!("{:.3}", c.compared.corr_q_zero)
            },
            compared(&c.compared),
        )
        .expect("string");
    }
    s
}

/// A power law `y = a x^p` fitted by least squares in logs, each point weighted by its
/// standard error where all have one: the exponent with its standard error and the prefactor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerLaw {
    /// The exponent `p`.
    pub exponent: f64,
    /// Its standard error: the larger of what the points' standard errors give
    /// (`1/sqrt(Sxx_w)`, so two points have one) and what the scatter about the line gives
    /// (`sqrt(chi^2 / (n - 2) / Sxx_w)`, from three points); NaN where neither exists.
    pub std_error: f64,
    /// The prefactor `a`.
    pub prefactor: f64,
}

/// A point to fit: `y` at `x` with `y`'s standard error `sy` (0 where it has none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    /// Abscissa (positive).
    pub x: f64,
    /// Value (positive).
    pub y: f64,
    /// Standard error of `y`.
    pub sy: f64,
}

/// [`PowerLaw`] through `points` (positive `x`, `y`); `None` with fewer than two distinct `x`.
pub fn fit_power_law(points: &[Measured]) -> Option<PowerLaw> {
    let kept: Vec<&Measured> = points.iter().filter(|p| p.x > 0.0 && p.y > 0.0).collect();
    if kept.len() < 2 {
        return None;
    }
    // ln y's standard error is sy / y; without one for every point, equal weights.
    let weighted = kept.iter().all(|p| p.sy > 0.0 && p.sy.is_finite());
    let logs: Vec<(f64, f64, f64)> = kept
        .iter()
        .map(|p| {
            let w = if weighted { (p.y / p.sy).powi(2) } else { 1.0 };
            (p.x.ln(), p.y.ln(), w)
        })
        .collect();
    let sw: f64 = logs.iter().map(|l| l.2).sum();
    let (mx, my) = logs.iter().fold((0.0, 0.0), |(a, b), (x, y, w)| {
        (a + w * x / sw, b + w * y / sw)
    });
    let sxx: f64 = logs.iter().map(|(x, _, w)| w * (x - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|(x, y, w)| w * (x - mx) * (y - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let p = sxy / sxx;
    let chi2: f64 = logs
        .iter()
        .map(|(x, y, w)| w * (y - my - p * (x - mx)).powi(2))
        .sum();
    let n = logs.len() as f64;
    let scatter = if logs.len() > 2 {
        (chi2 / (n - 2.0) / sxx).sqrt()
    } else {
        f64::NAN
    };
    let measured = if weighted {
        sxx.recip().sqrt()
    } else {
        f64::NAN
    };
    Some(PowerLaw {
        exponent: p,
        std_error: measured.max(scatter),
        prefactor: (my - p * mx).exp(),
    })
}

/// `norm_scaling.{png,svg}`: the time-averaged norm against L/l with its fitted power law and
/// the line l/L through the smallest box's point.
fn write_norm_scaling(rows: &[&Row], out: &Path) -> anyhow::Result<()> {
    let measured: Vec<Measured> = rows
        .iter()
        .map(|r| Measured {
            x: r.box_length,
            y: r.stats.norm.value,
            sy: r.stats.norm.spread,
        })
        .collect();
    let points: Vec<(f64, f64)> = measured.iter().map(|m| (m.x, m.y)).collect();
    let (lo, hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.0), b.max(p.0))
    });
    let mut series = vec![Series {
        label: "time-averaged ||u||_2 (later half of each run)".into(),
        points: points.clone(),
    }];
    let mut title = "Concentrated runs: velocity norm against box size".to_string();
    if let Some(fit) = fit_power_law(&measured) {
        series.push(Series {
            label: format!("fit: (L/l)^({:.2} +- {:.2})", fit.exponent, fit.std_error),
            points: [lo, hi]
                .iter()
                .map(|&x| (x, fit.prefactor * x.powf(fit.exponent)))
                .collect(),
        });
        title = format!(
            "{title}: exponent {:.2} +- {:.2} (paper: -1)",
            fit.exponent, fit.std_error
        );
    }
    let first = points
        .iter()
        .copied()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .expect("two points");
    series.push(Series {
        label: "l/L through the smallest box".into(),
        points: [lo, hi]
            .iter()
            .map(|&x| (x, first.1 * first.0 / x))
            .collect(),
    });
    let labels: Vec<(f64, f64, String)> = rows
        .iter()
        .map(|r| (r.box_length, r.stats.norm.value, r.run.clone()))
        .collect();
    log_chart(
        &out.join("norm_scaling"),
        &title,
        "L/l [1]",
        "time-averaged ||u||_2 [beta L]",
        &series,
        &labels,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_power_law_is_fitted_exactly_and_scatter_gives_its_error() {
        let exact: Vec<Measured> = [8.0, 11.0, 16.0]
            .iter()
            .map(|&x: &f64| Measured {
                x,
                y: 0.7 * x.powf(-1.0),
                sy: 0.0,
            })
            .collect();
        let fit = fit_power_law(&exact).unwrap();
        assert!(
            (fit.exponent + 1.0).abs() < 1e-12
                && fit.std_error < 1e-12
                && (fit.prefactor - 0.7).abs() < 1e-12,
            "{fit:?}"
        );
        // One point off by a factor e^0.1 in y: the residuals give the standard error of the
        // slope, sqrt(SSR / (n - 2) / Sxx), computed here by hand for three points.
        let mut scattered = exact.clone();
        scattered[1].y *= 0.1f64.exp();
        let fit = fit_power_law(&scattered).unwrap();
        let x: Vec<f64> = scattered.iter().map(|p| p.x.ln()).collect();
        let y: Vec<f64> = scattered.iter().map(|p| p.y.ln()).collect();
        let (mx, my) = (x.iter().sum::<f64>() / 3.0, y.iter().sum::<f64>() / 3.0);
        let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
        let slope: f64 = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - mx) * (b - my))
            .sum::<f64>()
            / sxx;
        let ssr: f64 = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (b - my - slope * (a - mx)).powi(2))
            .sum();
        assert!((fit.exponent - slope).abs() < 1e-12, "{fit:?}");
        assert!(
            (fit.std_error - (ssr / sxx).sqrt()).abs() < 1e-12,
            "{fit:?}"
        );
        let at = |x, y| Measured { x, y, sy: 0.0 };
        assert!(fit_power_law(&[at(8.0, 1.0), at(8.0, 2.0)]).is_none());
    }

    #[test]
    fn two_points_with_standard_errors_give_the_propagated_error() {
        // Slope ln(y2/y1)/ln(x2/x1); its error sqrt((s1/y1)^2 + (s2/y2)^2) / ln(x2/x1).
        let pts = [
            Measured {
                x: 6.0,
                y: 0.0718,
                sy: 0.00088,
            },
            Measured {
                x: 8.0,
                y: 0.0658,
                sy: 0.0011,
            },
        ];
        let fit = fit_power_law(&pts).unwrap();
        let dx = (8.0f64 / 6.0).ln();
        let slope = (0.0658f64 / 0.0718).ln() / dx;
        let err = ((0.00088f64 / 0.0718).powi(2) + (0.0011f64 / 0.0658).powi(2)).sqrt() / dx;
        assert!(
            (fit.exponent - slope).abs() < 1e-12,
            "{fit:?} against {slope}"
        );
        assert!((fit.std_error - err).abs() < 1e-12, "{fit:?} against {err}");
    }
}
