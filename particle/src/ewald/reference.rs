//! The slow, obviously correct twin of the periodic sums: a direct Ewald summation (docs/MODEL.md
//! §1: "every fast method must agree with a slow, obviously-correct Ewald sum").
//!
//! Real space: every source, every periodic image within `r_c = 6.5/xi` of the target (an
//! explicit image loop, no minimum-image shortcut). Fourier space: every mode with
//! `|k| <= 13 xi`, the structure factor summed directly. Both truncations leave below 1e-16 of
//! the kernel, so the sum is converged to round-off (about 1e-13 relative in the tests) and does
//! not depend on the splitting parameter `xi` (tested). Cost `O(N T)` for `T` targets plus
//! `O(K^3 (N + T))`: for tests and small problems only. Exclusions and the overlap correction
//! follow [`crate::ewald::kernels`].

use crate::ewald::kernels::{
    apply_radial, rpy_fourier_free_apply, rpy_fourier_mode, rpy_overlap_correction, rpy_real,
    stokeslet_real_derivatives, stresslet_fourier_mode, stresslet_fourier_self_gradient,
    stresslet_from_derivatives,
};
use crate::ewald::periodic::{PeriodicStokes, RpyGeometry, StressletField, SumError, check_rpy};
use crate::model::geometry::{Vec3, dot, sub};
use crate::model::units::VISCOSITY;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;

/// `xi r_c` and `k_max / (2 xi)` of the reference: the discarded parts are below 1e-16.
const REAL_REACH: f64 = 6.5;

/// Direct Ewald summation with splitting parameter `xi` (default `10 / L`).
#[derive(Clone, Debug, Default)]
pub struct EwaldReference {
    /// Splitting parameter; `None` picks `10 / L`.
    pub xi: Option<f64>,
}

impl EwaldReference {
    /// With a fixed splitting parameter.
    pub fn with_xi(xi: f64) -> Self {
        Self { xi: Some(xi) }
    }

    fn xi(&self, box_length: f64) -> f64 {
        self.xi.unwrap_or(10.0 / box_length)
    }

    /// RPY velocities at the points `targets` (indices into `points`).
    pub fn rpy_at(
        &self,
        geometry: &RpyGeometry,
        points: &[Vec3],
        forces: &[Vec3],
        targets: &[usize],
    ) -> Result<Vec<Vec3>, SumError> {
        check_rpy(geometry, points, forces)?;
        let l = geometry.box_length;
        let a = geometry.radius;
        let g = geometry.group;
        let xi = self.xi(l);
        let rc = REAL_REACH / xi;
        let modes = Modes::new(l, xi);
        // Structure factor f^(k) = sum_j f_j exp(-i k.y_j), one vector per mode.
        let fhat = modes.structure_factor(points, |j| forces[j].map(|c| Complex64::new(c, 0.0)));
        let vol = l * l * l;
        Ok(targets
            .par_iter()
            .map(|&t| {
                let y = points[t];
                let mut u = [0.0; 3];
                // Real space, explicit images.
                for (j, (yj, fj)) in points.iter().zip(forces).enumerate() {
                    let same = j / g == t / g;
                    let d = sub(y, *yj);
                    for_images(d, l, rc, |r, n_is_zero| {
                        if same && n_is_zero {
                            return;
                        }
                        let rn = dot(r, r).sqrt();
                        let rh = r.map(|c| c / rn);
                        let (ar, br) = rpy_real(rn, xi, a);
                        let (ac, bc) = rpy_overlap_correction(rn, a);
                        add(&mut u, apply_radial(ar + ac, br + bc, rh, *fj));
                    });
                }
                // Fourier space.
                let uf = modes.sum_at(y, |k, k2, e| rpy_fourier_mode(k, k2, xi, a, vol, fhat[e]));
                add(&mut u, uf);
                // Remove the own group's direct Fourier-part terms (itself included).
                for j in (t / g) * g..(t / g + 1) * g {
                    let v = rpy_fourier_free_apply(sub(y, points[j]), forces[j], xi, a);
                    add(&mut u, v.map(|c| -c));
                }
                u.map(|c| c / VISCOSITY)
            })
            .collect())
    }

    /// Stresslet velocities and gradients at the centres `targets`.
    pub fn stresslets_at(
        &self,
        box_length: f64,
        x: &[Vec3],
        p: &[Vec3],
        sigma: &[f64],
        targets: &[usize],
    ) -> StressletField {
        let l = box_length;
        let xi = self.xi(l);
        let rc = REAL_REACH / xi;
        let modes = Modes::new(l, xi);
        // S^(k) = sum_n sigma_n p_n p_n exp(-i k.x_n), stored as 3x3 (row major, 9 entries).
        let shat = modes.structure_factor(x, |n| {
            let mut s = [Complex64::default(); 9];
            for i in 0..3 {
                for j in 0..3 {
                    s[3 * i + j] = Complex64::new(sigma[n] * p[n][i] * p[n][j], 0.0);
                }
            }
            s
        });
        let vol = l * l * l;
        let results: Vec<(Vec3, [Vec3; 3])> = targets
            .par_iter()
            .map(|&t| {
                let y = x[t];
                let mut u = [0.0; 3];
                let mut grad = [[0.0; 3]; 3];
                for (n, xn) in x.iter().enumerate() {
                    let d = sub(y, *xn);
                    for_images(d, l, rc, |r, n_is_zero| {
                        if n == t && n_is_zero {
                            return;
                        }
                        let rn = dot(r, r).sqrt();
                        let dv = stokeslet_real_derivatives(rn, xi);
                        let (du, dg) = stresslet_from_derivatives(r, rn, p[n], sigma[n], &dv);
                        add(&mut u, du);
                        for i in 0..3 {
                            add(&mut grad[i], dg[i]);
                        }
                    });
                }
                // Fourier: F^ = -i k.S^, u^ = phi (I - kk/k^2) F^/k^2, grad u^ = i k u^.
                let sum = modes.sum_at(y, |k, k2, e| {
                    let sh = &shat[e];
                    stresslet_fourier_mode(k, k2, xi, vol, |i, j| sh[3 * i + j])
                });
                for i in 0..3 {
                    u[i] += sum[i];
                    for l in 0..3 {
                        grad[i][l] += sum[3 + 3 * i + l];
                    }
                }
                let own = stresslet_fourier_self_gradient(p[t], sigma[t], xi);
                for i in 0..3 {
                    for l in 0..3 {
                        grad[i][l] -= own[i][l];
                    }
                }
                (
                    u.map(|c| c / VISCOSITY),
                    grad.map(|r| r.map(|c| c / VISCOSITY)),
                )
            })
            .collect();
        StressletField {
            u: results.iter().map(|r| r.0).collect(),
            grad: results.iter().map(|r| r.1).collect(),
        }
    }
}

impl PeriodicStokes for EwaldReference {
    fn rpy(
        &mut self,
        geometry: &RpyGeometry,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<Vec<Vec3>, SumError> {
        let all: Vec<usize> = (0..points.len()).collect();
        self.rpy_at(geometry, points, forces, &all)
    }

    fn stresslets(
        &mut self,
        box_length: f64,
        x: &[Vec3],
        p: &[Vec3],
        sigma: &[f64],
    ) -> Result<StressletField, SumError> {
        let all: Vec<usize> = (0..x.len()).collect();
        Ok(self.stresslets_at(box_length, x, p, sigma, &all))
    }
}

#[inline]
fn add(u: &mut Vec3, v: Vec3) {
    for d in 0..3 {
        u[d] += v[d];
    }
}

/// Calls `f(d + n L, n == 0)` for every image `n` with `|d + n L| < rc`.
fn for_images(d: Vec3, l: f64, rc: f64, mut f: impl FnMut(Vec3, bool)) {
    let range = |c: f64| (((-rc - c) / l).floor() as i64, ((rc - c) / l).ceil() as i64);
    let (r0, r1, r2) = (range(d[0]), range(d[1]), range(d[2]));
    let rc2 = rc * rc;
    for n2 in r2.0..=r2.1 {
        for n1 in r1.0..=r1.1 {
            for n0 in r0.0..=r0.1 {
                let r = [
                    d[0] + n0 as f64 * l,
                    d[1] + n1 as f64 * l,
                    d[2] + n2 as f64 * l,
                ];
                let r2 = dot(r, r);
                // Coincident points (r = 0) only occur for a point and itself, which is
                // excluded; other coincidences have no split form and are skipped.
                if r2 < rc2 && r2 > 0.0 {
                    f(r, n0 == 0 && n1 == 0 && n2 == 0);
                }
            }
        }
    }
}

/// The Fourier modes of the reference: every `k = 2 pi m / L != 0` with `|k| <= 13 xi`.
struct Modes {
    l: f64,
    mmax: i64,
    list: Vec<[i64; 3]>,
}

impl Modes {
    fn new(l: f64, xi: f64) -> Self {
        let kmax = 2.0 * REAL_REACH * xi;
        let mmax = (kmax * l / (2.0 * PI)).ceil() as i64;
        let mut list = Vec::new();
        let m2max = (kmax * l / (2.0 * PI)).powi(2);
        for m2 in -mmax..=mmax {
            for m1 in -mmax..=mmax {
                for m0 in -mmax..=mmax {
                    let mm = (m0 * m0 + m1 * m1 + m2 * m2) as f64;
                    if mm > 0.0 && mm <= m2max {
                        list.push([m0, m1, m2]);
                    }
                }
            }
        }
        Self { l, mmax, list }
    }

    fn k(&self, m: [i64; 3]) -> (Vec3, f64) {
        let s = 2.0 * PI / self.l;
        let k = m.map(|c| c as f64 * s);
        (k, dot(k, k))
    }

    /// `exp(-i 2 pi m y_d / L)` for `m` in `-mmax..=mmax`, per axis.
    fn phases(&self, y: Vec3) -> [Vec<Complex64>; 3] {
        let n = (2 * self.mmax + 1) as usize;
        [0, 1, 2].map(|d| {
            (0..n)
                .map(|i| {
                    let m = i as i64 - self.mmax;
                    Complex64::from_polar(1.0, -2.0 * PI * m as f64 * y[d] / self.l)
                })
                .collect()
        })
    }

    fn phase(&self, ph: &[Vec<Complex64>; 3], m: [i64; 3]) -> Complex64 {
        let i = m.map(|c| (c + self.mmax) as usize);
        ph[0][i[0]] * ph[1][i[1]] * ph[2][i[2]]
    }

    /// `sum_j f(j) exp(-i k.y_j)` for every mode, `C` components at once.
    fn structure_factor<const C: usize>(
        &self,
        y: &[Vec3],
        f: impl Fn(usize) -> [Complex64; C] + Sync,
    ) -> Vec<[Complex64; C]> {
        let ph: Vec<_> = y.par_iter().map(|y| self.phases(*y)).collect();
        self.list
            .par_iter()
            .map(|&m| {
                let mut acc = [Complex64::default(); C];
                for (j, p) in ph.iter().enumerate() {
                    let e = self.phase(p, m);
                    let v = f(j);
                    for d in 0..C {
                        acc[d] += v[d] * e;
                    }
                }
                acc
            })
            .collect()
    }

    /// `Re sum_k g(k) exp(+i k.y)`, `C` components.
    fn sum_at<const C: usize>(
        &self,
        y: Vec3,
        g: impl Fn(Vec3, f64, usize) -> [Complex64; C],
    ) -> [f64; C] {
        let ph = self.phases(y);
        let mut acc = [0.0; C];
        for (e, &m) in self.list.iter().enumerate() {
            let (k, k2) = self.k(m);
            let v = g(k, k2, e);
            let p = self.phase(&ph, m).conj();
            for d in 0..C {
                acc[d] += (v[d] * p).re;
            }
        }
        acc
    }
}
