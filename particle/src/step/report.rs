//! What a particle step did ([`StepReport`]) and why one failed ([`StepError`]).

use crate::model::geometry::Vec3;
use crate::step::contact::{ContactError, ContactReport};
use serde::{Deserialize, Serialize};

/// Seconds in the stages of a step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimes {
    /// The cell list and the rods sorted in its order.
    pub cells: f64,
    /// The contact constraints' assembly.
    pub constraints: f64,
    /// The velocities the contact problem plans with (the mobility's prediction).
    pub free_velocities: f64,
    /// The contact problem.
    pub contacts: f64,
    /// The step's velocities from the contact forces, the correction and the move.
    pub update: f64,
}

impl StageTimes {
    /// The stages' seconds in the order of the fields.
    pub fn as_array(&self) -> [f64; 5] {
        [
            self.cells,
            self.constraints,
            self.free_velocities,
            self.contacts,
            self.update,
        ]
    }
}

impl std::ops::AddAssign<&StageTimes> for StageTimes {
    fn add_assign(&mut self, other: &StageTimes) {
        self.cells += other.cells;
        self.constraints += other.constraints;
        self.free_velocities += other.free_velocities;
        self.contacts += other.contacts;
        self.update += other.update;
    }
}

/// What a step did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    /// Contact solver report.
    pub contact: ContactReport,
    /// Largest overlap among constrained pairs after the step (rod lengths).
    pub max_overlap: f64,
    /// Constraints that needed a correction impulse after the step's velocities were known
    /// (zero without hydrodynamics; see [`crate::step::stepper::Stepper::step`]).
    pub correction_active: usize,
    /// Rounds of the position projection that removed overlaps the linearised step left
    /// (zero in most steps; see [`crate::step::stepper::Stepper::step`]).
    pub projections: usize,
    /// Mean rod speed.
    pub mean_speed: f64,
    /// Largest rod speed `max |v|` (beta l).
    pub max_speed: f64,
    /// Largest rotation rate `max |w|` (beta): `dt max|w|` is the angle the linearised contact
    /// constraints neglect the square of.
    pub max_rotation_rate: f64,
    /// Polar order `|mean p|`.
    pub polar_order: f64,
    /// Sum of all contact forces (zero up to round-off: they are equal and opposite).
    pub net_contact_force: Vec3,
    /// Seconds in the step's stages.
    pub seconds: StageTimes,
    /// What the hydrodynamics did (GMRES iterations and residuals, sums).
    pub hydro: crate::hydro::mobility::HydroReport,
}

/// Step failures.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StepError {
    /// The contact solver failed.
    #[error(transparent)]
    Contact(#[from] ContactError),
    /// Rods overlap beyond the tolerance after the step.
    #[error(
        "rods {i} and {j} overlap by {overlap:.3e} l after the step (tolerance {tolerance:.1e} l): reduce dt or increase contact.margin"
    )]
    Overlap {
        /// First rod.
        i: u32,
        /// Second rod.
        j: u32,
        /// Overlap depth.
        overlap: f64,
        /// Tolerance.
        tolerance: f64,
    },
    /// The hydrodynamic solve failed.
    #[error(transparent)]
    Hydrodynamics(#[from] crate::hydro::mobility::MobilityError),
    /// A velocity or position became NaN or infinite, or a velocity would carry a rod across
    /// the box in one step.
    #[error(
        "rod {0} has a non-finite velocity or position, or one that crosses the box in one step"
    )]
    NonFinite(usize),
    /// A step shared by several ranks with a mobility that is not shared yet.
    #[error(
        "the {mobility_name} mobility runs on one process only ({ranks} ranks asked for): run it without mpirun"
    )]
    NotShared {
        /// The mobility's name.
        mobility_name: &'static str,
        /// Ranks asked for.
        ranks: usize,
    },
    /// The device (feature `gpu`) failed.
    #[error("the GPU step failed: {0}")]
    Device(String),
    /// The time step is not a positive finite number.
    #[error("time step dt = {0} must be positive and finite (units of l / U)")]
    InvalidTimeStep(f64),
    /// The rods' diameter is not the one the mobility was built for.
    #[error(
        "the rods have diameter {rods} l but the {mobility_name} mobility was built for {mobility} l: build both from one diameter"
    )]
    DiameterMismatch {
        /// The rods' diameter.
        rods: f64,
        /// The mobility's.
        mobility: f64,
        /// The mobility's name.
        mobility_name: &'static str,
    },
}
