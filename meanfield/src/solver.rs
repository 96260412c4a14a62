//! The mean-field equations (M1)-(M2) of docs/MODEL.md §4, pseudo-spectrally on the periodic unit
//! cube:
//!
//! ```text
//! d_t Q = -u.grad Q + (grad u) Q + Q (grad u)^T - 2 S:E + D lap Q,   (grad u)_ik = d_k u_i
//! -lap u + grad q = div(-Q + zeta S:E),  div u = 0
//! ```
//!
//! State: Fourier coefficients of the six components of Q (xx, xy, xz, yy, yz, zz), modes
//! `k = 2 pi m`. First derivatives multiply by `i k` with the Nyquist mode zeroed. Products are
//! formed on the grid and dealiased by the 2/3 rule: after each forward transform of a product,
//! modes with any `|m_d| > n/3` are zeroed.
//!
//! The Stokes problem is solved by fixed-point iteration on `u` (warm-started from the previous
//! step): `u <- Stokes(div(-Q + zeta S:E(u)))`. The closure depends on Q only, so its eigenframe
//! and interpolated fourth moments are computed once per right-hand side and only re-contracted
//! with each new `E`.

use crate::closure::BinghamClosure;
use crate::eigen::{Sym3, sym3_eigen_sorted};
use motile_analysis::fft3::RealFft3;
use motile_analysis::params::{InvalidParameter, check_range};
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Component order of symmetric tensors.
pub const SYM: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// Index into [`SYM`] of the pair `(i, j)`.
pub(crate) fn sym_index(i: usize, j: usize) -> usize {
    let (a, b) = if i <= j { (i, j) } else { (j, i) };
    match (a, b) {
        (0, 0) => 0,
        (0, 1) => 1,
        (0, 2) => 2,
        (1, 1) => 3,
        (1, 2) => 4,
        _ => 5,
    }
}

/// Physical parameters of the mean-field model.
#[derive(Clone, Debug, PartialEq)]
pub struct MeanFieldParams {
    /// `zeta = sigma_b / mu` (0.1421 at nu = 0.625).
    pub zeta: f64,
    /// Diffusion `D` (default 1e-4).
    pub diffusion: f64,
    /// Relative tolerance of the Stokes fixed point (default 1e-8).
    pub fixed_point_tolerance: f64,
    /// Iteration cap of the fixed point (default 50).
    pub fixed_point_max_iterations: usize,
}

impl MeanFieldParams {
    /// Check every field (the error names it, its value, the allowed range and the unit).
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        check_range(
            "zeta",
            self.zeta,
            0.0,
            10.0,
            false,
            "sigma_b/mu, dimensionless",
        )?;
        check_range(
            "diffusion",
            self.diffusion,
            0.0,
            1.0,
            false,
            "L^2 |sigma_a|/mu",
        )?;
        check_range(
            "fixed_point_tolerance",
            self.fixed_point_tolerance,
            0.0,
            1e-2,
            true,
            "relative change of u",
        )?;
        check_range(
            "fixed_point_max_iterations",
            self.fixed_point_max_iterations as f64,
            1.0,
            1e4,
            false,
            "iterations",
        )
    }
}

impl Default for MeanFieldParams {
    fn default() -> Self {
        Self {
            zeta: 0.1421,
            diffusion: 1e-4,
            fixed_point_tolerance: 1e-8,
            fixed_point_max_iterations: 50,
        }
    }
}

/// Mean-field failures.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeanFieldError {
    /// The Stokes fixed point did not converge.
    #[error(
        "Stokes fixed point did not converge: relative change {residual:.2e} after {iterations} iterations (tolerance {tolerance:.1e})"
    )]
    FixedPoint {
        /// Iterations done.
        iterations: usize,
        /// Last relative change.
        residual: f64,
        /// Tolerance.
        tolerance: f64,
    },
    /// A non-finite value.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
}

/// Report of one right-hand-side evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RhsReport {
    /// Fixed-point iterations.
    pub iterations: usize,
    /// Final relative change of `u`.
    pub residual: f64,
}

/// Spectral grid on the unit cube: wavenumbers, real-to-complex transforms, dealiasing.
///
/// Coefficients are stored as the half spectrum of real fields: index
/// `(i2 * n + i1) * h + i0` with `h = n / 2 + 1`, axis 0 holding `m_0 = 0..=n/2` only (the
/// other half is the complex conjugate). Sums over the full spectrum weigh each stored mode
/// by [`SpectralGrid::weight`].
#[derive(Debug, Clone)]
pub struct SpectralGrid {
    /// Points per dimension.
    pub n: usize,
    /// Stored modes along axis 0, `n / 2 + 1`.
    h: usize,
    fft: RealFft3,
    /// `2 pi m` per FFT index, Nyquist zeroed (first derivatives); axes 1 and 2.
    k1: Vec<f64>,
    /// `(2 pi m)^2` per FFT index (second derivatives keep the Nyquist mode); axes 1 and 2.
    k2: Vec<f64>,
    /// Whether the index survives the 2/3 rule; axes 1 and 2.
    keep: Vec<bool>,
}

impl SpectralGrid {
    /// Grid of `n^3` points (`n` even, at least 4).
    pub fn new(n: usize) -> Self {
        assert!(
            n >= 4 && n.is_multiple_of(2),
            "grid size must be even and at least 4, got {n}"
        );
        let m = |i: usize| {
            if i <= n / 2 {
                i as i64
            } else {
                i as i64 - n as i64
            }
        };
        let k1 = (0..n)
            .map(|i| {
                if i == n / 2 {
                    0.0
                } else {
                    2.0 * PI * m(i) as f64
                }
            })
            .collect();
        let k2 = (0..n).map(|i| (2.0 * PI * m(i) as f64).powi(2)).collect();
        let keep = (0..n)
            .map(|i| 3 * m(i).unsigned_abs() as usize <= n)
            .collect();
        Self {
            n,
            h: n / 2 + 1,
            fft: RealFft3::new([n; 3]),
            k1,
            k2,
            keep,
        }
    }

    /// Grid points in total, `n^3`.
    pub fn len(&self) -> usize {
        self.n.pow(3)
    }

    /// Stored Fourier coefficients per field, `(n / 2 + 1) n^2`.
    pub fn spectral_len(&self) -> usize {
        self.h * self.n * self.n
    }

    /// True for an empty grid (never).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// FFT indices `[i0, i1, i2]` of a stored coefficient (`i0 < n / 2 + 1`).
    fn idx3(&self, idx: usize) -> [usize; 3] {
        [
            idx % self.h,
            (idx / self.h) % self.n,
            idx / (self.h * self.n),
        ]
    }

    /// Weight of a stored coefficient in sums over the full spectrum: 1 on the planes
    /// `m_0 = 0` and `m_0 = n/2`, whose conjugates are stored themselves, 2 elsewhere.
    pub fn weight(&self, idx: usize) -> f64 {
        let i0 = idx % self.h;
        if i0 == 0 || i0 == self.n / 2 {
            1.0
        } else {
            2.0
        }
    }

    /// `sum_k |c_k|^2` over the full spectrum (the mean square of the field, by Parseval).
    pub fn norm_sqr(&self, c: &[Complex64]) -> f64 {
        c.iter()
            .enumerate()
            .map(|(idx, v)| self.weight(idx) * v.norm_sqr())
            .sum()
    }

    fn kept(&self, idx: usize) -> bool {
        let [a, b, d] = self.idx3(idx);
        3 * a <= self.n && self.keep[b] && self.keep[d]
    }

    /// Fourier coefficients of a real field (forward FFT / n^3), dealiased if asked.
    pub fn forward(&self, f: &[f64], dealias: bool) -> Vec<Complex64> {
        let mut c = vec![Complex64::default(); self.spectral_len()];
        self.forward_into(f, dealias, &mut c);
        c
    }

    /// [`Self::forward`] into a caller's buffer.
    pub fn forward_into(&self, f: &[f64], dealias: bool, c: &mut [Complex64]) {
        self.fft.forward(f, c);
        let scale = 1.0 / self.len() as f64;
        c.par_iter_mut().enumerate().for_each(|(idx, v)| {
            *v = if !dealias || self.kept(idx) {
                *v * scale
            } else {
                Complex64::default()
            };
        });
    }

    /// Grid values of a real field from its coefficients.
    pub fn inverse(&self, c: &[Complex64]) -> Vec<f64> {
        let mut g = vec![0.0; self.len()];
        let mut work = c.to_vec();
        self.fft.inverse(&mut work, &mut g);
        g
    }

    /// Grid values of `d_dir f` from the coefficients of `f`.
    pub fn inverse_derivative(&self, c: &[Complex64], dir: usize) -> Vec<f64> {
        let mut work = self.derivative(c, dir);
        let mut g = vec![0.0; self.len()];
        self.fft.inverse(&mut work, &mut g);
        g
    }

    /// Grid values of the symmetric gradient `(d_j u_i + d_i u_j) / 2` of velocity
    /// coefficients `u`, component `(i, j)`.
    pub fn inverse_strain(&self, u: &[Vec<Complex64>; 3], i: usize, j: usize) -> Vec<f64> {
        let mut work: Vec<Complex64> = (0..self.spectral_len())
            .into_par_iter()
            .map(|idx| {
                let k = self.k_vector(idx);
                Complex64::new(0.0, 0.5) * (u[i][idx] * k[j] + u[j][idx] * k[i])
            })
            .collect();
        let mut g = vec![0.0; self.len()];
        self.fft.inverse(&mut work, &mut g);
        g
    }

    /// Coefficients of `d_dir f`.
    pub fn derivative(&self, c: &[Complex64], dir: usize) -> Vec<Complex64> {
        c.par_iter()
            .enumerate()
            .map(|(idx, v)| {
                let k = self.k_vector(idx)[dir];
                v * Complex64::new(0.0, k)
            })
            .collect()
    }

    /// Coefficients on this grid of a field given by its coefficients `c` on grid `from`
    /// (spectral interpolation): modes with every `|m_d| < min(n, n_from) / 2` are copied,
    /// the others (those beyond the coarser grid, and its Nyquist modes) are zero.
    pub fn resample(&self, c: &[Complex64], from: &SpectralGrid) -> Vec<Complex64> {
        assert_eq!(c.len(), from.spectral_len(), "resample: coefficient count");
        let lim = (self.n.min(from.n) / 2) as i64;
        let signed = |i: usize, n: usize| {
            if i <= n / 2 {
                i as i64
            } else {
                i as i64 - n as i64
            }
        };
        let wrap = |m: i64, n: usize| m.rem_euclid(n as i64) as usize;
        let mut out = vec![Complex64::default(); self.spectral_len()];
        for (idx, v) in c.iter().enumerate() {
            let [a, b, d] = from.idx3(idx);
            let m = [a as i64, signed(b, from.n), signed(d, from.n)];
            if m.iter().all(|x| x.abs() < lim) {
                let j = (wrap(m[2], self.n) * self.n + wrap(m[1], self.n)) * self.h + a;
                out[j] = *v;
            }
        }
        out
    }

    /// `|k|^2` at a coefficient index.
    pub fn k_squared(&self, idx: usize) -> f64 {
        let [a, b, d] = self.idx3(idx);
        // Axis 0 stores m_0 = a >= 0 only, so (2 pi a)^2 is k2[a] as on the other axes.
        self.k2[a] + self.k2[b] + self.k2[d]
    }

    /// First-derivative wavevector at a coefficient index.
    pub fn k_vector(&self, idx: usize) -> [f64; 3] {
        let [a, b, d] = self.idx3(idx);
        [self.k1[a], self.k1[b], self.k1[d]]
    }

    /// Zero-mean Stokes velocity from the coefficients of a symmetric stress `sigma`:
    /// `u = (I - kk/k^2)/k^2 . (i k . sigma)`.
    pub fn stokes(&self, sigma: &[Vec<Complex64>; 6]) -> [Vec<Complex64>; 3] {
        let mut u: [Vec<Complex64>; 3] =
            std::array::from_fn(|_| vec![Complex64::default(); self.spectral_len()]);
        let (u0, rest) = u.split_at_mut(1);
        let (u1, u2) = rest.split_at_mut(1);
        u0[0]
            .par_iter_mut()
            .zip(u1[0].par_iter_mut())
            .zip(u2[0].par_iter_mut())
            .enumerate()
            .for_each(|(idx, ((a, b), c))| {
                let kk = self.k_squared(idx);
                if kk == 0.0 {
                    return;
                }
                let k = self.k_vector(idx);
                let s = |i: usize, j: usize| sigma[sym_index(i, j)][idx];
                let f: [Complex64; 3] = std::array::from_fn(|i| {
                    Complex64::new(0.0, 1.0) * (k[0] * s(i, 0) + k[1] * s(i, 1) + k[2] * s(i, 2))
                });
                let kf = k[0] * f[0] + k[1] * f[1] + k[2] * f[2];
                let k1sq = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
                let proj = |i: usize| (f[i] - kf * (k[i] / k1sq.max(1e-300))) / kk;
                *a = proj(0);
                *b = proj(1);
                *c = proj(2);
            });
        u
    }
}

/// The closure at every grid point, for one Q: rotation `R` and eigenframe fourth moments
/// (scaled by the concentration `tr Q`).
#[derive(Debug, Clone, Default)]
pub struct ClosureField {
    r: Vec<Sym3>,
    s: Vec<Sym3>,
    /// Smallest eigenvalue of `Q / tr Q` over the grid (realizability).
    pub min_eigenvalue: f64,
    /// Largest eigenvalue of `Q / tr Q` over the grid.
    pub max_eigenvalue: f64,
    /// Relative entropy `H`, volume-averaged: `<c ln c + c h(Q/c)>`, `h` the tabulated
    /// Bingham entropy density (NaN when not asked for).
    pub entropy: f64,
}

impl ClosureField {
    /// Evaluate the closure for grid values `q` (six components); the entropy (a diagnostic)
    /// only if asked.
    pub fn new(closure: &BinghamClosure, q: &[Vec<f64>; 6], with_entropy: bool) -> Self {
        let n = q[0].len();
        // Eigen-decomposition of Q / tr Q at every point, eigenvalues in descending order.
        let eig: Vec<(Sym3, [f64; 3], f64)> = (0..n)
            .into_par_iter()
            .map(|p| {
                let a: Sym3 =
                    std::array::from_fn(|i| std::array::from_fn(|j| q[sym_index(i, j)][p]));
                let c = a[0][0] + a[1][1] + a[2][2];
                let an: Sym3 = a.map(|row| row.map(|v| v / c));
                // Largest eigenvalue first: the tables' most accurate order.
                let (w, r) = sym3_eigen_sorted(&an);
                (r, w, c)
            })
            .collect();
        // Table evaluation in blocks (one matrix product per block).
        const BLOCK: usize = 512;
        let blocks: Vec<(Vec<Sym3>, Vec<f64>)> = eig
            .par_chunks(BLOCK)
            .map_init(
                || {
                    (
                        crate::closure::BatchScratch::default(),
                        Vec::new(),
                        Vec::new(),
                    )
                },
                |(scratch, f, h), chunk| {
                    let mus: Vec<[f64; 3]> = chunk.iter().map(|e| e.1).collect();
                    closure.evaluate_batch_into(&mus, with_entropy, scratch, f, h);
                    let s = f
                        .iter()
                        .zip(chunk)
                        .map(|(f, e)| f.map(|row| row.map(|v| v * e.2)))
                        .collect();
                    let h = h
                        .iter()
                        .zip(chunk)
                        .map(|(h, e)| e.2 * e.2.max(1e-300).ln() + e.2 * h)
                        .collect();
                    (s, h)
                },
            )
            .collect();
        let min_eigenvalue = eig
            .iter()
            .map(|e| e.1.iter().copied().fold(f64::INFINITY, f64::min))
            .fold(f64::INFINITY, f64::min);
        let max_eigenvalue = eig
            .iter()
            .map(|e| e.1.iter().copied().fold(f64::NEG_INFINITY, f64::max))
            .fold(f64::NEG_INFINITY, f64::max);
        let entropy = if with_entropy {
            blocks.iter().flat_map(|b| b.1.iter()).sum::<f64>() / n as f64
        } else {
            f64::NAN
        };
        Self {
            r: eig.iter().map(|e| e.0).collect(),
            s: blocks.into_iter().flat_map(|b| b.0).collect(),
            min_eigenvalue,
            max_eigenvalue,
            entropy,
        }
    }

    /// `(S:E)` at every point for grid values `e` (six components).
    pub fn contract(&self, e: &[Vec<f64>; 6]) -> [Vec<f64>; 6] {
        let n = self.r.len();
        let vals: Vec<[f64; 6]> = (0..n)
            .into_par_iter()
            .map(|p| {
                let r = &self.r[p];
                let s = &self.s[p];
                let em = |i: usize, j: usize| e[sym_index(i, j)][p];
                // E' = R^T E R
                let mut ep = [[0.0; 3]; 3];
                for a in 0..3 {
                    for b in a..3 {
                        let mut acc = 0.0;
                        for i in 0..3 {
                            for j in 0..3 {
                                acc += r[i][a] * em(i, j) * r[j][b];
                            }
                        }
                        ep[a][b] = acc;
                        ep[b][a] = acc;
                    }
                }
                // T' = S':E' (only S'_aabb and its permutations are non-zero).
                let mut tp = [[0.0; 3]; 3];
                for a in 0..3 {
                    tp[a][a] = (0..3).map(|c| s[a][c] * ep[c][c]).sum();
                    for b in 0..3 {
                        if a != b {
                            tp[a][b] = 2.0 * s[a][b] * ep[a][b];
                        }
                    }
                }
                // back: R T' R^T
                std::array::from_fn(|c| {
                    let (i, j) = SYM[c];
                    let mut acc = 0.0;
                    for a in 0..3 {
                        for b in 0..3 {
                            acc += r[i][a] * tp[a][b] * r[j][b];
                        }
                    }
                    acc
                })
            })
            .collect();
        std::array::from_fn(|c| vals.iter().map(|v| v[c]).collect())
    }
}

/// Everything one right-hand-side evaluation produces.
#[derive(Debug, Clone)]
pub struct RhsEval {
    /// Coefficients of the explicit terms `-u.grad Q + grad u Q + Q grad u^T - 2 S:E`.
    pub nonlinear: [Vec<Complex64>; 6],
    /// Converged velocity coefficients.
    pub u: [Vec<Complex64>; 3],
    /// Grid values of `E`.
    pub e: [Vec<f64>; 6],
    /// Grid values of `S:E`.
    pub se: [Vec<f64>; 6],
    /// Grid values of `Q`.
    pub q: [Vec<f64>; 6],
    /// Grid values of `u`.
    pub u_grid: [Vec<f64>; 3],
    /// Fixed-point report.
    pub report: RhsReport,
    /// Smallest eigenvalue of `Q / tr Q`.
    pub min_eigenvalue: f64,
    /// Largest eigenvalue of `Q / tr Q`.
    pub max_eigenvalue: f64,
    /// Relative entropy `H` (volume average).
    pub entropy: f64,
}

/// Flow speed below which the fixed point's change is measured absolutely (mean-field units):
/// O(1) stresses leave round-off flows near 1e-17, and a flow that small (e.g. a perturbation
/// whose active stress is a pure gradient, balanced by pressure) has no digits for a relative
/// criterion to converge on. Regression: a plane wave with m = (1, 1, 0) stopped at t = 11.4
/// with "fixed point did not converge" while its flow was 1e-23.
const FLOW_FLOOR: f64 = 1e-14;

fn rel_change(grid: &SpectralGrid, a: &[Vec<Complex64>; 3], b: &[Vec<Complex64>; 3]) -> f64 {
    let mut num = 0.0;
    let mut den = 0.0;
    for c in 0..3 {
        for (idx, (x, y)) in a[c].iter().zip(&b[c]).enumerate() {
            let w = grid.weight(idx);
            num += w * (x - y).norm_sqr();
            den += w * x.norm_sqr();
        }
    }
    (num / den.max(FLOW_FLOOR * FLOW_FLOOR)).sqrt()
}

/// The mean-field right-hand side: grid, closure tables, parameters.
#[derive(Debug)]
pub struct MeanFieldRhs<'a> {
    /// Grid.
    pub grid: &'a SpectralGrid,
    /// Closure tables.
    pub closure: &'a BinghamClosure,
    /// Parameters.
    pub params: &'a MeanFieldParams,
    /// Also evaluate the relative entropy (a diagnostic: costs a fourth table).
    pub with_entropy: bool,
}

impl MeanFieldRhs<'_> {
    /// Grid values of `E` from velocity coefficients.
    pub fn strain(&self, u: &[Vec<Complex64>; 3]) -> [Vec<f64>; 6] {
        std::array::from_fn(|c| {
            let (i, j) = SYM[c];
            self.grid.inverse_strain(u, i, j)
        })
    }

    /// Evaluate the explicit right-hand side at `q_hat`, the velocity fixed point started
    /// from `u_guess`.
    pub fn eval(
        &self,
        q_hat: &[Vec<Complex64>; 6],
        u_guess: &[Vec<Complex64>; 3],
    ) -> Result<RhsEval, MeanFieldError> {
        let g = self.grid;
        let q: [Vec<f64>; 6] = std::array::from_fn(|c| g.inverse(&q_hat[c]));
        let closure = ClosureField::new(self.closure, &q, self.with_entropy);
        let zeta = self.params.zeta;
        let mut u = u_guess.clone();
        let mut report = RhsReport::default();
        loop {
            report.iterations += 1;
            let e = self.strain(&u);
            let se = if zeta != 0.0 {
                closure.contract(&e)
            } else {
                std::array::from_fn(|_| vec![0.0; g.len()])
            };
            let sigma: [Vec<Complex64>; 6] = std::array::from_fn(|c| {
                let s: Vec<f64> = q[c]
                    .iter()
                    .zip(&se[c])
                    .map(|(q, s)| -q + zeta * s)
                    .collect();
                g.forward(&s, true)
            });
            let u_new = g.stokes(&sigma);
            report.residual = rel_change(g, &u_new, &u);
            u = u_new;
            if zeta == 0.0 || report.residual <= self.params.fixed_point_tolerance {
                break;
            }
            if report.iterations >= self.params.fixed_point_max_iterations
                || !report.residual.is_finite()
            {
                return Err(MeanFieldError::FixedPoint {
                    iterations: report.iterations,
                    residual: report.residual,
                    tolerance: self.params.fixed_point_tolerance,
                });
            }
        }
        // Velocity and gradients on the grid; E from the gradient (no extra transforms).
        let ug: [Vec<f64>; 3] = std::array::from_fn(|i| g.inverse(&u[i]));
        let grad_u: [[Vec<f64>; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|k| g.inverse_derivative(&u[i], k)));
        let e: [Vec<f64>; 6] = std::array::from_fn(|c| {
            let (i, j) = SYM[c];
            grad_u[i][j]
                .iter()
                .zip(&grad_u[j][i])
                .map(|(a, b)| 0.5 * (a + b))
                .collect()
        });
        let se = closure.contract(&e);
        let nonlinear: [Vec<Complex64>; 6] = std::array::from_fn(|c| {
            let (i, j) = SYM[c];
            let dq: [Vec<f64>; 3] = std::array::from_fn(|k| g.inverse_derivative(&q_hat[c], k));
            let vals: Vec<f64> = (0..g.len())
                .into_par_iter()
                .map(|p| {
                    let adv = ug[0][p] * dq[0][p] + ug[1][p] * dq[1][p] + ug[2][p] * dq[2][p];
                    let mut stretch = 0.0;
                    for k in 0..3 {
                        stretch += grad_u[i][k][p] * q[sym_index(k, j)][p]
                            + q[sym_index(i, k)][p] * grad_u[j][k][p];
                    }
                    -adv + stretch - 2.0 * se[c][p]
                })
                .collect();
            g.forward(&vals, true)
        });
        if nonlinear
            .iter()
            .any(|c| c.iter().any(|v| !v.re.is_finite() || !v.im.is_finite()))
        {
            return Err(MeanFieldError::NonFinite("the right-hand side"));
        }
        Ok(RhsEval {
            nonlinear,
            u,
            e,
            se,
            q,
            u_grid: ug,
            report,
            min_eigenvalue: closure.min_eigenvalue,
            max_eigenvalue: closure.max_eigenvalue,
            entropy: closure.entropy,
        })
    }
}

/// A multistep IMEX scheme as a coefficient table: for step ratio `w = dt_n / dt_{n-1}`,
/// `(a0 Q^{n+1} + a1 Q^n + a2 Q^{n-1}) / dt = b0 N^n + b1 N^{n-1} + D lap Q^{n+1}`.
#[derive(Clone, Copy, Debug)]
pub struct ImexScheme {
    /// Name.
    pub name: &'static str,
    /// Steps of history it needs (1 or 2).
    pub steps: usize,
    /// Coefficients `([a0, a1, a2], [b0, b1])` for a step ratio.
    pub coefficients: fn(f64) -> ([f64; 3], [f64; 2]),
}

/// First-order IMEX Euler (SBDF1).
pub const SBDF1: ImexScheme = ImexScheme {
    name: "SBDF1",
    steps: 1,
    coefficients: |_| ([1.0, -1.0, 0.0], [1.0, 0.0]),
};

/// Second-order variable-step SBDF2 (zero-stable for step ratios below 1 + sqrt 2).
pub const SBDF2: ImexScheme = ImexScheme {
    name: "SBDF2",
    steps: 2,
    coefficients: |w| {
        (
            [(1.0 + 2.0 * w) / (1.0 + w), -(1.0 + w), w * w / (1.0 + w)],
            [1.0 + w, -w],
        )
    },
};

/// Coefficients of the six components of a symmetric tensor field.
pub type TensorCoefficients = [Vec<Complex64>; 6];

/// The previous step's Q, explicit right-hand side and step size.
#[derive(Debug, Clone)]
pub struct History {
    /// `Q^{n-1}`.
    pub q_hat: TensorCoefficients,
    /// `N^{n-1}`.
    pub nonlinear: TensorCoefficients,
    /// `dt_{n-1}`.
    pub dt: f64,
}

/// Time stepper state: the current and previous Q and right-hand sides.
#[derive(Debug, Clone)]
pub struct MeanFieldStepper {
    /// Scheme used once enough history exists (the first step always uses SBDF1).
    pub scheme: ImexScheme,
    /// Current time.
    pub t: f64,
    /// Current Q coefficients.
    pub q_hat: [Vec<Complex64>; 6],
    prev: Option<History>,
    /// Last velocity (warm start of the fixed point).
    pub u_hat: [Vec<Complex64>; 3],
}

/// What a step did, and diagnostics of the state it started from (volume averages over the
/// unit cube).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeanFieldStepReport {
    /// Fixed-point report of the right-hand side.
    pub rhs: RhsReport,
    /// Smallest eigenvalue of `Q / tr Q` before the step (realizability).
    pub min_eigenvalue: f64,
    /// `||u||_2`, volume-averaged.
    pub u_l2: f64,
    /// `max_x (|u_x| + |u_y| + |u_z|)`: the CFL velocity (sum over axes).
    pub u_max: f64,
    /// `||E||_2 = sqrt(<E:E>)`.
    pub e_l2: f64,
    /// `<E:Q>`, the power the active stress injects (docs/MODEL.md §4 energy identity).
    pub e_dot_q: f64,
    /// Largest eigenvalue of `Q / tr Q`.
    pub max_eigenvalue: f64,
    /// Relative entropy `H` (volume average), docs/MODEL.md §4.
    pub entropy: f64,
    /// Energy identity residual `(<2 E:E + zeta E:S:E> - <E:Q>) / <E:Q>` (zero up to the
    /// fixed-point tolerance).
    pub energy_residual: f64,
}

impl MeanFieldStepper {
    /// Start from grid values of Q.
    pub fn new(grid: &SpectralGrid, q: &[Vec<f64>; 6], scheme: ImexScheme) -> Self {
        Self {
            scheme,
            t: 0.0,
            q_hat: std::array::from_fn(|c| grid.forward(&q[c], false)),
            prev: None,
            u_hat: std::array::from_fn(|_| vec![Complex64::default(); grid.spectral_len()]),
        }
    }

    /// The previous step's history (what SBDF2 needs besides the current state).
    pub fn history(&self) -> Option<&History> {
        self.prev.as_ref()
    }

    /// Restore a state saved from [`Self::q_hat`], [`Self::history`], [`Self::u_hat`], [`Self::t`].
    pub fn restore(
        &mut self,
        t: f64,
        q_hat: TensorCoefficients,
        history: Option<History>,
        u_hat: [Vec<Complex64>; 3],
    ) {
        self.t = t;
        self.q_hat = q_hat;
        self.prev = history;
        self.u_hat = u_hat;
    }

    /// Advance by `dt`.
    pub fn step(
        &mut self,
        rhs: &MeanFieldRhs,
        dt: f64,
    ) -> Result<MeanFieldStepReport, MeanFieldError> {
        let ev = rhs.eval(&self.q_hat, &self.u_hat)?;
        let (scheme, w) = match (&self.prev, self.scheme.steps) {
            (Some(h), 2) => (self.scheme, dt / h.dt),
            _ => (SBDF1, 1.0),
        };
        let ([a0, a1, a2], [b0, b1]) = (scheme.coefficients)(w);
        let d = rhs.params.diffusion;
        let g = rhs.grid;
        let new: [Vec<Complex64>; 6] = std::array::from_fn(|c| {
            (0..g.spectral_len())
                .into_par_iter()
                .map(|idx| {
                    let mut r = -a1 * self.q_hat[c][idx] + dt * b0 * ev.nonlinear[c][idx];
                    if let Some(h) = &self.prev
                        && scheme.steps == 2
                    {
                        r += -a2 * h.q_hat[c][idx] + dt * b1 * h.nonlinear[c][idx];
                    }
                    r / (a0 + dt * d * g.k_squared(idx))
                })
                .collect()
        });
        // Nothing is committed unless the new state is finite: on an error the stepper still
        // holds the last good state, for the caller to save.
        if new
            .iter()
            .any(|c| c.iter().any(|v| !v.re.is_finite() || !v.im.is_finite()))
        {
            return Err(MeanFieldError::NonFinite("Q after the step"));
        }
        let report = state_report(rhs, &ev);
        let old_q = std::mem::replace(&mut self.q_hat, new);
        self.prev = Some(History {
            q_hat: old_q,
            nonlinear: ev.nonlinear,
            dt,
        });
        self.u_hat = ev.u;
        self.t += dt;
        Ok(report)
    }

    /// The diagnostics of the current state, without stepping: the report a step from here
    /// would give, and the right-hand side evaluation behind it (for output at the end of a
    /// run).
    pub fn diagnostics(
        &self,
        rhs: &MeanFieldRhs,
    ) -> Result<(RhsEval, MeanFieldStepReport), MeanFieldError> {
        let ev = rhs.eval(&self.q_hat, &self.u_hat)?;
        let report = state_report(rhs, &ev);
        Ok((ev, report))
    }
}

/// Norms, eigenvalue bounds, entropy and the energy identity's residual of one evaluation.
fn state_report(rhs: &MeanFieldRhs, ev: &RhsEval) -> MeanFieldStepReport {
    let g = rhs.grid;
    let npts = g.len() as f64;
    let u_l2 = ev.u.iter().map(|c| g.norm_sqr(c)).sum::<f64>().sqrt();
    let ug = &ev.u_grid;
    let u_max = (0..g.len())
        .map(|p| ug[0][p].abs() + ug[1][p].abs() + ug[2][p].abs())
        .fold(0.0, f64::max);
    let w = |c: usize| if SYM[c].0 == SYM[c].1 { 1.0 } else { 2.0 };
    let (mut ee, mut eq, mut ese) = (0.0, 0.0, 0.0);
    for c in 0..6 {
        for p in 0..g.len() {
            ee += w(c) * ev.e[c][p] * ev.e[c][p];
            eq += w(c) * ev.e[c][p] * ev.q[c][p];
            ese += w(c) * ev.e[c][p] * ev.se[c][p];
        }
    }
    let energy_residual = (2.0 * ee + rhs.params.zeta * ese - eq) / eq.abs().max(1e-300);
    MeanFieldStepReport {
        rhs: ev.report,
        min_eigenvalue: ev.min_eigenvalue,
        u_l2,
        u_max,
        e_l2: (ee / npts).sqrt(),
        e_dot_q: eq / npts,
        max_eigenvalue: ev.max_eigenvalue,
        entropy: ev.entropy,
        energy_residual,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A real field with modes up to |m| = 3 on every axis, including m_0 = 0 and m_0 > 0.
    fn field(n: usize) -> Vec<f64> {
        (0..n * n * n)
            .map(|idx| {
                let x =
                    [idx % n, (idx / n) % n, idx / (n * n)].map(|i| 2.0 * PI * i as f64 / n as f64);
                0.3 + (x[0] + 2.0 * x[1]).cos()
                    + 0.5 * (3.0 * x[2] - x[1]).sin()
                    + 0.25 * (2.0 * x[0] - 3.0 * x[1] + x[2]).cos()
            })
            .collect()
    }

    /// The closure field against the quadrature moments at a low table degree, over random Q
    /// (eigenvalues uniform on the triangle, at least 1e-3, random rotations and
    /// concentrations) and random E: `S:E` from the tables against `S:E` from
    /// `exact_fourth` (Newton plus quadrature) in the same eigenframe. With the largest
    /// eigenvalue first (the tables' most accurate order) the worst error at degree 20 is
    /// 6.7e-6 relative to |E|, RMS 1.1e-6; with the Jacobi output's arbitrary order it was
    /// 1.3e-5 and 1.7e-6, which this test rejects.
    #[test]
    fn closure_field_is_accurate_at_low_degree() {
        use crate::closure::exact_fourth;
        use rand::{RngExt, SeedableRng};
        let closure = BinghamClosure::new(20).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let n = 400;
        let mut q: [Vec<f64>; 6] = std::array::from_fn(|_| Vec::new());
        let mut e: [Vec<f64>; 6] = std::array::from_fn(|_| Vec::new());
        let mut exact = Vec::new();
        while exact.len() < n {
            let (a, b): (f64, f64) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            let mu = [a, b, 1.0 - a - b];
            if mu.iter().any(|&m| m < 1e-3) {
                continue;
            }
            // A random rotation from a random unit quaternion.
            let v: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let nv = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let [w, x, y, z] = v.map(|c| c / nv);
            let r = [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - w * z),
                    2.0 * (x * z + w * y),
                ],
                [
                    2.0 * (x * y + w * z),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - w * x),
                ],
                [
                    2.0 * (x * z - w * y),
                    2.0 * (y * z + w * x),
                    1.0 - 2.0 * (x * x + y * y),
                ],
            ];
            let c = rng.random_range(0.5..1.5);
            for (k, &(i, j)) in SYM.iter().enumerate() {
                q[k].push(c * (0..3).map(|a| r[i][a] * mu[a] * r[j][a]).sum::<f64>());
            }
            let em: [[f64; 3]; 3] = {
                let g: [f64; 6] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                std::array::from_fn(|i| std::array::from_fn(|j| g[sym_index(i, j)]))
            };
            for (k, &(i, j)) in SYM.iter().enumerate() {
                e[k].push(em[i][j]);
            }
            // Exact S:E in the eigenframe of the exact decomposition.
            let s = exact_fourth(mu).unwrap();
            let ep: [[f64; 3]; 3] = std::array::from_fn(|a| {
                std::array::from_fn(|b| {
                    (0..3)
                        .flat_map(|i| (0..3).map(move |j| (i, j)))
                        .map(|(i, j)| r[i][a] * em[i][j] * r[j][b])
                        .sum()
                })
            });
            let tp: [[f64; 3]; 3] = std::array::from_fn(|a| {
                std::array::from_fn(|b| {
                    if a == b {
                        (0..3).map(|k| s[a][k] * ep[k][k]).sum()
                    } else {
                        2.0 * s[a][b] * ep[a][b]
                    }
                })
            });
            let t: [f64; 6] = std::array::from_fn(|k| {
                let (i, j) = SYM[k];
                c * (0..3)
                    .flat_map(|a| (0..3).map(move |b| (a, b)))
                    .map(|(a, b)| r[i][a] * tp[a][b] * r[j][b])
                    .sum::<f64>()
            });
            let enorm = em.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
            exact.push((t, c * enorm));
        }
        let field = ClosureField::new(&closure, &q, false);
        let fast = field.contract(&e);
        let (mut worst, mut sq): (f64, f64) = (0.0, 0.0);
        for (p, (t, scale)) in exact.iter().enumerate() {
            let err = (0..6)
                .map(|k| (fast[k][p] - t[k]).abs())
                .fold(0.0, f64::max)
                / scale;
            worst = worst.max(err);
            sq += err * err;
        }
        let rms = (sq / n as f64).sqrt();
        eprintln!("degree 20 closure field: worst {worst:.2e}, rms {rms:.2e} (relative to |E|)");
        assert!(
            worst <= 1e-5 && rms <= 2e-6,
            "degree-20 closure field against quadrature: worst {worst:.2e} (bound 1e-5), rms \
             {rms:.2e} (bound 2e-6)"
        );
    }

    #[test]
    fn half_spectrum_parseval_and_round_trip() {
        let grid = SpectralGrid::new(10);
        let f = field(10);
        let c = grid.forward(&f, false);
        let mean_sq = f.iter().map(|v| v * v).sum::<f64>() / f.len() as f64;
        let parseval = grid.norm_sqr(&c);
        assert!(
            (parseval - mean_sq).abs() < 1e-13,
            "Parseval: {parseval} vs mean square {mean_sq}"
        );
        let back = grid.inverse(&c);
        let err = f
            .iter()
            .zip(&back)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-13, "round trip error {err:.2e}");
    }

    #[test]
    fn resampling_a_band_limited_field_is_exact() {
        for (from, to) in [(8, 14), (14, 8), (10, 10)] {
            let (gf, gt) = (SpectralGrid::new(from), SpectralGrid::new(to));
            let c = gt.resample(&gf.forward(&field(from), false), &gf);
            let got = gt.inverse(&c);
            let err = got
                .iter()
                .zip(field(to))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-13, "{from} -> {to}: max error {err:.2e}");
        }
    }
}
