//! The particle step on a GPU (feature `gpu`), room by room; what is here so far:
//! - the rods' cell list and their neighbour pairs (`cells.rs`, `cells.cu`), the twins of
//!   `model::cells` (the contact search's candidates: every pair of centres closer
//!   than the reach, each once, `i < j`). Each centre's cell and the cells' counts
//!   (`cell_count`, an integer atomic), the cells' starts (a prefix sum, `scan.cu`), the
//!   members scattered into cell order (`cell_scatter`) and each cell's members put in
//!   increasing index (`cell_order`, so the list is the CPU's whatever order the atomics
//!   took); then each centre's neighbours `j > i` counted over the 27 cells around its own
//!   (`pair_count`), offset by the same prefix sum and written in increasing `j`
//!   (`pair_write`). The pairs come out sorted by `(i, j)` with no atomics after the cell
//!   counts, so the list is the same from run to run on a GPU too. Counted work: 7 launches, 2
//!   integer atomics per centre, one pass over the 27 cells around each centre twice;
//! - the rods' update (`update.rs`, `update.cu`), the twin of the stepper's: explicit Euler for
//!   the centres, wrapped into the box with the images crossed counted, and the quaternions
//!   turned by the exponential of `dt w` (one thread per rod, no atomics);
//! - the contact constraints of the pairs (`contacts.rs`, `contacts.cu`), the twins of
//!   [`crate::step::constraints::constraint`]: the closest points of each pair's centerlines,
//!   a constraint where they are closer than `b + margin`, compacted in the pairs' order by a
//!   flag per pair and its prefix sum (no atomics);
//! - the contact solver (`solver.rs`, `contacts.cu`): BBPGD with its products (forces and
//!   local drag per rod over per-rod lists in constraint order, rates per constraint) and its
//!   reductions (the CPU's fixed chunks) on the device, the host deciding each iteration from
//!   four downloaded numbers;
//! - a step of the local-drag (`none`) level joining them (`step.rs`, `step.cu`): pairs,
//!   constraints, swimming velocities, the contact problem, the contact velocities, the move,
//!   the true overlaps after it and their projection (the stepper's: the same pairs'
//!   constraints rebuilt, a contact problem with no free motion through the translational
//!   drag, the rods translated);
//! - [`DeviceStepper`] (`stepper.rs`): that step with the rods resident on the device, each
//!   contact problem started from the last step's multipliers of the same pairs (a binary
//!   search of each constraint's pair among the last step's, both sorted by pair), the CPU
//!   step's report and failures, downloads only for outputs, checkpoints and failures;
//!   [`DeviceStepper::step_from`] takes the free velocities from the host instead of
//!   swimming alone: the step of the levels whose contacts act through the local drag
//!   (`dipole`, `sbt-explicit`), their flow summed on the host (its Fourier part on the
//!   device), which then downloads the rods (7 values each) and uploads the free velocities
//!   (6) every step.
//!
//! Runs with `device = "gpu"` step with [`DeviceStepper`] at every level; at `sbt` (GMRES,
//! contact forces through the full mobility) the step's final velocities come from the
//! mobility's solve with the contact forces on the device, followed by the CPU stepper's
//! correction (a second contact problem from zero), before the move
//! ([`crate::hydro::mobility::Mobility::final_velocities_resident`]).
//! The device itself and the prefix sum the rooms share are in `device.rs`.

mod cells;
mod contacts;
mod device;
mod signatures;
mod solver;
mod step;
mod stepper;
mod update;

pub use cells::DevicePairs;
pub use contacts::DeviceConstraints;
pub use device::GpuStep;
pub use solver::{DeviceContactError, DeviceContactProblem};
pub use step::DeviceStepReport;
pub use stepper::{DeviceStepper, RodKinematics};
pub use update::DeviceRods;
