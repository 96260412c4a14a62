//! How rods move under forces: the pluggable part of the step.
//!
//! A [`Mobility`] gives (a) the velocities the rods would have without contacts (swimming plus,
//! in later models, the hydrodynamic flow) and (b) the local response to a force and torque on
//! one rod, which the contact solver uses (docs/MODEL.md §3: the QP may use the local mobility of
//! (P2)-(P3), block diagonal, while the flows that contact forces induce on other rods are left
//! to the hydrodynamic solve).
//!
//! [`LocalDrag`] is `hydrodynamics = "none"`: free swimming at `U p`, translational mobility
//! `(eta/l)(I + pp)` and rotational mobility `(12 eta / l^3)(I - pp)`. The projection `I - pp`
//! makes the rotational block well posed: spin about the rod's own axis is undefined for a
//! slender body and moves no point of the centerline, so it is set to zero (a torque's axial
//! part does nothing).

pub use crate::hydro::gpu::ResidentMobility;
pub use crate::hydro::report::{ForceDensity, HydroReport, MobilityError, RodVelocities};
use crate::model::geometry::{Vec3, axpy, dot, scale, sub};
use crate::model::rods::RodSet;
use crate::model::units::{DEFAULT_DIAMETER, ROD_LENGTH, SWIM_SPEED, eta};
use rayon::prelude::*;

/// The pluggable mobility of the particle step: its physics. What a checkpoint keeps of it is
/// [`MobilityState`] (a supertrait), its path on one rank's part of a box shared by several
/// [`SharedMobility`] (reached through [`Self::on_ranks`]), its path on a device
/// [`ResidentMobility`] (reached through [`Self::resident`]).
pub trait Mobility: MobilityState + Send + Sync + std::fmt::Debug {
    /// Name as in the config (`"none"`, `"dipole"`, `"sbt-explicit"`, `"sbt"`).
    fn name(&self) -> &'static str;
    /// The rod diameter `b` its drag coefficients (`eta`) were built for: the stepper refuses
    /// rods of another diameter.
    fn diameter(&self) -> f64;
    /// Velocities without contact forces, written into `out`.
    fn free_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError>;
    /// Local response `(v, w)` of a rod with axis `p` to force `f` and torque `t`: the block
    /// diagonal mobility the contact solver uses.
    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3);
    /// The velocities the contact solver plans with, written into `out`. The default is the
    /// free velocities; the slender-body model reuses the previous step's flow here and solves
    /// once in [`Self::final_velocities`].
    fn predicted_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        self.free_velocities(rods, p, out)
    }
    /// Set the force density ([`Self::force_density`]) for rods with axes `p` where it
    /// depends on nothing else (the dipole level), without a step: a shared run's rank 0 writes
    /// its outputs from a gathered state this way. Others keep their last step's.
    fn density_for(&mut self, _p: &[Vec3]) {}
    /// The step's velocities given the contact forces and torques `contact` (caller's
    /// numbering); `out` holds the prediction on entry. The default adds the local response to
    /// `contact`.
    fn final_velocities(
        &mut self,
        _rods: &RodSet,
        p: &[Vec3],
        contact: &[(Vec3, Vec3)],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        out.v
            .par_iter_mut()
            .zip(out.w.par_iter_mut())
            .zip(contact)
            .zip(p)
            .for_each(|(((v, w), (f, t)), p)| {
                let (dv, dw) = self.local(*p, *f, *t);
                *v = axpy(*v, 1.0, dv);
                *w = axpy(*w, 1.0, dw);
            });
        Ok(())
    }
    /// What the last step's hydrodynamics did.
    fn report(&self) -> HydroReport {
        HydroReport::default()
    }
    /// The force density of the last step, for models that have one.
    fn force_density(&self) -> Option<ForceDensity<'_>> {
        None
    }
    /// This mobility on one rank's part of a box shared by several, where it was built for
    /// one; `None` where it cannot run there.
    fn on_ranks(&mut self) -> Option<&mut dyn SharedMobility> {
        None
    }
    /// This mobility's path on a device (its flow summed where the rods are); `None` where it
    /// has none. Without the `gpu` feature the path's methods say that nothing is on a device.
    fn resident(&mut self) -> Option<&mut dyn ResidentMobility> {
        None
    }
}

/// What a checkpoint saves of a mobility: state that the next step starts from (the GMRES warm
/// start, the periodic sum's refinement level), so that a run resumed with it continues bit
/// for bit. The defaults are a mobility without state.
pub trait MobilityState {
    /// The warm state, in the single-process layout. Empty for models without such state.
    fn warm_state(&self) -> Vec<f64> {
        Vec::new()
    }
    /// Restore what [`Self::warm_state`] returned.
    fn set_warm_state(&mut self, _state: Vec<f64>) {}

    /// [`Self::warm_state`] wherever it is kept: downloaded where resident steps keep it on a
    /// device ([`ResidentMobility::resident_warm_state`]), else the host's.
    fn current_warm_state(&self) -> Result<Vec<f64>, MobilityError> {
        Ok(self.warm_state())
    }

    /// Values per rod in [`Self::rod_state`]; zero for mobilities without per-rod state.
    fn rod_state_width(&self) -> usize {
        0
    }

    /// [`Self::warm_state`] rod by rod: [`Self::rod_state_width`] values per rod, the rods in
    /// order, so that a box shared among ranks can move each rod's state with it. The rows are
    /// those of the rods of the last solve (none before the first): callers check their count
    /// against their rods. `None` for mobilities without per-rod state.
    fn rod_state(&self) -> Option<Vec<f64>> {
        None
    }

    /// Restore rows of [`Self::rod_state`] (an empty or incomplete set: no state, the next
    /// step starts afresh).
    fn set_rod_state(&mut self, _rows: Vec<f64>) {}

    /// The [`Self::warm_state`] of rods whose [`Self::rod_state`] is `rows` (to checkpoint a
    /// whole box gathered from ranks in the single-process layout).
    fn warm_state_of(&self, _rows: &[f64]) -> Vec<f64> {
        Vec::new()
    }

    /// The periodic sum's adaptive state ([`crate::ewald::periodic::PeriodicStokes::adaptive_state`]),
    /// for checkpoints; empty without a sum.
    fn sum_state(&self) -> Vec<u32> {
        Vec::new()
    }

    /// Restore what [`Self::sum_state`] returned.
    fn set_sum_state(&mut self, _state: &[u32]) {}
}

/// A mobility on one rank's part of a box shared by several (collective; see
/// [`crate::parallel::comm`]): `rods` are the rank's own rods, then copies. The defaults are the
/// single-process methods, right for mobilities that act rod by rod.
pub trait SharedMobility: Mobility {
    /// How far beyond its slab a rank should hold copies for this mobility's shared sums
    /// (`total` rods in a box of side `box_length`); zero for mobilities that act rod by rod.
    fn shared_reach(&self, _total: usize, _box_length: f64) -> f64 {
        0.0
    }
    /// [`Mobility::predicted_velocities`], correct for the own rods (the step copies the
    /// owners' values to the copies).
    fn predicted_velocities_shared(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
        _part: crate::parallel::part::Part<'_>,
    ) -> Result<(), MobilityError> {
        self.predicted_velocities(rods, p, out)
    }
    /// [`Mobility::final_velocities`] (the caller then copies the owners' velocities to the
    /// copies): correct for the own rods, whose `contact` are their owners' totals.
    fn final_velocities_shared(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        contact: &[(Vec3, Vec3)],
        out: &mut RodVelocities,
        _part: crate::parallel::part::Part<'_>,
    ) -> Result<(), MobilityError> {
        self.final_velocities(rods, p, contact, out)
    }
}

/// Free swimming with local slender-body drag (`hydrodynamics = "none"`).
#[derive(Clone, Debug)]
pub struct LocalDrag {
    diameter: f64,
    trans: f64,
    rot: f64,
}

impl LocalDrag {
    /// Local drag of rods of diameter `b`: `(eta/l)(I + pp)`, `(12 eta/l^3)(I - pp)` with
    /// `eta = ln(2l/b)/(4 pi mu)`.
    pub fn new(diameter: f64) -> Self {
        let e = eta(diameter);
        Self {
            diameter,
            trans: e / ROD_LENGTH,
            rot: 12.0 * e / ROD_LENGTH.powi(3),
        }
    }

    /// The translational and rotational coefficients `(eta/l, 12 eta/l^3)`.
    pub fn coefficients(&self) -> (f64, f64) {
        (self.trans, self.rot)
    }
}

impl Default for LocalDrag {
    /// Rods of the default diameter `l/5`.
    fn default() -> Self {
        Self::new(DEFAULT_DIAMETER)
    }
}

impl MobilityState for LocalDrag {}

impl SharedMobility for LocalDrag {}

impl Mobility for LocalDrag {
    fn name(&self) -> &'static str {
        "none"
    }

    fn on_ranks(&mut self) -> Option<&mut dyn SharedMobility> {
        Some(self)
    }

    fn diameter(&self) -> f64 {
        self.diameter
    }

    fn free_velocities(
        &mut self,
        _rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        out.v
            .par_iter_mut()
            .zip(p)
            .for_each(|(v, p)| *v = scale(SWIM_SPEED, *p));
        out.w.par_iter_mut().for_each(|w| *w = [0.0; 3]);
        Ok(())
    }

    #[inline]
    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3) {
        let v = scale(self.trans, axpy(f, dot(p, f), p));
        let w = scale(self.rot, sub(t, scale(dot(p, t), p)));
        (v, w)
    }
}
