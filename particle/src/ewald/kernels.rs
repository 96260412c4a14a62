//! Kernels of the periodic Stokes sums (docs/MODEL.md §1, §2) and their Ewald split.
//!
//! The Rotne-Prager-Yamakawa tensor of two spheres of radius `a` (mu = 1 throughout; divide
//! by the viscosity at the call site):
//!
//! ```text
//! r >= 2a:  M(r) = (1/(8 pi)) [ (I + rr/r^2)/r + (2a^2/3)(I - 3rr/r^2)/r^3 ]   ("far" form)
//! r <  2a:  M(r) = (1/(6 pi a)) [ (1 - 9r/(32a)) I + (3r/(32a)) rr/r^2 ]        (overlap form)
//! ```
//!
//! The far form has the Fourier transform `(1 - a^2k^2/6)^2 (I - kk/k^2)/k^2`. Hasimoto's
//! splitting multiplies it by `phi(k) = (1 + k^2/(4 xi^2)) exp(-k^2/(4 xi^2))` for the smooth
//! Fourier part `M_F`, leaving the short-ranged real-space part `M_R = M_far - M_F`; since
//! `1 - phi(k) = O(k^4)`, `M_R` has zero mean and the periodic sum `sum_images M_R + (1/V)
//! sum_{k != 0} M^_F(k) e^{ik.r}` is the zero-mean-flow periodic RPY sum for every `xi`.
//! Pairs closer than `2a` add the compact correction `M_overlap - M_far`.
//!
//! Both parts are written `A(r) I + B(r) rr/r^2`. The closed forms come from
//! `bench/derive_ewald_kernels.py` (sympy) and are checked in the tests against quadrature of
//! the Fourier integral. The Stokeslet (`a = 0`) real part and its radial derivatives drive
//! the point-stresslet sums of the dipole model.

use crate::model::geometry::{Vec3, dot};
use num_complex::Complex64;
use std::f64::consts::PI;

/// `pi^(3/2)`.
const PI_3_2: f64 = 5.568_327_996_831_708;

/// `A I + B rr/r^2` applied to `f`, with `rh` the unit vector.
#[inline]
pub fn apply_radial(a: f64, b: f64, rh: Vec3, f: Vec3) -> Vec3 {
    let s = b * dot(rh, f);
    [
        a * f[0] + s * rh[0],
        a * f[1] + s * rh[1],
        a * f[2] + s * rh[2],
    ]
}

/// Far form of the RPY tensor, `(A, B)`.
#[inline]
pub fn rpy_far(r: f64, a: f64) -> (f64, f64) {
    let (r3, a2) = (r * r * r, a * a);
    (
        (1.0 / r + 2.0 * a2 / (3.0 * r3)) / (8.0 * PI),
        (1.0 / r - 2.0 * a2 / r3) / (8.0 * PI),
    )
}

/// Overlap form of the RPY tensor (`r < 2a`), `(A, B)`.
#[inline]
pub fn rpy_overlap(r: f64, a: f64) -> (f64, f64) {
    let c = 1.0 / (6.0 * PI * a);
    (c * (1.0 - 9.0 * r / (32.0 * a)), c * 3.0 * r / (32.0 * a))
}

/// The RPY tensor in free space, far or overlap form as `r` asks; `(A, B)`.
#[inline]
pub fn rpy(r: f64, a: f64) -> (f64, f64) {
    if r >= 2.0 * a {
        rpy_far(r, a)
    } else {
        rpy_overlap(r, a)
    }
}

/// Correction `M_overlap - M_far` for `r < 2a` (zero beyond).
#[inline]
pub fn rpy_overlap_correction(r: f64, a: f64) -> (f64, f64) {
    if r >= 2.0 * a {
        return (0.0, 0.0);
    }
    let (ao, bo) = rpy_overlap(r, a);
    let (af, bf) = rpy_far(r, a);
    (ao - af, bo - bf)
}

/// Hasimoto's screening `phi(k)` times the RPY factor `(1 - a^2k^2/6)^2`, over `k^2`, with the
/// projection left to the caller: the Fourier multiplier of `M_F` is `this * (I - kk/k^2)`.
#[inline]
pub fn rpy_fourier_scalar(k2: f64, xi: f64, a: f64) -> f64 {
    rpy_fourier_scalar_screened(k2, (-k2 / (4.0 * xi * xi)).exp(), xi, a)
}

/// [`rpy_fourier_scalar`] given the screening exponential `exp(-k^2 / 4 xi^2)` (the fast sums
/// build it from per-axis factors instead of one exponential per mode).
#[inline]
pub fn rpy_fourier_scalar_screened(k2: f64, screen: f64, xi: f64, a: f64) -> f64 {
    let x = k2 / (4.0 * xi * xi);
    let g = 1.0 - a * a * k2 / 6.0;
    (1.0 + x) * screen * g * g / k2
}

/// The Fourier part of the split RPY sum at one mode: `u^ = s(k) (I - kk/k^2) f^ / vol`, with
/// `s` from [`rpy_fourier_scalar`] (mu = 1).
#[inline]
pub fn rpy_fourier_mode(
    k: Vec3,
    k2: f64,
    xi: f64,
    a: f64,
    vol: f64,
    f: [Complex64; 3],
) -> [Complex64; 3] {
    rpy_fourier_mode_screened(k, k2, (-k2 / (4.0 * xi * xi)).exp(), xi, a, vol, f)
}

/// [`rpy_fourier_mode`] given the screening exponential `exp(-k^2 / 4 xi^2)`.
#[inline]
pub fn rpy_fourier_mode_screened(
    k: Vec3,
    k2: f64,
    screen: f64,
    xi: f64,
    a: f64,
    vol: f64,
    f: [Complex64; 3],
) -> [Complex64; 3] {
    let s = rpy_fourier_scalar_screened(k2, screen, xi, a) / vol;
    let kf = (f[0] * k[0] + f[1] * k[1] + f[2] * k[2]) / k2;
    [0, 1, 2].map(|d| (f[d] - kf * k[d]) * s)
}

/// The Fourier part of the split stresslet sum at one mode, from the stresslet spectrum
/// `S^(i, j)` (symmetric): force density `F^ = -i k . S^`, velocity `u^` as for a point force
/// (`a = 0`), gradient `i k_l u^_i`. Returns `[u^_0..2, grad^_00, grad^_01, ..., grad^_22]`.
#[inline]
pub fn stresslet_fourier_mode(
    k: Vec3,
    k2: f64,
    xi: f64,
    vol: f64,
    s: impl Fn(usize, usize) -> Complex64,
) -> [Complex64; 12] {
    stresslet_fourier_mode_screened(k, k2, (-k2 / (4.0 * xi * xi)).exp(), xi, vol, s)
}

/// [`stresslet_fourier_mode`] given the screening exponential `exp(-k^2 / 4 xi^2)`.
#[inline]
pub fn stresslet_fourier_mode_screened(
    k: Vec3,
    k2: f64,
    screen: f64,
    xi: f64,
    vol: f64,
    s: impl Fn(usize, usize) -> Complex64,
) -> [Complex64; 12] {
    let f: [Complex64; 3] =
        [0, 1, 2].map(|i| -Complex64::i() * (s(i, 0) * k[0] + s(i, 1) * k[1] + s(i, 2) * k[2]));
    let uh = rpy_fourier_mode_screened(k, k2, screen, xi, 0.0, vol, f);
    let mut o = [Complex64::default(); 12];
    for i in 0..3 {
        o[i] = uh[i];
        for m in 0..3 {
            o[3 + 3 * i + m] = Complex64::i() * k[m] * uh[i];
        }
    }
    o
}

/// Real-space part `M_R = M_far - M_F` of the split RPY tensor, `(A, B)`.
#[inline]
pub fn rpy_real(r: f64, xi: f64, a: f64) -> (f64, f64) {
    let (a2, r2, x2) = (a * a, r * r, xi * xi);
    let ec = libm::erfc(xi * r);
    let e = (-x2 * r2).exp();
    let x4 = x2 * x2;
    let (a4x4, x6, x8) = (a2 * a2 * x4, x4 * x2, x4 * x4);
    let a4 = a2 * a2;
    let poly_a = -4.0 * a4 * r2 * r2 * x8 + 22.0 * a4 * r2 * x6 - 14.0 * a4x4 - 12.0 * a2 * r2 * x4
        + 24.0 * a2 * x2
        - 9.0;
    let poly_b =
        4.0 * a4 * r2 * r2 * x8 - 18.0 * a4 * r2 * x6 + 12.0 * a2 * r2 * x4 - 12.0 * a2 * x2 + 9.0;
    let g = xi * e / PI_3_2;
    let c = ec / (PI * r * r2);
    (
        c * (r2 / 8.0 + a2 / 12.0) + g * (a2 / (6.0 * r2) + poly_a / 36.0),
        c * (r2 / 8.0 - a2 / 4.0) + g * (-a2 / (2.0 * r2) + poly_b / 36.0),
    )
}

/// Fourier part `M_F` in free space (smooth), `(A, B)`; at `r = 0` its limit `A_F(0) I`.
#[inline]
pub fn rpy_fourier_free(r: f64, xi: f64, a: f64) -> (f64, f64) {
    if r == 0.0 {
        let (a2, x2) = (a * a, xi * xi);
        return (
            xi * (7.0 * a2 * a2 * x2 * x2 - 10.0 * a2 * x2 + 9.0) / (18.0 * PI_3_2),
            0.0,
        );
    }
    let (af, bf) = rpy_far(r, a);
    let (ar, br) = rpy_real(r, xi, a);
    (af - ar, bf - br)
}

/// `M_F(r) f`: the free Fourier part applied to `f` at offset `r` (the point itself at `r = 0`),
/// the own-group term the periodic sums remove.
#[inline]
pub fn rpy_fourier_free_apply(r: Vec3, f: Vec3, xi: f64, a: f64) -> Vec3 {
    let rn = dot(r, r).sqrt();
    let rh = if rn > 0.0 {
        r.map(|c| c / rn)
    } else {
        [0.0; 3]
    };
    let (af, bf) = rpy_fourier_free(rn, xi, a);
    apply_radial(af, bf, rh, f)
}

/// The Stokeslet's real-space part `A I + C x x` (not normalised `x`) and radial derivatives:
/// `[A, A', A'', C, C', C'']` at distance `r`.
#[inline]
pub fn stokeslet_real_derivatives(r: f64, xi: f64) -> [f64; 6] {
    let (r2, x2) = (r * r, xi * xi);
    let ec = libm::erfc(xi * r) / PI;
    let g = xi * (-x2 * r2).exp() / PI_3_2;
    let (r3, r4) = (r2 * r, r2 * r2);
    [
        ec / (8.0 * r) - g / 4.0,
        g * x2 * r / 2.0 - g / (4.0 * r) - ec / (8.0 * r2),
        g * x2 * (1.0 - r2 * x2) + g / (2.0 * r2) + ec / (4.0 * r3),
        g / (4.0 * r2) + ec / (8.0 * r3),
        -g * x2 / (2.0 * r) - 3.0 * g / (4.0 * r3) - 3.0 * ec / (8.0 * r4),
        g * (x2 * x2 + 2.0 * x2 / r2 + 3.0 / r4) + 3.0 * ec / (2.0 * r4 * r),
    ]
}

/// Velocity and velocity gradient at offset `x` (target minus source) of a point stresslet
/// `sigma p p` with Stokeslet kernel `A I + C x x` given by its radial derivatives `d`
/// (`[A, A', A'', C, C', C'']`): `u_i = -sigma p_k p_j d_k G_ij`,
/// `grad[i][l] = d u_i / d x_l`.
#[inline]
pub fn stresslet_from_derivatives(
    x: Vec3,
    r: f64,
    p: Vec3,
    sigma: f64,
    d: &[f64; 6],
) -> (Vec3, [Vec3; 3]) {
    let [_a, a1r, a2r, c, c1r, c2r] = *d;
    let q = dot(p, x);
    let inv = 1.0 / r;
    let a1 = a1r * inv;
    let c1 = c1r * inv;
    let a1p = (a2r - a1) * inv;
    let c1p = (c2r - c1) * inv;
    let vp = (a1 + c) * q;
    let vx = c1 * q * q + c;
    let u = [0, 1, 2].map(|i| -sigma * (vp * p[i] + vx * x[i]));
    let ap = (a1p + c1r) * q * inv;
    let bx = (c1p * q * q + c1r) * inv;
    let mut grad = [[0.0; 3]; 3];
    for i in 0..3 {
        for l in 0..3 {
            let v = p[i] * (ap * x[l] + (a1 + c) * p[l])
                + x[i] * (bx * x[l] + 2.0 * c1 * q * p[l])
                + if i == l { vx } else { 0.0 };
            grad[i][l] = -sigma * v;
        }
    }
    (u, grad)
}

/// Free-space Stokeslet `(I + xx/r^2)/(8 pi r)` as `[A, A', A'', C, C', C'']`.
#[inline]
pub fn stokeslet_free_derivatives(r: f64) -> [f64; 6] {
    let c = 1.0 / (8.0 * PI);
    let i1 = 1.0 / r;
    let i2 = i1 * i1;
    let i3 = i2 * i1;
    [
        c * i1,
        -c * i2,
        2.0 * c * i3,
        c * i3,
        -3.0 * c * i3 * i1,
        12.0 * c * i3 * i2,
    ]
}

/// Velocity gradient of a stresslet's Fourier part at its own centre (free space), the term a
/// rod's own stresslet contributes through the Fourier sum and that is removed:
/// `sigma sqrt(pi) xi^3/(2 pi^2) (pp - I/3)`; its velocity there is zero by symmetry.
#[inline]
pub fn stresslet_fourier_self_gradient(p: Vec3, sigma: f64, xi: f64) -> [Vec3; 3] {
    let c = sigma * PI.sqrt() * xi * xi * xi / (2.0 * PI * PI);
    let mut g = [[0.0; 3]; 3];
    for i in 0..3 {
        for l in 0..3 {
            g[i][l] = c * (p[i] * p[l] - if i == l { 1.0 / 3.0 } else { 0.0 });
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::scale;
    use motile_analysis::quadrature::gauss_legendre;

    /// `M_F` by quadrature of its Fourier integral:
    /// `A = (1/2pi^2) int k^2 h (j0 - j1/x) dk`, `B = (1/2pi^2) int k^2 h j2 dk`, `x = kr`.
    fn fourier_by_quadrature(r: f64, xi: f64, a: f64) -> (f64, f64) {
        let (nodes, weights) = gauss_legendre(40);
        let kmax = 2.0 * xi * 8.0;
        let panels = 400;
        let h = kmax / panels as f64;
        let (mut sa, mut sb) = (0.0, 0.0);
        for p in 0..panels {
            for (t, w) in nodes.iter().zip(&weights) {
                let k = h * (p as f64 + 0.5 * (t + 1.0));
                let x = k * r;
                let (j0m, j2) = if x < 5e-2 {
                    let x2 = x * x;
                    let x4 = x2 * x2;
                    (
                        2.0 / 3.0 - 2.0 * x2 / 15.0 + x4 / 140.0 - x4 * x2 / 5670.0,
                        x2 / 15.0 - x4 / 210.0 + x4 * x2 / 7560.0,
                    )
                } else {
                    let (s, c) = x.sin_cos();
                    let j0 = s / x;
                    let j1 = s / (x * x) - c / x;
                    let j2 = (3.0 / (x * x) - 1.0) * s / x - 3.0 * c / (x * x);
                    (j0 - j1 / x, j2)
                };
                let kh = rpy_fourier_scalar(k * k, xi, a) * k * k;
                sa += 0.5 * h * w * kh * j0m;
                sb += 0.5 * h * w * kh * j2;
            }
        }
        (sa / (2.0 * PI * PI), sb / (2.0 * PI * PI))
    }

    #[test]
    fn fourier_part_closed_form_matches_quadrature() {
        let mut worst: f64 = 0.0;
        for &(xi, a) in &[(1.3, 0.2), (0.7, 0.0866), (3.0, 0.0866), (2.0, 0.0)] {
            for &r in &[0.0, 0.05, 0.17, 0.5, 1.0, 2.5] {
                let (aq, bq) = fourier_by_quadrature(r, xi, a);
                let (ac, bc) = rpy_fourier_free(r, xi, a);
                let scale = aq.abs().max(1e-3);
                let err = ((aq - ac).abs()).max((bq - bc).abs()) / scale;
                worst = worst.max(err);
                assert!(
                    err < 1e-10,
                    "xi {xi} a {a} r {r}: closed ({ac}, {bc}) quadrature ({aq}, {bq}), rel err {err:e}"
                );
            }
        }
        assert!(worst < 1e-10, "worst {worst:e}");
    }

    #[test]
    fn real_space_table_matches_the_closed_form() {
        for &(xi, a, rc) in &[(1.1, 0.0866, 2.8), (2.0, 0.0, 2.2), (0.8, 0.0866, 5.5)] {
            let t = RealSpaceTable::new(rc, xi, a);
            let mut worst: f64 = 0.0;
            for k in 1..5000 {
                let r = rc * k as f64 / 5000.0;
                let (ae, be) = rpy_real(r, xi, a);
                let (at, bt) = t.eval(r);
                let (far_a, _) = rpy_far(r, a);
                worst = worst.max((ae - at).abs().max((be - bt).abs()) / far_a);
            }
            assert!(
                worst < 1e-10,
                "xi {xi} a {a}: worst error relative to the kernel {worst:e}"
            );
            // The series agrees with the closed form where both are accurate.
            let r = 0.05 / xi;
            let (s_a, s_b) = rpy_fourier_free_series(r, xi, a);
            let (c_a, c_b) = rpy_fourier_free(r, xi, a);
            assert!(
                (s_a - c_a).abs() < 1e-10 * c_a.abs()
                    && (s_b * r * r - c_b).abs() < 1e-9 * c_a.abs(),
                "series ({s_a}, {}) vs closed ({c_a}, {c_b})",
                s_b * r * r
            );
        }
    }

    #[test]
    fn stresslet_table_matches_the_closed_form() {
        for &(xi, rc) in &[(0.7, 4.3), (1.5, 2.5)] {
            let t = StressletTable::new(rc, xi);
            let mut worst: f64 = 0.0;
            for k in 1..5000 {
                let r = rc * k as f64 / 5000.0;
                let e = stokeslet_real_derivatives(r, xi);
                let v = t.eval(r);
                let f = stokeslet_free_derivatives(r);
                for c in 1..6 {
                    worst = worst.max((e[c] - v[c]).abs() / f[c].abs());
                }
            }
            assert!(
                worst < 1e-10,
                "xi {xi}: worst error relative to the free kernel {worst:e}"
            );
        }
    }

    #[test]
    fn stokeslet_real_part_is_the_zero_radius_rpy_real_part_and_derivatives_agree() {
        let xi = 1.7;
        for &r in &[0.1, 0.4, 1.0, 2.0] {
            let d = stokeslet_real_derivatives(r, xi);
            let (ar, br) = rpy_real(r, xi, 0.0);
            assert!((d[0] - ar).abs() < 1e-14 && (d[3] * r * r - br).abs() < 1e-14);
            // Finite differences of A and C.
            let h = 1e-5;
            let dp = stokeslet_real_derivatives(r + h, xi);
            let dm = stokeslet_real_derivatives(r - h, xi);
            for (k, name) in [(0, "A"), (3, "C")] {
                let d1 = (dp[k] - dm[k]) / (2.0 * h);
                let d2 = (dp[k + 1] - dm[k + 1]) / (2.0 * h);
                let e1 = (d1 - d[k + 1]).abs() / d[k + 1].abs().max(1e-3);
                let e2 = (d2 - d[k + 2]).abs() / d[k + 2].abs().max(1e-3);
                assert!(
                    e1 < 1e-7 && e2 < 1e-7,
                    "{name} at r {r}: errors {e1:e} {e2:e}"
                );
            }
        }
    }

    #[test]
    fn stresslet_gradient_matches_finite_differences() {
        let d = stokeslet_free_derivatives;
        let p = {
            let v = [0.3, -0.5, 0.8];
            let n = dot(v, v).sqrt();
            scale(1.0 / n, v)
        };
        let x = [0.7, 0.2, -0.4];
        let r = dot(x, x).sqrt();
        let (_, g) = stresslet_from_derivatives(x, r, p, 1.3, &d(r));
        let h = 1e-6;
        for l in 0..3 {
            let mut xp = x;
            let mut xm = x;
            xp[l] += h;
            xm[l] -= h;
            let (up, _) =
                stresslet_from_derivatives(xp, dot(xp, xp).sqrt(), p, 1.3, &d(dot(xp, xp).sqrt()));
            let (um, _) =
                stresslet_from_derivatives(xm, dot(xm, xm).sqrt(), p, 1.3, &d(dot(xm, xm).sqrt()));
            for i in 0..3 {
                let fd = (up[i] - um[i]) / (2.0 * h);
                assert!(
                    (fd - g[i][l]).abs() < 1e-7,
                    "grad[{i}][{l}] {} vs fd {fd}",
                    g[i][l]
                );
            }
        }
        // Against the two-force definition: +f p at +eps p/2, -f p at -eps p/2, sigma = f eps.
        let eps = 1e-4;
        let st = |y: Vec3| {
            let r = dot(y, y).sqrt();
            let [a, _, _, c, _, _] = d(r);
            let s = c * dot(y, p);
            [0, 1, 2].map(|i| a * p[i] + s * y[i])
        };
        let f = 1.3 / eps;
        let up = st(crate::model::geometry::axpy(x, -eps / 2.0, p));
        let um = st(crate::model::geometry::axpy(x, eps / 2.0, p));
        let (u, _) = stresslet_from_derivatives(x, r, p, 1.3, &d(r));
        for i in 0..3 {
            let two = f * (up[i] - um[i]);
            assert!(
                (two - u[i]).abs() < 1e-6,
                "u[{i}] {} vs force pair {two}",
                u[i]
            );
        }
    }
}

/// Cubic Lagrange interpolation on a uniform table of `n` intervals at position `x` (in
/// intervals): the first of the 4 nodes used and their weights.
#[inline]
fn lagrange4(x: f64, n: usize) -> (usize, [f64; 4]) {
    let i = (x as usize).saturating_sub(1).min(n - 3);
    let t = x - i as f64;
    let (t1, t2, t3) = (t - 1.0, t - 2.0, t - 3.0);
    const SIXTH: f64 = 1.0 / 6.0;
    (
        i,
        [
            -t1 * t2 * t3 * SIXTH,
            t * t2 * t3 * 0.5,
            -t * t1 * t3 * 0.5,
            t * t1 * t2 * SIXTH,
        ],
    )
}

/// Taylor series of the free Fourier part near `r = 0`: `(A_F, B_F / r^2)` to `r^6`
/// (from `bench/derive_ewald_kernels.py`); relative error below 1e-12 for `xi r < 0.05`.
pub fn rpy_fourier_free_series(r: f64, xi: f64, a: f64) -> (f64, f64) {
    let (a2, x2, r2) = (a * a, xi * xi, r * r);
    let a4 = a2 * a2;
    let z2 = x2 * r2;
    let c = xi / PI_3_2;
    let aa = [
        0.5 + 7.0 * a4 * x2 * x2 / 18.0 - 5.0 * a2 * x2 / 9.0,
        -a4 * x2 * x2 * x2 + 14.0 * a2 * x2 * x2 / 15.0 - x2 / 3.0,
        11.0 * a4 * x2.powi(4) / 12.0 - 9.0 * a2 * x2.powi(3) / 14.0 + 3.0 * x2 * x2 / 20.0,
        -13.0 * a4 * x2.powi(5) / 27.0 + 22.0 * a2 * x2.powi(4) / 81.0 - x2.powi(3) / 21.0,
    ];
    let bb = [
        a4 * x2.powi(3) / 2.0 - 7.0 * a2 * x2 * x2 / 15.0 + x2 / 6.0,
        -11.0 * a4 * x2.powi(4) / 18.0 + 3.0 * a2 * x2.powi(3) / 7.0 - x2 * x2 / 10.0,
        13.0 * a4 * x2.powi(5) / 36.0 - 11.0 * a2 * x2.powi(4) / 54.0 + x2.powi(3) / 28.0,
        -5.0 * a4 * x2.powi(6) / 36.0 + 13.0 * a2 * x2.powi(5) / 198.0 - x2.powi(4) / 108.0,
    ];
    let _ = z2;
    let horner = |k: &[f64; 4]| k[0] + r2 * (k[1] + r2 * (k[2] + r2 * k[3]));
    (c * horner(&aa), c * horner(&bb))
}

/// The real-space RPY part `(A_R, B_R) = M_far - M_F` for fast pair sums: the smooth Fourier
/// part `(A_F, B_F / r^2)` tabulated on `[0, r_c]` at 4096 uniform intervals (Taylor series
/// for `xi r < 0.05`, closed form beyond) with cubic Lagrange interpolation, the far form
/// evaluated exactly. No erfc or exp per pair.
#[derive(Clone, Debug)]
pub(crate) struct RealSpaceTable {
    inv_h: f64,
    n: usize,
    /// `1/(8 pi)`, `(2a^2/3)/(8 pi)`, `2a^2/(8 pi)`: the far form's coefficients.
    c: f64,
    ca: f64,
    cb: f64,
    /// `[A_F, B_F / r^2]` at the nodes `r = k h`, `k = 0..=n`.
    g: Vec<[f64; 2]>,
}

impl RealSpaceTable {
    /// Table of the split RPY tensor with parameters `xi`, `a` up to `cutoff`.
    pub(crate) fn new(cutoff: f64, xi: f64, a: f64) -> Self {
        let n = 4096;
        let h = cutoff / n as f64;
        let g = (0..=n)
            .map(|k| {
                let r = k as f64 * h;
                if xi * r < 0.05 {
                    let (af, bf) = rpy_fourier_free_series(r, xi, a);
                    [af, bf]
                } else {
                    let (af, bf) = rpy_fourier_free(r, xi, a);
                    [af, bf / (r * r)]
                }
            })
            .collect();
        let c = 1.0 / (8.0 * PI);
        Self {
            inv_h: 1.0 / h,
            n,
            c,
            ca: c * 2.0 * a * a / 3.0,
            cb: c * 2.0 * a * a,
            g,
        }
    }

    /// `(A_R, B_R)` at `0 < r <= cutoff` (the tests' view of [`Self::eval_a_b_r2`]).
    #[cfg(test)]
    pub(crate) fn eval(&self, r: f64) -> (f64, f64) {
        let (a, b_r2) = self.eval_a_b_r2(r, 1.0 / r);
        (a, b_r2 * r * r)
    }

    /// The table as the GPU's twin reads it: `(1/h, intervals, c, ca, cb, [A_F, B_F / r^2]
    /// at every node, flattened)`.
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn parts(&self) -> (f64, usize, [f64; 3], Vec<f64>) {
        (
            self.inv_h,
            self.n,
            [self.c, self.ca, self.cb],
            self.g.iter().flatten().copied().collect(),
        )
    }

    /// `(A_R, B_R / r^2)` given `r` and `1/r`: the pair sums apply `A f + (B / r^2)(r . f) r`
    /// and need no unit vector.
    #[inline]
    pub(crate) fn eval_a_b_r2(&self, r: f64, inv: f64) -> (f64, f64) {
        let (i, w) = lagrange4(r * self.inv_h, self.n);
        let g = &self.g[i..i + 4];
        let af = w[0] * g[0][0] + w[1] * g[1][0] + w[2] * g[2][0] + w[3] * g[3][0];
        let bf = w[0] * g[0][1] + w[1] * g[1][1] + w[2] * g[2][1] + w[3] * g[3][1];
        let inv2 = inv * inv;
        let inv3 = inv2 * inv;
        (
            self.c * inv + self.ca * inv3 - af,
            (self.c - self.cb * inv2) * inv3 - bf,
        )
    }
}

/// The Stokeslet's real-space radial derivatives `[A, A', A'', C, C', C'']` (see
/// [`stokeslet_real_derivatives`]) for fast stresslet pair sums: the smooth Fourier part
/// `free - real` tabulated on `[0, r_c]` at 4096 uniform intervals with cubic Lagrange
/// interpolation, the free-space part exact. Distances within `0.05/xi` plus three intervals of
/// zero (where the subtraction loses digits) use the closed form. `A` itself is not needed by
/// [`stresslet_from_derivatives`] and is returned as 0.
#[derive(Clone, Debug)]
pub(crate) struct StressletTable {
    inv_h: f64,
    n: usize,
    xi: f64,
    r_direct: f64,
    /// `[A', A'', C, C', C'']` of the Fourier part at the nodes.
    g: Vec<[f64; 5]>,
}

impl StressletTable {
    /// Table for splitting parameter `xi` up to `cutoff`.
    pub(crate) fn new(cutoff: f64, xi: f64) -> Self {
        let n = 4096;
        let h = cutoff / n as f64;
        let r_direct = 0.05 / xi + 3.0 * h;
        let g = (0..=n)
            .map(|k| {
                let r = (k as f64 * h).max(0.5 * r_direct);
                let f = stokeslet_free_derivatives(r);
                let d = stokeslet_real_derivatives(r, xi);
                [
                    f[1] - d[1],
                    f[2] - d[2],
                    f[3] - d[3],
                    f[4] - d[4],
                    f[5] - d[5],
                ]
            })
            .collect();
        Self {
            inv_h: 1.0 / h,
            n,
            xi,
            r_direct,
            g,
        }
    }

    /// The table as the GPU's twin reads it: `(1/h, intervals, xi, r_direct, [A', A'', C, C',
    /// C''] of the Fourier part at every node, flattened)`.
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn parts(&self) -> (f64, usize, f64, f64, Vec<f64>) {
        (
            self.inv_h,
            self.n,
            self.xi,
            self.r_direct,
            self.g.iter().flatten().copied().collect(),
        )
    }

    /// `[0, A', A'', C, C', C'']` of the real-space part at `0 < r <= cutoff`.
    #[inline]
    pub(crate) fn eval(&self, r: f64) -> [f64; 6] {
        if r < self.r_direct {
            let mut d = stokeslet_real_derivatives(r, self.xi);
            d[0] = 0.0;
            return d;
        }
        let (i, w) = lagrange4(r * self.inv_h, self.n);
        let g = &self.g[i..i + 4];
        let f = stokeslet_free_derivatives(r);
        let mut out = [0.0; 6];
        for c in 0..5 {
            let v = w[0] * g[0][c] + w[1] * g[1][c] + w[2] * g[2][c] + w[3] * g[3][c];
            out[c + 1] = f[c + 1] - v;
        }
        out
    }
}
