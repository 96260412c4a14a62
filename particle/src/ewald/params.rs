//! Parameters of the spectral Ewald sums ([`crate::ewald::spectral`]) from a tolerance, per
//! output (docs/MODEL.md §1, §2; the accuracy contract is stated in `docs/accuracy.md`).
//!
//! Three outputs, the `n`-th derivative of the Stokeslet sum: RPY velocities (`n = 0`),
//! stresslet velocities (`n = 1`), stresslet velocity gradients (`n = 2`). Each source's
//! contribution near itself is carried by the smooth Fourier part, whose size at `r = 0` per
//! unit source is `Phi_n = xi^(n+1) / (2 pi^(3/2) mu)` (for `n = 0` the RPY self term
//! `M_F(0)`, for `n = 2` the stresslet self gradient `sqrt(pi) xi^3 / (2 pi^2)`; for `n = 1` the
//! same scale, the self velocity itself being zero by symmetry). Every truncation of the
//! method leaves an error proportional to that scale, so each is chosen to leave a fixed
//! fraction of `tol Phi_n` per source (`tol` the internal tolerance of one attempt, see
//! [`crate::ewald::spectral`]):
//!
//! - **Fourier cutoff** `k_max = 2 xi c_F`: the output's spectrum near a source is
//!   `k^n (1 + k^2/4xi^2) exp(-k^2/4xi^2)` over `k^2 dk` (the Hasimoto-screened Stokeslet,
//!   times `k^n` for `n` derivatives), so the part beyond `k_max` is the fraction
//!   `I_n(c_F) / I_n(0)`, `I_n(c) = int_c^inf t^n (1 + t^2) exp(-t^2) dt` (`fourier_tail`):
//!   `c_F` solves `I_n(c_F)/I_n(0) = FOURIER_SHARE tol`. The factor `t^n` is why one cutoff for
//!   every output failed the gradients: at `c = sqrt(ln(1/tol))` the gradient's tail is 16 tol
//!   at 1e-4 and grows like `c^3`.
//! - **Real-space cutoff** `r_c = c_R / xi`: the real-space kernel's `n`-th derivative at
//!   `r_c`, relative to `Phi_n` (`real_tail`, from the closed forms of
//!   [`crate::ewald::kernels::stokeslet_real_derivatives`]), equals `REAL_SHARE tol`.
//! - **Gaussian window** (support, shape, grid oversampling): `window_for` at
//!   `WINDOW_SHARE tol` (the gradient's window, differentiated in the gather, gets
//!   `GRADIENT_WINDOW_SHARE`).
//!
//! The shares were calibrated against the direct Ewald sum (the calibration is the test
//! `tests/accuracy_contract.rs`): with them, the error at each target is within a calibrated
//! multiple (`error_model_constants`) of `tol Phi_n sqrt(sum_j w(r_j) s_j^2)`, the sum over the
//! target's own group and its real-space neighbours of the sources' strengths squared, weighted
//! by `w(r) = 1 / (1 + (r / 2h)^2)` (`h` the grid spacing: errors of the Fourier part decay
//! over a few grid spacings from each source). That per-target estimate is what the sums
//! compare with the requested tolerance after each attempt.

use crate::ewald::kernels::stokeslet_real_derivatives;
use crate::ewald::window::window_for;
use motile_analysis::fft3::next_smooth_even;
use std::f64::consts::PI;

/// Cost of one real-space pair relative to one grid point of the Fourier stage (its six
/// real FFTs and the multiplication); calibrated at 1e5 points, tolerance 1e-4, where the
/// measured total is flat within the machine's noise from 0.09 to 0.2 (grids 100-108).
pub const PAIR_COST: f64 = 0.14;

/// The same for a stresslet pair (velocity and gradient from a table) against its Fourier
/// side (nine transforms instead of six, six fields spread, the gradient gathered);
/// calibrated at 78 125 centres, tolerance 1e-4 (flat from 0.15 to 0.45: grids 100-120).
pub const STRESSLET_PAIR_COST: f64 = 0.3;

/// Share of `tol Phi_n` per source left by the Fourier cutoff.
pub(crate) const FOURIER_SHARE: f64 = 0.3;
/// Share left by the real-space cutoff.
pub(crate) const REAL_SHARE: f64 = 0.3;
/// Share left by the Gaussian window (aliasing and truncation) for velocities.
pub(crate) const WINDOW_SHARE: f64 = 0.3;
/// The same for gradients (the window's derivative amplifies its truncation).
pub(crate) const GRADIENT_WINDOW_SHARE: f64 = 0.1;

/// Constants `(C_max, C_2)` of the error estimate at internal tolerance `tol` (see the module
/// doc): the largest error over the targets is within `C_max tol max_t model_t` and the L2 norm
/// of the errors within `C_2 tol ||model||_2`, `model_t = Phi_n sqrt(sum_j w s_j^2)`. Both grow
/// like `c = sqrt(ln(1/tol))` (the truncated tails' polynomial prefactors), normalised at
/// `tol = 1e-10`. Calibrated against the direct sum on random, clustered and force-free
/// configurations at internal tolerances 1e-2 to 1e-10 with the shares above: without the
/// factor `c` the worst measured/estimate ratios of RPY velocities grew from 0.22 (1e-2) to
/// 0.69 (1e-10); with it they stay within 0.44-0.69 (`tests/accuracy_contract.rs`,
/// `error_estimates_bound_the_measured_errors`). Stresslet velocities get smaller constants:
/// their parameters are set by the gradient's stricter needs.
pub(crate) fn error_model_constants(output: SumOutput, tol: f64) -> (f64, f64) {
    let g = (1.0 / tol).ln().sqrt() / (1e10f64).ln().sqrt();
    let (c_max, c_2) = match output {
        SumOutput::RpyVelocity | SumOutput::StressletGradient => (1.25, 0.6),
        SumOutput::StressletVelocity => (0.15, 0.1),
    };
    (g * c_max, g * c_2)
}

/// Range of the error model's weight, in grid spacings: `w(r) = 1 / (1 + (r / (W h))^2)`.
pub(crate) const ERROR_MODEL_RANGE: f64 = 2.0;

/// What a sum returns: the derivative order of the Stokeslet sum behind it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SumOutput {
    /// RPY velocities of point forces.
    RpyVelocity,
    /// Velocities of point stresslets.
    StressletVelocity,
    /// Velocity gradients of point stresslets.
    StressletGradient,
}

impl SumOutput {
    /// Derivative order `n`.
    pub fn order(self) -> i32 {
        match self {
            Self::RpyVelocity => 0,
            Self::StressletVelocity => 1,
            Self::StressletGradient => 2,
        }
    }

    /// `Phi_n = xi^(n+1) / (2 pi^(3/2))` per unit source and unit viscosity: the size of one
    /// source's smooth part at its own position (see the module doc).
    pub fn self_scale(self, xi: f64) -> f64 {
        xi.powi(self.order() + 1) / (2.0 * PI.powf(1.5))
    }

    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::RpyVelocity => "RPY velocity",
            Self::StressletVelocity => "stresslet velocity",
            Self::StressletGradient => "stresslet velocity gradient",
        }
    }
}

/// `I_n(c) / I_n(0)`, `I_n(c) = int_c^inf t^n (1 + t^2) exp(-t^2) dt`: the fraction of the
/// output's self-term spectrum beyond `k = 2 xi c` (closed forms).
pub(crate) fn fourier_tail(output: SumOutput, c: f64) -> f64 {
    let e = (-c * c).exp();
    let sp = PI.sqrt();
    let erfc = libm::erfc(c);
    match output.order() {
        0 => (0.75 * sp * erfc + 0.5 * c * e) / (0.75 * sp),
        1 => 0.5 * e * (c * c + 2.0),
        _ => (e * (0.5 * c * c * c + 1.25 * c) + 0.625 * sp * erfc) / (0.625 * sp),
    }
}

/// The magnitude of the real-space part's `n`-th derivative (Stokeslet, `a = 0`) at
/// `xi r = c`, relative to `Phi_n`: for `G = A I + C x x`, `|A| + |C| r^2` (`n = 0`),
/// `|A'| + 2|C| r + |C'| r^2` (`n = 1`), `|A''| + 2|C| + 4|C'| r + |C''| r^2` (`n = 2`).
/// Scale free: evaluated at `xi = 1`.
pub(crate) fn real_tail(output: SumOutput, c: f64) -> f64 {
    let [a, a1, a2, cc, c1, c2] = stokeslet_real_derivatives(c, 1.0);
    let m = match output.order() {
        0 => a.abs() + cc.abs() * c * c,
        1 => a1.abs() + 2.0 * cc.abs() * c + c1.abs() * c * c,
        _ => a2.abs() + 2.0 * cc.abs() + 4.0 * c1.abs() * c + c2.abs() * c * c,
    };
    m / output.self_scale(1.0)
}

/// The smallest `c` in `[0.5, 12]` beyond which `tail` stays below `target` (the tails
/// decrease monotonically there), by bisection.
fn cutoff_for(tail: impl Fn(f64) -> f64, target: f64) -> f64 {
    let (mut lo, mut hi) = (0.5, 12.0);
    if tail(lo) <= target {
        return lo;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if tail(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// `c_F` and `c_R` for internal tolerance `tol` and the outputs asked for (the largest over
/// them), and the window's tolerance (the smallest).
pub(crate) fn cutoffs(tol: f64, outputs: &[SumOutput]) -> (f64, f64, f64) {
    let mut c_f: f64 = 0.5;
    let mut c_r: f64 = 0.5;
    let mut window = f64::INFINITY;
    for &o in outputs {
        c_f = c_f.max(cutoff_for(|c| fourier_tail(o, c), FOURIER_SHARE * tol));
        c_r = c_r.max(cutoff_for(|c| real_tail(o, c), REAL_SHARE * tol));
        let share = if o == SumOutput::StressletGradient {
            GRADIENT_WINDOW_SHARE
        } else {
            WINDOW_SHARE
        };
        window = window.min(share * tol);
    }
    (c_f, c_r, window)
}

/// The resolved parameters of one spectral Ewald sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EwaldParams {
    /// Splitting parameter xi (1/length).
    pub xi: f64,
    /// Real-space cutoff.
    pub cutoff: f64,
    /// Fourier modes per dimension, the Gaussian grid's size (even).
    pub modes: usize,
    /// Gaussian support per axis, in grid points.
    pub support: usize,
    /// Gaussian shape: standard deviations at the support's edge.
    pub shape: f64,
}

impl EwaldParams {
    /// Parameters for RPY velocities at internal tolerance `tol`, `n` points in a box of side
    /// `l`.
    pub fn choose(tol: f64, n: usize, l: f64) -> Self {
        Self::choose_for(tol, n, l, &[SumOutput::RpyVelocity], PAIR_COST)
    }

    /// Parameters for the given outputs at internal tolerance `tol`, with the cost of a
    /// real-space pair relative to a grid point.
    ///
    /// Each FFT-friendly grid size `M` fixes the largest `xi` it resolves,
    /// `M = over k_max L / pi` with `k_max = 2 xi c_F` (which also keeps every `|k| <= k_max`
    /// on the grid); the cost model weighs the real-space pairs of that `xi` (cutoff `c_R/xi`,
    /// at most `L/2` so the minimum image is exact) against the grid and keeps the cheapest.
    pub fn choose_for(tol: f64, n: usize, l: f64, outputs: &[SumOutput], pair_cost: f64) -> Self {
        Self::choose_within(tol, n, l, outputs, pair_cost, 0.5 * l)
    }

    /// [`Self::choose_for`] with the real-space cutoff at most `max_cutoff` (itself at most
    /// `L/2`): a sum shared among ranks keeps its pairs within the copies each rank holds.
    pub(crate) fn choose_within(
        tol: f64,
        n: usize,
        l: f64,
        outputs: &[SumOutput],
        pair_cost: f64,
        max_cutoff: f64,
    ) -> Self {
        let max_cutoff = max_cutoff.min(0.5 * l);
        let (c_f, c_r, window_tol) = cutoffs(tol, outputs);
        let density = n as f64 / (l * l * l);
        let (support, shape, over) = window_for(window_tol);
        let mut best: Option<(f64, Self)> = None;
        let mut m = next_smooth_even(support.max(4));
        while m <= 4096 {
            let xi = m as f64 * PI / (2.0 * c_f * l * over);
            let p = Self {
                xi,
                cutoff: c_r / xi,
                modes: m,
                support,
                shape,
            };
            let grid = (m * m * m) as f64;
            if best.as_ref().is_some_and(|(b, _)| grid > *b) {
                break;
            }
            if p.cutoff <= max_cutoff {
                let pairs = n as f64 * density * 4.0 / 3.0 * PI * p.cutoff.powi(3);
                let cost = pair_cost * pairs + grid;
                if best.as_ref().is_none_or(|(b, _)| cost < *b) {
                    best = Some((cost, p));
                }
            }
            m = next_smooth_even(m + 1);
        }
        best.expect("a grid of 4096^3 or less resolves any supported tolerance")
            .1
    }

    /// Grid spacing `L / M` for a box of side `l`.
    pub fn spacing(&self, l: f64) -> f64 {
        l / self.modes as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motile_analysis::quadrature::gauss_legendre;

    /// The closed-form tails against quadrature of their integrals.
    #[test]
    fn fourier_tails_match_quadrature() {
        let (x, w) = gauss_legendre(200);
        for o in [
            SumOutput::RpyVelocity,
            SumOutput::StressletVelocity,
            SumOutput::StressletGradient,
        ] {
            let n = o.order();
            // int_c^12 on Gauss-Legendre nodes (the rest is below 1e-60).
            let integral = |c: f64| -> f64 {
                let h = 0.5 * (12.0 - c);
                x.iter()
                    .zip(&w)
                    .map(|(xi, wi)| {
                        let t = c + h * (xi + 1.0);
                        h * wi * t.powi(n) * (1.0 + t * t) * (-t * t).exp()
                    })
                    .sum()
            };
            for c in [0.7, 2.0, 3.5, 5.0] {
                let q = integral(c) / integral(0.0);
                let f = fourier_tail(o, c);
                assert!(
                    (q - f).abs() <= 1e-12 * q,
                    "{o:?} at c {c}: closed form {f:e}, quadrature {q:e}"
                );
            }
        }
    }

    #[test]
    fn cutoffs_grow_with_the_derivative_order() {
        for tol in [1e-2, 1e-6, 1e-10] {
            let c = |o| cutoffs(tol, &[o]);
            let (u, s, g) = (
                c(SumOutput::RpyVelocity),
                c(SumOutput::StressletVelocity),
                c(SumOutput::StressletGradient),
            );
            assert!(
                u.0 < s.0 && s.0 < g.0,
                "Fourier cutoffs at {tol:e}: {u:?} {s:?} {g:?}"
            );
            assert!(
                (fourier_tail(SumOutput::StressletGradient, g.0) - FOURIER_SHARE * tol).abs()
                    < 1e-6 * tol,
                "the cutoff solves its equation"
            );
        }
    }
}
