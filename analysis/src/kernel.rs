//! The spreading kernel of the NUFFT: a function `phi(z)` on `|z| <= 1`, zero outside,
//! spread over `w` fine-grid points at upsampling factor 2.
//!
//! Two shapes:
//! - the prolate spheroidal wave function of order zero `psi_0(c; z)` (the default), the
//!   function of support `[-1, 1]` whose Fourier transform is most concentrated in
//!   `|alpha| <= c`. With `c = pi w (1 - 1/(2 sigma)) - 0.1` (the transform's cutoff aligned
//!   with the start of aliasing at upsampling `sigma = 2`, less a shift) its aliasing error
//!   falls like `exp(-pi w sqrt(1 - 1/sigma))`, and the width
//!   `w = ceil(ln(0.353/tol) / (pi sqrt(1/2)) + 1)` keeps the relative L2 error of a 3D
//!   transform at or below `tol` from 1e-1 to 1e-12 (`tests/nufft_accuracy.rs`). Kernel and
//!   width rule follow FINUFFT's recent versions (Barnett et al.); the shift 0.1 (FINUFFT uses
//!   0.05) minimised the worst error over mode counts 12-53 and tolerances 1e-1 to 1e-12 in a
//!   scan of 0 to 0.4 (worst 0.89 tol, against 1.11 tol with 0.05). The widths are those of
//!   the ES kernel below at every decade of `tol`, so the cost is unchanged. `psi_0` is
//!   computed from its Legendre expansion, the eigenvector of the prolate operator's
//!   symmetric tridiagonal matrix (Xiao, Rokhlin and Yarvin 2001).
//! - the "exponential of semicircle" `exp(beta (sqrt(1 - z^2) - 1))` (Barnett, Magland, af
//!   Klinteberg 2019), FINUFFT's kernel to 2025, with `w = ceil(log10(1/tol)) + 1` and
//!   `beta = 2.30 w`: at the same widths its error is 1-5 times `tol` (measured), so it is kept
//!   only as a comparison ([`SpreadKernel::exponential_semicircle`]).
//!
//! For speed the `w` kernel values a point needs are evaluated as `w` polynomials in the
//! point's sub-grid offset (Horner's rule, vectorisable over the `w` values), fitted once per
//! plan by Chebyshev interpolation. [`SpreadKernel::eval_exact`] is the slow twin that the
//! tests compare against.

use crate::quadrature::gauss_legendre;
use std::f64::consts::PI;

/// Widest kernel supported (tolerance 1e-15).
pub(crate) const MAX_WIDTH: usize = 16;

/// `ceil(y)` as an integer without a libm call (baseline x86-64 has no rounding instruction).
#[inline(always)]
fn ceil_i64(y: f64) -> i64 {
    let t = y as i64; // truncates toward zero
    if (t as f64) < y { t + 1 } else { t }
}

/// Evaluates `$e` (which may use `W`) with the runtime kernel width `$w` bound to the
/// compile-time constant `W`, so that loops over the kernel unroll and vectorise.
macro_rules! with_kernel_width {
    ($w:expr, $obj:ident . $f:ident ( $($arg:expr),* )) => {
        match $w {
            2 => $obj.$f::<2>($($arg),*),
            3 => $obj.$f::<3>($($arg),*),
            4 => $obj.$f::<4>($($arg),*),
            5 => $obj.$f::<5>($($arg),*),
            6 => $obj.$f::<6>($($arg),*),
            7 => $obj.$f::<7>($($arg),*),
            8 => $obj.$f::<8>($($arg),*),
            9 => $obj.$f::<9>($($arg),*),
            10 => $obj.$f::<10>($($arg),*),
            11 => $obj.$f::<11>($($arg),*),
            12 => $obj.$f::<12>($($arg),*),
            13 => $obj.$f::<13>($($arg),*),
            14 => $obj.$f::<14>($($arg),*),
            15 => $obj.$f::<15>($($arg),*),
            16 => $obj.$f::<16>($($arg),*),
            _ => unreachable!("kernel width outside 2..=16"),
        }
    };
}
pub(crate) use with_kernel_width;

/// The kernel function on `[-1, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Shape {
    /// `psi_0(c; z) / psi_0(c; 0)` from its normalised-Legendre coefficients (even degrees
    /// `0, 2, 4, ...`).
    Prolate {
        /// Bandwidth `c`.
        c: f64,
        /// Coefficients of `sqrt(2k + 1/2) P_{2k}(z)`, scaled so that `phi(0) = 1`.
        legendre: Vec<f64>,
    },
    /// `exp(beta (sqrt(1 - z^2) - 1))`: only the tests' comparison constructs it.
    #[cfg_attr(not(test), allow(dead_code))]
    ExponentialSemicircle {
        /// Shape parameter.
        beta: f64,
    },
}

/// A spreading kernel of a given width, with its piecewise-polynomial evaluation table.
#[derive(Clone, Debug)]
pub(crate) struct SpreadKernel {
    /// Width in fine-grid points.
    pub width: usize,
    /// The function.
    pub shape: Shape,
    /// Horner coefficients, `coef[d * width + j]` multiplies `t^d` for kernel value `j`.
    coef: Vec<f64>,
    /// Polynomial degree.
    degree: usize,
}

/// Width of the prolate kernel for relative tolerance `tol` at upsampling 2 in three
/// dimensions: `ceil(ln(0.353 / tol) / (pi sqrt(1/2)) + 1)`, clamped to `2..=MAX_WIDTH`.
pub(crate) fn prolate_width(tol: f64) -> usize {
    let rate = PI * (0.5f64).sqrt();
    (((0.353 / tol).ln() / rate + 1.0).ceil() as usize).clamp(2, MAX_WIDTH)
}

/// Normalised-Legendre coefficients of `psi_0(c; z)` (even degrees), from the smallest
/// eigenvalue of the prolate operator's matrix in that basis (a symmetric tridiagonal matrix
/// over the even degrees): bisection on Sturm counts for the eigenvalue, inverse iteration
/// for the eigenvector. Scaled so that `psi_0(0) = 1`.
fn prolate_coefficients(c: f64) -> Vec<f64> {
    let n = (c as usize) / 2 + 40;
    let c2 = c * c;
    let diag: Vec<f64> = (0..n)
        .map(|j| {
            let k = (2 * j) as f64;
            k * (k + 1.0) + c2 * (2.0 * k * (k + 1.0) - 1.0) / ((2.0 * k + 3.0) * (2.0 * k - 1.0))
        })
        .collect();
    let off: Vec<f64> = (0..n - 1)
        .map(|j| {
            let k = (2 * j) as f64;
            c2 * (k + 1.0) * (k + 2.0)
                / ((2.0 * k + 3.0) * ((2.0 * k + 1.0) * (2.0 * k + 5.0)).sqrt())
        })
        .collect();
    // Number of eigenvalues below x (Sturm sequence of the LDL^T pivots).
    let below = |x: f64| {
        let mut count = 0;
        let mut q = diag[0] - x;
        for j in 0..n {
            if j > 0 {
                q = diag[j] - x - off[j - 1] * off[j - 1] / if q == 0.0 { 1e-300 } else { q };
            }
            if q < 0.0 {
                count += 1;
            }
        }
        count
    };
    // Gershgorin bounds, then bisection to the smallest eigenvalue.
    let mut lo = (0..n)
        .map(|j| {
            let r =
                if j > 0 { off[j - 1].abs() } else { 0.0 } + off.get(j).map_or(0.0, |v| v.abs());
            diag[j] - r
        })
        .fold(f64::INFINITY, f64::min);
    let mut hi = diag[0];
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if below(mid) >= 1 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let chi = 0.5 * (lo + hi);
    // Inverse iteration with (T - (chi - delta) I), a tridiagonal solve each round.
    let shift = chi - 1e-10 * chi.abs().max(1.0);
    let mut v = vec![1.0; n];
    for _ in 0..4 {
        // Thomas algorithm.
        let mut cp = vec![0.0; n];
        let mut dp = vec![0.0; n];
        let mut b = diag[0] - shift;
        cp[0] = if n > 1 { off[0] / b } else { 0.0 };
        dp[0] = v[0] / b;
        for j in 1..n {
            b = diag[j] - shift - off[j - 1] * cp[j - 1];
            if j < n - 1 {
                cp[j] = off[j] / b;
            }
            dp[j] = (v[j] - off[j - 1] * dp[j - 1]) / b;
        }
        let mut x = vec![0.0; n];
        x[n - 1] = dp[n - 1];
        for j in (0..n - 1).rev() {
            x[j] = dp[j] - cp[j] * x[j + 1];
        }
        let norm = x.iter().map(|a| a * a).sum::<f64>().sqrt();
        v = x.into_iter().map(|a| a / norm).collect();
    }
    let at_zero = legendre_even_sum(&v, 0.0);
    v.into_iter().map(|a| a / at_zero).collect()
}

/// `sum_j a_j sqrt(2 (2j) + 1) / sqrt 2 P_{2j}(z)`, the normalised Legendre series over even
/// degrees.
fn legendre_even_sum(a: &[f64], z: f64) -> f64 {
    // P_k by the three-term recurrence, keeping the even ones.
    let (mut p0, mut p1) = (1.0, z);
    let mut sum = a[0] * (0.5f64).sqrt();
    let mut k = 1;
    for (j, aj) in a.iter().enumerate().skip(1) {
        while k < 2 * j {
            let kf = k as f64;
            let p2 = ((2.0 * kf + 1.0) * z * p1 - kf * p0) / (kf + 1.0);
            p0 = p1;
            p1 = p2;
            k += 1;
        }
        // p1 = P_{2j}
        sum += aj * ((2 * (2 * j) + 1) as f64 / 2.0).sqrt() * p1;
    }
    sum
}

impl SpreadKernel {
    /// The prolate kernel for a requested relative tolerance (upsampling factor 2), width from
    /// [`prolate_width`].
    pub(crate) fn for_tolerance(tol: f64) -> Self {
        let width = prolate_width(tol);
        let c = PI * width as f64 * 0.75 - 0.1;
        Self::new(
            width,
            Shape::Prolate {
                c,
                legendre: prolate_coefficients(c),
            },
        )
    }

    /// The exponential-of-semicircle kernel with FINUFFT's parameters to 2025 (width
    /// `ceil(log10(1/tol)) + 1`, `beta = 2.30 w`, small-width tweaks): the comparison.
    #[cfg(test)]
    pub(crate) fn exponential_semicircle(tol: f64) -> Self {
        let width = ((1.0 / tol).log10().ceil() as usize + 1).clamp(2, MAX_WIDTH);
        let beta_over_w = match width {
            2 => 2.20,
            3 => 2.26,
            4 => 2.38,
            _ => 2.30,
        };
        Self::new(
            width,
            Shape::ExponentialSemicircle {
                beta: beta_over_w * width as f64,
            },
        )
    }

    /// Kernel with explicit width and shape.
    pub(crate) fn new(width: usize, shape: Shape) -> Self {
        assert!(
            (2..=MAX_WIDTH).contains(&width),
            "kernel width {width} outside 2..=16"
        );
        let degree = (width + 4).min(20);
        let mut k = Self {
            width,
            shape,
            coef: Vec::new(),
            degree,
        };
        k.coef = k.fit_polynomials();
        k
    }

    /// `phi(z)`, evaluated directly.
    pub(crate) fn phi(&self, z: f64) -> f64 {
        // The edge value is the limit from inside (a point exactly at the support's edge gets
        // the value the fitted polynomial gives it).
        if z.abs() > 1.0 {
            return 0.0;
        }
        match &self.shape {
            Shape::Prolate { legendre, .. } => legendre_even_sum(legendre, z),
            Shape::ExponentialSemicircle { beta } => (beta * ((1.0 - z * z).sqrt() - 1.0)).exp(),
        }
    }

    /// Kernel values at the `w` grid points a point at fine-grid coordinate `g` touches, the
    /// leftmost being `ceil(g - w/2)` (returned). Slow twin of [`Self::eval`].
    #[cfg(test)]
    pub(crate) fn eval_exact(&self, g: f64, out: &mut [f64]) -> i64 {
        let half = self.width as f64 / 2.0;
        let i0 = (g - half).ceil();
        for (j, o) in out.iter_mut().enumerate().take(self.width) {
            *o = self.phi((i0 + j as f64 - g) / half);
        }
        i0 as i64
    }

    /// Kernel values at the `w` grid points touched from fine-grid coordinate `g`; returns the
    /// leftmost index `ceil(g - w/2)`. Horner's rule on the fitted polynomials.
    #[inline(always)]
    pub(crate) fn eval(&self, g: f64, out: &mut [f64; MAX_WIDTH]) -> i64 {
        crate::kernel::with_kernel_width!(self.width, self.eval_w(g, out))
    }

    /// [`Self::eval`] with the width as a compile-time constant (must equal `self.width`), so
    /// the loops unroll; the spreading loops call this directly.
    #[inline(always)]
    pub(crate) fn eval_w<const W: usize>(&self, g: f64, out: &mut [f64; MAX_WIDTH]) -> i64 {
        debug_assert_eq!(W, self.width);
        let y = g - W as f64 / 2.0;
        let i0 = ceil_i64(y);
        let t = 2.0 * (i0 as f64 - y) - 1.0; // 2u - 1 with u in [0, 1)
        let d = self.degree;
        let mut acc = [0.0; W];
        acc.copy_from_slice(&self.coef[d * W..(d + 1) * W]);
        for deg in (0..d).rev() {
            let c: &[f64; W] = self.coef[deg * W..(deg + 1) * W]
                .try_into()
                .expect("coefficient row");
            for j in 0..W {
                acc[j] = acc[j] * t + c[j];
            }
        }
        out[..W].copy_from_slice(&acc);
        i0
    }

    /// `(w/2) * integral_{-1}^{1} phi(z) cos(alpha z) dz`: the kernel's Fourier transform in
    /// fine-grid units, for `alpha = k * (2 pi / nf) * (w / 2)`.
    pub(crate) fn fourier_transform(&self, k: &[f64], nf: usize) -> Vec<f64> {
        let (z, wq) = gauss_legendre(2 * self.width + 200);
        let half = self.width as f64 / 2.0;
        let phi: Vec<f64> = z.iter().map(|&z| self.phi(z)).collect();
        k.iter()
            .map(|&k| {
                let alpha = k * 2.0 * PI / nf as f64 * half;
                half * z
                    .iter()
                    .zip(&wq)
                    .zip(&phi)
                    .map(|((z, w), p)| w * p * (alpha * z).cos())
                    .sum::<f64>()
            })
            .collect()
    }

    /// Chebyshev interpolation of each of the `w` kernel pieces in `t = 2u - 1`, converted to
    /// monomial coefficients.
    fn fit_polynomials(&self) -> Vec<f64> {
        let w = self.width;
        let n = self.degree + 1;
        let half = w as f64 / 2.0;
        let mut coef = vec![0.0; n * w];
        // Chebyshev points of the first kind and the transform to Chebyshev coefficients.
        let nodes: Vec<f64> = (0..n)
            .map(|i| (PI * (i as f64 + 0.5) / n as f64).cos())
            .collect();
        // Monomial coefficients of T_0..T_{n-1}.
        let mut tmono = vec![vec![0.0; n]; n];
        tmono[0][0] = 1.0;
        if n > 1 {
            tmono[1][1] = 1.0;
        }
        for m in 2..n {
            for d in 0..n {
                let shifted = if d > 0 {
                    2.0 * tmono[m - 1][d - 1]
                } else {
                    0.0
                };
                tmono[m][d] = shifted - tmono[m - 2][d];
            }
        }
        for j in 0..w {
            let f: Vec<f64> = nodes
                .iter()
                .map(|&t| {
                    let u = (t + 1.0) / 2.0;
                    self.phi((u + j as f64) / half - 1.0)
                })
                .collect();
            for m in 0..n {
                let scale = if m == 0 { 1.0 } else { 2.0 } / n as f64;
                let cm: f64 = (0..n)
                    .map(|i| f[i] * (PI * m as f64 * (i as f64 + 0.5) / n as f64).cos())
                    .sum::<f64>()
                    * scale;
                for d in 0..n {
                    coef[d * w + j] += cm * tmono[m][d];
                }
            }
        }
        coef
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn horner_matches_direct_evaluation_well_below_tolerance() {
        for e in (1..=15).rev() {
            let tol = 10f64.powi(-e);
            let k = SpreadKernel::for_tolerance(tol);
            let mut fast = [0.0; MAX_WIDTH];
            let mut slow = [0.0; MAX_WIDTH];
            let mut worst: f64 = 0.0;
            for i in 0..1000 {
                let g = 37.0 + i as f64 / 1000.0 * 0.999_999;
                let a = k.eval(g, &mut fast);
                let b = k.eval_exact(g, &mut slow);
                assert_eq!(a, b);
                for j in 0..k.width {
                    worst = worst.max((fast[j] - slow[j]).abs());
                }
            }
            // The prolate kernel is smooth to its edge, so the fit is far below the method's
            // error: a hundredth of the tolerance (floor 1e-14: round-off of degree-20 Horner).
            assert!(
                worst < (0.01 * tol).max(1e-14),
                "tol {tol:.0e}, width {}: max Horner error {worst:.2e}",
                k.width
            );
        }
    }

    #[test]
    fn exponential_semicircle_fit_is_within_a_fifth_of_the_tolerance() {
        for e in [2, 6, 10] {
            let tol = 10f64.powi(-e);
            let k = SpreadKernel::exponential_semicircle(tol);
            let (mut fast, mut slow) = ([0.0; MAX_WIDTH], [0.0; MAX_WIDTH]);
            let mut worst: f64 = 0.0;
            for i in 0..1000 {
                let g = 37.0 + i as f64 / 1000.0 * 0.999_999;
                k.eval(g, &mut fast);
                k.eval_exact(g, &mut slow);
                for j in 0..k.width {
                    worst = worst.max((fast[j] - slow[j]).abs());
                }
            }
            // The pieces at its edge carry a sqrt singularity: the fit error is a fraction of
            // exp(-beta), itself of the order of the method's error.
            assert!(
                worst < 0.2 * tol,
                "tol {tol:.0e}: max Horner error {worst:.2e}"
            );
        }
    }

    /// The prolate function solves its eigenproblem: `psi_0` is even, equals 1 at 0, and its
    /// Fourier transform over `[-1, 1]` at `alpha = c x` is proportional to itself at `x`
    /// (the defining integral equation), checked by quadrature.
    #[test]
    fn prolate_function_is_its_own_band_limited_transform() {
        for width in [3, 7, 13] {
            let c = PI * width as f64 * 0.75 - 0.1;
            let k = SpreadKernel::new(
                width,
                Shape::Prolate {
                    c,
                    legendre: prolate_coefficients(c),
                },
            );
            let (z, w) = gauss_legendre(200);
            let ft = |x: f64| -> f64 {
                z.iter()
                    .zip(&w)
                    .map(|(zi, wi)| wi * k.phi(*zi) * (c * x * zi).cos())
                    .sum()
            };
            let lambda = ft(0.0) / k.phi(0.0);
            for x in [0.1, 0.4, 0.8, 0.95] {
                let lhs = ft(x);
                let rhs = lambda * k.phi(x);
                assert!(
                    (lhs - rhs).abs() < 1e-10 * lambda.abs(),
                    "width {width}, x {x}: transform {lhs:e} vs lambda psi {rhs:e}"
                );
                assert!((k.phi(-x) - k.phi(x)).abs() < 1e-14);
            }
            assert!((k.phi(0.0) - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn fourier_transform_at_zero_is_kernel_integral() {
        let k = SpreadKernel::for_tolerance(1e-6);
        // Riemann sum over a fine grid of the kernel in grid units equals its integral.
        let half = k.width as f64 / 2.0;
        let n = 200_000;
        let h = 2.0 / n as f64;
        let integral: f64 = (0..n)
            .map(|i| k.phi(-1.0 + (i as f64 + 0.5) * h) * h)
            .sum::<f64>()
            * half;
        let ft = k.fourier_transform(&[0.0], 64)[0];
        assert!(
            (ft - integral).abs() < 1e-9,
            "FT(0) = {ft}, midpoint integral {integral}"
        );
    }
}
