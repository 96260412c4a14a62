//! How a run fails, typed from the libraries' errors to the CLI: a failed step ends a run with a
//! [`RunFailure`] (what failed, when, where the last good state is) inside its `anyhow` chain,
//! so callers such as the stability maps classify failures by variant, never by message text.

use motile_meanfield::solver::params::MeanFieldError;
use motile_particle::ewald::periodic::SumError;
use motile_particle::hydro::mobility::MobilityError;
use motile_particle::step::report::StepError;

/// What made a step fail.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FailureKind {
    /// Particle: rods overlap beyond the tolerance after the step.
    Overlap,
    /// Particle: the contact solver did not converge.
    ContactSolver,
    /// Particle: GMRES (slender-body solve) or a fast sum failed.
    Hydrodynamics,
    /// A velocity, position or field value became NaN or infinite.
    NonFinite,
    /// Mean field: `Q / tr Q` lost positive semi-definiteness beyond the limit.
    Realizability,
    /// Mean field: the Stokes fixed point did not converge.
    FixedPoint,
    /// The GPU failed (a driver, compiler or cuFFT error), not the model.
    Device,
    /// The step was given inconsistent inputs (rods and mobility of different diameters): a
    /// setup error, not a numerical failure.
    Setup,
}

impl From<&StepError> for FailureKind {
    fn from(e: &StepError) -> Self {
        match e {
            StepError::Contact(_) => Self::ContactSolver,
            StepError::Overlap { .. } => Self::Overlap,
            StepError::Hydrodynamics(MobilityError::Sum(SumError::Device(_))) => Self::Device,
            StepError::Hydrodynamics(MobilityError::Gmres { .. } | MobilityError::Sum(_)) => {
                Self::Hydrodynamics
            }
            StepError::NonFinite(_) => Self::NonFinite,
            StepError::Device(_) => Self::Device,
            StepError::DiameterMismatch { .. }
            | StepError::InvalidTimeStep(_)
            | StepError::NotShared { .. }
            | StepError::Hydrodynamics(MobilityError::NotShared(_)) => Self::Setup,
        }
    }
}

impl From<&MeanFieldError> for FailureKind {
    fn from(e: &MeanFieldError) -> Self {
        match e {
            MeanFieldError::FixedPoint { .. } => Self::FixedPoint,
            MeanFieldError::NonFinite(_) => Self::NonFinite,
        }
    }
}

/// A run stopped by a failed step. Its message says what failed, at which step and time, and
/// where the state before it is saved.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct RunFailure {
    /// What failed.
    pub kind: FailureKind,
    /// The step that failed (1-based).
    pub step: u64,
    /// The simulated time the run reached (the state before the failed step).
    pub t: f64,
    /// The whole message.
    pub message: String,
}

impl RunFailure {
    /// The failure inside an error chain, if the error is one.
    pub fn of(e: &anyhow::Error) -> Option<&RunFailure> {
        e.chain().find_map(|c| c.downcast_ref::<RunFailure>())
    }
}
