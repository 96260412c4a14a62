//! One time step (docs/MODEL.md §1, §3): the cell list, contact constraints, the BBPGD contact
//! solver and the stepper that runs them around a mobility.

pub(crate) mod cells;
pub mod constraints;
pub mod contact;
pub mod report;
pub mod stepper;
