//! The statistics a particle run's figures are read from, over a time window: the
//! time-averaged velocity norm, the rate at which orientations decorrelate, the mean squared
//! displacement at a fixed lag and the first zero of the time-averaged `Corr[Q]`. Contact-driven
//! runs (nu = 5) do not converge pathwise in any setting (the `dt` study of the `concentrated`
//! scene), so settings are compared on these, each with an uncertainty from the spread between
//! the window's two halves.

use crate::io::rundir::{RunDir, TimeSeries};
use crate::io::snapshot::{ParticleSnapshot, Snapshot, read_snapshot};
use anyhow::Context;
use motile_analysis::correlation::{
    CorrelationOptions, OrderParameter, ParticleSpectra, RadialCorrelation, Spectrum,
    pair_correlation,
};
use motile_analysis::stats::{
    correlation_length, least_squares_slope, mean_squared_displacement,
    orientation_autocorrelation, unwrap, window_average,
};
use std::path::Path;

/// The fewest snapshots in a window that the statistics are taken from.
pub const MIN_SNAPSHOTS: usize = 4;

/// Where the statistics are taken: the window `[t0, t1]` (1/beta), the lags of the
/// orientation fit `[fit_from, fit_to]` and the MSD's lag (1/beta).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatisticsWindow {
    /// Start of the window.
    pub t0: f64,
    /// End of the window.
    pub t1: f64,
    /// Shortest lag of the decorrelation fit.
    pub fit_from: f64,
    /// Longest lag of the decorrelation fit.
    pub fit_to: f64,
    /// The MSD's lag.
    pub msd_lag: f64,
}

/// One statistic with its uncertainty (half the difference between the window's halves).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Over the whole window.
    pub value: f64,
    /// `|first half - second half| / 2`, NaN where a half has too little to measure.
    pub spread: f64,
}

/// A run's statistics over a window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunStatistics {
    /// Time-averaged `||u||_2` (beta L), with the batch-means standard error as its spread.
    pub norm: Estimate,
    /// `-d ln <p(t0 + tau).p(t0)> / d tau` over the fit's lags, averaged over origins t0 (beta).
    pub decorrelation_rate: Estimate,
    /// `<|x(t0 + lag) - x(t0)|^2>` averaged over origins (l^2).
    pub msd: Estimate,
    /// First zeros of the time-averaged `Corr[c]`, `Corr[n]` and `Corr[Q]` (l), in that order.
    pub corr_zeros: [Estimate; 3],
    /// Snapshots in the window.
    pub snapshots: usize,
}

impl RunStatistics {
    /// The statistics of the particle run in `dir` over `window`; `None` where the window
    /// holds fewer than [`MIN_SNAPSHOTS`] snapshots.
    pub fn of(dir: &Path, window: &StatisticsWindow) -> anyhow::Result<Option<Self>> {
        Self::of_snapshots(dir, &window_snapshots(dir, window)?, window)
    }

    /// [`Self::of`] from the window's snapshots `snaps` ([`window_snapshots`]) and the time
    /// series of the run in `dir`.
    pub fn of_snapshots(
        dir: &Path,
        snaps: &[ParticleSnapshot],
        window: &StatisticsWindow,
    ) -> anyhow::Result<Option<Self>> {
        let ts = TimeSeries::read(&dir.join("timeseries.csv"))?;
        if snaps.len() < MIN_SNAPSHOTS {
            return Ok(None);
        }
        let mid = 0.5 * (window.t0 + window.t1);
        let halves = |f: &dyn Fn(f64, f64) -> f64| {
            let (a, b) = (f(window.t0, mid), f(mid, window.t1));
            Estimate {
                value: f(window.t0, window.t1),
                spread: 0.5 * (a - b).abs(),
            }
        };
        let norm_column = ts
            .column("velocity_norm [beta L]")
            .context("the time series has no velocity_norm column")?;
        let t = ts.column("t [1/beta]").context("no time column")?;
        let average = window_average(&t, &norm_column, window.t0, window.t1);
        let in_window =
            |s: &ParticleSnapshot, lo: f64, hi: f64| s.time >= lo - 1e-9 && s.time <= hi + 1e-9;
        let pick = |lo: f64, hi: f64| -> Vec<&ParticleSnapshot> {
            snaps.iter().filter(|s| in_window(s, lo, hi)).collect()
        };
        // Each snapshot's correlations once; the halves and the whole average them.
        let all: Vec<&ParticleSnapshot> = snaps.iter().collect();
        let curves = snapshot_curves(
            &all,
            &ORDER_PARAMETERS,
            rod_scale_modes(snaps[0].box_length),
            &|spec, _, _| spec.correlation(None),
        )?;
        let zeros = |lo: f64, hi: f64| {
            let picked: Vec<usize> = (0..snaps.len())
                .filter(|&i| in_window(&snaps[i], lo, hi))
                .collect();
            corr_zeros(&curves, &picked)
        };
        let (a, b, all) = (
            zeros(window.t0, mid),
            zeros(mid, window.t1),
            zeros(window.t0, window.t1),
        );
        let corr_zeros = [0, 1, 2].map(|k| Estimate {
            value: all[k],
            spread: 0.5 * (a[k] - b[k]).abs(),
        });
        Ok(Some(Self {
            norm: Estimate {
                value: average.mean,
                spread: average.std_error,
            },
            decorrelation_rate: halves(&|lo, hi| decorrelation_rate(&pick(lo, hi), window)),
            msd: halves(&|lo, hi| msd_at(&pick(lo, hi), window.msd_lag)),
            corr_zeros,
            snapshots: snaps.len(),
        }))
    }
}

/// The particle snapshots of the run in `dir` with `t0 <= time <= t1`, in order.
pub fn window_snapshots(dir: &Path, w: &StatisticsWindow) -> anyhow::Result<Vec<ParticleSnapshot>> {
    let mut out = Vec::new();
    for path in RunDir::open(dir)?.snapshot_paths()? {
        if let Snapshot::Particle(s) = read_snapshot(&path)?
            && s.time >= w.t0 - 1e-9
            && s.time <= w.t1 + 1e-9
        {
            out.push(s);
        }
    }
    Ok(out)
}

/// The time-averaged pair correlations ([`pair_correlation`]: without each rod's correlation
/// with itself) of `c`, `n` and `Q` over the snapshots `snaps` ([`window_snapshots`]), on
/// [`pair_modes`] modes per axis (a resolution of l/4 up to L/l = 32, so that boxes compare at
/// the same resolution in `l`), against `r` in `l`: `(name, curve)`, empty without snapshots.
pub fn pair_correlations(
    snaps: &[ParticleSnapshot],
) -> anyhow::Result<Vec<(&'static str, RadialCorrelation)>> {
    let Some(first) = snaps.first() else {
        return Ok(Vec::new());
    };
    let window: Vec<&ParticleSnapshot> = snaps.iter().collect();
    let curves = snapshot_curves(
        &window,
        &ORDER_PARAMETERS,
        pair_modes(first.box_length),
        &|spec, which, rods| pair_correlation(spec, which, rods, Some(PAIR_SHELL)),
    )?;
    Ok(["c", "n", "Q"]
        .into_iter()
        .enumerate()
        .filter_map(|(k, name)| {
            let mut acc = summed(curves.iter().map(|c| &c[k]))?;
            acc.value.iter_mut().for_each(|v| *v /= snaps.len() as f64);
            Some((name, acc))
        })
        .collect())
}

/// The order parameters of the statistics, in the order of their columns.
pub(crate) const ORDER_PARAMETERS: [OrderParameter; 3] = [
    OrderParameter::Concentration,
    OrderParameter::Polarity,
    OrderParameter::Nematic,
];

/// A curve of an order parameter's spectrum of `rods` rods.
pub(crate) type CurveOf<'a> = &'a dyn Fn(&Spectrum, OrderParameter, usize) -> RadialCorrelation;

/// `curve` of each of `which` in every snapshot of `snaps`, on `modes` modes per axis, indexed
/// `[snapshot][parameter]`: one NUFFT plan for them all, each snapshot's parameters spread in one
/// pass over its rods.
pub(crate) fn snapshot_curves(
    snaps: &[&ParticleSnapshot],
    which: &[OrderParameter],
    modes: usize,
    curve: CurveOf,
) -> anyhow::Result<Vec<Vec<RadialCorrelation>>> {
    let mut spectra = ParticleSpectra::new(modes, CorrelationOptions::default().tolerance)?;
    snaps
        .iter()
        .map(|s| {
            let specs = spectra.of(&s.positions, &s.orientations, s.box_length, which)?;
            Ok(specs
                .iter()
                .zip(which)
                .map(|(spec, &w)| curve(spec, w, s.positions.len()))
                .collect())
        })
        .collect()
}

/// The sum of `curves` (in order); `None` without any.
pub(crate) fn summed<'a>(
    curves: impl IntoIterator<Item = &'a RadialCorrelation>,
) -> Option<RadialCorrelation> {
    let mut sum = None;
    for c in curves {
        add_to(&mut sum, c.clone());
    }
    sum
}

/// Add correlation `c` to the running sum `sum` (the first one starts it).
pub(crate) fn add_to(sum: &mut Option<RadialCorrelation>, c: RadialCorrelation) {
    match sum {
        Some(acc) => acc
            .value
            .iter_mut()
            .zip(&c.value)
            .for_each(|(a, v)| *a += v),
        None => *sum = Some(c),
    }
}

/// The radial spacing of the pair correlations (l).
const PAIR_SHELL: f64 = 0.05;

/// Fourier modes per axis of the pair correlations: `4 L/l` (even), at most 128: a resolution of
/// l/4 up to L/l = 32, coarser above (the figures' legends give each run's).
pub fn pair_modes(box_length: f64) -> usize {
    ((4.0 * box_length).round() as usize).clamp(8, 128) & !1
}

/// Fourier modes per axis that resolve the rod scale: `2 L/l`, between 16 and 64.
fn rod_scale_modes(box_length: f64) -> usize {
    ((2.0 * box_length).round() as usize).clamp(16, 64)
}

/// `f(earlier, later)` averaged over the pairs of snapshots `lag` apart (within 1e-6).
fn lag_average(
    snaps: &[&ParticleSnapshot],
    lag: f64,
    f: &dyn Fn(&ParticleSnapshot, &ParticleSnapshot) -> f64,
) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0usize;
    for (i, a) in snaps.iter().enumerate() {
        if let Some(b) = snaps[i..]
            .iter()
            .find(|b| (b.time - a.time - lag).abs() < 1e-6)
        {
            sum += f(a, b);
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// The rate of `-ln <p(t0 + tau).p(t0)>` against the lag `tau`, least squares over the lags
/// of the snapshots' spacing in `[fit_from, fit_to]`; NaN with fewer than 2 lags.
fn decorrelation_rate(snaps: &[&ParticleSnapshot], w: &StatisticsWindow) -> f64 {
    if snaps.len() < 2 {
        return f64::NAN;
    }
    let spacing = snaps[1].time - snaps[0].time;
    let points: Vec<(f64, f64)> = (1..)
        .map(|k| k as f64 * spacing)
        .take_while(|&tau| tau <= w.fit_to + 1e-9)
        .filter(|&tau| tau >= w.fit_from - 1e-9)
        .filter_map(|tau| {
            lag_average(snaps, tau, &|a, b| {
                orientation_autocorrelation(&a.orientations, &b.orientations)
            })
            .filter(|c| *c > 0.0)
            .map(|c| (tau, c.ln()))
        })
        .collect();
    least_squares_slope(&points).map_or(f64::NAN, |s| -s)
}

/// The MSD at `lag` (rounded down to a whole number of the snapshots' spacing) averaged over
/// origins (unwrapped positions); NaN where no pair is that far apart.
fn msd_at(snaps: &[&ParticleSnapshot], lag: f64) -> f64 {
    if snaps.len() < 2 {
        return f64::NAN;
    }
    let spacing = snaps[1].time - snaps[0].time;
    let lag = (lag / spacing + 1e-9).floor() * spacing;
    let unwrapped = |s: &ParticleSnapshot| -> Vec<[f64; 3]> {
        s.positions
            .iter()
            .zip(&s.image_counts)
            .map(|(x, i)| unwrap(*x, *i, s.box_length))
            .collect()
    };
    lag_average(snaps, lag, &|a, b| {
        mean_squared_displacement(&unwrapped(a), &unwrapped(b))
    })
    .unwrap_or(f64::NAN)
}

/// The first zeros (l) of `Corr[c]`, `Corr[n]` and `Corr[Q]` averaged over the snapshots
/// `picked` of `curves` (each snapshot's three correlations; NaN where one does not cross zero,
/// or without snapshots).
fn corr_zeros(curves: &[Vec<RadialCorrelation>], picked: &[usize]) -> [f64; 3] {
    [0, 1, 2].map(|k| {
        summed(picked.iter().map(|&i| &curves[i][k]))
            .and_then(|acc| correlation_length(&acc.r, &acc.value))
            .unwrap_or(f64::NAN)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rods in a plane turning at rates drawn (by quantiles) from a Cauchy distribution of
    /// width `gamma`, moving at speeds `v`: `<p(t0 + tau).p(t0)> = E[cos(w tau)] = exp(-gamma
    /// tau)` for every origin, and the MSD at `lag` is `<v^2> lag^2`.
    fn snapshots(gamma: f64, spacing: f64, count: usize) -> Vec<ParticleSnapshot> {
        let n = 20_000;
        let rates: Vec<f64> = (0..n)
            .map(|i| {
                let u = (i as f64 + 0.5) / n as f64;
                gamma * (std::f64::consts::PI * (u - 0.5)).tan()
            })
            .collect();
        let speeds: Vec<f64> = (0..n).map(|i| 0.1 + 0.01 * (i % 7) as f64).collect();
        (0..count)
            .map(|k| {
                let t = k as f64 * spacing;
                ParticleSnapshot {
                    time: t,
                    step: k as u64,
                    box_length: 1e6,
                    positions: speeds.iter().map(|v| [v * t, 0.0, 0.0]).collect(),
                    orientations: rates
                        .iter()
                        .map(|w| [(w * t).cos(), (w * t).sin(), 0.0])
                        .collect(),
                    image_counts: vec![[0; 3]; n],
                    forces: None,
                    kinematics: None,
                }
            })
            .collect()
    }

    #[test]
    fn decorrelation_rate_and_msd_match_their_closed_forms() {
        let (gamma, spacing) = (0.3, 0.4);
        let snaps = snapshots(gamma, spacing, 41);
        let refs: Vec<&ParticleSnapshot> = snaps.iter().collect();
        let w = statistics_window_for_test();
        let rate = decorrelation_rate(&refs, &w);
        // The quantiles' sum approximates the expectation to O(1/n) at these lags.
        assert!(
            (rate - gamma).abs() < 1e-2 * gamma,
            "decorrelation rate {rate} against exp(-{gamma} tau): error {:.2e}",
            (rate - gamma).abs() / gamma
        );
        let v2: f64 = (0..20_000)
            .map(|i| (0.1 + 0.01 * (i % 7) as f64).powi(2))
            .sum::<f64>()
            / 20_000.0;
        // A lag of 3.9 rounds down to 3.6 (nine spacings).
        let msd = msd_at(&refs, 3.9);
        let want = v2 * 3.6 * 3.6;
        assert!(
            (msd - want).abs() < 1e-9 * want,
            "MSD {msd} against <v^2> lag^2 = {want}"
        );
    }

    fn statistics_window_for_test() -> StatisticsWindow {
        StatisticsWindow {
            t0: 0.0,
            t1: 16.0,
            fit_from: 1.0,
            fit_to: 4.0,
            msd_lag: 4.0,
        }
    }
}
