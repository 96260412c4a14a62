//! One time step (docs/MODEL.md §1, §3): contact constraints, the BBPGD contact solver, the
//! stepper that runs them around a mobility, the driver of a box shared among ranks; (feature
//! `gpu`) the whole step on a device.

pub mod constraints;
pub mod contact;
pub mod distributed;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod report;
pub mod stepper;
