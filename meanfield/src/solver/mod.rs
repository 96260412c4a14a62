//! The mean-field solver (docs/MODEL.md §4): parameters and failures, the spectral grid, the
//! closure field, the right-hand side with its Stokes fixed point, and the IMEX time stepper.

pub mod closure_field;
pub mod grid;
pub mod params;
pub mod rhs;
pub mod stepper;
