//! Steric contacts (docs/MODEL.md §3) as a linear complementarity problem solved by BBPGD.
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
//! tolerance. BBPGD is fast on most problems but stalls on some dense ones (nu = 5: its
//! residual creeping from 6e-6 to 5e-6 over 1 500 iterations): when its best residual has not
//! halved in [`ContactParams::stall_iterations`] iterations, the solve goes on from where
//! BBPGD stopped with Nesterov's accelerated projected gradient (APGD: a fixed step `1/L` from
//! a power-iteration estimate of `A`'s largest eigenvalue, restarted where the momentum points
//! uphill, as O'Donoghue and Candes do), whose convergence does not depend on the spectrum's
//! spread the way BB's does. Products with `D` go through a per-rod list of constraints in a fixed order and
//! every reduction is summed in fixed chunks, so results are bit-identical for any thread count.

use crate::hydro::mobility::Mobility;
use crate::model::geometry::{Vec3, axpy, cross, dot, scale, sub};
use crate::parallel::comm::SingleProcess;
use crate::parallel::halo::Halo;
use crate::parallel::part::Share;
use motile_analysis::params::{InvalidParameter, check_range};
use motile_analysis::reduce::{chunk_partials, det_sum};
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
    /// Iteration cap of a solve (BBPGD and the APGD it may hand over to, together).
    /// Default 2000.
    pub max_iterations: usize,
    /// Iterations without BBPGD's best residual halving after which the solve goes on with APGD.
    /// Default 200 (BBPGD converges in 60-600 iterations on the nu = 5 problems; where it
    /// stalls, its residual falls by less than 2 in 1 500). 0: APGD after BBPGD's first step.
    pub stall_iterations: usize,
    /// Largest overlap (rod lengths) allowed after a step before the run stops. Default 5e-3 l
    /// (2.5% of the diameter). The linearised problem leaves overlaps of order
    /// `(dt w)^2 l / 2` for rods turning at rate `w`, corrected at the next step rather than
    /// accumulated: 1.6e-3 l was the largest in 1000 steps at nu = 5, dt = 0.002.
    pub overlap_tolerance: f64,
}

impl ContactParams {
    /// Check every field (the error names it, its value, the allowed range and the unit).
    /// `margin` must also exceed `2.5 U dt` for the run's step: checked where `dt` is known.
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        check_range("margin", self.margin, 0.0, 1.0, true, "rod lengths")?;
        check_range("tolerance", self.tolerance, 0.0, 1e-2, true, "rod lengths")?;
        check_range(
            "max_iterations",
            self.max_iterations as f64,
            1.0,
            1e7,
            false,
            "iterations",
        )?;
        check_range(
            "stall_iterations",
            self.stall_iterations as f64,
            0.0,
            1e7,
            false,
            "iterations",
        )?;
        check_range(
            "overlap_tolerance",
            self.overlap_tolerance,
            0.0,
            0.1,
            true,
            "rod lengths",
        )
    }
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            margin: 0.1,
            tolerance: 1e-7,
            max_iterations: 2000,
            stall_iterations: STALL_ITERATIONS,
            overlap_tolerance: 5e-3,
        }
    }
}

/// Contact multipliers by rod pair `(i, j)`, `i < j`, sorted by pair: a solve's warm start.
pub type WarmStart = Vec<((u32, u32), f64)>;

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
    /// Iterations (BBPGD and APGD together).
    pub iterations: usize,
    /// Of these, the iterations of APGD after BBPGD stalled (0 where BBPGD converged).
    #[serde(default)]
    pub accelerated: usize,
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
        "contact solver (BBPGD, then APGD where it stalls) did not converge: residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:.1e})"
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

/// `[max |min(lam_new, g_new)|, |s|^2, s.y, |y|^2]` with `s = lam_new - lam`, `y = g_new - g`,
/// summed in fixed chunks (the maximum is exact in any order).
fn fused_stats(lam: &[f64], lam_new: &[f64], g: &[f64], g_new: &[f64]) -> [f64; 4] {
    let partial = chunk_partials(lam.len(), |chunk| {
        let mut a = [0.0f64; 4];
        for k in chunk {
            let (s, y) = (lam_new[k] - lam[k], g_new[k] - g[k]);
            a[0] = a[0].max(lam_new[k].min(g_new[k]).abs());
            a[1] += s * s;
            a[2] += s * y;
            a[3] += y * y;
        }
        a
    });
    partial.iter().fold([0.0; 4], |acc, a| {
        [
            acc[0].max(a[0]),
            acc[1] + a[1],
            acc[2] + a[2],
            acc[3] + a[3],
        ]
    })
}

/// The default of [`ContactParams::stall_iterations`].
pub const STALL_ITERATIONS: usize = 200;

/// Power iterations for APGD's estimate of `A`'s largest eigenvalue.
pub const POWER_ITERATIONS: usize = 30;

/// APGD's Lipschitz constant over the power-iteration estimate (which approaches the largest
/// eigenvalue from below): its step `1/L` stays within the `1/lambda_max` that descent needs.
pub(crate) const LIPSCHITZ_MARGIN: f64 = 1.2;

/// Whether BBPGD has stalled: its best residual has not halved in `patience` iterations.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stall {
    /// The iteration of the last halving.
    since: usize,
    /// The residual then.
    residual: f64,
    /// [`ContactParams::stall_iterations`].
    patience: usize,
}

impl Stall {
    /// Watching from the start's residual.
    pub(crate) fn new(residual: f64, params: &ContactParams) -> Self {
        Self {
            since: 0,
            residual,
            patience: params.stall_iterations,
        }
    }

    /// After iteration `iterations` with residual `res`: whether BBPGD has stalled.
    pub(crate) fn stalled(&mut self, iterations: usize, res: f64) -> bool {
        if res < 0.5 * self.residual {
            self.since = iterations;
            self.residual = res;
        }
        iterations - self.since >= self.patience
    }
}

/// Nesterov's momentum for APGD: `theta` from 1, restarted where the step went uphill.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Momentum {
    theta: f64,
}

impl Momentum {
    /// From rest.
    pub(crate) fn new() -> Self {
        Self { theta: 1.0 }
    }

    /// The extrapolation weight `beta` of the next point `y = x_new + beta (x_new - x)`, given
    /// `uphill = (y - x_new).(x_new - x)` of the step just taken: 0 and a restart where it is
    /// positive.
    pub(crate) fn beta(&mut self, uphill: f64) -> f64 {
        if uphill > 0.0 {
            self.theta = 1.0;
            return 0.0;
        }
        let t = self.theta;
        let next = 0.5 * (-t * t + t * (t * t + 4.0).sqrt());
        self.theta = next;
        t * (1.0 - t) / (t * t + next)
    }
}

/// After BBPGD iteration `iterations` with residual `res` and the Barzilai-Borwein products
/// `[s.s, s.y, y.y]`: `None` when done (converged, or no move), else the next step length
/// (the two BB formulas alternating; the last step where `s.y <= 0`), or the error at the cap.
/// The CPU solver's and the device solver's.
pub(crate) fn next_step(
    alpha: f64,
    iterations: usize,
    res: f64,
    [ss, sy, yy]: [f64; 3],
    params: &ContactParams,
) -> Result<Option<f64>, ContactError> {
    if res <= params.tolerance || ss == 0.0 {
        return Ok(None);
    }
    if iterations >= params.max_iterations {
        return Err(ContactError::NoConvergence {
            iterations,
            residual: res,
            tolerance: params.tolerance,
        });
    }
    Ok(Some(if sy <= 0.0 {
        alpha
    } else if iterations % 2 == 1 {
        ss / sy
    } else {
        sy / yy
    }))
}

/// Maximum of `f(k)` (exact in any order).
fn par_max(n: usize, f: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    (0..n)
        .into_par_iter()
        .map(f)
        .reduce(|| f64::NEG_INFINITY, f64::max)
}

/// One contact problem (docs/MODEL.md §3): the constraints, the rods' axes, the velocities the
/// rods would have without contacts, the local mobility that turns contact forces into
/// velocities, and the time step.
#[derive(Clone, Copy, Debug)]
pub struct ContactProblem<'a> {
    /// The constraints.
    pub cons: &'a [Constraint],
    /// Each rod's axis.
    pub p: &'a [Vec3],
    /// Velocities without contacts.
    pub free_v: &'a [Vec3],
    /// Angular velocities without contacts.
    pub free_w: &'a [Vec3],
    /// The local mobility.
    pub mobility: &'a dyn Mobility,
    /// The time step.
    pub dt: f64,
}

/// The BBPGD contact solver; holds only scratch memory.
#[derive(Debug, Default)]
pub struct ContactSolver {
    /// `rod_start[r]..rod_start[r + 1]` index `rod_entries` for rod `r`.
    rod_start: Vec<usize>,
    /// (constraint, +1 for the `i` side / -1 for the `j` side), constraint order.
    rod_entries: Vec<(u32, f64)>,
    /// Scratch: each rod's velocity response `(v, w)` in [`Self::apply`].
    vel: Vec<(Vec3, Vec3)>,
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

    /// `out = A lambda + shift = dt D^T M D lambda + shift` (`shift` may be empty for zero).
    /// Forces and the local mobility are fused in one pass over rods into reused buffers.
    fn apply(
        &mut self,
        share: Share<'_>,
        problem: &ContactProblem<'_>,
        lambda: &[f64],
        shift: &[f64],
        out: &mut [f64],
    ) {
        let (cons, p, mob, dt) = (problem.cons, problem.p, problem.mobility, problem.dt);
        let n = p.len();
        self.vel.resize(n, ([0.0; 3], [0.0; 3]));
        let (start, entries) = (&self.rod_start, &self.rod_entries);
        let force_on = |r: usize| {
            let mut f = [0.0; 3];
            let mut t = [0.0; 3];
            for &(a, side) in &entries[start[r]..start[r + 1]] {
                let c = &cons[a as usize];
                let fa = scale(side * lambda[a as usize], c.n);
                let arm = if side > 0.0 { c.ri } else { c.rj };
                f = axpy(f, 1.0, fa);
                t = axpy(t, 1.0, cross(arm, fa));
            }
            (f, t)
        };
        if share.comm.size() == 1 {
            self.vel.par_iter_mut().enumerate().for_each(|(r, vw)| {
                let (f, t) = force_on(r);
                *vw = mob.local(p[r], f, t);
            });
        } else {
            // Forces from this rank's constraints, the copies' added into their owners, the
            // owners' velocities copied back.
            let mut ft: Vec<[f64; 6]> = (0..n)
                .into_par_iter()
                .map(|r| {
                    let (f, t) = force_on(r);
                    [f[0], f[1], f[2], t[0], t[1], t[2]]
                })
                .collect();
            share.halo.accumulate(share.comm, &mut ft);
            ft.par_iter_mut().enumerate().for_each(|(r, x)| {
                let (v, w) = mob.local(p[r], [x[0], x[1], x[2]], [x[3], x[4], x[5]]);
                *x = [v[0], v[1], v[2], w[0], w[1], w[2]];
            });
            share.halo.refresh(share.comm, &mut ft);
            self.vel
                .par_iter_mut()
                .zip(&ft)
                .for_each(|(vw, x)| *vw = ([x[0], x[1], x[2]], [x[3], x[4], x[5]]));
        }
        let vel = &self.vel;
        out.par_iter_mut()
            .zip(cons)
            .enumerate()
            .for_each(|(k, (o, c))| {
                let (i, j) = (c.i as usize, c.j as usize);
                let vi = axpy(vel[i].0, 1.0, cross(vel[i].1, c.ri));
                let vj = axpy(vel[j].0, 1.0, cross(vel[j].1, c.rj));
                let s = if shift.is_empty() { 0.0 } else { shift[k] };
                *o = dt * dot(c.n, sub(vi, vj)) + s;
            });
    }

    /// Solve for the multipliers given the free velocities; returns `lambda` and a report.
    pub fn solve(
        &mut self,
        problem: ContactProblem<'_>,
        params: &ContactParams,
        initial: &[f64],
    ) -> Result<(Vec<f64>, ContactReport), ContactError> {
        let halo = Halo::none(problem.p.len());
        let share = Share {
            comm: &SingleProcess,
            halo: &halo,
        };
        self.solve_shared(share, problem, params, initial)
    }

    /// [`Self::solve`] for one rank's part of a problem shared by several (collective): `cons`
    /// are this rank's constraints over its local rods (own rods and copies, numbered as in
    /// `share.halo`); `free_v`, `free_w` hold the owners' values on the copies too. Sums and
    /// maxima are over all ranks, so every rank takes the same iterations and returns its own
    /// constraints' multipliers; the report is the whole problem's.
    pub fn solve_shared(
        &mut self,
        share: Share<'_>,
        problem: ContactProblem<'_>,
        params: &ContactParams,
        initial: &[f64],
    ) -> Result<(Vec<f64>, ContactReport), ContactError> {
        let m = problem.cons.len();
        let total = global_sum(share, m as f64);
        if total == 0.0 {
            return Ok((Vec::new(), ContactReport::default()));
        }
        assert!(
            initial.is_empty() || initial.len() == m,
            "initial guess has the wrong length"
        );
        self.index(problem.cons, problem.p.len());
        let q = Self::shifts(&problem);
        let (lam, g) = self.start(share, &problem, initial, &q);
        let solved = self.iterate(share, &problem, (lam, g, &q), params)?;
        let (lam, g) = (solved.lam, solved.g);
        let active = global_sum(share, lam.iter().filter(|&&l| l > 0.0).count() as f64) as usize;
        let predicted_overlap = global_max(share, par_max(m, |k| -g[k])).max(0.0);
        Ok((
            lam,
            ContactReport {
                constraints: total as usize,
                active,
                iterations: solved.iterations,
                accelerated: solved.accelerated,
                residual: solved.residual,
                predicted_overlap,
            },
        ))
    }

    /// The gradient's shift: each constraint's gap plus `dt` times its rate of approach under
    /// the velocities without contacts.
    fn shifts(problem: &ContactProblem<'_>) -> Vec<f64> {
        let (cons, dt) = (problem.cons, problem.dt);
        let mut q = vec![0.0; cons.len()];
        Self::rates(cons, problem.free_v, problem.free_w, &mut q);
        q.par_iter_mut()
            .zip(cons)
            .for_each(|(q, c)| *q = c.phi + dt * *q);
        q
    }

    /// The multipliers a solve starts from and their gradient: `initial` projected onto
    /// `lambda >= 0` where any rank has a positive one, else zero (whose gradient is `q`).
    fn start(
        &mut self,
        share: Share<'_>,
        problem: &ContactProblem<'_>,
        initial: &[f64],
        q: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let m = q.len();
        let positive = if initial.iter().any(|&l| l > 0.0) {
            1.0
        } else {
            0.0
        };
        if global_max(share, positive) > 0.0 {
            let lam: Vec<f64> = initial.iter().map(|l| l.max(0.0)).collect();
            let mut g = vec![0.0; m];
            self.apply(share, problem, &lam, q, &mut g);
            (lam, g)
        } else {
            (vec![0.0; m], q.to_vec())
        }
    }

    /// The Barzilai-Borwein projected gradient iterations from `(lam, g)` until the residual
    /// `max_k |min(lambda_k, g_k)|` (over all ranks) meets the tolerance.
    fn iterate(
        &mut self,
        share: Share<'_>,
        problem: &ContactProblem<'_>,
        (mut lam, mut g, q): (Vec<f64>, Vec<f64>, &[f64]),
        params: &ContactParams,
    ) -> Result<Iterated, ContactError> {
        let m = q.len();
        let mut residual = global_max(share, par_max(m, |k| lam[k].min(g[k]).abs()));
        let mut iterations = 0;
        if residual <= params.tolerance {
            return Ok(Iterated {
                lam,
                g,
                iterations,
                residual,
                accelerated: 0,
            });
        }
        let mut alpha = self.first_step(share, problem, &lam, &g);
        let mut stall = Stall::new(residual, params);
        let mut lam_new = vec![0.0; m];
        let mut g_new = vec![0.0; m];
        loop {
            iterations += 1;
            lam_new
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, l)| *l = (lam[k] - alpha * g[k]).max(0.0));
            self.apply(share, problem, &lam_new, q, &mut g_new);
            // Residual and the three Barzilai-Borwein products in one fixed-chunk pass.
            let [r, ss, sy, yy] = fused_stats(&lam, &lam_new, &g, &g_new);
            let (r, [ss, sy, yy]) = if share.comm.size() == 1 {
                (r, [ss, sy, yy])
            } else {
                // One exchange for the maximum and the three sums (in rank order).
                share
                    .comm
                    .all_gather(&[r, ss, sy, yy])
                    .iter()
                    .fold((f64::NEG_INFINITY, [0.0; 3]), |(m, s), a| {
                        (m.max(a[0]), [s[0] + a[1], s[1] + a[2], s[2] + a[3]])
                    })
            };
            residual = r;
            if !residual.is_finite() {
                return Err(ContactError::NonFinite(iterations));
            }
            std::mem::swap(&mut lam, &mut lam_new);
            std::mem::swap(&mut g, &mut g_new);
            match next_step(alpha, iterations, residual, [ss, sy, yy], params)? {
                Some(a) => alpha = a,
                None => {
                    return Ok(Iterated {
                        lam,
                        g,
                        iterations,
                        residual,
                        accelerated: 0,
                    });
                }
            }
            if stall.stalled(iterations, residual) {
                return self.accelerate(share, problem, (lam, g, q), params, iterations);
            }
        }
    }

    /// APGD from `(x, gx)` where BBPGD stalled after `done` iterations, until the residual
    /// meets the tolerance (or the cap, counting `done`). The gradient at the extrapolated
    /// point follows from the two last ones (`A` is linear), so each iteration costs one
    /// product, as BBPGD's do.
    fn accelerate(
        &mut self,
        share: Share<'_>,
        problem: &ContactProblem<'_>,
        (mut x, mut gx, q): (Vec<f64>, Vec<f64>, &[f64]),
        params: &ContactParams,
        done: usize,
    ) -> Result<Iterated, ContactError> {
        let m = q.len();
        let step = 1.0 / (LIPSCHITZ_MARGIN * self.largest_eigenvalue(share, problem, m));
        let (mut y, mut gy) = (x.clone(), gx.clone());
        let (mut xn, mut gn) = (vec![0.0; m], vec![0.0; m]);
        let mut momentum = Momentum::new();
        let mut iterations = done;
        loop {
            iterations += 1;
            xn.par_iter_mut()
                .enumerate()
                .for_each(|(k, v)| *v = (y[k] - step * gy[k]).max(0.0));
            self.apply(share, problem, &xn, q, &mut gn);
            let [residual, uphill] = reduce_max_sum(share, apgd_stats(&x, &xn, &y, &gn));
            if !residual.is_finite() {
                return Err(ContactError::NonFinite(iterations));
            }
            if residual <= params.tolerance {
                return Ok(Iterated {
                    lam: xn,
                    g: gn,
                    iterations,
                    residual,
                    accelerated: iterations - done,
                });
            }
            if iterations >= params.max_iterations {
                return Err(ContactError::NoConvergence {
                    iterations,
                    residual,
                    tolerance: params.tolerance,
                });
            }
            let beta = momentum.beta(uphill);
            y.par_iter_mut()
                .zip(gy.par_iter_mut())
                .enumerate()
                .for_each(|(k, (y, gy))| {
                    *y = xn[k] + beta * (xn[k] - x[k]);
                    *gy = gn[k] + beta * (gn[k] - gx[k]);
                });
            std::mem::swap(&mut x, &mut xn);
            std::mem::swap(&mut gx, &mut gn);
        }
    }

    /// The largest eigenvalue of `A` by power iteration from the uniform vector (from below).
    fn largest_eigenvalue(
        &mut self,
        share: Share<'_>,
        problem: &ContactProblem<'_>,
        m: usize,
    ) -> f64 {
        let total = global_sum(share, m as f64);
        let mut v = vec![1.0 / total.sqrt(); m];
        let mut av = vec![0.0; m];
        let mut estimate = 0.0;
        for _ in 0..POWER_ITERATIONS {
            self.apply(share, problem, &v, &[], &mut av);
            estimate = global_sum(share, det_sum(m, |k| av[k] * av[k])).sqrt();
            if !(estimate > 0.0 && estimate.is_finite()) {
                return 1.0;
            }
            v.par_iter_mut()
                .zip(&av)
                .for_each(|(v, a)| *v = a / estimate);
        }
        estimate
    }

    /// The first step length: the exact line search along the projected-free gradient of
    /// `(lam, g)`, `gp.gp / gp.A gp` (1 where the denominator is not positive).
    fn first_step(
        &mut self,
        share: Share<'_>,
        problem: &ContactProblem<'_>,
        lam: &[f64],
        g: &[f64],
    ) -> f64 {
        let m = g.len();
        let gp: Vec<f64> = (0..m)
            .map(|k| {
                if lam[k] > 0.0 || g[k] < 0.0 {
                    g[k]
                } else {
                    0.0
                }
            })
            .collect();
        let mut ag = vec![0.0; m];
        self.apply(share, problem, &gp, &[], &mut ag);
        let gg = global_sum(share, det_sum(m, |k| gp[k] * gp[k]));
        let gag = global_sum(share, det_sum(m, |k| gp[k] * ag[k]));
        if gag > 0.0 { gg / gag } else { 1.0 }
    }
}

/// What the iterations of a solve reached.
struct Iterated {
    lam: Vec<f64>,
    g: Vec<f64>,
    iterations: usize,
    residual: f64,
    /// Of the iterations, APGD's.
    accelerated: usize,
}

/// APGD's `[max |min(x_new, g_new)|, (y - x_new).(x_new - x)]`, summed in fixed chunks.
fn apgd_stats(x: &[f64], x_new: &[f64], y: &[f64], g_new: &[f64]) -> [f64; 2] {
    let partial = chunk_partials(x.len(), |chunk| {
        let mut a = [0.0f64; 2];
        for k in chunk {
            a[0] = a[0].max(x_new[k].min(g_new[k]).abs());
            a[1] += (y[k] - x_new[k]) * (x_new[k] - x[k]);
        }
        a
    });
    partial
        .iter()
        .fold([0.0; 2], |acc, a| [acc[0].max(a[0]), acc[1] + a[1]])
}

/// `[max, sum]` over the ranks of `share` (the sum in rank order).
fn reduce_max_sum(share: Share<'_>, [max, sum]: [f64; 2]) -> [f64; 2] {
    if share.comm.size() == 1 {
        return [max, sum];
    }
    share
        .comm
        .all_gather(&[max, sum])
        .iter()
        .fold([f64::NEG_INFINITY, 0.0], |acc, a| {
            [acc[0].max(a[0]), acc[1] + a[1]]
        })
}

/// `x` summed over the ranks of `share` (in rank order).
fn global_sum(share: Share<'_>, x: f64) -> f64 {
    let mut v = [x];
    share.comm.sum(&mut v);
    v[0]
}

/// The largest `x` over the ranks of `share`.
fn global_max(share: Share<'_>, x: f64) -> f64 {
    let mut v = [x];
    share.comm.max(&mut v);
    v[0]
}
