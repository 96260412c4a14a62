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

/// Device bytes per grid point at the GPU step's peak (state, history, velocity, the closure's
/// per-point values and the transforms' buffers; tables and wavenumbers are small), measured
/// on the host emulation's tally of device buffers at 12^3 and 20^3 (`tests/gpu_memory.rs`,
/// feature `gpu`, which fails where the measured figure is not within 0.8-1 of this): what a
/// run's memory check assumes. With the CUDA context (0.55 GB) it gives 10.6 GB at 256^3,
/// against 9.89 GB in use measured on an H100 (docs/gpu.md): 7% to spare.
pub const GPU_BYTES_PER_POINT: f64 = 600.0;

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
