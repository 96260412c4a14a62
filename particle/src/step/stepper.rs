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
use crate::step::contact::{Constraint, ContactParams, ContactProblem, ContactSolver};
use crate::step::report::{StepError, StepReport};
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
        let n = rods.len();
        let b = rods.diameter;
        let comm = part.comm;
        let shared = comm.size() > 1;
        let owned = part.halo.owned;
        let gid = |k: usize| -> u32 {
            if part.ids.is_empty() {
                k as u32
            } else {
                part.ids[k]
            }
        };
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(StepError::InvalidTimeStep(dt));
        }
        if b != self.mobility.diameter() {
            return Err(StepError::DiameterMismatch {
                rods: b,
                mobility: self.mobility.diameter(),
                mobility_name: self.mobility.name(),
            });
        }
        let name = self.mobility.name();
        if shared && self.mobility.on_ranks().is_none() {
            return Err(StepError::NotShared {
                mobility_name: self.mobility.name(),
                ranks: comm.size(),
            });
        }
        let mut seconds = [0.0; 5];
        let t0 = Instant::now();
        let p = rods.orientations();
        let reach = ROD_LENGTH + b + self.contact.margin;
        let cells = CellList::build(&rods.x, rods.box_length, reach);
        let order = cells.order();
        let xs = gather(order, &rods.x);
        let ps = gather(order, &p);
        let sorted = cells.renumbered();
        // The halo in the solver's (cell) numbering.
        let inner_halo = if shared {
            let mut inverse = vec![0u32; n];
            for (k, &r) in order.iter().enumerate() {
                inverse[r as usize] = k as u32;
            }
            part.halo.renumbered(&inverse)
        } else {
            Halo::none(n)
        };
        let share = Share {
            comm,
            halo: &inner_halo,
        };
        seconds[0] = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let margin = self.contact.margin;
        let mut cons = sorted.map_pairs(&xs, reach, |i, j, d| {
            constraint(&xs, &ps, i, j, d, b, margin)
        });
        if shared {
            // A pair is its smaller-numbered rod's owner's.
            cons.retain(|c| {
                let (a, bb) = (order[c.i as usize] as usize, order[c.j as usize] as usize);
                let first = if gid(a) < gid(bb) { a } else { bb };
                first < owned
            });
        }
        seconds[1] = t1.elapsed().as_secs_f64();
        let t2 = Instant::now();
        if self.velocities.v.len() != n {
            self.velocities = RodVelocities::zeros(n);
        }
        if shared {
            self.mobility
                .on_ranks()
                .ok_or(MobilityError::NotShared(name))?
                .predicted_velocities_shared(rods, &p, &mut self.velocities, part)?;
            self.refresh_velocities(part);
        } else {
            self.mobility
                .predicted_velocities(rods, &p, &mut self.velocities)?;
        }
        let fv = gather(order, &self.velocities.v);
        let fw = gather(order, &self.velocities.w);
        seconds[2] = t2.elapsed().as_secs_f64();
        let t3 = Instant::now();
        let key = |c: &crate::step::contact::Constraint| {
            let (a, b) = (
                gid(order[c.i as usize] as usize),
                gid(order[c.j as usize] as usize),
            );
            (a.min(b), a.max(b))
        };
        let initial: Vec<f64> = cons
            .par_iter()
            .map(|c| {
                self.warm
                    .binary_search_by_key(&key(c), |w| w.0)
                    .map_or(0.0, |k| self.warm[k].1)
            })
            .collect();
        let problem = ContactProblem {
            cons: &cons,
            p: &ps,
            free_v: &fv,
            free_w: &fw,
            mobility: self.mobility.as_ref(),
            dt,
        };
        let (lambda, contact) =
            self.solver
                .solve_shared(share, problem, &self.contact, &initial)?;
        let mut warm: Vec<((u32, u32), f64)> = cons
            .iter()
            .zip(&lambda)
            .filter(|(_, l)| **l > 0.0)
            .map(|(c, l)| (key(c), *l))
            .collect();
        warm.par_sort_unstable_by_key(|w| w.0);
        self.warm = warm;
        seconds[3] = t3.elapsed().as_secs_f64();
        let t4 = Instant::now();
        // Contact forces and torques, back in the caller's numbering (copies' shares added
        // into their owners).
        let mut ft = self.rod_forces(&cons, &lambda, order, part);
        if shared {
            self.mobility
                .on_ranks()
                .ok_or(MobilityError::NotShared(name))?
                .final_velocities_shared(rods, &p, &ft, &mut self.velocities, part)?;
            self.refresh_velocities(part);
        } else {
            self.mobility
                .final_velocities(rods, &p, &ft, &mut self.velocities)?;
        }
        // Correction: with hydrodynamics the step's velocities are not the ones the contact
        // problem planned with (contact forces act through the full mobility, which moves a
        // close pair apart more weakly than the local mobility). The linearised constraints are
        // checked with the actual velocities; where they fail, a second complementarity
        // problem (local mobility, from zero) adds the impulses that restore them. Without
        // hydrodynamics the velocities are the planned ones and this finds nothing to do.
        let mut correction_active = 0;
        let mut total_constraints = [cons.len() as f64];
        comm.sum(&mut total_constraints);
        if total_constraints[0] > 0.0 {
            let av = gather(order, &self.velocities.v);
            let aw = gather(order, &self.velocities.w);
            let problem = ContactProblem {
                cons: &cons,
                p: &ps,
                free_v: &av,
                free_w: &aw,
                mobility: self.mobility.as_ref(),
                dt,
            };
            let (dlambda, _) = self
                .solver
                .solve_shared(share, problem, &self.contact, &[])?;
            let mut active = [dlambda.iter().filter(|l| **l > 0.0).count() as f64];
            comm.sum(&mut active);
            correction_active = active[0] as usize;
            if correction_active > 0 {
                let dft = self.rod_forces(&cons, &dlambda, order, part);
                for (r, &(f, t)) in dft.iter().enumerate() {
                    if f == [0.0; 3] && t == [0.0; 3] {
                        continue;
                    }
                    let (dv, dw) = self.mobility.local(p[r], f, t);
                    self.velocities.v[r] = axpy(self.velocities.v[r], 1.0, dv);
                    self.velocities.w[r] = axpy(self.velocities.w[r], 1.0, dw);
                    ft[r].0 = axpy(ft[r].0, 1.0, f);
                    ft[r].1 = axpy(ft[r].1, 1.0, t);
                }
                if shared {
                    self.refresh_velocities(part);
                }
            }
        }
        self.contact_force = ft.par_iter().map(|(f, _)| *f).collect();
        let mut net_contact_force = [0, 1, 2]
            .map(|d| crate::parallel::reduce::det_sum(owned, |r| self.contact_force[r][d]));
        comm.sum(&mut net_contact_force);
        // The first rod with a non-finite velocity (by number over all ranks), then every rod
        // moved (in parallel: each rod's update is its own, so the result does not depend on
        // the thread count; copies move with their owners' velocities).
        let (vel, ang) = (&self.velocities.v, &self.velocities.w);
        let bad = (0..owned)
            .into_par_iter()
            .filter(|&r| !(vel[r].iter().chain(&ang[r]).all(|c| c.is_finite())))
            .map(&gid)
            .min();
        let (found, first) = max_with_key(
            comm,
            if bad.is_some() { 1.0 } else { 0.0 },
            [bad.map_or(f64::INFINITY, f64::from), 0.0],
        );
        if found > 0.0 {
            return Err(StepError::NonFinite(first[0] as usize));
        }
        let l = rods.box_length;
        rods.x
            .par_iter_mut()
            .zip(rods.image.par_iter_mut())
            .zip(rods.q.par_iter_mut())
            .zip(vel.par_iter().zip(ang.par_iter()))
            .for_each(|(((x, image), q), (v, w))| {
                crate::model::rods::translate_wrapped(x, image, scale(dt, *v), l);
                *q = quat_mul(quat_exp(scale(dt, *w)), *q);
            });
        seconds[4] = t4.elapsed().as_secs_f64();
        // True overlaps after the move, over the constrained pairs (caller's numbering).
        // The projection below only translates, so the axes after the rotation update hold.
        let p_new = rods.orientations();
        let overlap_of = |rods: &RodSet| {
            let (v, (i, j)) = true_overlap(rods, &p_new, &cons, order, &gid);
            let (v, pair) = max_with_key(comm, v, [f64::from(i), f64::from(j)]);
            (v, (pair[0] as u32, pair[1] as u32))
        };
        let (mut max_overlap, mut worst) = overlap_of(rods);
        // Projection: one contact point per pair cannot hold nearly parallel rods that turn (the
        // far ends approach at first order in the angle), and the linearisation misses
        // (dt w)^2 terms. Where the true overlap exceeds half the tolerance, the constraints
        // are rebuilt at the new positions (every pair within the margin, so pushing one pair
        // apart cannot push a neighbour into another) and a complementarity problem with no
        // free motion finds displacements that remove it. The displacements are translations
        // only (the local translational mobility): the distance between two segments is convex
        // under translation, so the linearised constraints are conservative and one round
        // leaves no overlap among these pairs beyond the solver's tolerance; more rounds only
        // for pairs that come within reach.
        let mut projections = 0;
        while max_overlap > 0.5 * self.contact.overlap_tolerance && projections < PROJECTIONS {
            projections += 1;
            let xs = gather(order, &rods.x);
            let ps = gather(order, &p_new);
            let again: Vec<Constraint> = cons
                .par_iter()
                .filter_map(|c| {
                    let d = min_image(sub(xs[c.j as usize], xs[c.i as usize]), rods.box_length);
                    constraint(&xs, &ps, c.i, c.j, d, b, self.contact.margin)
                })
                .collect();
            let zero = vec![[0.0; 3]; n];
            let translation = TranslationOnly(self.mobility.as_ref());
            let problem = ContactProblem {
                cons: &again,
                p: &ps,
                free_v: &zero,
                free_w: &zero,
                mobility: &translation,
                dt,
            };
            let (lambda, _) = self
                .solver
                .solve_shared(share, problem, &self.contact, &[])?;
            let mut pft = self.rod_forces(&again, &lambda, order, part);
            if shared {
                // The owners' totals on their copies too, so that copies move with them.
                let mut flat = flatten(&pft);
                part.halo.refresh(comm, &mut flat);
                pft = unflatten(&flat);
            }
            for (r, &(f, t)) in pft.iter().enumerate() {
                if f == [0.0; 3] && t == [0.0; 3] {
                    continue;
                }
                let (dv, _) = translation.local(p_new[r], f, t);
                rods.translate(r, scale(dt, dv));
                self.velocities.v[r] = axpy(self.velocities.v[r], 1.0, dv);
                self.contact_force[r] = axpy(self.contact_force[r], 1.0, f);
            }
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
        let total = part.total.max(1) as f64;
        let mut sums = [
            crate::parallel::reduce::det_sum(owned, |r| norm(self.velocities.v[r])),
            crate::parallel::reduce::det_sum(owned, |r| p_new[r][0]),
            crate::parallel::reduce::det_sum(owned, |r| p_new[r][1]),
            crate::parallel::reduce::det_sum(owned, |r| p_new[r][2]),
        ];
        comm.sum(&mut sums);
        let mean_speed = sums[0] / total;
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
        comm.max(&mut maxima);
        let mp = [sums[1] / total, sums[2] / total, sums[3] / total];
        Ok(StepReport {
            contact,
            max_overlap: max_overlap.max(0.0),
            correction_active,
            projections,
            mean_speed,
            max_speed: maxima[0],
            max_rotation_rate: maxima[1],
            polar_order: norm(mp),
            net_contact_force,
            seconds,
            hydro: self.mobility.report(),
        })
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
