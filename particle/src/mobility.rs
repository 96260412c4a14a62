//! How rods move under forces: the pluggable part of the step.
//!
//! A [`Mobility`] gives (a) the velocities the rods would have without contacts (swimming plus,
//! in later models, the hydrodynamic flow) and (b) the local response to a force and torque on
//! one rod, which the contact solver uses (MODEL.md §3: the QP may use the local mobility of
//! (P2)-(P3), block diagonal, while the flows that contact forces induce on other rods are left
//! to the hydrodynamic solve).
//!
//! [`LocalDrag`] is `hydrodynamics = "none"`: free swimming at `U p`, translational mobility
//! `(eta/l)(I + pp)` and rotational mobility `(12 eta / l^3)(I - pp)`. The projection `I - pp`
//! makes the rotational block well posed: spin about the rod's own axis is undefined for a
//! slender body and moves no point of the centerline, so it is set to zero (a torque's axial
//! part does nothing).

use crate::geometry::{Vec3, axpy, dot, scale, sub};
use crate::rods::RodSet;
use crate::units::{ROD_LENGTH, SWIM_SPEED, eta};
use rayon::prelude::*;

/// Velocities of all rods.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RodVelocities {
    /// Centre velocities.
    pub v: Vec<Vec3>,
    /// Angular velocities.
    pub w: Vec<Vec3>,
}

impl RodVelocities {
    /// Zero velocities for `n` rods.
    pub fn zeros(n: usize) -> Self {
        Self {
            v: vec![[0.0; 3]; n],
            w: vec![[0.0; 3]; n],
        }
    }
}

/// The pluggable mobility of the particle step.
pub trait Mobility: Send + Sync + std::fmt::Debug {
    /// Name as in the config (`"none"`, later `"dipole"`, `"sbt"`).
    fn name(&self) -> &'static str;
    /// Velocities without contact forces, written into `out`.
    fn free_velocities(&mut self, rods: &RodSet, p: &[Vec3], out: &mut RodVelocities);
    /// Local response `(v, w)` of a rod with axis `p` to force `f` and torque `t`.
    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3);
}

/// Free swimming with local slender-body drag (`hydrodynamics = "none"`).
#[derive(Clone, Debug)]
pub struct LocalDrag {
    trans: f64,
    rot: f64,
}

impl Default for LocalDrag {
    fn default() -> Self {
        Self {
            trans: eta() / ROD_LENGTH,
            rot: 12.0 * eta() / ROD_LENGTH.powi(3),
        }
    }
}

impl Mobility for LocalDrag {
    fn name(&self) -> &'static str {
        "none"
    }

    fn free_velocities(&mut self, _rods: &RodSet, p: &[Vec3], out: &mut RodVelocities) {
        out.v
            .par_iter_mut()
            .zip(p)
            .for_each(|(v, p)| *v = scale(SWIM_SPEED, *p));
        out.w.par_iter_mut().for_each(|w| *w = [0.0; 3]);
    }

    #[inline]
    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3) {
        let v = scale(self.trans, axpy(f, dot(p, f), p));
        let w = scale(self.rot, sub(t, scale(dot(p, t), p)));
        (v, w)
    }
}
