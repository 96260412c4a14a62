//! One time step (docs/MODEL.md §1, §3): the cell list, contact constraints, the BBPGD contact
//! solver and the stepper that runs them around a mobility; (feature `gpu`) the cell list and
//! neighbour pairs on a device.

pub(crate) mod cells;
pub mod constraints;
pub mod contact;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod report;
pub mod stepper;
