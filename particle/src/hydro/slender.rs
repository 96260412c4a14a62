//! The slender-body mobility (`hydrodynamics = "sbt"`, docs/MODEL.md §1): the second-kind equation
//! (P4) for the force densities, solved by GMRES with the periodic RPY sum applied
//! matrix-free, then the rigid-body velocities (P2)-(P3).
//!
//! Quadrature: Gauss-Legendre on each half rod (`M/2` nodes per half, `M` even, default 4),
//! which respects the jump of the slip at `s = 0`: the discrete rod carries exactly the
//! stresslet `U l^2/(8 eta)` (docs/MODEL.md's caution; a Chebyshev rule over the whole rod would be
//! 11% too strong at M = 4) and integrates `s^2` exactly, so the discrete (P4) keeps the
//! identities behind it: zero net force and torque without contacts, for any flow.
//!
//! Rod n's own direct terms are excluded from `u_n` (the point-group exclusion of
//! [`crate::ewald::periodic`]); all periodic images, its own included, are in.
//!
//! Contacts (docs/MODEL.md §3), the splitting: the contact solver plans with the local mobility of
//! (P2)-(P3) applied to predicted velocities, namely swimming plus the previous step's flow
//! velocities (an exact free solve on the first step). Once it has the contact forces `F_n` and
//! torques `T_n`, one GMRES solve of (P4) with swimming and contact terms together gives the
//! step's velocities: the contact forces act through the full hydrodynamics (their local
//! response and the flows they induce on every other rod). Only the complementarity problem
//! sees the approximations (local mobility, one-step-old flow); the post-step overlap check
//! covers them. The solve starts from the previous step's solution, which already carries the
//! persistent contact forces; one solve per step instead of a free and a contact solve halved
//! the step's cost (BENCHMARKS.md).

use crate::ewald::periodic::{PeriodicStokes, RpyGeometry, SumError};
use crate::ewald::shared::{RankShare, SharedEwald};
use crate::hydro::gmres::{GmresInfo, GmresParams, LinOp, gmres_shared};
use crate::hydro::mobility::{
    ForceDensity, HydroReport, LocalDrag, Mobility, MobilityError, MobilityState, ResidentMobility,
    RodVelocities, SharedMobility,
};
use crate::hydro::sum::FlowSum;
use crate::model::geometry::{Vec3, cross, dot};
use crate::model::rods::RodSet;
use crate::model::units::{DEFAULT_DIAMETER, ROD_LENGTH, SWIM_SPEED, check_diameter, eta};
use crate::parallel::comm::{Comm, SingleProcess};
use crate::parallel::part::Part;
use motile_analysis::params::{InvalidParameter, check_range};
use motile_analysis::quadrature::gauss_legendre;
use rayon::prelude::*;
use std::time::Instant;

// Without the `gpu` feature, `slender/device_off.rs`: no solve on a device, nothing kept there.
#[cfg_attr(not(feature = "gpu"), path = "slender/device_off.rs")]
mod device;

/// Settings of the slender-body model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlenderParams {
    /// Rod diameter `b` (rod lengths), which sets `eta = ln(2l/b)/(4 pi mu)` in (P2)-(P4).
    /// Default `l/5`.
    pub diameter: f64,
    /// Quadrature nodes per rod, even (Gauss-Legendre on each half). Default 4.
    pub quadrature_points: usize,
    /// RPY radius `a`. Default `(sqrt 3 / 2)(b / 2)` ([`default_rpy_radius`]).
    pub rpy_radius: f64,
    /// GMRES settings (defaults: [`GmresParams::default`]).
    pub gmres: GmresParams,
}

impl Default for SlenderParams {
    fn default() -> Self {
        Self::for_diameter(DEFAULT_DIAMETER)
    }
}

impl SlenderParams {
    /// The defaults for rods of diameter `b`: the RPY radius follows `b`.
    pub fn for_diameter(diameter: f64) -> Self {
        Self {
            diameter,
            quadrature_points: 4,
            rpy_radius: default_rpy_radius(diameter),
            gmres: GmresParams::default(),
        }
    }
}

impl SlenderParams {
    /// Check every field, GMRES's as `gmres.NAME` (the error names it, its value, the allowed
    /// range and the unit).
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        check_diameter(self.diameter)?;
        check_range("rpy_radius", self.rpy_radius, 0.0, 0.5, true, "rod lengths")?;
        let q = self.quadrature_points;
        if !(2..=64).contains(&q) || q % 2 == 1 {
            return Err(InvalidParameter {
                name: "quadrature_points".into(),
                problem: format!("{q} must be even and in [2, 64] (nodes per rod)"),
            });
        }
        self.gmres.validate().map_err(|e| e.in_table("gmres"))
    }
}

/// `a = (sqrt 3 / 2)(b / 2)` for rods of diameter `b`.
pub fn default_rpy_radius(diameter: f64) -> f64 {
    3f64.sqrt() / 2.0 * diameter / 2.0
}

/// Nodes and weights of Gauss-Legendre on each half of `[-l/2, l/2]`, `m` nodes in all.
pub fn half_rod_rule(m: usize, l: f64) -> (Vec<f64>, Vec<f64>) {
    assert!(
        m >= 2 && m.is_multiple_of(2),
        "quadrature points must be even and >= 2"
    );
    let (x, w) = gauss_legendre(m / 2);
    let h = l / 4.0;
    let mut s = Vec::with_capacity(m);
    let mut ws = Vec::with_capacity(m);
    for centre in [-h, h] {
        for (xi, wi) in x.iter().zip(&w) {
            s.push(centre + h * xi);
            ws.push(h * wi);
        }
    }
    (s, ws)
}

/// The slender-body mobility; owns the periodic sum, the quadrature and the warm starts.
#[derive(Debug)]
pub struct SlenderBody {
    /// Settings.
    pub params: SlenderParams,
    sum: Box<dyn FlowSum>,
    /// The sum shared among ranks, when this mobility runs on one rank's part of a box.
    shared: Option<SharedEwald>,
    s: Vec<f64>,
    w: Vec<f64>,
    /// The last solution of (P4) (own rods on a rank): the next solve's warm start.
    warm_free: Vec<f64>,
    density: Vec<Vec3>,
    report: HydroReport,
    local: LocalDrag,
    /// Flow velocities `([u]_l / l, w)` of the last solve (own rods on a rank): the next
    /// step's prediction.
    flow: Vec<(Vec3, Vec3)>,
    /// Whether this step's prediction was an exact free solve.
    predicted_exactly: bool,
    /// (P4) on its sum's device: the kernels (opened at the first solve there) and what
    /// resident steps keep there.
    device: crate::hydro::gpu::SlenderState,
}

/// Where (P4)'s sums run.
enum P4Sum<'a> {
    /// One process: every rod is in `points`.
    One(&'a mut dyn PeriodicStokes),
    /// One rank's part of a shared box: `points` are the own rods' nodes, then the copies';
    /// node pairs within `reach` enter the real-space sum.
    Shared {
        sum: &'a mut SharedEwald,
        part: Part<'a>,
        reach: f64,
    },
}

/// The operator of (P4) on the force densities of the own rods (flattened
/// `[rod][node][xyz]`; on one process, all rods).
struct P4<'a> {
    sum: P4Sum<'a>,
    geometry: RpyGeometry,
    /// Nodes of every local rod (own rods first).
    points: &'a [Vec3],
    /// Axes of every local rod.
    p: &'a [Vec3],
    /// Own rods (the unknowns' rods).
    owned: usize,
    s: &'a [f64],
    w: &'a [f64],
    /// `eta` of the rods' diameter.
    eta: f64,
    seconds: f64,
    /// The sums' accuracy, folded as they run.
    accuracy: HydroReport,
    /// The last `(f, u)` computed: GMRES's final true-residual product is at the solution,
    /// so the velocities reuse it instead of summing again.
    cache: Option<(Vec<f64>, Vec<Vec3>)>,
}

impl P4<'_> {
    /// `u` at every own node from the own rods' force density `f` (flattened; on ranks
    /// collective: the copies' densities come from their owners).
    fn flow(&mut self, f: &[f64]) -> Result<Vec<Vec3>, SumError> {
        let hit = matches!(&self.cache, Some((cf, _)) if cf.as_slice() == f);
        let hit = match &self.sum {
            P4Sum::One(_) => hit,
            // Every rank must take the same branch: a rank that skipped the sum would leave
            // the others waiting in its exchanges.
            P4Sum::Shared { part, .. } => {
                let mut miss = [if hit { 0.0 } else { 1.0 }];
                part.comm.max(&mut miss);
                miss[0] == 0.0
            }
        };
        if hit && let Some((_, cu)) = &self.cache {
            return Ok(cu.clone());
        }
        let m = self.s.len();
        let weighted = |f: &[f64]| -> Vec<Vec3> {
            f.par_chunks_exact(3)
                .enumerate()
                .map(|(k, c)| {
                    let wk = self.w[k % m];
                    [c[0] * wk, c[1] * wk, c[2] * wk]
                })
                .collect()
        };
        let t = Instant::now();
        let (u, report) = match &mut self.sum {
            P4Sum::One(sum) => {
                let forces = weighted(f);
                let u = sum.rpy(&self.geometry, self.points, &forces)?;
                (u, sum.last_report())
            }
            P4Sum::Shared { sum, part, reach } => {
                let width = 3 * m;
                let mut full = vec![0.0; self.points.len() * 3];
                full[..f.len()].copy_from_slice(f);
                part.halo.refresh_rows(part.comm, &mut full, width);
                let counts = RankShare {
                    owned: self.owned * m,
                    total: part.total * m,
                    reach: *reach,
                };
                let u = sum.rpy(
                    part.comm,
                    counts,
                    &self.geometry,
                    self.points,
                    &weighted(&full),
                )?;
                (u, sum.last_report())
            }
        };
        self.seconds += t.elapsed().as_secs_f64();
        self.accuracy.add_sum(report);
        self.cache = Some((f.to_vec(), u.clone()));
        Ok(u)
    }
}

/// `[u]_l` and `[s u]_l` of one rod's node values.
pub(crate) fn moments(u: &[Vec3], s: &[f64], w: &[f64]) -> (Vec3, Vec3) {
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    for ((uj, sj), wj) in u.iter().zip(s).zip(w) {
        for d in 0..3 {
            a[d] += wj * uj[d];
            b[d] += wj * sj * uj[d];
        }
    }
    (a, b)
}

impl LinOp for P4<'_> {
    type Error = SumError;

    fn dim(&self) -> usize {
        3 * self.s.len() * self.owned
    }

    fn apply(&mut self, x: &[f64], out: &mut [f64]) -> Result<(), SumError> {
        let u = self.flow(x)?;
        let m = self.s.len();
        let (s, w, p) = (self.s, self.w, self.p);
        let e = self.eta;
        let l = ROD_LENGTH;
        out.par_chunks_exact_mut(3 * m)
            .zip(x.par_chunks_exact(3 * m))
            .zip(u.par_chunks_exact(m))
            .enumerate()
            .for_each(|(n, ((o, f), un))| {
                let pn = p[n];
                let (ubar, su) = moments(un, s, w);
                let half = |v: Vec3| {
                    let c = 0.5 * dot(pn, v);
                    [v[0] - c * pn[0], v[1] - c * pn[1], v[2] - c * pn[2]]
                };
                let perp = |v: Vec3| {
                    let c = dot(pn, v);
                    [v[0] - c * pn[0], v[1] - c * pn[1], v[2] - c * pn[2]]
                };
                let hb = half(ubar);
                let ps = perp(su);
                for j in 0..m {
                    let hj = half(un[j]);
                    let c = 12.0 * s[j] / (e * l * l * l);
                    for d in 0..3 {
                        o[3 * j + d] = f[3 * j + d] + hj[d] / e - hb[d] / (e * l) - c * ps[d];
                    }
                }
            });
        Ok(())
    }
}

impl SlenderBody {
    /// A slender-body mobility on the given periodic sum.
    pub fn new(params: SlenderParams, sum: Box<dyn FlowSum>) -> Self {
        let (s, w) = half_rod_rule(params.quadrature_points, ROD_LENGTH);
        Self {
            params,
            sum,
            shared: None,
            s,
            w,
            warm_free: Vec::new(),
            density: Vec::new(),
            report: HydroReport::default(),
            local: LocalDrag::new(params.diameter),
            flow: Vec::new(),
            predicted_exactly: false,
            device: crate::hydro::gpu::SlenderState::default(),
        }
    }

    /// Node positions `x_n + s_j p_n`.
    pub fn node_positions(&self, rods: &RodSet, p: &[Vec3]) -> Vec<Vec3> {
        node_positions(&rods.x, p, &self.s)
    }

    /// Solve (P4) with right-hand side `rhs` (the own rods') from the warm start `x`; returns
    /// the GMRES info and the flow at the own nodes for the solution. With `part`, on one
    /// rank's part of a shared box (collective).
    fn solve(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        (rhs, x): (&[f64], &mut Vec<f64>),
        stage: &'static str,
        part: Option<Part<'_>>,
    ) -> Result<(GmresInfo, Vec<Vec3>), MobilityError> {
        let points = self.node_positions(rods, p);
        if x.len() != rhs.len() {
            *x = rhs.to_vec();
        }
        if part.is_none()
            && let Some(done) = self.solve_resident(rods.box_length, &points, p, rhs, x, stage)
        {
            return done;
        }
        let (sum, comm, owned): (P4Sum<'_>, &dyn Comm, usize) = match part {
            None => (P4Sum::One(self.sum.as_mut()), &SingleProcess, rods.len()),
            Some(part) => {
                let sum = self
                    .shared
                    .as_mut()
                    .ok_or(MobilityError::NotShared("sbt"))?;
                // Copies reach `part.reach` beyond the slab from their centres; nodes lie
                // within half a rod of theirs.
                let reach = part.reach - ROD_LENGTH;
                (
                    P4Sum::Shared { sum, part, reach },
                    part.comm,
                    part.halo.owned,
                )
            }
        };
        let mut op = P4 {
            sum,
            owned,
            geometry: RpyGeometry {
                box_length: rods.box_length,
                radius: self.params.rpy_radius,
                group: self.s.len(),
            },
            points: &points,
            p,
            s: &self.s,
            w: &self.w,
            eta: eta(self.params.diameter),
            seconds: 0.0,
            accuracy: HydroReport::default(),
            cache: None,
        };
        let info = gmres_shared(comm, &mut op, rhs, x, &self.params.gmres)
            .map_err(|source| MobilityError::Gmres { stage, source })?;
        let u = op.flow(x)?;
        let (accuracy, seconds) = (op.accuracy, op.seconds);
        self.fold_sums(&accuracy, seconds);
        Ok((info, u))
    }

    /// A solve's sums (`accuracy`, `seconds`) into the step's report.
    fn fold_sums(&mut self, acc: &HydroReport, seconds: f64) {
        self.report.seconds_sums += seconds;
        if acc.sums > 0 {
            self.report.sum_tolerance_met =
                acc.sum_tolerance_met && (self.report.sums == 0 || self.report.sum_tolerance_met);
            self.report.sum_error_ratio = self.report.sum_error_ratio.max(acc.sum_error_ratio);
            self.report.sum_level = acc.sum_level;
        }
        self.report.sums += acc.sums;
    }

    /// Rigid-body velocities (P2)-(P3) from the flow at the nodes, without the swimming and
    /// contact terms ([`flow_velocities`]).
    fn flow_velocities(&self, p: &[Vec3], u: &[Vec3]) -> Vec<(Vec3, Vec3)> {
        flow_velocities(p, u, (&self.s, &self.w))
    }
}

/// Rigid-body velocities (P2)-(P3) of rods with axes `p` from the flow `u` at their nodes
/// (`M` per rod, the rule `(s, w)`), without the swimming and contact terms:
/// `v = [u]_l / l`, `w = p x (12/l^3)(I - pp)[s u]_l`.
pub(crate) fn flow_velocities(
    p: &[Vec3],
    u: &[Vec3],
    (s, w): (&[f64], &[f64]),
) -> Vec<(Vec3, Vec3)> {
    let m = s.len();
    let l = ROD_LENGTH;
    u.par_chunks_exact(m)
        .zip(p)
        .map(|(un, pn)| {
            let (ubar, su) = moments(un, s, w);
            let c = dot(*pn, su);
            let pdot = [0, 1, 2].map(|d| 12.0 / (l * l * l) * (su[d] - c * pn[d]));
            (ubar.map(|v| v / l), cross(*pn, pdot))
        })
        .collect()
}

/// Node positions `x_n + s_j p_n` of rods with centres `x` and axes `p`.
pub(crate) fn node_positions(x: &[Vec3], p: &[Vec3], s: &[f64]) -> Vec<Vec3> {
    let m = s.len();
    (0..x.len() * m)
        .into_par_iter()
        .map(|k| {
            let (n, j) = (k / m, k % m);
            [0, 1, 2].map(|d| x[n][d] + s[j] * p[n][d])
        })
        .collect()
}

impl SlenderBody {
    /// Right-hand side of (P4): swimming, plus the contact terms if `ft` is given.
    fn rhs(&self, p: &[Vec3], ft: Option<&[(Vec3, Vec3)]>) -> Vec<f64> {
        let m = self.s.len();
        let l = ROD_LENGTH;
        let c = SWIM_SPEED / (2.0 * eta(self.params.diameter));
        (0..p.len() * m * 3)
            .into_par_iter()
            .map(|k| {
                let (n, j, d) = (k / (3 * m), (k / 3) % m, k % 3);
                let swim = c * self.s[j].signum() * p[n][d];
                match ft {
                    Some(ft) => {
                        let (f, t) = ft[n];
                        let txp = cross(t, p[n]);
                        swim + f[d] / l + 12.0 * self.s[j] / (l * l * l) * txp[d]
                    }
                    None => swim,
                }
            })
            .collect()
    }

    /// Solve (P4) (warm-started from the previous solution) and write the velocities (P2)-(P3)
    /// into `out`; remembers the flow part for the next step's prediction. With `part`, on one
    /// rank's part of a shared box (collective; the own rods' velocities only).
    fn solve_and_move(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        ft: Option<&[(Vec3, Vec3)]>,
        out: &mut RodVelocities,
        part: Option<Part<'_>>,
    ) -> Result<(), MobilityError> {
        self.device_to_host()?;
        let owned = part.map_or(rods.len(), |q| q.halo.owned);
        let p_own = &p[..owned];
        let rhs = self.rhs(p_own, ft.map(|f| &f[..owned]));
        let mut x = std::mem::take(&mut self.warm_free);
        let stage = if ft.is_some() {
            "swimming + contact"
        } else {
            "free"
        };
        let result = self.solve(rods, p, (&rhs, &mut x), stage, part);
        self.warm_free = x;
        let (info, u) = result?;
        self.report.gmres_iterations = info.iterations;
        self.report.gmres_residual = info.final_residual;
        self.flow = self.flow_velocities(p_own, &u);
        let local = &self.local;
        out.v[..owned]
            .par_iter_mut()
            .zip(out.w[..owned].par_iter_mut())
            .zip(&self.flow)
            .zip(p_own)
            .enumerate()
            .for_each(|(n, (((v, w), (dv, dw)), pn))| {
                let (lv, lw) = match ft {
                    Some(ft) => local.local(*pn, ft[n].0, ft[n].1),
                    None => ([0.0; 3], [0.0; 3]),
                };
                *v = [0, 1, 2].map(|d| SWIM_SPEED * pn[d] + dv[d] + lv[d]);
                *w = [0, 1, 2].map(|d| dw[d] + lw[d]);
            });
        self.density = densities(&self.warm_free);
        Ok(())
    }

    /// Swimming plus the last solve's flow velocities, for the rods with axes `p`.
    fn predict(&self, p: &[Vec3], out: &mut RodVelocities) {
        out.v
            .par_iter_mut()
            .zip(out.w.par_iter_mut())
            .zip(&self.flow)
            .zip(p)
            .for_each(|(((v, w), (dv, dw)), pn)| {
                *v = [0, 1, 2].map(|d| SWIM_SPEED * pn[d] + dv[d]);
                *w = *dw;
            });
    }

    /// The same mobility able to run on one rank's part of a box shared by several, its sum
    /// then [`SharedEwald`] at tolerance `tol` ([`SharedMobility::predicted_velocities_shared`]).
    pub fn shared(mut self, tol: f64) -> Result<Self, SumError> {
        self.shared = Some(SharedEwald::new(tol)?);
        Ok(self)
    }
}

/// Whether any force or torque is non-zero.
fn any_force(ft: &[(Vec3, Vec3)]) -> bool {
    ft.iter().any(|(f, t)| f.iter().chain(t).any(|c| *c != 0.0))
}

/// Force densities per node from the flattened solution.
fn densities(x: &[f64]) -> Vec<Vec3> {
    x.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

impl MobilityState for SlenderBody {
    fn current_warm_state(&self) -> Result<Vec<f64>, MobilityError> {
        match self.resident_warm_state() {
            Some(state) => state,
            None => Ok(self.warm_state()),
        }
    }

    fn sum_state(&self) -> Vec<u32> {
        crate::hydro::sum::adaptive_state(self.sum.as_ref(), self.shared.as_ref())
    }

    fn set_sum_state(&mut self, state: &[u32]) {
        crate::hydro::sum::set_adaptive_state(self.sum.as_mut(), self.shared.as_mut(), state);
    }

    /// The last solution of (P4) followed by the last flow velocities (v, w per rod): both
    /// shape the next step (warm start and prediction).
    fn warm_state(&self) -> Vec<f64> {
        let mut s = self.warm_free.clone();
        for (v, w) in &self.flow {
            s.extend_from_slice(v);
            s.extend_from_slice(w);
        }
        s
    }

    /// Also sets the force density ([`Mobility::force_density`]) to the restored solution.
    fn set_warm_state(&mut self, state: Vec<f64>) {
        self.device.forget();
        // len = n (3 M + 6) for n rods.
        let per_rod = 3 * self.s.len() + 6;
        let n = state.len() / per_rod;
        let split = 3 * self.s.len() * n;
        self.flow = state[split..]
            .chunks_exact(6)
            .map(|c| ([c[0], c[1], c[2]], [c[3], c[4], c[5]]))
            .collect();
        self.warm_free = state[..split].to_vec();
        self.density = densities(&self.warm_free);
    }

    /// The solution of (P4) (`3 M` values), then the flow velocities `v, w`.
    fn rod_state_width(&self) -> usize {
        3 * self.s.len() + 6
    }

    fn rod_state(&self) -> Option<Vec<f64>> {
        let width = 3 * self.s.len();
        if self.warm_free.len() != width * self.flow.len() {
            return None;
        }
        let rows = self
            .warm_free
            .chunks_exact(width)
            .zip(&self.flow)
            .flat_map(|(f, (v, w))| f.iter().chain(v).chain(w).copied())
            .collect();
        Some(rows)
    }

    fn set_rod_state(&mut self, rows: Vec<f64>) {
        let state = self.warm_state_of(&rows);
        self.set_warm_state(state);
    }

    fn warm_state_of(&self, rows: &[f64]) -> Vec<f64> {
        let width = self.rod_state_width();
        let split = width - 6;
        let mut state: Vec<f64> = rows
            .chunks_exact(width)
            .flat_map(|r| r[..split].iter().copied())
            .collect();
        state.extend(rows.chunks_exact(width).flat_map(|r| r[split..].to_vec()));
        state
    }
}

impl SharedMobility for SlenderBody {
    fn shared_reach(&self, total: usize, box_length: f64) -> f64 {
        // Node pairs within the cutoff; nodes lie within half a rod of their centres.
        self.shared.as_ref().map_or(0.0, |s| {
            s.preferred_rpy_reach(total * self.s.len(), box_length) + ROD_LENGTH
        })
    }

    /// As [`Self::predicted_velocities`]; the exact free solve when any rank lacks the last
    /// flow of one of its rods (the first step).
    fn predicted_velocities_shared(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
        part: Part<'_>,
    ) -> Result<(), MobilityError> {
        self.report = HydroReport::default();
        let mut missing = [if self.flow.len() == part.halo.owned {
            0.0
        } else {
            1.0
        }];
        part.comm.max(&mut missing);
        if missing[0] > 0.0 {
            self.predicted_exactly = true;
            return self.solve_and_move(rods, p, None, out, Some(part));
        }
        self.predicted_exactly = false;
        self.predict(&p[..part.halo.owned], out);
        Ok(())
    }

    fn final_velocities_shared(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        ft: &[(Vec3, Vec3)],
        out: &mut RodVelocities,
        part: Part<'_>,
    ) -> Result<(), MobilityError> {
        let owned = part.halo.owned;
        let mut any = [if any_force(&ft[..owned]) { 1.0 } else { 0.0 }];
        part.comm.max(&mut any);
        if self.predicted_exactly && any[0] == 0.0 {
            return Ok(());
        }
        self.solve_and_move(rods, p, Some(ft), out, Some(part))
    }
}

impl Mobility for SlenderBody {
    fn name(&self) -> &'static str {
        "sbt"
    }

    fn diameter(&self) -> f64 {
        self.params.diameter
    }

    fn on_ranks(&mut self) -> Option<&mut dyn SharedMobility> {
        if self.shared.is_some() {
            Some(self)
        } else {
            None
        }
    }

    fn resident(&mut self) -> Option<&mut dyn ResidentMobility> {
        Some(self)
    }

    fn free_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        self.report = HydroReport::default();
        self.solve_and_move(rods, p, None, out, None)
    }

    /// The previous step's flow velocities plus swimming (no solve), or an exact free solve on
    /// the first step.
    fn predicted_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        self.report = HydroReport::default();
        self.device_to_host()?;
        if self.flow.len() != rods.len() {
            self.predicted_exactly = true;
            return self.solve_and_move(rods, p, None, out, None);
        }
        self.predicted_exactly = false;
        self.predict(p, out);
        Ok(())
    }

    /// One solve of (P4) with swimming and contact terms together, unless the prediction was
    /// already the exact free solution and there are no contact forces.
    fn final_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        ft: &[(Vec3, Vec3)],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        if self.predicted_exactly && !any_force(ft) {
            return Ok(());
        }
        self.solve_and_move(rods, p, Some(ft), out, None)
    }

    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3) {
        self.local.local(p, f, t)
    }

    fn report(&self) -> HydroReport {
        self.report.clone()
    }

    fn force_density(&self) -> Option<ForceDensity<'_>> {
        Some(ForceDensity {
            s: &self.s,
            w: &self.w,
            f: &self.density,
        })
    }
}
