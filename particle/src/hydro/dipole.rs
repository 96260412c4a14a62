//! The far-field (dipole) mobility (`hydrodynamics = "dipole"`, docs/MODEL.md §2): each rod is a
//! point stresslet `sigma_0 p p`, `sigma_0 = U l^2/(8 eta)`, at its centre; it swims at `U p`
//! plus the periodic flow of all the others (its own singular term excluded) and turns with
//! Jeffery's rule `pdot = (I - pp)(grad u) p`. No GMRES: one stresslet sum per step.
//!
//! For output (snapshots, the velocity spectrum) each rod's stresslet is written as the force
//! density of an isolated rod, `(U/(2 eta)) sign(s) p` at the 4-point half-rod Gauss rule,
//! which carries exactly the same stresslet.
//!
//! Contacts act through the local mobility of (P2)-(P3) only: the flows of the contact forces
//! themselves (force pairs, far field of order `lambda b / r^2`) are not carried in this model,
//! unlike the slender-body one. Measured consequences belong to the model comparison.

use crate::ewald::periodic::StressletField;
use crate::ewald::shared::{RankShare, SharedEwald};
use crate::hydro::mobility::{
    ForceDensity, HydroReport, LocalDrag, Mobility, MobilityError, MobilityState, ResidentMobility,
    RodVelocities, SharedMobility,
};
use crate::hydro::sum::FlowSum;
use crate::model::geometry::{Vec3, cross, dot};
use crate::model::rods::RodSet;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED, eta};
use rayon::prelude::*;
use std::time::Instant;

/// Stresslet strength of one rod of diameter `b`, `U l^2/(8 eta)`.
pub fn stresslet_strength(diameter: f64) -> f64 {
    SWIM_SPEED * ROD_LENGTH * ROD_LENGTH / (8.0 * eta(diameter))
}

/// The dipole mobility; owns the periodic sum.
#[derive(Debug)]
pub struct Dipole {
    pub(crate) sum: Box<dyn FlowSum>,
    /// The sum shared among ranks, when this mobility runs on one rank's part of a box.
    pub(crate) shared: Option<SharedEwald>,
    pub(crate) diameter: f64,
    local: LocalDrag,
    pub(crate) report: HydroReport,
    pub(crate) s: Vec<f64>,
    pub(crate) w: Vec<f64>,
    density: Vec<Vec3>,
}

impl Dipole {
    /// A dipole mobility for rods of diameter `b` on the given periodic sum.
    pub fn new(sum: Box<dyn FlowSum>, diameter: f64) -> Self {
        let (s, w) = crate::hydro::slender::half_rod_rule(4, ROD_LENGTH);
        Self {
            sum,
            shared: None,
            diameter,
            local: LocalDrag::new(diameter),
            report: HydroReport::default(),
            s,
            w,
            density: Vec::new(),
        }
    }
}

impl Dipole {
    /// The same mobility able to run on one rank's part of a box shared by several, its sum
    /// then [`SharedEwald`] at tolerance `tol` ([`SharedMobility::predicted_velocities_shared`]).
    pub fn shared(mut self, tol: f64) -> Result<Self, crate::ewald::periodic::SumError> {
        self.shared = Some(SharedEwald::new(tol)?);
        Ok(self)
    }

    /// Velocities from the flow `field` at the first `field.u.len()` rods (swimming plus
    /// the flow; Jeffery's rotation), and the force density of every rod for output.
    fn apply_field(&mut self, p: &[Vec3], field: &StressletField, out: &mut RodVelocities) {
        let k = field.u.len();
        out.v[..k]
            .par_iter_mut()
            .zip(out.w[..k].par_iter_mut())
            .zip(field.u.par_iter().zip(&field.grad))
            .zip(&p[..k])
            .for_each(|(((v, w), (u, g)), pn)| {
                *v = [0, 1, 2].map(|d| SWIM_SPEED * pn[d] + u[d]);
                let gp = [0, 1, 2].map(|i| dot(g[i], *pn));
                let c = dot(*pn, gp);
                let pdot = [0, 1, 2].map(|d| gp[d] - c * pn[d]);
                *w = cross(*pn, pdot);
            });
        self.density_for(p);
    }
}

impl MobilityState for Dipole {
    fn sum_state(&self) -> Vec<u32> {
        crate::hydro::sum::adaptive_state(self.sum.as_ref(), self.shared.as_ref())
    }

    fn set_sum_state(&mut self, state: &[u32]) {
        crate::hydro::sum::set_adaptive_state(self.sum.as_mut(), self.shared.as_mut(), state);
    }
}

impl SharedMobility for Dipole {
    fn shared_reach(&self, total: usize, box_length: f64) -> f64 {
        self.shared
            .as_ref()
            .map_or(0.0, |s| s.preferred_reach(total, box_length))
    }

    fn predicted_velocities_shared(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
        part: crate::parallel::part::Part<'_>,
    ) -> Result<(), MobilityError> {
        let sigma = vec![stresslet_strength(self.diameter); rods.len()];
        let t = Instant::now();
        let shared = self
            .shared
            .as_mut()
            .ok_or(MobilityError::NotShared("dipole"))?;
        let field = shared.stresslets(
            part.comm,
            RankShare {
                owned: part.halo.owned,
                total: part.total,
                reach: part.reach,
            },
            rods.box_length,
            &rods.x,
            p,
            &sigma,
        )?;
        self.report = HydroReport {
            seconds_sums: t.elapsed().as_secs_f64(),
            ..HydroReport::default()
        };
        self.report.add_sum(shared.last_report());
        self.apply_field(p, &field, out);
        Ok(())
    }
}

impl Mobility for Dipole {
    fn name(&self) -> &'static str {
        "dipole"
    }

    fn diameter(&self) -> f64 {
        self.diameter
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
        let sigma = vec![stresslet_strength(self.diameter); rods.len()];
        let t = Instant::now();
        let field = self.sum.stresslets(rods.box_length, &rods.x, p, &sigma)?;
        self.report = HydroReport {
            seconds_sums: t.elapsed().as_secs_f64(),
            ..HydroReport::default()
        };
        self.report.add_sum(self.sum.last_report());
        self.apply_field(p, &field, out);
        Ok(())
    }

    fn density_for(&mut self, p: &[Vec3]) {
        let c = SWIM_SPEED / (2.0 * eta(self.diameter));
        self.density = p
            .iter()
            .flat_map(|pn| self.s.iter().map(move |sj| pn.map(|v| c * sj.signum() * v)))
            .collect();
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
