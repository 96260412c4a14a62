//! The "exponential of semicircle" (ES) spreading kernel of the NUFFT.
//!
//! `phi(z) = exp(beta (sqrt(1 - z^2) - 1))` on `|z| <= 1`, zero outside, spread over `w` fine
//! grid points (Barnett, Magland, af Klinteberg 2019, the kernel FINUFFT uses). With an
//! upsampling factor of 2, `w = ceil(log10(1/tol)) + 1` and `beta = 2.30 w` give a relative
//! error close to `tol`.
//!
//! For speed the `w` kernel values a point needs are evaluated as `w` polynomials in the
//! point's sub-grid offset (Horner's rule, vectorisable over the `w` values), fitted once per
//! plan by Chebyshev interpolation. [`EsKernel::eval_exact`] is the slow twin that the tests
//! compare against.

use crate::quadrature::gauss_legendre;
use std::f64::consts::PI;

/// Widest kernel supported (tolerance 1e-15).
pub const MAX_WIDTH: usize = 16;

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

/// ES kernel of a given width, with its piecewise-polynomial evaluation table.
#[derive(Clone, Debug)]
pub struct EsKernel {
    /// Width in fine-grid points.
    pub width: usize,
    /// Shape parameter.
    pub beta: f64,
    /// Horner coefficients, `coef[d * width + j]` multiplies `t^d` for kernel value `j`.
    coef: Vec<f64>,
    /// Polynomial degree.
    degree: usize,
}

impl EsKernel {
    /// Kernel for a requested relative tolerance (upsampling factor 2).
    pub fn for_tolerance(tol: f64) -> Self {
        let width = ((1.0 / tol).log10().ceil() as usize + 1).clamp(2, MAX_WIDTH);
        let beta_over_w = match width {
            2 => 2.20,
            3 => 2.26,
            4 => 2.38,
            _ => 2.30,
        };
        Self::new(width, beta_over_w * width as f64)
    }

    /// Kernel with explicit width and shape parameter.
    pub fn new(width: usize, beta: f64) -> Self {
        assert!(
            (2..=MAX_WIDTH).contains(&width),
            "kernel width {width} outside 2..=16"
        );
        let degree = (width + 4).min(20);
        let mut k = Self {
            width,
            beta,
            coef: Vec::new(),
            degree,
        };
        k.coef = k.fit_polynomials();
        k
    }

    /// `phi(z)`, evaluated directly.
    pub fn phi(&self, z: f64) -> f64 {
        if z.abs() >= 1.0 {
            0.0
        } else {
            (self.beta * ((1.0 - z * z).sqrt() - 1.0)).exp()
        }
    }

    /// Kernel values at the `w` grid points a point at fine-grid coordinate `g` touches, the
    /// leftmost being `ceil(g - w/2)` (returned). Slow twin of [`Self::eval`].
    pub fn eval_exact(&self, g: f64, out: &mut [f64]) -> i64 {
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
    pub fn eval(&self, g: f64, out: &mut [f64; MAX_WIDTH]) -> i64 {
        crate::kernel::with_kernel_width!(self.width, self.eval_w(g, out))
    }

    /// [`Self::eval`] with the width as a compile-time constant (must equal `self.width`), so
    /// the loops unroll; the spreading loops call this directly.
    #[inline(always)]
    pub fn eval_w<const W: usize>(&self, g: f64, out: &mut [f64; MAX_WIDTH]) -> i64 {
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
    pub fn fourier_transform(&self, k: &[f64], nf: usize) -> Vec<f64> {
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
            let k = EsKernel::for_tolerance(tol);
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
            // The pieces touching the kernel's edge carry its sqrt singularity, so the fit error
            // is a fixed fraction of exp(-beta), itself of the order of the method's error: ask
            // for it to stay below a fifth of the tolerance (floor: round-off of degree-20 Horner).
            assert!(
                worst < 0.2 * tol.max(2e-13),
                "tol {tol:.0e}, width {}: max Horner error {worst:.2e}",
                k.width
            );
        }
    }

    #[test]
    fn fourier_transform_at_zero_is_kernel_integral() {
        let k = EsKernel::for_tolerance(1e-6);
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
