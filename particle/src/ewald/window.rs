//! The Gaussian window of the spectral Ewald grid (the SE method of Lindbo and Tornberg,
//! J. Comput. Phys. 229, 2010; docs/accuracy.md): its support, shape and the grid's
//! oversampling chosen from the tolerance, and its values on a grid.

use std::f64::consts::PI;

/// Largest supported support (grid points per axis of one Gaussian).
pub(crate) const MAX_SUPPORT: usize = 24;

/// The window for relative tolerance `tol` with `c = sqrt(ln(1/tol))`: support `P`, shape
/// `m` and the grid's oversampling `r` (the grid has at least `r k_max L / pi` points per
/// axis, `k_max = 2 xi c`).
///
/// Two errors, from the analysis of Lindbo and Tornberg: truncating the Gaussian at `m`
/// standard deviations, relative `erfc(m / sqrt 2)` per axis and pass; and aliasing on the
/// grid, which after the Ewald factor is largest near `k = eta k_N` and is about
/// `exp(-(c^2 / 2) r^2 (4 eta - 2 eta^2))` with `eta = eta_0 / r^2`,
/// `eta_0 = (P pi / (2 c m))^2`. The truncation error measured against the reference sums is
/// about five times `erfc(m / sqrt 2)` (three axes, two passes), so `m` makes that
/// `tol / 10`. The aliasing is `tol / 2` when `r^2 = eta_0^2 / (2 eta_0 - 1 - ln 2 / c^2)`;
/// `P` is the smallest support for which that `r` is at most 1.1 (a wider support costs
/// `P^3` per point, a finer grid `r^3` per grid point), or the one with the least `r`. From
/// 1e-2 to 1e-12 this gives `P` = 5, 6, 8, 12, 15, 18, 22 at 1e-2, 1e-3, 1e-4, 1e-6, 1e-8,
/// 1e-10, 1e-12, with `r` 1.04-1.10 and `eta` 0.63-1.07.
pub(crate) fn window_for(tol: f64) -> (usize, f64, f64) {
    let c2 = (1.0 / tol).ln();
    let c = c2.sqrt();
    let m = std::f64::consts::SQRT_2 * erfc_inv(tol / 10.0);
    let q = 1.0 + std::f64::consts::LN_2 / c2;
    let over = |p: usize| {
        let eta0 = (p as f64 * PI / (2.0 * c * m)).powi(2);
        let d = 2.0 * eta0 - q;
        if d <= 0.0 {
            f64::INFINITY
        } else {
            (eta0 * eta0 / d).sqrt().max(1.0)
        }
    };
    // r is smallest near eta_0 = 1 + ln 2 / c^2 (about 1.14 at tol = 0.1): stop there too.
    let mut p = 2;
    while p < MAX_SUPPORT && over(p) > 1.1 && over(p + 1) <= over(p) {
        p += 1;
    }
    (p, m, over(p))
}

/// `erfc^-1(y)` for `0 < y < 1` by bisection (a few dozen evaluations, once per plan).
fn erfc_inv(y: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 10.0);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if libm::erfc(mid) > y {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The Gaussian window on an `m^3` grid of a box of side `l` (see the module doc).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Window {
    /// Support, grid points per axis.
    pub(crate) p: usize,
    /// Grid spacing.
    pub(crate) h: f64,
    /// Exponent `2 xi^2 / eta`.
    pub(crate) alpha: f64,
    /// 1D normalisation `sqrt(alpha / pi)`.
    pub(crate) norm: f64,
    /// Width parameter `eta`.
    pub(crate) eta: f64,
}

impl Window {
    /// The window for splitting `xi`, support `p` (clamped to 2..=[`MAX_SUPPORT`] and the
    /// grid), `shape` standard deviations wide at the support's edge.
    pub(crate) fn new(l: f64, xi: f64, m: usize, p: usize, shape: f64) -> Self {
        let p = p.clamp(2, MAX_SUPPORT).min(m);
        let h = l / m as f64;
        let w = p as f64 * h / 2.0;
        let eta = (2.0 * w * xi / shape).powi(2);
        let alpha = 2.0 * xi * xi / eta;
        Self {
            p,
            h,
            alpha,
            norm: (alpha / PI).sqrt(),
            eta,
        }
    }
}
