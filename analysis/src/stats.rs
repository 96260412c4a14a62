//! Scalar statistics of fields and trajectories (docs/MODEL.md §6): volume-averaged L2 norms,
//! correlation lengths, time averages over a window, mean squared displacement of unwrapped
//! positions and orientation autocorrelation.

/// Volume-averaged L2 norm of a vector field sampled on a uniform grid, one slice per
/// component: `sqrt(mean over points of sum over components of v^2)`.
pub fn volume_l2_norm(components: &[&[f64]]) -> f64 {
    let n = components.first().map_or(0, |c| c.len());
    if n == 0 {
        return 0.0;
    }
    let sum: f64 = components
        .iter()
        .map(|c| c.iter().map(|v| v * v).sum::<f64>())
        .sum();
    (sum / n as f64).sqrt()
}

/// First zero crossing of a correlation function, linearly interpolated between the bracketing
/// samples; `None` if it never changes sign.
pub fn correlation_length(r: &[f64], c: &[f64]) -> Option<f64> {
    for i in 1..r.len().min(c.len()) {
        if c[i] == 0.0 {
            return Some(r[i]);
        }
        if c[i - 1] > 0.0 && c[i] < 0.0 {
            return Some(r[i - 1] + (r[i] - r[i - 1]) * c[i - 1] / (c[i - 1] - c[i]));
        }
    }
    None
}

/// Mean of a sampled quantity over a time window, with a standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowAverage {
    /// Mean of the samples with `t0 <= t <= t1`.
    pub mean: f64,
    /// Standard error of the mean from batch means over [`Self::batches`] contiguous blocks
    /// (which absorbs correlation between neighbouring samples shorter than a block); NaN
    /// with fewer than 2 batches.
    pub std_error: f64,
    /// Number of samples in the window.
    pub samples: usize,
    /// Number of batches used for the error (up to 10, at least 2 samples each).
    pub batches: usize,
}

/// Average of `y(t)` over `t0 <= t <= t1` (samples counted equally).
pub fn window_average(t: &[f64], y: &[f64], t0: f64, t1: f64) -> WindowAverage {
    let vals: Vec<f64> = t
        .iter()
        .zip(y)
        .filter(|(t, _)| **t >= t0 && **t <= t1)
        .map(|(_, y)| *y)
        .collect();
    let n = vals.len();
    let mean = if n > 0 {
        vals.iter().sum::<f64>() / n as f64
    } else {
        f64::NAN
    };
    let batches = (n / 2).min(10);
    let std_error = if batches >= 2 {
        let size = n / batches;
        let means: Vec<f64> = (0..batches)
            .map(|b| vals[b * size..(b + 1) * size].iter().sum::<f64>() / size as f64)
            .collect();
        let m = means.iter().sum::<f64>() / batches as f64;
        let var = means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (batches - 1) as f64;
        (var / batches as f64).sqrt()
    } else {
        f64::NAN
    };
    WindowAverage {
        mean,
        std_error,
        samples: n,
        batches,
    }
}

/// An exponential growth rate fitted to `y(t)` over a window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GrowthFit {
    /// Least-squares slope of `ln y` against `t`.
    pub rate: f64,
    /// Its standard error (from the residuals; 0 for an exact exponential).
    pub std_error: f64,
    /// Samples used.
    pub samples: usize,
    /// The window.
    pub t0: f64,
    /// The window's end.
    pub t1: f64,
    /// Coefficient of determination of the fit of `ln y` (1 for an exact exponential).
    pub r_squared: f64,
    /// `exp(rate (t_last - t_first))` over the samples used: how much the fit grew.
    pub growth_factor: f64,
    /// The largest local rate (slope of `ln y` over 7 neighbouring samples, away from the
    /// ends) in a [`growth_phase`]: the linear-theory rate before saturation slows the growth;
    /// equal to `rate` for a plain fit.
    pub peak_rate: f64,
}

impl GrowthFit {
    /// Whether the window is a growth phase by the stated criterion (docs/MODEL.md §6): grew by
    /// at least `min_factor` with `R^2` at least `min_r2`.
    pub fn is_growth(&self, min_factor: f64, min_r2: f64) -> bool {
        self.growth_factor >= min_factor && self.r_squared >= min_r2
    }
}

/// The least-squares slope of the points `(x, y)`: `sum (x - xm)(y - ym) / sum (x - xm)^2`;
/// `None` with fewer than two points or no spread in `x`.
pub fn least_squares_slope(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let xm = points.iter().map(|p| p.0).sum::<f64>() / n;
    let ym = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - xm).powi(2)).sum();
    if sxx == 0.0 {
        return None;
    }
    Some(points.iter().map(|p| (p.0 - xm) * (p.1 - ym)).sum::<f64>() / sxx)
}

/// Fit `y = A exp(rate t)` over `t0 <= t <= t1` by least squares on `ln y` (samples with
/// `y > 0` only); `None` with fewer than 3 samples. The standard error allows for correlated
/// residuals (integrated autocorrelation of the residuals).
pub fn fit_growth_rate(t: &[f64], y: &[f64], t0: f64, t1: f64) -> Option<GrowthFit> {
    let pts: Vec<(f64, f64)> = t
        .iter()
        .zip(y)
        .filter(|(t, y)| **t >= t0 && **t <= t1 && **y > 0.0 && y.is_finite())
        .map(|(t, y)| (*t, y.ln()))
        .collect();
    let n = pts.len();
    if n < 3 {
        return None;
    }
    let tm = pts.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let ym = pts.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let stt: f64 = pts.iter().map(|p| (p.0 - tm).powi(2)).sum();
    let rate = least_squares_slope(&pts)?;
    let r: Vec<f64> = pts.iter().map(|p| p.1 - ym - rate * (p.0 - tm)).collect();
    let res: f64 = r.iter().map(|v| v * v).sum();
    // Residuals of a time series are correlated (a noisy norm sampled faster than it
    // decorrelates): the least-squares error is scaled by sqrt(tau), tau = 1 + 2 sum rho_k over
    // the residuals' autocorrelations up to the first that is not positive (at most n/4 lags).
    let mut tau = 1.0;
    if res > 0.0 {
        for k in 1..=n / 4 {
            let rho = r.iter().zip(&r[k..]).map(|(a, b)| a * b).sum::<f64>() / res;
            if rho <= 0.0 {
                break;
            }
            tau += 2.0 * rho;
        }
    }
    let syy: f64 = pts.iter().map(|p| (p.1 - ym).powi(2)).sum();
    let span = pts[n - 1].0 - pts[0].0;
    Some(GrowthFit {
        rate,
        std_error: (tau * res / (n - 2) as f64 / stt).sqrt(),
        samples: n,
        t0,
        t1,
        r_squared: if syy > 0.0 { 1.0 - res / syy } else { 1.0 },
        growth_factor: (rate * span).exp(),
        peak_rate: rate,
    })
}

/// The growth phase of a series that may grow and then saturate (docs/MODEL.md §6). The local
/// growth rate is the slope of `ln y` over 7 neighbouring samples (away from the ends); the
/// phase runs from the first sample to where the local rate, past its largest value, first
/// falls below [`SATURATION_FRACTION`] of it (saturation bends the curve), or to the end if it
/// never does (a pure exponential), or if that window is not a growth phase, the whole series.
/// The flag says whether the fit over the window is a growth phase: grew by at least `min_factor` with `R^2` at least `min_r2`; its `peak_rate` is the
/// largest local rate. Without one, the fit over the whole series is returned (a decay or a flat
/// line) with the flag false; `None` with fewer than 3 positive samples.
pub fn growth_phase(
    t: &[f64],
    y: &[f64],
    min_factor: f64,
    min_r2: f64,
) -> Option<(GrowthFit, bool)> {
    let (t, y): (Vec<f64>, Vec<f64>) = t
        .iter()
        .zip(y)
        .filter(|(_, v)| **v > 0.0 && v.is_finite())
        .map(|(a, b)| (*a, *b))
        .unzip();
    let (&t0, &t_last) = (t.first()?, t.last()?);
    let whole = fit_growth_rate(&t, &y, t0, t_last)?;
    const HALF_WIDTH: usize = 3;
    let n = t.len();
    if n < 2 * HALF_WIDTH + 1 {
        return Some((whole, false));
    }
    let local: Vec<f64> = (HALF_WIDTH..n - HALF_WIDTH)
        .map(|i| {
            fit_growth_rate(&t, &y, t[i - HALF_WIDTH], t[i + HALF_WIDTH])
                .map_or(f64::NAN, |g| g.rate)
        })
        .collect();
    let (k_max, s_max) = local
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, s)| s.is_finite())
        .fold(
            (0, f64::NEG_INFINITY),
            |a, (i, s)| if s > a.1 { (i, s) } else { a },
        );
    if s_max <= 0.0 {
        return Some((whole, false));
    }
    let end = (k_max..local.len())
        .find(|&k| local[k] < SATURATION_FRACTION * s_max)
        .map_or(n - 1, |k| k + HALF_WIDTH);
    // The window up to the bend, else the whole series (a run that grows throughout, its local
    // rate noisy enough to dip early).
    for g in [fit_growth_rate(&t, &y, t0, t[end]), Some(whole)]
        .into_iter()
        .flatten()
    {
        if g.is_growth(min_factor, min_r2) {
            return Some((
                GrowthFit {
                    peak_rate: s_max,
                    ..g
                },
                true,
            ));
        }
    }
    Some((whole, false))
}

/// Where a growth phase ends: the local growth rate has fallen below this fraction of its
/// largest value ([`growth_phase`]).
pub const SATURATION_FRACTION: f64 = 0.4;

/// Unwrapped position `x + L * image` of one particle.
pub fn unwrap(x: [f64; 3], image: [i64; 3], box_length: f64) -> [f64; 3] {
    [0, 1, 2].map(|d| x[d] + box_length * image[d] as f64)
}

/// Mean squared displacement `<|x_n(t) - x_n(t0)|^2>` between two sets of unwrapped positions.
pub fn mean_squared_displacement(x0: &[[f64; 3]], xt: &[[f64; 3]]) -> f64 {
    assert_eq!(
        x0.len(),
        xt.len(),
        "MSD needs the same particles at both times"
    );
    if x0.is_empty() {
        return 0.0;
    }
    x0.iter()
        .zip(xt)
        .map(|(a, b)| (0..3).map(|d| (b[d] - a[d]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / x0.len() as f64
}

/// Orientation autocorrelation `<p_n(t) . p_n(t0)>`.
pub fn orientation_autocorrelation(p0: &[[f64; 3]], pt: &[[f64; 3]]) -> f64 {
    assert_eq!(
        p0.len(),
        pt.len(),
        "orientation autocorrelation needs the same particles at both times"
    );
    if p0.is_empty() {
        return 0.0;
    }
    p0.iter()
        .zip(pt)
        .map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        .sum::<f64>()
        / p0.len() as f64
}

/// A complex growth rate fitted to the amplitudes of one real field's modes (a pair of
/// conjugate rates `sigma`, `conj(sigma)`, or two real rates), from [`fit_complex_rate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComplexRateFit {
    /// The dominant rate: largest real part, `Im >= 0` (the beat of the amplitude's norm has
    /// the angular frequency `2 Im sigma`).
    pub sigma: num_complex::Complex64,
    /// The other root: `conj(sigma)` for a complex pair, the second real rate otherwise.
    pub other: num_complex::Complex64,
    /// The window.
    pub t0: f64,
    /// The window's end.
    pub t1: f64,
    /// Fraction of the data's squared norm the two-rate recurrence explains (1 when exact).
    pub r_squared: f64,
    /// The lag (samples) of the recurrence.
    pub lag: usize,
}

/// Fit `x(t) = A e^{sigma t} + B e^{sigma' t}` with one pair of rates shared by every series of
/// `series` (complex amplitudes sampled at the evenly spaced times `t`) over the window
/// `[t0, t1]`: the least-squares linear recurrence `x(t + 2 h) = c1 x(t + h) + c0 x(t)` with
/// real `c0`, `c1` (a real field's modes carry `sigma` and `conj(sigma)` together, or two real
/// rates), whose roots are `e^{sigma h}`. The lag `h` is a whole number of samples, chosen so
/// that `|sigma| h` is not too small for the recurrence to resolve (`h` about a fifth of the
/// window), and (`max_frequency` > 0) at most a quarter period of `max_frequency`, the
/// highest angular frequency the series may carry: frequencies up to it then stay below the
/// recurrence's Nyquist limit `pi / h` and cannot alias (a longer lag would fold them back:
/// a root on the negative real axis reads as `Im sigma = pi / h`). `None` with too few samples
/// or a degenerate system.
pub fn fit_complex_rate(
    t: &[f64],
    series: &[Vec<num_complex::Complex64>],
    t0: f64,
    t1: f64,
    max_frequency: f64,
) -> Option<ComplexRateFit> {
    use num_complex::Complex64;
    let idx: Vec<usize> = (0..t.len()).filter(|&k| t[k] >= t0 && t[k] <= t1).collect();
    if idx.len() < 7 {
        return None;
    }
    let (first, n) = (idx[0], idx.len());
    let dt = (t[idx[n - 1]] - t[first]) / (n - 1) as f64;
    let mut lag = (n / 5).max(1);
    if max_frequency > 0.0 && dt > 0.0 {
        let quarter = (0.5 * std::f64::consts::PI / (max_frequency * dt)).floor() as usize;
        lag = lag.min(quarter.max(1));
    }
    if n < 2 * lag + 3 {
        return None;
    }
    // Normal equations of the real 2x2 least-squares problem.
    let (mut a11, mut a12, mut a22, mut b1, mut b2, mut yy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for s in series {
        for k in first..first + n - 2 * lag {
            let (x0, x1, x2) = (s[k], s[k + lag], s[k + 2 * lag]);
            for (p0, p1, p2) in [(x0.re, x1.re, x2.re), (x0.im, x1.im, x2.im)] {
                a11 += p1 * p1;
                a12 += p1 * p0;
                a22 += p0 * p0;
                b1 += p1 * p2;
                b2 += p0 * p2;
                yy += p2 * p2;
            }
        }
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() <= 1e-14 * (a11 * a22).abs() || yy == 0.0 {
        return None;
    }
    let c1 = (b1 * a22 - b2 * a12) / det;
    let c0 = (a11 * b2 - a12 * b1) / det;
    // Residual of the recurrence against the data it predicts.
    let res = yy - 2.0 * (c1 * b1 + c0 * b2) + c1 * c1 * a11 + 2.0 * c1 * c0 * a12 + c0 * c0 * a22;
    let disc = Complex64::new(c1 * c1 + 4.0 * c0, 0.0).sqrt();
    let roots = [(c1 + disc) / 2.0, (c1 - disc) / 2.0];
    let h = lag as f64 * dt;
    let mut rates = roots.map(|z| z.ln() / h);
    rates.sort_by(|a, b| b.re.total_cmp(&a.re));
    let sigma = Complex64::new(rates[0].re, rates[0].im.abs());
    let other = if rates[0].im.abs() > 0.0 {
        sigma.conj()
    } else {
        rates[1]
    };
    Some(ComplexRateFit {
        sigma,
        other,
        t0: t[first],
        t1: t[first + n - 1],
        r_squared: (1.0 - res / yy).clamp(0.0, 1.0),
        lag,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_slope_of_a_line_and_of_too_little() {
        let line: Vec<(f64, f64)> = (0..5).map(|i| (i as f64, 3.0 - 0.25 * i as f64)).collect();
        let s = least_squares_slope(&line).unwrap();
        assert!((s + 0.25).abs() < 1e-15, "slope {s} of y = 3 - x/4");
        assert_eq!(least_squares_slope(&line[..2]), Some(-0.25));
        assert_eq!(least_squares_slope(&line[..1]), None);
        assert_eq!(least_squares_slope(&[(1.0, 0.0), (1.0, 2.0)]), None);
    }

    #[test]
    fn growth_fit_recovers_an_exponential_and_its_error_bar_covers_noise() {
        let t: Vec<f64> = (0..50).map(|k| 0.1 * k as f64).collect();
        let y: Vec<f64> = t.iter().map(|t| 3e-4 * (0.1942 * t).exp()).collect();
        let f = fit_growth_rate(&t, &y, 0.0, 10.0).unwrap();
        assert!(
            (f.rate - 0.1942).abs() < 1e-12 && f.std_error < 1e-12,
            "{f:?}"
        );
        // Deterministic multiplicative wiggle of 1%: the fitted rate stays within 3 standard
        // errors of the true one.
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, t)| {
                3e-4 * (0.1942 * t).exp() * (1.0 + 0.01 * ((k * 7919) % 13) as f64 / 6.0 - 0.01)
            })
            .collect();
        let f = fit_growth_rate(&t, &y, 0.0, 10.0).unwrap();
        assert!((f.rate - 0.1942).abs() < 3.0 * f.std_error + 1e-4, "{f:?}");
        assert!(fit_growth_rate(&t[..2], &y[..2], 0.0, 1.0).is_none());
    }

    #[test]
    fn growth_fit_error_bar_covers_a_flat_but_correlated_signal() {
        // ln y = AR(1) noise with rho = 0.9 around a constant: the true rate is 0. Over 400
        // series, |rate| < 2 standard errors should hold about 95% of the time; the plain
        // least-squares error (independent residuals) would cover far less.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let t: Vec<f64> = (0..200).map(|k| 0.2 * k as f64).collect();
        let (mut covered, trials) = (0, 400);
        for _ in 0..trials {
            let mut e = 0.0;
            let y: Vec<f64> = t
                .iter()
                .map(|_| {
                    // Sum of uniforms: close enough to Gaussian for coverage.
                    let z = (0..12).map(|_| uniform()).sum::<f64>() - 6.0;
                    e = 0.9 * e + 0.05 * z;
                    (-5.0 + e).exp()
                })
                .collect();
            let f = fit_growth_rate(&t, &y, 0.0, 40.0).unwrap();
            if f.rate.abs() < 2.0 * f.std_error {
                covered += 1;
            }
        }
        let coverage = covered as f64 / trials as f64;
        eprintln!("2-sigma coverage of the rate 0: {coverage:.3}");
        assert!(
            (0.85..=1.0).contains(&coverage),
            "2-sigma coverage {coverage:.3} (expected about 0.95)"
        );
    }

    #[test]
    fn msd_of_straight_lines_crossing_the_box_is_v2_t2() {
        // Particles moving at constant velocity, stored wrapped with image counters, cross the
        // periodic boundary several times.
        let l = 5.0;
        let v = [[1.3, -0.4, 2.2], [-3.1, 0.0, 0.7], [0.5, 0.5, -4.0]];
        let x0 = [[0.1, 4.9, 2.5], [4.95, 0.05, 1.0], [2.0, 3.0, 0.01]];
        let wrapped = |t: f64| -> Vec<([f64; 3], [i64; 3])> {
            x0.iter()
                .zip(&v)
                .map(|(x, v)| {
                    let raw = [0, 1, 2].map(|d| x[d] + v[d] * t);
                    let img = raw.map(|r| (r / l).floor() as i64);
                    ([0, 1, 2].map(|d| raw[d] - l * img[d] as f64), img)
                })
                .collect()
        };
        let start: Vec<[f64; 3]> = wrapped(0.0)
            .iter()
            .map(|(x, i)| unwrap(*x, *i, l))
            .collect();
        for t in [0.5, 3.0, 17.25] {
            let w = wrapped(t);
            assert!(
                w.iter().any(|(_, i)| i.iter().any(|&k| k != 0)),
                "trajectories must cross the boundary"
            );
            let now: Vec<[f64; 3]> = w.iter().map(|(x, i)| unwrap(*x, *i, l)).collect();
            let msd = mean_squared_displacement(&start, &now);
            let exact = v
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * t * t)
                .sum::<f64>()
                / 3.0;
            assert!(
                (msd - exact).abs() <= 1e-12 * exact,
                "t = {t}: MSD {msd} vs v^2 t^2 = {exact}"
            );
        }
    }

    #[test]
    fn correlation_length_interpolates_the_first_zero() {
        let r: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let c: Vec<f64> = r.iter().map(|r| (r * 1.1).cos()).collect();
        let zero = correlation_length(&r, &c).unwrap();
        let exact = std::f64::consts::FRAC_PI_2 / 1.1;
        // Linear interpolation over a step h misses c by at most h^2 max|c''| / 8, and within h of
        // the zero |c''| = k^2 |cos| <= k^3 h; divided by |c'| ~ k: root error <= h^3 k^2 / 8.
        let (h, k) = (0.1f64, 1.1f64);
        let bound = h.powi(3) * k * k / 8.0;
        assert!(
            (zero - exact).abs() < bound,
            "zero {zero} vs {exact}: error {:.2e} > {bound:.2e}",
            (zero - exact).abs()
        );
        assert_eq!(correlation_length(&r, &vec![1.0; 50]), None);
    }

    #[test]
    fn window_average_of_a_constant_plus_alternating_noise() {
        let t: Vec<f64> = (0..100).map(|i| i as f64).collect();
        let y: Vec<f64> = t
            .iter()
            .map(|t| 2.0 + if (*t as i64) % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let a = window_average(&t, &y, 10.0, 89.0);
        assert_eq!(a.samples, 80);
        assert!((a.mean - 2.0).abs() < 1e-14, "mean {}", a.mean);
        // Each batch of 8 samples averages exactly to 2: zero error.
        assert!(a.std_error.abs() < 1e-14, "std error {}", a.std_error);
    }

    #[test]
    fn l2_norm_and_orientation_autocorrelation() {
        let a = [3.0, 0.0];
        let b = [4.0, 0.0];
        assert!((volume_l2_norm(&[&a, &b]) - (25.0f64 / 2.0).sqrt()).abs() < 1e-15);
        let p0 = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let pt = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!((orientation_autocorrelation(&p0, &pt) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn complex_rates_of_beating_and_of_real_modes_are_recovered() {
        use num_complex::Complex64;
        let t: Vec<f64> = (0..200).map(|k| k as f64 * 0.5).collect();
        let sigma = Complex64::new(0.028, 0.065);
        // Three modes of a real field: each a sum of e^{sigma t} and e^{conj(sigma) t} with its
        // own amplitudes, plus a little noise.
        let series: Vec<Vec<Complex64>> = (0..3)
            .map(|m| {
                let a = Complex64::new(1.0 + m as f64, 0.3);
                let b = Complex64::new(0.4, -0.7 * m as f64);
                t.iter()
                    .enumerate()
                    .map(|(k, &t)| {
                        let noise = 1e-3 * (((k * 7919 + m * 104729) % 1000) as f64 / 1000.0 - 0.5);
                        a * (sigma * t).exp() + b * (sigma.conj() * t).exp() + noise
                    })
                    .collect()
            })
            .collect();
        let f = fit_complex_rate(&t, &series, 0.0, 99.5, 0.0).unwrap();
        assert!(
            (f.sigma - sigma).norm() < 2e-3 * sigma.norm() && f.r_squared > 0.999,
            "{f:?}"
        );
        // Two real rates (a growing and a decaying mode).
        let series: Vec<Vec<Complex64>> = vec![
            t.iter()
                .map(|&t| Complex64::new((0.05 * t).exp() + 2.0 * (-0.02 * t).exp(), 0.0))
                .collect(),
        ];
        let f = fit_complex_rate(&t, &series, 0.0, 60.0, 0.0).unwrap();
        assert!(
            (f.sigma.re - 0.05).abs() < 1e-6
                && f.sigma.im == 0.0
                && (f.other.re + 0.02).abs() < 1e-6,
            "{f:?}"
        );
        // A frequency above the default lag's Nyquist limit (window 100, lag 20: pi/20 =
        // 0.157) aliases without the cap; with the highest frequency stated it is recovered.
        let fast = Complex64::new(-0.01, 0.3);
        let series: Vec<Vec<Complex64>> = vec![
            t.iter()
                .map(|&t| {
                    let z = (fast * t).exp();
                    Complex64::new(2.0 * z.re, 0.0)
                })
                .collect(),
        ];
        let aliased = fit_complex_rate(&t, &series, 0.0, 99.5, 0.0).unwrap();
        assert!((aliased.sigma.im - 0.3).abs() > 0.05, "{aliased:?}");
        let f = fit_complex_rate(&t, &series, 0.0, 99.5, 0.4).unwrap();
        assert!((f.sigma - fast).norm() < 1e-6, "{f:?}");
    }
}
