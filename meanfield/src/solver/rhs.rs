//! The right-hand side of the mean-field equations (M1)-(M2) of docs/MODEL.md §4,
//! pseudo-spectrally on the periodic unit cube:
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
//! The Stokes problem is solved by fixed-point iteration on `u` (started from the stepper's
//! guess, `stepper::warm_start`): `u <- Stokes(div(-Q + zeta S:E(u)))`. The closure depends on Q only, so its eigenframe
//! and interpolated fourth moments are computed once per right-hand side and only re-contracted
//! with each new `E`.

use crate::closure::BinghamClosure;
use num_complex::Complex64;
use rayon::prelude::*;

use crate::solver::closure_field::ClosureField;
use crate::solver::grid::SpectralGrid;
use crate::solver::params::{MeanFieldError, MeanFieldParams, RhsReport, SYM, sym_index};

/// Wall-clock seconds of the phases of one right-hand side (for scaling studies; not part of
/// any result).
#[derive(Clone, Copy, Debug, Default)]
pub struct RhsTiming {
    /// Q to the grid (6 transforms).
    pub q_to_grid: f64,
    /// The closure field: eigen-decompositions, tables, lab-frame tensors.
    pub closure: f64,
    /// The Stokes fixed point: per iteration 6 strain transforms, the contraction, 6 stress
    /// transforms, the Stokes solve and the change of u.
    pub fixed_point: f64,
    /// u and grad u on the grid (12 transforms), E and its contraction.
    pub gradients: f64,
    /// The explicit terms: grad Q (18 transforms), the products, 6 transforms back.
    pub nonlinear: f64,
}

/// Everything one right-hand-side evaluation produces.
#[derive(Debug, Clone)]
pub struct RhsEval {
    /// Where the evaluation's time went.
    pub timing: RhsTiming,
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
    let h = grid.h;
    // The change and the norm in one pass.
    let [num, den] = grid.sum_rows(|row, i| {
        let w = grid.weight_of(i);
        let mut r = [0.0; 2];
        for c in 0..3 {
            let (x, y) = (a[c][row * h + i], b[c][row * h + i]);
            r[0] += w * (x - y).norm_sqr();
            r[1] += w * x.norm_sqr();
        }
        r
    });
    (num / den.max(FLOW_FLOOR * FLOW_FLOOR)).sqrt()
}

/// Whether every coefficient of every component is finite (checked in parallel).
pub(crate) fn all_finite(c: &[Vec<Complex64>]) -> bool {
    c.iter()
        .all(|v| v.par_iter().all(|z| z.re.is_finite() && z.im.is_finite()))
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
        let g = self.grid;
        let mut work = vec![Complex64::default(); g.spectral_len()];
        let mut e: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; g.len()]);
        self.strain_into(u, &mut work, &mut e);
        e
    }

    /// [`Self::strain`] into `e`, with `work` (spectral length) as scratch.
    fn strain_into(&self, u: &[Vec<Complex64>; 3], work: &mut [Complex64], e: &mut [Vec<f64>; 6]) {
        for (c, ec) in e.iter_mut().enumerate() {
            let (i, j) = SYM[c];
            self.grid.inverse_strain_into(u, i, j, work, ec);
        }
    }

    /// Evaluate the explicit right-hand side at `q_hat`, the velocity fixed point started
    /// from `u_guess`.
    pub fn eval(
        &self,
        q_hat: &[Vec<Complex64>; 6],
        u_guess: &[Vec<Complex64>; 3],
    ) -> Result<RhsEval, MeanFieldError> {
        let g = self.grid;
        let (len, slen) = (g.len(), g.spectral_len());
        let mut timing = RhsTiming::default();
        let mut clock = std::time::Instant::now();
        let mut lap = |t: &mut f64| {
            *t = clock.elapsed().as_secs_f64();
            clock = std::time::Instant::now();
        };
        let grid_fields = || -> [Vec<f64>; 6] { std::array::from_fn(|_| vec![0.0; len]) };
        let mut work = vec![Complex64::default(); slen];
        let mut q = grid_fields();
        for (c, qc) in q.iter_mut().enumerate() {
            g.inverse_into(&q_hat[c], &mut work, qc);
        }
        lap(&mut timing.q_to_grid);
        let closure = ClosureField::new(self.closure, &q, self.with_entropy);
        lap(&mut timing.closure);
        let zeta = self.params.zeta;
        let mut u = u_guess.clone();
        let mut u_new: [Vec<Complex64>; 3] =
            std::array::from_fn(|_| vec![Complex64::default(); slen]);
        let mut e = grid_fields();
        let mut se = grid_fields();
        let mut sigma: [Vec<Complex64>; 6] =
            std::array::from_fn(|_| vec![Complex64::default(); slen]);
        let mut report = RhsReport::default();
        loop {
            report.iterations += 1;
            self.strain_into(&u, &mut work, &mut e);
            if zeta != 0.0 {
                closure.contract_into(&e, &mut se);
            }
            for c in 0..6 {
                // The stress -Q + zeta S:E, formed in place of S:E.
                se[c]
                    .par_iter_mut()
                    .zip(&q[c])
                    .for_each(|(s, q)| *s = -q + zeta * *s);
                g.forward_into(&se[c], true, &mut sigma[c]);
            }
            g.stokes_into(&sigma, &mut u_new);
            report.residual = rel_change(g, &u_new, &u);
            std::mem::swap(&mut u, &mut u_new);
            if self.params.fixed_point_done(&report)? {
                break;
            }
        }
        lap(&mut timing.fixed_point);
        // Velocity and gradients on the grid; E from the gradient (no extra transforms).
        let mut ug: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; len]);
        for (i, ui) in ug.iter_mut().enumerate() {
            g.inverse_into(&u[i], &mut work, ui);
        }
        let mut grad_u: [[Vec<f64>; 3]; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| vec![0.0; len]));
        for (i, row) in grad_u.iter_mut().enumerate() {
            for (k, gik) in row.iter_mut().enumerate() {
                g.inverse_derivative_into(&u[i], k, &mut work, gik);
            }
        }
        for (c, ec) in e.iter_mut().enumerate() {
            let (i, j) = SYM[c];
            ec.par_iter_mut()
                .zip(&grad_u[i][j])
                .zip(&grad_u[j][i])
                .for_each(|((e, a), b)| *e = 0.5 * (a + b));
        }
        // S:E of the converged flow: the Q equation's -2 S:E term, whatever zeta.
        closure.contract_into(&e, &mut se);
        lap(&mut timing.gradients);
        let mut nonlinear: [Vec<Complex64>; 6] =
            std::array::from_fn(|_| vec![Complex64::default(); slen]);
        let mut dq: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; len]);
        let mut vals = vec![0.0; len];
        for (c, nc) in nonlinear.iter_mut().enumerate() {
            let (i, j) = SYM[c];
            for (k, dqk) in dq.iter_mut().enumerate() {
                g.inverse_derivative_into(&q_hat[c], k, &mut work, dqk);
            }
            vals.par_iter_mut().enumerate().for_each(|(p, v)| {
                let adv = ug[0][p] * dq[0][p] + ug[1][p] * dq[1][p] + ug[2][p] * dq[2][p];
                let mut stretch = 0.0;
                for k in 0..3 {
                    stretch += grad_u[i][k][p] * q[sym_index(k, j)][p]
                        + q[sym_index(i, k)][p] * grad_u[j][k][p];
                }
                *v = -adv + stretch - 2.0 * se[c][p];
            });
            g.forward_into(&vals, true, nc);
        }
        if !all_finite(&nonlinear) {
            return Err(MeanFieldError::NonFinite("the right-hand side"));
        }
        lap(&mut timing.nonlinear);
        Ok(RhsEval {
            timing,
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
