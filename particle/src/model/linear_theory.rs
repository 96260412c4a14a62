//! Linear kinetic theory of swimmers in a periodic box (docs/MODEL.md §5b): the growth rate of a
//! perturbation of the isotropic state with wavevector `k`, for rods that swim at `U`, carry
//! the stresslet of an isolated rod (`sigma_0 = U l^2/(8 eta)`), turn by Jeffery's rule with
//! shape factor 1, feel the constraint stress of the continuum model (an effective viscosity
//! `mu (1 + zeta/15)`), and optionally diffuse in orientation at the rate `d_r`.
//!
//! With `a = U |k|`, `c = p.k/|k|` and `Gamma_0 = (nu/(8 eta mu)) / (1 + zeta/15)` (five times
//! the continuum's rate M3 in particle units), the growth rate `sigma` of the mode solves
//!
//! ```text
//! 1 = (3 Gamma_0 / 4) G(sigma),   G(sigma) = <h | (sigma + i a c - d_r Lap_p)^-1 | h>,       (K1)
//! h(c) = c sqrt(1 - c^2) cos(phi)
//! ```
//!
//! (the perturbation's azimuthal order is one: only it is driven by the transverse flow). Without
//! diffusion `G(sigma) = int_{-1}^{1} c^2 (1 - c^2) / (sigma + i a c) dc`, in closed form
//! ([`g_closed`]); with it, in the basis of normalised associated Legendre functions `P_l^1`,
//! where `c` couples `l` and `l +- 1` (a tridiagonal matrix) and `Lap_p` is `-l (l + 1)`
//! ([`g_spectral`]). For a real field the roots come in conjugate pairs (`k -> -k`): where the
//! dominant root is complex, a mode's amplitude beats at `2 Im sigma`. As `a -> 0`, `sigma`
//! tends to the continuum's `Gamma_0 / 5 - 6 d_r`.

use crate::model::units::{SWIM_SPEED, VISCOSITY, eta, zeta};
use num_complex::Complex64;

/// `Gamma_0 = (nu/(8 eta mu)) / (1 + zeta/15)` for volume fraction `nu` and diameter `b`: five
/// times the continuum's growth rate (M3) in particle units.
pub fn gamma0(nu: f64, diameter: f64) -> f64 {
    nu / (8.0 * eta(diameter) * VISCOSITY) / (1.0 + zeta(nu, diameter) / 15.0)
}

/// `G(sigma)` of (K1) without diffusion, in closed form: with `z = i sigma / a`,
/// `G = (1/(i a)) J(z)`, `J(z) = int (c^2 - c^4)/(c - z) dc = -(2 z^3 - 4 z/3 + z^2 (z^2 - 1)
/// ln((z - 1)/(z + 1)))`, valid for `Re sigma > 0` (the logarithm's cut is `z` in `[-1, 1]`).
/// `a = 0` gives `4/(15 sigma)`.
pub fn g_closed(sigma: Complex64, a: f64) -> Complex64 {
    g_closed_with_derivative(sigma, a).0
}

/// [`g_closed`] and its derivative in `sigma`.
fn g_closed_with_derivative(sigma: Complex64, a: f64) -> (Complex64, Complex64) {
    let i = Complex64::i();
    if a.abs() < 1e-12 * sigma.norm().max(1e-300) {
        let g = Complex64::new(4.0 / 15.0, 0.0) / sigma;
        return (g, -g / sigma);
    }
    let z = i * sigma / a;
    let (j, dj) = if z.norm() > 4.0 {
        // Far from the cut the closed form cancels to ~1/z: its series in 1/z instead,
        // J = -sum_m z^-(2m+1) (2/(2m+3) - 2/(2m+5)).
        let (mut j, mut dj) = (Complex64::default(), Complex64::default());
        let inv = 1.0 / z;
        let mut pow = inv;
        for m in 0..40 {
            let c = 2.0 / (2 * m + 3) as f64 - 2.0 / (2 * m + 5) as f64;
            j -= c * pow;
            dj += c * (2 * m + 1) as f64 * pow * inv;
            pow *= inv * inv;
        }
        (j, dj)
    } else {
        let log = ((z - 1.0) / (z + 1.0)).ln();
        let dlog = 1.0 / (z - 1.0) - 1.0 / (z + 1.0);
        (
            -(2.0 * z * z * z - 4.0 / 3.0 * z + z * z * (z * z - 1.0) * log),
            -(6.0 * z * z - 4.0 / 3.0
                + (4.0 * z * z * z - 2.0 * z) * log
                + z * z * (z * z - 1.0) * dlog),
        )
    };
    let scale = 1.0 / (i * a);
    // dz/dsigma = i/a.
    (scale * j, scale * dj * (i / a))
}

/// `G(sigma)` of (K1) with rotational diffusion `d_r`, from the resolvent of the tridiagonal
/// matrix `T = diag(sigma + d_r l (l + 1)) + i a C` over `l = 1..=lmax` (normalised `P_l^1`;
/// `C_{l,l+1} = sqrt(l (l + 2) / ((2l + 1)(2l + 3)))`): `G = (4/15) [T^-1]_{22}`. Converges as
/// `lmax` grows where the root is isolated (`Re sigma > -d_r`); with `d_r = 0` it is an
/// independent computation of [`g_closed`].
pub fn g_spectral(sigma: Complex64, a: f64, d_r: f64, lmax: usize) -> Complex64 {
    assert!(lmax >= 3, "at least l = 1..3");
    let n = lmax;
    let i = Complex64::i();
    // T x = e_2 (index 1 for l = 2) by the Thomas algorithm.
    let diag: Vec<Complex64> = (1..=n)
        .map(|l| sigma + d_r * (l * (l + 1)) as f64)
        .collect();
    let off: Vec<Complex64> = (1..n)
        .map(|l| {
            let l = l as f64;
            i * a * (l * (l + 2.0) / ((2.0 * l + 1.0) * (2.0 * l + 3.0))).sqrt()
        })
        .collect();
    let mut rhs = vec![Complex64::default(); n];
    rhs[1] = Complex64::new(1.0, 0.0);
    let mut c = vec![Complex64::default(); n];
    let mut d = vec![Complex64::default(); n];
    c[0] = if n > 1 { off[0] / diag[0] } else { 0.0.into() };
    d[0] = rhs[0] / diag[0];
    for k in 1..n {
        let m = diag[k] - off[k - 1] * c[k - 1];
        if k < n - 1 {
            c[k] = off[k] / m;
        }
        d[k] = (rhs[k] - off[k - 1] * d[k - 1]) / m;
    }
    let mut x = vec![Complex64::default(); n];
    x[n - 1] = d[n - 1];
    for k in (0..n - 1).rev() {
        x[k] = d[k] - c[k] * x[k + 1];
    }
    x[1] * (4.0 / 15.0)
}

/// A growth rate of (K1) and how it was found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GrowthRate {
    /// The rate `sigma` (1/beta), its imaginary part the angular frequency of the mode's beat.
    pub sigma: Complex64,
    /// `|1 - (3 Gamma_0/4) G(sigma)|` at the root.
    pub residual: f64,
}

/// The dominant root (largest real part) of (K1) for a box mode of wavenumber `k` (1/l) at
/// volume fraction `nu`, diameter `b` and rotational diffusion `d_r` (1/beta): Newton from a
/// grid of starting points in the right half plane, the closed form without diffusion and the
/// spectral resolvent (secant steps) with it. `None` if no root with `Re sigma > -d_r` is found
/// (the mode is damped).
pub fn growth_rate(nu: f64, diameter: f64, k: f64, d_r: f64) -> Option<GrowthRate> {
    let g0 = gamma0(nu, diameter);
    let a = SWIM_SPEED * k;
    let f = |s: Complex64| -> Complex64 {
        if d_r == 0.0 {
            1.0 - 0.75 * g0 * g_closed(s, a)
        } else {
            1.0 - 0.75 * g0 * g_spectral(s, a, d_r, lmax_for(a, d_r))
        }
    };
    let df = |s: Complex64| -> Complex64 {
        if d_r == 0.0 {
            -0.75 * g0 * g_closed_with_derivative(s, a).1
        } else {
            let h = 1e-7 * (1.0 + s.norm());
            (f(s + h) - f(s - h)) / (2.0 * h)
        }
    };
    let scale = g0 / 5.0;
    let mut best: Option<GrowthRate> = None;
    for re in [1.0, 0.5, 0.2, 0.05] {
        for im in [0.0, 0.1, 0.3, 0.6, 1.0, 2.0] {
            let mut s = Complex64::new(re * scale, im * a.max(scale));
            let mut ok = false;
            for _ in 0..80 {
                let fs = f(s);
                let step = fs / df(s);
                s -= step;
                if !s.re.is_finite() || !s.im.is_finite() || s.re < -d_r - 10.0 * scale {
                    break;
                }
                if step.norm() < 1e-13 * (1.0 + s.norm()) {
                    ok = true;
                    break;
                }
            }
            // Without diffusion the closed form holds for Re sigma > 0 only.
            let valid = ok && s.re > if d_r == 0.0 { 1e-9 * scale } else { -d_r };
            if !valid {
                continue;
            }
            let residual = f(s).norm();
            if residual > 1e-9 {
                continue;
            }
            // One of each conjugate pair: the one with Im >= 0.
            let s = Complex64::new(s.re, s.im.abs());
            if best.is_none_or(|b| s.re > b.sigma.re + 1e-12) {
                best = Some(GrowthRate { sigma: s, residual });
            }
        }
    }
    best
}

/// Legendre orders for the spectral resolvent: enough that the coupling `a` is resolved
/// against the damping `d_r l^2`.
fn lmax_for(a: f64, d_r: f64) -> usize {
    let by_diffusion = (a / d_r.max(1e-12)).sqrt() * 4.0;
    (40.0f64.max(by_diffusion).min(400.0)) as usize
}

/// The lowest box mode's wavenumber `2 pi / L` (1/l) of a box of side `L` (rod lengths).
pub fn lowest_mode(box_length: f64) -> f64 {
    2.0 * std::f64::consts::PI / box_length
}

/// The smallest box side (rod lengths) whose lowest mode grows without diffusion (`d_r = 0`)
/// or with it, found by bisection on `Re sigma(2 pi/L) = 0` between `lo` and `hi`.
pub fn onset_box(nu: f64, diameter: f64, d_r: f64, (lo, hi): (f64, f64)) -> Option<f64> {
    let grows =
        |l: f64| growth_rate(nu, diameter, lowest_mode(l), d_r).is_some_and(|g| g.sigma.re > 1e-9);
    if grows(lo) || !grows(hi) {
        return None;
    }
    let (mut a, mut b) = (lo, hi);
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if grows(m) { b = m } else { a = m }
    }
    Some(0.5 * (a + b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::units::{DEFAULT_DIAMETER as B, continuum_growth_rate, meanfield_time_unit};

    /// `G` by Gauss-Legendre quadrature of the integral, the obviously correct twin.
    fn g_quadrature(sigma: Complex64, a: f64) -> Complex64 {
        let (x, w) = motile_analysis::quadrature::gauss_legendre(400);
        x.iter()
            .zip(&w)
            .map(|(c, w)| {
                Complex64::new(w * c * c * (1.0 - c * c), 0.0) / (sigma + Complex64::i() * a * c)
            })
            .sum()
    }

    #[test]
    fn the_three_ways_to_g_agree() {
        for (s, a) in [
            (Complex64::new(0.05, 0.0), 0.1),
            (Complex64::new(0.03, 0.07), 0.25),
            (Complex64::new(0.2, -0.1), 0.05),
            (Complex64::new(0.01, 0.2), 0.3),
        ] {
            let (c, q, p) = (
                g_closed(s, a),
                g_quadrature(s, a),
                g_spectral(s, a, 0.0, 400),
            );
            let scale = c.norm();
            // The spectral sum converges slowly as the root nears the continuous spectrum
            // (Re sigma -> 0): 4e-8 at Re sigma = 0.01, a = 0.3 with 400 orders.
            assert!(
                (c - q).norm() < 1e-10 * scale && (c - p).norm() < 1e-7 * scale,
                "sigma {s}, a {a}: closed {c}, quadrature {q}, spectral {p}"
            );
        }
    }

    #[test]
    fn long_waves_grow_at_the_continuum_rate() {
        let nu = 0.625;
        let continuum = continuum_growth_rate(zeta(nu, B)) / meanfield_time_unit(nu, B);
        let g = growth_rate(nu, B, 1e-6, 0.0).unwrap();
        assert!(
            (g.sigma.re - continuum).abs() < 1e-9 * continuum && g.sigma.im.abs() < 1e-9,
            "k -> 0: {} against the continuum's {continuum}",
            g.sigma
        );
        // With diffusion: the continuum's rate less 6 d_r (the l = 2 decay).
        let d_r = 0.004;
        let g = growth_rate(nu, B, 1e-6, d_r).unwrap();
        assert!(
            (g.sigma.re - (continuum - 6.0 * d_r)).abs() < 1e-7,
            "k -> 0 with d_r: {} against {}",
            g.sigma,
            continuum - 6.0 * d_r
        );
    }

    #[test]
    fn roots_solve_the_relation_computed_by_quadrature() {
        for l in [32.0, 50.0, 100.0] {
            let k = lowest_mode(l);
            let g = growth_rate(0.625, B, k, 0.0).unwrap();
            let f = 1.0 - 0.75 * gamma0(0.625, B) * g_quadrature(g.sigma, k);
            assert!(f.norm() < 1e-7, "L/l = {l}: sigma {} leaves {f}", g.sigma);
            // The spectral resolvent with a small diffusion converges to the same root, less
            // about 6 d_r (the l = 2 decay).
            let d_r = 1e-6;
            let gd = growth_rate(0.625, B, k, d_r).unwrap();
            assert!(
                (gd.sigma - g.sigma).norm() < 10.0 * d_r,
                "L/l = {l}: {} without, {} with d_r = 1e-6",
                g.sigma,
                gd.sigma
            );
        }
    }
}
