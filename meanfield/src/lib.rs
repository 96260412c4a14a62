//! The mean-field model of docs/MODEL.md §4: the orientation tensor Q with the Bingham closure.
//! The Bingham distribution's moments and its inversion ([`bingham`]), the tabulated fast closure
//! ([`closure`], eigenvalues sorted largest first by the `eigen` module), the pseudo-spectral Stokes
//! fixed point and SBDF2 stepping ([`solver`]), its step-size control ([`control`]), and initial perturbations of the isotropic state
//! shared with the particle model ([`initial`]).
#![warn(missing_docs)]
#![warn(unreachable_pub)]

mod bessel;
pub mod bingham;
pub mod closure;
pub mod control;
mod eigen;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod initial;
pub mod solver;

/// What a user of the mean-field model needs, in one import: `use motile_meanfield::prelude::*;`.
pub mod prelude {
    pub use crate::closure::BinghamClosure;
    pub use crate::control::StepControl;
    pub use crate::initial::{Perturbation, PerturbationField, from_particles};
    pub use crate::solver::grid::SpectralGrid;
    pub use crate::solver::params::{MeanFieldError, MeanFieldParams};
    pub use crate::solver::rhs::MeanFieldRhs;
    pub use crate::solver::stepper::{MeanFieldStepReport, MeanFieldStepper, SBDF2};
}
