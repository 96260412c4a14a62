//! Exponentially scaled modified Bessel functions `e^{-a} I_n(a)`, `n = 0, 1, 2`, `a >= 0`, to
//! about 1e-15 relative: the power series below `a = 25` (all terms positive, no cancellation),
//! the asymptotic expansion above (its smallest term is below `e^{-2a}`).

/// `[e^{-a} I_0(a), e^{-a} I_1(a), e^{-a} I_2(a)]` for `a >= 0`.
pub(crate) fn scaled_i012(a: f64) -> [f64; 3] {
    debug_assert!(a >= 0.0);
    if a <= 25.0 {
        let h = 0.5 * a;
        let mut out = [0.0; 3];
        for (n, o) in out.iter_mut().enumerate() {
            // sum_k (a/2)^{2k+n} / (k! (k+n)!)
            let mut term = h.powi(n as i32) / (1..=n).map(|k| k as f64).product::<f64>();
            let mut sum = term;
            for k in 1..200 {
                term *= h * h / (k as f64 * (k + n) as f64);
                sum += term;
                if term < 1e-17 * sum {
                    break;
                }
            }
            *o = sum * (-a).exp();
        }
        out
    } else {
        let pre = 1.0 / (2.0 * std::f64::consts::PI * a).sqrt();
        [0.0, 1.0, 2.0].map(|n: f64| {
            let mu = 4.0 * n * n;
            let mut term = 1.0;
            let mut sum = 1.0;
            for k in 1..60 {
                let kf = k as f64;
                let next = -term * (mu - (2.0 * kf - 1.0).powi(2)) / (kf * 8.0 * a);
                if next.abs() > term.abs() {
                    break; // the asymptotic series starts to diverge
                }
                term = next;
                sum += term;
                if term.abs() < 1e-17 * sum.abs() {
                    break;
                }
            }
            pre * sum
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `e^{-a} I_n(a) = (1/pi) int_0^pi e^{a (cos t - 1)} cos(n t) dt`; the trapezoid rule on this
    /// periodic integrand converges exponentially.
    fn by_quadrature(n: usize, a: f64) -> f64 {
        let m = 4000;
        let h = std::f64::consts::PI / m as f64;
        let f = |t: f64| (a * (t.cos() - 1.0)).exp() * (n as f64 * t).cos();
        (h * (0.5 * f(0.0)
            + (1..m).map(|k| f(k as f64 * h)).sum::<f64>()
            + 0.5 * f(std::f64::consts::PI)))
            / std::f64::consts::PI
    }

    #[test]
    fn matches_the_integral_representation() {
        for a in [0.0, 1e-8, 0.3, 2.0, 10.0, 24.9, 25.1, 40.0, 300.0, 5000.0] {
            let got = scaled_i012(a);
            for n in 0..3 {
                let exact = by_quadrature(n, a);
                // Relative 2e-14, or absolute 2e-15: the reference sums 4000 terms of an
                // oscillating integrand, so its own round-off is about 1e-15 absolute.
                let diff = (got[n] - exact).abs();
                assert!(
                    diff <= 2e-14 * exact.abs() || diff < 2e-15,
                    "I_{n}e({a}) = {} vs {exact}: error {diff:.2e}",
                    got[n]
                );
            }
        }
    }
}
