//! Steric contacts (MODEL.md §3) as a linear complementarity problem solved by BBPGD.
//!
//! For each pair closer than `b + margin`, a constraint `alpha` between the closest points
//! `y_i`, `y_j` of the two centerlines, unit normal `n` from `j` to `i`, separation
//! `Phi = |y_i - y_j| - b`. A multiplier `lambda >= 0` pushes `i` along `+n` and `j` along
//! `-n` (equal and opposite forces; torques `(y - x) x f`). Over one step, linearised:
//!
//! ```text
//! Phi_new = Phi + dt D^T (V_free + M D lambda) = A lambda + q,
//! A = dt D^T M D (symmetric positive semi-definite),  q = Phi + dt D^T V_free,
//! 0 <= lambda  perp  A lambda + q >= 0,
//! ```
//!
//! i.e. `lambda = argmin_{lambda >= 0} (1/2) lambda.A lambda + lambda.q`, with `M` the local
//! mobility of the [`Mobility`]. Solved matrix-free by projected gradient descent with
//! Barzilai-Borwein steps (alternating the two BB formulas, as aLENS does), stopping when the
//! complementarity residual `max_alpha |min(lambda, A lambda + q)|` (a length) is below the
//! tolerance. Products with `D` go through a per-rod list of constraints in a fixed order and
//! every reduction is summed in fixed chunks, so results are bit-identical for any thread count.

use crate::geometry::{Vec3, axpy, cross, dot, scale, sub};
use crate::mobility::Mobility;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Contact solver settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactParams {
    /// Pairs closer than `b + margin` (rod lengths) get a constraint, so rods approaching within
    /// a step are caught. Default 0.1 l; must exceed the distance rods close in one step
    /// (about `2 U dt`).
    pub margin: f64,
    /// Complementarity residual tolerance (rod lengths). Default 1e-7: far below the overlap
    /// tolerance. Smaller costs iterations.
    pub tolerance: f64,
    /// Iteration cap of BBPGD. Default 2000.
    pub max_iterations: usize,
    /// Largest overlap (rod lengths) allowed after a step before the run stops. Default 5e-3 l
    /// (2.5% of the diameter). The linearised problem leaves overlaps of order
    /// `(dt w)^2 l / 2` for rods turning at rate `w`, corrected at the next step rather than
    /// accumulated: 1.6e-3 l was the largest in 1000 steps at nu = 5, dt = 0.002.
    pub overlap_tolerance: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            margin: 0.1,
            tolerance: 1e-7,
            max_iterations: 2000,
            overlap_tolerance: 5e-3,
        }
    }
}

/// One constraint between rods `i < j`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Constraint {
    /// First rod.
    pub i: u32,
    /// Second rod.
    pub j: u32,
    /// `y_i - x_i`.
    pub ri: Vec3,
    /// `y_j - x_j` (in `i`'s periodic image of `j`).
    pub rj: Vec3,
    /// Unit normal from `j` to `i`.
    pub n: Vec3,
    /// Separation `|y_i - y_j| - b`.
    pub phi: f64,
}

/// What the solver did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactReport {
    /// Constraints in the problem.
    pub constraints: usize,
    /// Constraints with `lambda > 0`.
    pub active: usize,
    /// BBPGD iterations.
    pub iterations: usize,
    /// Final complementarity residual (rod lengths).
    pub residual: f64,
    /// Largest overlap predicted by the linearised problem after the step (rod lengths).
    pub predicted_overlap: f64,
}

/// Contact solver failures.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ContactError {
    /// The iteration cap was reached.
    #[error(
        "contact solver (BBPGD) did not converge: residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:.1e})"
    )]
    NoConvergence {
        /// Iterations done.
        iterations: usize,
        /// Residual reached.
        residual: f64,
        /// Tolerance asked for.
        tolerance: f64,
    },
    /// A non-finite value appeared.
    #[error("contact solver produced a non-finite value at iteration {0}")]
    NonFinite(usize),
}

const CHUNK: usize = 4096;

/// Sum of `f(k)` for `k` in `0..n`, in fixed chunks: the same bits for any thread count.
pub fn det_sum(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(&f).sum())
        .collect();
    partial.iter().sum()
}

/// Maximum of `f(k)` (exact in any order).
fn par_max(n: usize, f: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    (0..n)
        .into_par_iter()
        .map(f)
        .reduce(|| f64::NEG_INFINITY, f64::max)
}

/// The BBPGD contact solver; holds only scratch memory.
#[derive(Debug, Default)]
pub struct ContactSolver {
    /// `rod_start[r]..rod_start[r + 1]` index `rod_entries` for rod `r`.
    rod_start: Vec<usize>,
    /// (constraint, +1 for the `i` side / -1 for the `j` side), constraint order.
    rod_entries: Vec<(u32, f64)>,
}

impl ContactSolver {
    /// Generalised force (force, torque) on each rod from multipliers `lambda`.
    pub fn forces(&self, cons: &[Constraint], lambda: &[f64], nrods: usize) -> Vec<(Vec3, Vec3)> {
        (0..nrods)
            .into_par_iter()
            .map(|r| {
                let mut f = [0.0; 3];
                let mut t = [0.0; 3];
                for &(a, side) in &self.rod_entries[self.rod_start[r]..self.rod_start[r + 1]] {
                    let c = &cons[a as usize];
                    let fa = scale(side * lambda[a as usize], c.n);
                    let arm = if side > 0.0 { c.ri } else { c.rj };
                    f = axpy(f, 1.0, fa);
                    t = axpy(t, 1.0, cross(arm, fa));
                }
                (f, t)
            })
            .collect()
    }

    fn index(&mut self, cons: &[Constraint], nrods: usize) {
        self.rod_start.clear();
        self.rod_start.resize(nrods + 1, 0);
        for c in cons {
            self.rod_start[c.i as usize + 1] += 1;
            self.rod_start[c.j as usize + 1] += 1;
        }
        for r in 0..nrods {
            self.rod_start[r + 1] += self.rod_start[r];
        }
        let mut next = self.rod_start.clone();
        self.rod_entries.clear();
        self.rod_entries.resize(2 * cons.len(), (0, 0.0));
        for (a, c) in cons.iter().enumerate() {
            for (r, side) in [(c.i, 1.0), (c.j, -1.0)] {
                self.rod_entries[next[r as usize]] = (a as u32, side);
                next[r as usize] += 1;
            }
        }
    }

    /// Rate of change of each constraint's separation for rod velocities `(v, w)`: `D^T V`.
    fn rates(cons: &[Constraint], v: &[Vec3], w: &[Vec3], out: &mut [f64]) {
        out.par_iter_mut().zip(cons).for_each(|(o, c)| {
            let (i, j) = (c.i as usize, c.j as usize);
            let vi = axpy(v[i], 1.0, cross(w[i], c.ri));
            let vj = axpy(v[j], 1.0, cross(w[j], c.rj));
            *o = dot(c.n, sub(vi, vj));
        });
    }

    /// `A lambda = dt D^T M D lambda`.
    fn apply(
        &self,
        cons: &[Constraint],
        p: &[Vec3],
        mob: &dyn Mobility,
        dt: f64,
        lambda: &[f64],
        out: &mut [f64],
    ) {
        let ft = self.forces(cons, lambda, p.len());
        let (v, w): (Vec<Vec3>, Vec<Vec3>) = ft
            .par_iter()
            .zip(p)
            .map(|((f, t), p)| mob.local(*p, *f, *t))
            .unzip();
        Self::rates(cons, &v, &w, out);
        out.par_iter_mut().for_each(|o| *o *= dt);
    }

    /// Solve for the multipliers given the free velocities; returns `lambda` and a report.
    pub fn solve(
        &mut self,
        cons: &[Constraint],
        p: &[Vec3],
        free_v: &[Vec3],
        free_w: &[Vec3],
        mob: &dyn Mobility,
        dt: f64,
        params: &ContactParams,
    ) -> Result<(Vec<f64>, ContactReport), ContactError> {
        let m = cons.len();
        if m == 0 {
            return Ok((Vec::new(), ContactReport::default()));
        }
        self.index(cons, p.len());
        let mut q = vec![0.0; m];
        Self::rates(cons, free_v, free_w, &mut q);
        q.par_iter_mut()
            .zip(cons)
            .for_each(|(q, c)| *q = c.phi + dt * *q);
        let residual_of = |lam: &[f64], g: &[f64]| par_max(m, |k| lam[k].min(g[k]).abs());
        let mut lam = vec![0.0; m];
        let mut g = q.clone(); // gradient A lambda + q at lambda = 0
        let mut res = residual_of(&lam, &g);
        let mut ag = vec![0.0; m];
        let mut iterations = 0;
        if res > params.tolerance {
            // First step: exact line search along the projected-free gradient.
            let gp: Vec<f64> = (0..m)
                .map(|k| {
                    if lam[k] > 0.0 || g[k] < 0.0 {
                        g[k]
                    } else {
                        0.0
                    }
                })
                .collect();
            self.apply(cons, p, mob, dt, &gp, &mut ag);
            let gg = det_sum(m, |k| gp[k] * gp[k]);
            let gag = det_sum(m, |k| gp[k] * ag[k]);
            let mut alpha = if gag > 0.0 { gg / gag } else { 1.0 };
            let mut lam_new = vec![0.0; m];
            let mut g_new = vec![0.0; m];
            loop {
                iterations += 1;
                lam_new
                    .par_iter_mut()
                    .enumerate()
                    .for_each(|(k, l)| *l = (lam[k] - alpha * g[k]).max(0.0));
                self.apply(cons, p, mob, dt, &lam_new, &mut g_new);
                g_new.par_iter_mut().zip(&q).for_each(|(g, q)| *g += q);
                res = residual_of(&lam_new, &g_new);
                if !res.is_finite() {
                    return Err(ContactError::NonFinite(iterations));
                }
                let ss = det_sum(m, |k| (lam_new[k] - lam[k]).powi(2));
                let sy = det_sum(m, |k| (lam_new[k] - lam[k]) * (g_new[k] - g[k]));
                let yy = det_sum(m, |k| (g_new[k] - g[k]).powi(2));
                std::mem::swap(&mut lam, &mut lam_new);
                std::mem::swap(&mut g, &mut g_new);
                if res <= params.tolerance || ss == 0.0 {
                    break;
                }
                if iterations >= params.max_iterations {
                    return Err(ContactError::NoConvergence {
                        iterations,
                        residual: res,
                        tolerance: params.tolerance,
                    });
                }
                alpha = if sy <= 0.0 {
                    alpha
                } else if iterations % 2 == 1 {
                    ss / sy
                } else {
                    sy / yy
                };
            }
        }
        let active = lam.iter().filter(|&&l| l > 0.0).count();
        let predicted_overlap = par_max(m, |k| -g[k]).max(0.0);
        Ok((
            lam,
            ContactReport {
                constraints: m,
                active,
                iterations,
                residual: res,
                predicted_overlap,
            },
        ))
    }
}
