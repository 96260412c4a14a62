//! The Bingham distribution `Psi_B(p) = exp(p.B p) / Z` on the unit sphere (docs/MODEL.md §4): its
//! moments by accurate quadrature, and the exponent `B` whose second moment has given
//! eigenvalues (Newton). This is the slow, accurate reference; [`crate::closure`] tabulates it.
//!
//! In the eigenframe `B = diag(b)`. Only differences of the `b_i` matter, so the largest
//! eigenvalue's axis `k` gets `b_k = 0` and the others `b <= 0`. With `k` as the polar axis
//! (`u = p_k`, `s = 1 - u^2`) the exponent is `s (A + a cos 2 phi)`; the `phi` integrals are
//! exact in terms of scaled Bessel functions, and the remaining integral over `u` (even, peaked
//! only at `u = 1` as the distribution concentrates) uses Gauss-Legendre panels graded
//! geometrically towards `u = 1`, accurate for any concentration the tables reach.

use crate::bessel::scaled_i012;
use motile_analysis::quadrature::gauss_legendre;
use std::sync::OnceLock;

/// Second and fourth moments in the eigenframe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moments {
    /// `<p_i^2>`.
    pub second: [f64; 3],
    /// `<p_i^2 p_j^2>` (symmetric; the diagonal is `<p_i^4>`).
    pub fourth: [[f64; 3]; 3],
    /// `ln Z` with `Z = (1/4pi) int exp(p.B p) dp` for the exponent as given (no gauge shift).
    pub log_z: f64,
}

/// Quadrature nodes and weights in `u` on `[0, 1]`, panels `[1 - 10^-(j), 1 - 10^-(j+1)]`.
fn u_rule() -> &'static (Vec<f64>, Vec<f64>) {
    static RULE: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    RULE.get_or_init(|| {
        let (x, w) = gauss_legendre(24);
        // Breakpoints in v = 1 - u: 1, 0.5, 0.1, 1e-2 ... 1e-9, 0.
        let mut v = vec![1.0, 0.5, 0.1];
        for e in 2..=9 {
            v.push(10f64.powi(-e));
        }
        v.push(0.0);
        let mut nodes = Vec::new();
        let mut weights = Vec::new();
        for p in v.windows(2) {
            let (hi, lo) = (p[0], p[1]);
            for (xi, wi) in x.iter().zip(&w) {
                let vv = lo + (hi - lo) * (xi + 1.0) / 2.0;
                nodes.push(1.0 - vv);
                weights.push(wi * (hi - lo) / 2.0);
            }
        }
        (nodes, weights)
    })
}

/// Moments of the Bingham distribution with exponent `diag(b)` in its eigenframe.
pub fn moments(b: [f64; 3]) -> Moments {
    // Gauge: the largest exponent becomes 0 and is the polar axis.
    let k = (0..3).max_by(|&i, &j| b[i].total_cmp(&b[j])).unwrap_or(0);
    let (ia, ib) = ((k + 1) % 3, (k + 2) % 3);
    let (ba, bb) = (b[ia] - b[k], b[ib] - b[k]);
    let (us, ws) = u_rule();
    // Accumulate over u in [0, 1] (the integrand is even in u).
    let mut acc = [0.0f64; 10];
    for (&u, &w) in us.iter().zip(ws) {
        let s = 1.0 - u * u;
        let big_a = 0.5 * s * (ba + bb);
        let a = 0.5 * s * (ba - bb);
        let [i0, i1, i2] = scaled_i012(a.abs());
        let e = (big_a + a.abs()).exp() * w;
        let j0 = e * i0;
        let j1 = e * i1 * a.signum();
        let j2 = e * 0.5 * (i0 + i2);
        let (u2, s2) = (u * u, s * s);
        acc[0] += j0; // Z
        acc[1] += u2 * j0; // <k^2>
        acc[2] += s * 0.5 * (j0 + j1); // <a^2>
        acc[3] += s * 0.5 * (j0 - j1); // <b^2>
        acc[4] += u2 * u2 * j0; // <k^4>
        acc[5] += s2 * 0.25 * (j0 + 2.0 * j1 + j2); // <a^4>
        acc[6] += s2 * 0.25 * (j0 - 2.0 * j1 + j2); // <b^4>
        acc[7] += s2 * 0.25 * (j0 - j2); // <a^2 b^2>
        acc[8] += u2 * s * 0.5 * (j0 + j1); // <k^2 a^2>
        acc[9] += u2 * s * 0.5 * (j0 - j1); // <k^2 b^2>
    }
    let z = acc[0];
    let mut second = [0.0; 3];
    let mut fourth = [[0.0; 3]; 3];
    second[k] = acc[1] / z;
    second[ia] = acc[2] / z;
    second[ib] = acc[3] / z;
    fourth[k][k] = acc[4] / z;
    fourth[ia][ia] = acc[5] / z;
    fourth[ib][ib] = acc[6] / z;
    fourth[ia][ib] = acc[7] / z;
    fourth[ib][ia] = acc[7] / z;
    fourth[k][ia] = acc[8] / z;
    fourth[ia][k] = acc[8] / z;
    fourth[k][ib] = acc[9] / z;
    fourth[ib][k] = acc[9] / z;
    // (1/4pi) int over the sphere = (1/2) int_{-1}^{1} du (1/2pi) int dphi; the u-integral over
    // [0, 1] is half of [-1, 1]; undo the gauge shift.
    let log_z = z.ln() + b[k];
    Moments {
        second,
        fourth,
        log_z,
    }
}

/// Errors of the Bingham inversion.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BinghamError {
    /// Eigenvalues not in the admissible triangle.
    #[error("eigenvalues {0:?} are not admissible (each in [0, 1], summing to 1)")]
    Inadmissible([f64; 3]),
    /// Newton did not converge.
    #[error(
        "Bingham Newton iteration did not converge for eigenvalues {mu:?} (residual {residual:.2e})"
    )]
    NoConvergence {
        /// Target eigenvalues.
        mu: [f64; 3],
        /// Final residual.
        residual: f64,
    },
}

/// The exponent `b` (eigenframe, gauge `max b = 0`) whose second moments are `mu` (summing to
/// 1, each positive), by damped Newton with the covariance of `p_i^2` as the Jacobian.
pub fn solve_exponent(mu: [f64; 3]) -> Result<[f64; 3], BinghamError> {
    if mu.iter().any(|&m| !(m > 0.0 && m < 1.0)) || (mu.iter().sum::<f64>() - 1.0).abs() > 1e-12 {
        return Err(BinghamError::Inadmissible(mu));
    }
    let k = (0..3).max_by(|&i, &j| mu[i].total_cmp(&mu[j])).unwrap_or(0);
    let free: Vec<usize> = (0..3).filter(|&i| i != k).collect();
    // Start from the near-isotropic linearisation, mu_i - 1/3 = (2/15)(b_i - mean b), capped,
    // and the strongly aligned limit, <p_i^2> ~ -1/(2 b_i) for the small eigenvalues.
    let mut b = [0.0; 3];
    for &i in &free {
        let lin = 7.5 * (mu[i] - mu[k]);
        let aligned = -0.5 / mu[i] + 0.5 / mu[k];
        b[i] = if mu[i] < 0.1 { aligned } else { lin };
    }
    let resid = |m: &Moments| -> f64 {
        free.iter()
            .map(|&i| (m.second[i] - mu[i]).abs())
            .fold(0.0, f64::max)
    };
    let mut m = moments(b);
    let mut r = resid(&m);
    for _ in 0..200 {
        if r < 1e-15 {
            return Ok(b);
        }
        // Jacobian d<p_i^2>/d b_j = <p_i^2 p_j^2> - <p_i^2><p_j^2> over the free indices.
        let (i, j) = (free[0], free[1]);
        let jac = |x: usize, y: usize| m.fourth[x][y] - m.second[x] * m.second[y];
        let (a11, a12, a21, a22) = (jac(i, i), jac(i, j), jac(j, i), jac(j, j));
        let (f1, f2) = (m.second[i] - mu[i], m.second[j] - mu[j]);
        let det = a11 * a22 - a12 * a21;
        let (d1, d2) = ((a22 * f1 - a12 * f2) / det, (a11 * f2 - a21 * f1) / det);
        // Damped step: halve until the residual decreases and b stays in the gauge (b <= 0).
        let mut t = 1.0;
        loop {
            let mut trial = b;
            trial[i] = (b[i] - t * d1).min(0.0);
            trial[j] = (b[j] - t * d2).min(0.0);
            let mt = moments(trial);
            let rt = resid(&mt);
            if rt < r || t < 1e-6 {
                b = trial;
                m = mt;
                r = rt;
                break;
            }
            t *= 0.5;
        }
    }
    if r < 1e-13 {
        Ok(b)
    } else {
        Err(BinghamError::NoConvergence { mu, residual: r })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Brute-force moments: Gauss-Legendre in cos(theta) times the trapezoid rule in phi over
    /// the whole sphere, in the lab axes (no gauge, no Bessel functions): the slow twin.
    fn brute(b: [f64; 3], nu: usize, nphi: usize) -> Moments {
        let (x, w) = gauss_legendre(nu);
        let bmax = b.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mut z = 0.0;
        let mut m2 = [0.0; 3];
        let mut m4 = [[0.0; 3]; 3];
        for (u, wu) in x.iter().zip(&w) {
            let s = (1.0 - u * u).sqrt();
            for j in 0..nphi {
                let phi = 2.0 * PI * j as f64 / nphi as f64;
                let p = [s * phi.cos(), s * phi.sin(), *u];
                let e = (b[0] * p[0] * p[0] + b[1] * p[1] * p[1] + b[2] * p[2] * p[2] - bmax).exp()
                    * wu;
                z += e;
                for i in 0..3 {
                    m2[i] += e * p[i] * p[i];
                    for k in 0..3 {
                        m4[i][k] += e * p[i] * p[i] * p[k] * p[k];
                    }
                }
            }
        }
        let log_z = (z / (2.0 * nphi as f64)).ln() + bmax;
        Moments {
            second: m2.map(|v| v / z),
            fourth: m4.map(|r| r.map(|v| v / z)),
            log_z,
        }
    }

    #[test]
    fn moments_match_brute_force_quadrature() {
        for b in [
            [0.0, 0.0, 0.0],
            [1.0, -2.0, 0.5],
            [-30.0, -5.0, 0.0],
            [-200.0, -200.0, 0.0],
            [0.0, -150.0, -3.0],
            [-60.0, 0.0, -60.0],
        ] {
            let fast = moments(b);
            let slow = brute(b, 800, 800);
            let mut worst: f64 = (fast.log_z - slow.log_z).abs();
            for i in 0..3 {
                worst = worst.max((fast.second[i] - slow.second[i]).abs());
                for k in 0..3 {
                    worst = worst.max((fast.fourth[i][k] - slow.fourth[i][k]).abs());
                }
            }
            // The brute-force sum of 640 000 terms carries ~1e-12 of round-off itself (its second
            // moments sum to 1 only to that); the fast path's identities hold to 1e-15.
            assert!(
                worst < 5e-12,
                "b = {b:?}: max difference {worst:.2e}\nfast {fast:?}\nslow {slow:?}"
            );
            let total: f64 = fast.second.iter().sum();
            assert!((total - 1.0).abs() < 1e-15, "sum of second moments {total}");
            for i in 0..3 {
                let row: f64 = fast.fourth[i].iter().sum();
                assert!(
                    (row - fast.second[i]).abs() < 1e-15,
                    "sum_j <p_i^2 p_j^2> = {row} vs {}",
                    fast.second[i]
                );
            }
        }
    }

    #[test]
    fn isotropic_moments_are_exact() {
        let m = moments([0.0; 3]);
        for i in 0..3 {
            assert!((m.second[i] - 1.0 / 3.0).abs() < 1e-15);
            assert!(
                (m.fourth[i][i] - 1.0 / 5.0).abs() < 1e-15,
                "<p^4> = {}",
                m.fourth[i][i]
            );
            for k in 0..3 {
                if k != i {
                    assert!((m.fourth[i][k] - 1.0 / 15.0).abs() < 1e-15);
                }
            }
        }
        assert!(m.log_z.abs() < 1e-15);
    }

    #[test]
    fn newton_recovers_the_eigenvalues() {
        for mu in [
            [1.0 / 3.0; 3],
            [0.5, 0.3, 0.2],
            [0.9, 0.05, 0.05],
            [0.49, 0.49, 0.02],
            [0.998, 0.001, 0.001],
            [0.2, 0.7999, 0.0001],
            [0.3334, 0.3333, 0.3333],
        ] {
            let mu: [f64; 3] = {
                let s: f64 = mu.iter().sum();
                mu.map(|m| m / s)
            };
            let b = solve_exponent(mu).unwrap_or_else(|e| panic!("{e}"));
            let m = moments(b);
            for i in 0..3 {
                assert!(
                    (m.second[i] - mu[i]).abs() < 1e-13,
                    "mu {mu:?}: b {b:?} gives {:?}",
                    m.second
                );
            }
            for i in 0..3 {
                let row: f64 = (0..3).map(|j| m.fourth[i][j]).sum();
                assert!(
                    (row - mu[i]).abs() < 1e-13,
                    "sum_j S_iijj = {row} vs mu_i = {}",
                    mu[i]
                );
            }
        }
    }
}
