//! One time step of the particle model (docs/MODEL.md §1, §3):
//!
//! 1. neighbour search (cell list) and one constraint per pair closer than `b + margin`;
//! 2. predicted velocities from the [`Mobility`] (swimming and, with hydrodynamics, the flow);
//! 3. contact multipliers from the complementarity problem ([`ContactSolver`]) with the local
//!    mobility;
//! 4. the step's velocities from the mobility given the contact forces (prediction plus local
//!    response, or a hydrodynamic solve with both); explicit Euler for centres (wrapped, image
//!    counters kept) and `q <- theta(dt w) q` for orientations;
//! 5. a correction: the linearised constraints checked with the step's actual velocities,
//!    and where the hydrodynamic response left them violated, impulses through the local
//!    mobility that restore them (a second complementarity solve, usually with nothing to do);
//! 6. the true (nonlinear) largest overlap among the constrained pairs after the move.

use crate::hydro::mobility::{Mobility, MobilityError, MobilityState, RodVelocities};
use crate::model::cells::CellList;
use crate::model::geometry::{Vec3, axpy, min_image, norm, quat_exp, quat_mul, scale, sub};
use crate::model::rods::RodSet;
use crate::model::units::ROD_LENGTH;
use crate::parallel::comm::SingleProcess;
use crate::parallel::halo::Halo;
use crate::parallel::part::{Part, Share};
use crate::parallel::reduce::max_with_key;
use crate::step::constraints::{constraint, true_overlap};
use crate::step::contact::{
    Constraint, ContactParams, ContactProblem, ContactReport, ContactSolver,
};
use crate::step::report::{StageTimes, StepError, StepReport};
use rayon::prelude::*;
use std::time::Instant;

/// Advances a [`RodSet`]; owns the mobility, the contact solver and scratch memory only.
#[derive(Debug)]
pub struct Stepper {
    /// Contact settings.
    pub contact: ContactParams,
    mobility: Box<dyn Mobility>,
    solver: ContactSolver,
    velocities: RodVelocities,
    contact_force: Vec<Vec3>,
    /// Multipliers of the last step by rod pair (caller's numbering, `i < j`), sorted: the warm
    /// start of the next solve, and part of the state a checkpoint must keep.
    warm: crate::step::contact::WarmStart,
}

/// The local mobility without rotation: the projection moves rods by translation only.
#[derive(Debug)]
struct TranslationOnly<'a>(&'a dyn Mobility);

impl MobilityState for TranslationOnly<'_> {}

impl Mobility for TranslationOnly<'_> {
    fn name(&self) -> &'static str {
        "translation-only"
    }

    fn diameter(&self) -> f64 {
        self.0.diameter()
    }

    fn free_velocities(
        &mut self,
        _rods: &RodSet,
        _p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), crate::hydro::mobility::MobilityError> {
        out.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        out.w.iter_mut().for_each(|w| *w = [0.0; 3]);
        Ok(())
    }

    fn local(&self, p: Vec3, f: Vec3, _t: Vec3) -> (Vec3, Vec3) {
        (self.0.local(p, f, [0.0; 3]).0, [0.0; 3])
    }
}

/// `v` in cell order: `v[order[k]]` for each `k`.
fn gather(order: &[u32], v: &[Vec3]) -> Vec<Vec3> {
    order.par_iter().map(|&i| v[i as usize]).collect()
}

/// Rounds of position projection per step at most.
pub(crate) const PROJECTIONS: usize = 5;

/// The rods of one step in cell order (spatially coherent, so the contact solver's gathers
/// hit cache): the contact problems' constraints carry these indices.
struct Plan {
    /// Axes, in the caller's numbering.
    p: Vec<Vec3>,
    /// `order[k]`: the caller's number of the `k`-th rod in cell order.
    order: Vec<u32>,
    /// Centres in cell order.
    xs: Vec<Vec3>,
    /// Axes in cell order.
    ps: Vec<Vec3>,
    /// The cell list in cell order.
    sorted: CellList,
    /// The contact reach `l + b + margin`.
    reach: f64,
    /// The halo of copies, in cell order.
    halo: Halo,
}

impl Plan {
    /// The plan of `rods` with contact margin `margin`, `part` saying which are copies.
    fn new(rods: &RodSet, margin: f64, part: Part<'_>) -> Self {
        let n = rods.len();
        let p = rods.orientations();
        let reach = ROD_LENGTH + rods.diameter + margin;
        let cells = CellList::build(&rods.x, rods.box_length, reach);
        let order = cells.order().to_vec();
        let xs = gather(&order, &rods.x);
        let ps = gather(&order, &p);
        let sorted = cells.renumbered();
        let halo = if part.comm.size() > 1 {
            let mut inverse = vec![0u32; n];
            for (k, &r) in order.iter().enumerate() {
                inverse[r as usize] = k as u32;
            }
            part.halo.renumbered(&inverse)
        } else {
            Halo::none(n)
        };
        Self {
            p,
            order,
            xs,
            ps,
            sorted,
            reach,
            halo,
        }
    }

    /// What the contact solver shares among ranks, in cell order.
    fn share<'a>(&'a self, part: Part<'a>) -> Share<'a> {
        Share {
            comm: part.comm,
            halo: &self.halo,
        }
    }
}

/// What the projection after a step left.
struct Projected {
    /// The largest true overlap among the constrained pairs (rod lengths).
    max_overlap: f64,
    /// Rounds of projection.
    rounds: usize,
}

/// The number in the whole box of local rod `k`.
fn global_id(part: Part<'_>, k: usize) -> u32 {
    if part.ids.is_empty() {
        k as u32
    } else {
        part.ids[k]
    }
}

/// The rod pair of constraint `c` (cell numbering, `order` back to the caller's) by numbers
/// in the whole box, smaller first: the key of the multipliers' warm start.
fn pair_key(part: Part<'_>, order: &[u32], c: &Constraint) -> (u32, u32) {
    let (a, b) = (
        global_id(part, order[c.i as usize] as usize),
        global_id(part, order[c.j as usize] as usize),
    );
    (a.min(b), a.max(b))
}

impl Stepper {
    /// A stepper with the given mobility and contact settings.
    pub fn new(mobility: Box<dyn Mobility>, contact: ContactParams) -> Self {
        Self {
            contact,
            mobility,
            solver: ContactSolver::default(),
            velocities: RodVelocities::default(),
            contact_force: Vec::new(),
            warm: Vec::new(),
        }
    }

    /// The contact multipliers of the last step, by rod pair `(i, j)`, `i < j`, sorted.
    pub fn warm_start(&self) -> &[((u32, u32), f64)] {
        &self.warm
    }

    /// Restore the multipliers a checkpoint saved (pairs sorted, as [`Self::warm_start`]).
    pub fn set_warm_start(&mut self, warm: crate::step::contact::WarmStart) {
        self.warm = warm;
    }

    /// Velocities of the last step.
    pub fn velocities(&self) -> &RodVelocities {
        &self.velocities
    }

    /// Contact force on each rod in the last step.
    pub fn contact_forces(&self) -> &[Vec3] {
        &self.contact_force
    }

    /// The mobility (for its report and force density).
    pub fn mobility(&self) -> &dyn Mobility {
        self.mobility.as_ref()
    }

    /// The mobility, mutable (to restore its warm state from a checkpoint).
    pub fn mobility_mut(&mut self) -> &mut dyn Mobility {
        self.mobility.as_mut()
    }

    /// The mobility's name.
    pub fn mobility_name(&self) -> &'static str {
        self.mobility.name()
    }

    /// Advance `rods` by `dt`.
    ///
    /// Internally the rods are renumbered in cell order (spatially coherent, so the contact
    /// solver's gathers hit cache); constraints carry those internal indices, and velocities
    /// and forces are mapped back to the caller's numbering.
    pub fn step(&mut self, rods: &mut RodSet, dt: f64) -> Result<StepReport, StepError> {
        let halo = Halo::none(rods.len());
        let part = Part {
            comm: &SingleProcess,
            halo: &halo,
            ids: &[],
            total: rods.len(),
            reach: 0.0,
        };
        self.step_part(rods, dt, part)
    }

    /// [`Self::step`] for one rank's part of a box shared by several (collective; see
    /// [`crate::parallel::comm`]): `rods` are this rank's own rods followed by copies of other ranks'
    /// rods within reach of them, as `part.halo` says. Every own rod and every copy moves
    /// (the copies with their owners' velocities); the report is the whole box's. Velocities and
    /// contact forces ([`Self::velocities`], [`Self::contact_forces`]) are those of the local
    /// rods, correct for the own ones. Mobilities not built to share ([`Mobility::on_ranks`] `None`)
    /// return [`StepError::NotShared`] on more than one rank.
    pub fn step_part(
        &mut self,
        rods: &mut RodSet,
        dt: f64,
        part: Part<'_>,
    ) -> Result<StepReport, StepError> {
        self.check_step(rods, dt, part)?;
        let mut times = StageTimes::default();
        let t = Instant::now();
        let plan = Plan::new(rods, self.contact.margin, part);
        times.cells = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let constraints = self.constraints(&plan, rods.diameter, part);
        times.constraints = t.elapsed().as_secs_f64();
        let t = Instant::now();
        self.predict(rods, &plan.p, part)?;
        times.free_velocities = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (lambda, contact) = self.solve_contacts(&plan, &constraints, dt, part)?;
        times.contacts = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut forces = self.rod_forces(&constraints, &lambda, &plan.order, part);
        self.finish_velocities(rods, &plan.p, &forces, part)?;
        let correction_active = self.correct(&plan, &constraints, &mut forces, dt, part)?;
        self.contact_force = forces.par_iter().map(|(f, _)| *f).collect();
        self.advance(rods, dt, part)?;
        times.update = t.elapsed().as_secs_f64();
        let net_contact_force = self.net_contact_force(part);
        let projected = self.project(rods, &plan, &constraints, dt, part)?;
        Ok(StepReport {
            contact,
            max_overlap: projected.max_overlap.max(0.0),
            correction_active,
            projections: projected.rounds,
            net_contact_force,
            seconds: times,
            hydro: self.mobility.report(),
            ..self.velocity_statistics(rods, part)
        })
    }

    /// The step's inputs checked against this stepper: `dt`, the rods' diameter against the
    /// mobility's, a mobility that can share a box among ranks when there are several.
    fn check_step(&mut self, rods: &RodSet, dt: f64, part: Part<'_>) -> Result<(), StepError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(StepError::InvalidTimeStep(dt));
        }
        if rods.diameter != self.mobility.diameter() {
            return Err(StepError::DiameterMismatch {
                rods: rods.diameter,
                mobility: self.mobility.diameter(),
                mobility_name: self.mobility.name(),
            });
        }
        let name = self.mobility.name();
        if part.comm.size() > 1 && self.mobility.on_ranks().is_none() {
            return Err(StepError::NotShared {
                mobility_name: name,
                ranks: part.comm.size(),
            });
        }
        Ok(())
    }

    /// One constraint per pair of rods closer than `b + margin`, in the plan's (cell)
    /// numbering; on several ranks each pair is its smaller-numbered rod's owner's.
    fn constraints(&self, plan: &Plan, b: f64, part: Part<'_>) -> Vec<Constraint> {
        let (xs, ps, order) = (&plan.xs, &plan.ps, &plan.order);
        let margin = self.contact.margin;
        let mut constraints = plan.sorted.map_pairs(xs, plan.reach, |i, j, d| {
            constraint(xs, ps, i, j, d, b, margin)
        });
        if part.comm.size() > 1 {
            let owned = part.halo.owned;
            constraints.retain(|c| {
                let (first, second) = (order[c.i as usize] as usize, order[c.j as usize] as usize);
                let owner = if global_id(part, first) < global_id(part, second) {
                    first
                } else {
                    second
                };
                owner < owned
            });
        }
        constraints
    }

    /// The velocities the contact problem plans with, from the mobility (on several ranks its
    /// shared path, the owners' values copied to their copies).
    fn predict(&mut self, rods: &RodSet, p: &[Vec3], part: Part<'_>) -> Result<(), StepError> {
        let n = rods.len();
        if self.velocities.v.len() != n {
            self.velocities = RodVelocities::zeros(n);
        }
        if part.comm.size() > 1 {
            let name = self.mobility.name();
            self.mobility
                .on_ranks()
                .ok_or(MobilityError::NotShared(name))?
                .predicted_velocities_shared(rods, p, &mut self.velocities, part)?;
            self.refresh_velocities(part);
        } else {
            self.mobility
                .predicted_velocities(rods, p, &mut self.velocities)?;
        }
        Ok(())
    }

    /// The contact multipliers (one per constraint) from the planned velocities, warm-started
    /// from the last step's multipliers of the same rod pairs, which they then replace.
    fn solve_contacts(
        &mut self,
        plan: &Plan,
        constraints: &[Constraint],
        dt: f64,
        part: Part<'_>,
    ) -> Result<(Vec<f64>, ContactReport), StepError> {
        let planned_v = gather(&plan.order, &self.velocities.v);
        let planned_w = gather(&plan.order, &self.velocities.w);
        let key = |c: &Constraint| pair_key(part, &plan.order, c);
        let initial: Vec<f64> = constraints
            .par_iter()
            .map(|c| {
                self.warm
                    .binary_search_by_key(&key(c), |w| w.0)
                    .map_or(0.0, |k| self.warm[k].1)
            })
            .collect();
        let problem = ContactProblem {
            cons: constraints,
            p: &plan.ps,
            free_v: &planned_v,
            free_w: &planned_w,
            mobility: self.mobility.as_ref(),
            dt,
        };
        let (lambda, contact) =
            self.solver
                .solve_shared(plan.share(part), problem, &self.contact, &initial)?;
        let mut warm: Vec<((u32, u32), f64)> = constraints
            .iter()
            .zip(&lambda)
            .filter(|(_, l)| **l > 0.0)
            .map(|(c, l)| (key(c), *l))
            .collect();
        warm.par_sort_unstable_by_key(|w| w.0);
        self.warm = warm;
        Ok((lambda, contact))
    }

    /// The step's velocities from the mobility given the contact forces and torques `forces`
    /// (caller's numbering; on several ranks the shared path, copies refreshed).
    fn finish_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        forces: &[(Vec3, Vec3)],
        part: Part<'_>,
    ) -> Result<(), StepError> {
        if part.comm.size() > 1 {
            let name = self.mobility.name();
            self.mobility
                .on_ranks()
                .ok_or(MobilityError::NotShared(name))?
                .final_velocities_shared(rods, p, forces, &mut self.velocities, part)?;
            self.refresh_velocities(part);
        } else {
            self.mobility
                .final_velocities(rods, p, forces, &mut self.velocities)?;
        }
        Ok(())
    }

    /// Correction: with hydrodynamics the step's velocities are not the ones the contact
    /// problem planned with (contact forces act through the full mobility, which moves a close
    /// pair apart more weakly than the local mobility). The linearised constraints are checked
    /// with the actual velocities; where they fail, a second complementarity problem (local
    /// mobility, from zero) adds the impulses that restore them, to the velocities and to
    /// `forces`. Without hydrodynamics the velocities are the planned ones and this finds
    /// nothing to do. Returns how many constraints it made active (over all ranks).
    fn correct(
        &mut self,
        plan: &Plan,
        constraints: &[Constraint],
        forces: &mut [(Vec3, Vec3)],
        dt: f64,
        part: Part<'_>,
    ) -> Result<usize, StepError> {
        let comm = part.comm;
        let mut total_constraints = [constraints.len() as f64];
        comm.sum(&mut total_constraints);
        if total_constraints[0] == 0.0 {
            return Ok(0);
        }
        let actual_v = gather(&plan.order, &self.velocities.v);
        let actual_w = gather(&plan.order, &self.velocities.w);
        let problem = ContactProblem {
            cons: constraints,
            p: &plan.ps,
            free_v: &actual_v,
            free_w: &actual_w,
            mobility: self.mobility.as_ref(),
            dt,
        };
        let (impulses, _) =
            self.solver
                .solve_shared(plan.share(part), problem, &self.contact, &[])?;
        let mut active = [impulses.iter().filter(|l| **l > 0.0).count() as f64];
        comm.sum(&mut active);
        let correction_active = active[0] as usize;
        if correction_active > 0 {
            let added = self.rod_forces(constraints, &impulses, &plan.order, part);
            for (r, &(f, t)) in added.iter().enumerate() {
                if f == [0.0; 3] && t == [0.0; 3] {
                    continue;
                }
                let (dv, dw) = self.mobility.local(plan.p[r], f, t);
                self.velocities.v[r] = axpy(self.velocities.v[r], 1.0, dv);
                self.velocities.w[r] = axpy(self.velocities.w[r], 1.0, dw);
                forces[r].0 = axpy(forces[r].0, 1.0, f);
                forces[r].1 = axpy(forces[r].1, 1.0, t);
            }
            if comm.size() > 1 {
                self.refresh_velocities(part);
            }
        }
        Ok(correction_active)
    }

    /// The sum of all contact forces over the own rods of every rank.
    fn net_contact_force(&self, part: Part<'_>) -> Vec3 {
        let mut net = [0, 1, 2].map(|d| {
            motile_analysis::reduce::det_sum(part.halo.owned, |r| self.contact_force[r][d])
        });
        part.comm.sum(&mut net);
        net
    }

    /// Every rod moved by the step's velocities: explicit Euler for the centres (wrapped,
    /// image counters kept), `q <- theta(dt w) q` for the orientations; first the rod with a
    /// non-finite velocity, by number over all ranks, if any (then nothing moves). Each rod's
    /// update is its own, so the result does not depend on the thread count; copies move
    /// with their owners' velocities.
    fn advance(&self, rods: &mut RodSet, dt: f64, part: Part<'_>) -> Result<(), StepError> {
        let (vel, ang) = (&self.velocities.v, &self.velocities.w);
        // A rod that would cross the box in one step has a runaway velocity (and its
        // wrap-around would take as many turns as the box lengths it crosses).
        let l = rods.box_length;
        let runaway = |r: usize| vel[r].iter().any(|c| c.abs() * dt >= l);
        let bad = (0..part.halo.owned)
            .into_par_iter()
            .filter(|&r| !(vel[r].iter().chain(&ang[r]).all(|c| c.is_finite())) || runaway(r))
            .map(|r| global_id(part, r))
            .min();
        let (found, first) = max_with_key(
            part.comm,
            if bad.is_some() { 1.0 } else { 0.0 },
            [bad.map_or(f64::INFINITY, f64::from), 0.0],
        );
        if found > 0.0 {
            return Err(StepError::NonFinite(first[0] as usize));
        }
        rods.x
            .par_iter_mut()
            .zip(rods.image.par_iter_mut())
            .zip(rods.q.par_iter_mut())
            .zip(vel.par_iter().zip(ang.par_iter()))
            .for_each(|(((x, image), q), (v, w))| {
                crate::model::rods::translate_wrapped(x, image, scale(dt, *v), l);
                *q = quat_mul(quat_exp(scale(dt, *w)), *q);
            });
        Ok(())
    }

    /// Projection, after the move: one contact point per pair cannot hold nearly parallel
    /// rods that turn (the far ends approach at first order in the angle), and the
    /// linearisation misses (dt w)^2 terms. While the true overlap among the constrained
    /// pairs exceeds half the tolerance, the constraints are rebuilt at the new positions
    /// (every pair within the margin, so pushing one pair apart cannot push a neighbour into
    /// another) and a complementarity problem with no free motion finds displacements that
    /// remove it. The displacements are translations only (the local translational mobility):
    /// the distance between two segments is convex under translation, so the linearised
    /// constraints are conservative and one round leaves no overlap among these pairs beyond
    /// the solver's tolerance; more rounds (at most [`PROJECTIONS`]) only for pairs that come
    /// within reach. An overlap still over the tolerance after them is an error.
    fn project(
        &mut self,
        rods: &mut RodSet,
        plan: &Plan,
        constraints: &[Constraint],
        dt: f64,
        part: Part<'_>,
    ) -> Result<Projected, StepError> {
        // The projection only translates, so the axes after the rotation update hold.
        let p_new = rods.orientations();
        let overlap_of = |rods: &RodSet| {
            let gid = |r: usize| global_id(part, r);
            let (v, (i, j)) = true_overlap(rods, &p_new, constraints, &plan.order, &gid);
            let (v, pair) = max_with_key(part.comm, v, [f64::from(i), f64::from(j)]);
            (v, (pair[0] as u32, pair[1] as u32))
        };
        let (mut max_overlap, mut worst) = overlap_of(rods);
        let mut rounds = 0;
        while max_overlap > 0.5 * self.contact.overlap_tolerance && rounds < PROJECTIONS {
            rounds += 1;
            self.project_once(rods, plan, constraints, dt, part)?;
            (max_overlap, worst) = overlap_of(rods);
        }
        if max_overlap > self.contact.overlap_tolerance {
            return Err(StepError::Overlap {
                i: worst.0,
                j: worst.1,
                overlap: max_overlap,
                tolerance: self.contact.overlap_tolerance,
            });
        }
        Ok(Projected {
            max_overlap,
            rounds,
        })
    }

    /// One round of [`Self::project`]: the constraints at the rods' positions now, the
    /// translations that remove their overlaps, applied to the rods, their velocities and
    /// contact forces.
    fn project_once(
        &mut self,
        rods: &mut RodSet,
        plan: &Plan,
        constraints: &[Constraint],
        dt: f64,
        part: Part<'_>,
    ) -> Result<(), StepError> {
        let p_new = rods.orientations();
        let xs = gather(&plan.order, &rods.x);
        let ps = gather(&plan.order, &p_new);
        let (b, margin) = (rods.diameter, self.contact.margin);
        let again: Vec<Constraint> = constraints
            .par_iter()
            .filter_map(|c| {
                let d = min_image(sub(xs[c.j as usize], xs[c.i as usize]), rods.box_length);
                constraint(&xs, &ps, c.i, c.j, d, b, margin)
            })
            .collect();
        let zero = vec![[0.0; 3]; rods.len()];
        let translation = TranslationOnly(self.mobility.as_ref());
        let problem = ContactProblem {
            cons: &again,
            p: &ps,
            free_v: &zero,
            free_w: &zero,
            mobility: &translation,
            dt,
        };
        let (lambda, _) =
            self.solver
                .solve_shared(plan.share(part), problem, &self.contact, &[])?;
        let mut pushes = self.rod_forces(&again, &lambda, &plan.order, part);
        if part.comm.size() > 1 {
            // The owners' totals on their copies too, so that copies move with them.
            let mut flat = flatten(&pushes);
            part.halo.refresh(part.comm, &mut flat);
            pushes = unflatten(&flat);
        }
        for (r, &(f, t)) in pushes.iter().enumerate() {
            if f == [0.0; 3] && t == [0.0; 3] {
                continue;
            }
            let (dv, _) = translation.local(p_new[r], f, t);
            rods.translate(r, scale(dt, dv));
            self.velocities.v[r] = axpy(self.velocities.v[r], 1.0, dv);
            self.contact_force[r] = axpy(self.contact_force[r], 1.0, f);
        }
        Ok(())
    }

    /// The report's velocity statistics over the own rods of every rank (the rest of the
    /// report default): mean and largest speed, largest rotation rate, polar order.
    fn velocity_statistics(&self, rods: &RodSet, part: Part<'_>) -> StepReport {
        let owned = part.halo.owned;
        let p = rods.orientations();
        let total = part.total.max(1) as f64;
        let mut sums = [
            motile_analysis::reduce::det_sum(owned, |r| norm(self.velocities.v[r])),
            motile_analysis::reduce::det_sum(owned, |r| p[r][0]),
            motile_analysis::reduce::det_sum(owned, |r| p[r][1]),
            motile_analysis::reduce::det_sum(owned, |r| p[r][2]),
        ];
        part.comm.sum(&mut sums);
        // Maxima are exact in any order.
        let mut maxima = [
            self.velocities.v[..owned]
                .par_iter()
                .map(|v| norm(*v))
                .reduce(|| 0.0, f64::max),
            self.velocities.w[..owned]
                .par_iter()
                .map(|w| norm(*w))
                .reduce(|| 0.0, f64::max),
        ];
        part.comm.max(&mut maxima);
        let mean_p = [sums[1] / total, sums[2] / total, sums[3] / total];
        StepReport {
            mean_speed: sums[0] / total,
            max_speed: maxima[0],
            max_rotation_rate: maxima[1],
            polar_order: norm(mean_p),
            ..StepReport::default()
        }
    }

    /// The generalised force of multipliers `lambda` (constraints `cons` in the solver's
    /// numbering, as indexed by its last solve) on each local rod, in the caller's numbering;
    /// on several ranks each owner's total, its copies' shares added in (collective).
    fn rod_forces(
        &self,
        cons: &[Constraint],
        lambda: &[f64],
        order: &[u32],
        part: Part<'_>,
    ) -> Vec<(Vec3, Vec3)> {
        let n = order.len();
        let mut ft = vec![([0.0; 3], [0.0; 3]); n];
        if !cons.is_empty() {
            for (k, f) in self.solver.forces(cons, lambda, n).into_iter().enumerate() {
                ft[order[k] as usize] = f;
            }
        }
        if part.comm.size() > 1 {
            let mut flat = flatten(&ft);
            part.halo.accumulate(part.comm, &mut flat);
            ft = unflatten(&flat);
        }
        ft
    }

    /// Copy the owners' velocities to their copies.
    fn refresh_velocities(&mut self, part: Part<'_>) {
        let mut vw: Vec<[f64; 6]> = self
            .velocities
            .v
            .iter()
            .zip(&self.velocities.w)
            .map(|(v, w)| [v[0], v[1], v[2], w[0], w[1], w[2]])
            .collect();
        part.halo.refresh(part.comm, &mut vw);
        for (k, x) in vw.iter().enumerate() {
            self.velocities.v[k] = [x[0], x[1], x[2]];
            self.velocities.w[k] = [x[3], x[4], x[5]];
        }
    }
}

/// Force-torque pairs as rows of six.
fn flatten(ft: &[(Vec3, Vec3)]) -> Vec<[f64; 6]> {
    ft.iter()
        .map(|(f, t)| [f[0], f[1], f[2], t[0], t[1], t[2]])
        .collect()
}

/// Rows of six as force-torque pairs.
fn unflatten(flat: &[[f64; 6]]) -> Vec<(Vec3, Vec3)> {
    flat.iter()
        .map(|x| ([x[0], x[1], x[2]], [x[3], x[4], x[5]]))
        .collect()
}
