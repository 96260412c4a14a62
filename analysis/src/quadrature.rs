//! Gauss-Legendre quadrature on `[-1, 1]`.
//!
//! Used for the NUFFT kernel's Fourier transform (the deconvolution factors) and, later, for
//! integrals along a rod's centreline (docs/MODEL.md §1). Nodes come from Newton's method on the
//! three-term Legendre recurrence, started at the Tricomi approximation; accurate to a few ulp
//! for every `n` used here (tested against polynomial integrals).

use std::f64::consts::PI;

/// Nodes and weights of the `n`-point Gauss-Legendre rule on `[-1, 1]`, nodes ascending.
///
/// Exact for polynomials of degree `2n - 1`.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(n > 0, "gauss_legendre needs at least one node");
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Tricomi's initial guess for the i-th largest root.
        let theta = PI * (4.0 * i as f64 + 3.0) / (4.0 * nf + 2.0);
        let mut z = (1.0 - (nf - 1.0) / (8.0 * nf * nf * nf)) * theta.cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, z);
            dp = d;
            let dz = p / d;
            z -= dz;
            if dz.abs() <= 4.0 * f64::EPSILON * z.abs().max(1.0) {
                let (_, d) = legendre_and_derivative(n, z);
                dp = d;
                break;
            }
        }
        let wi = 2.0 / ((1.0 - z * z) * dp * dp);
        x[n - 1 - i] = z;
        x[i] = -z;
        w[n - 1 - i] = wi;
        w[i] = wi;
    }
    if n % 2 == 1 {
        x[n / 2] = 0.0;
    }
    (x, w)
}

/// `P_n(z)` and `P_n'(z)` by the three-term recurrence.
fn legendre_and_derivative(n: usize, z: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, z);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * z * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (z * p1 - p0) / (z * z - 1.0);
    (p1, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrates_monomials_exactly_to_degree_2n_minus_1() {
        for n in [1usize, 2, 3, 4, 7, 16, 50, 200] {
            let (x, w) = gauss_legendre(n);
            for deg in 0..(2 * n).min(40) {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(deg as i32)).sum();
                let exact = if deg % 2 == 1 {
                    0.0
                } else {
                    2.0 / (deg as f64 + 1.0)
                };
                assert!(
                    (q - exact).abs() < 1e-14 * n as f64,
                    "n = {n}, degree {deg}: quadrature {q} vs exact {exact}, error {:.2e}",
                    (q - exact).abs()
                );
            }
        }
    }

    #[test]
    fn integrates_cosine_to_round_off() {
        let (x, w) = gauss_legendre(30);
        let q: f64 = x.iter().zip(&w).map(|(x, w)| w * (3.0 * x).cos()).sum();
        let exact = 2.0 * 3f64.sin() / 3.0;
        assert!((q - exact).abs() < 1e-15, "error {:.2e}", (q - exact).abs());
    }
}
