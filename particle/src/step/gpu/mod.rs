//! The particle step on a GPU (feature `gpu`), room by room; what is here so far:
//! - the rods' cell list and their neighbour pairs (`cells.rs`, `cells.cu`), the twins of
//!   [`crate::step::cells`] (the contact search's candidates: every pair of centres closer
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
//!   constraints, swimming velocities, the contact problem, the contact velocities, the move
//!   and the true overlaps after it (no warm start and no overlap projection yet);
//! - [`DeviceStepper`] (`stepper.rs`): that step with the rods resident on the device, the
//!   CPU step's report and failures, downloads only for outputs, checkpoints and failures.
//!
//! The hydrodynamic levels and GMRES still run on the CPU (issue 29's
//! item 2 is open beyond these rooms), so a run does not use them yet.
#![allow(unsafe_code)]

mod cells;
mod contacts;
mod signatures;
mod solver;
mod step;
mod stepper;
mod update;

pub use cells::DevicePairs;
pub use contacts::DeviceConstraints;
pub use solver::{DeviceContactError, DeviceContactProblem};
pub use step::DeviceStepReport;
pub use stepper::{DeviceStepper, RodKinematics};
pub use update::DeviceRods;

use motile_gpu::{Backend, Buffer, Device, GpuError, THREADS};

/// A device with the step's kernels compiled.
#[derive(Debug)]
pub struct GpuStep {
    dev: Device,
}

fn int(v: usize, what: &str) -> Result<i32, GpuError> {
    i32::try_from(v).map_err(|_| GpuError::Input(format!("{what} {v} exceeds an int")))
}

impl GpuStep {
    /// The device `backend` names, with the kernels compiled.
    pub fn open(backend: Backend) -> Result<Self, GpuError> {
        Ok(Self {
            dev: Device::open(backend, &signatures::KERNELS)?,
        })
    }

    /// What the device is, in words.
    pub fn describe(&self) -> String {
        self.dev.describe()
    }

    /// `start[0..=n]`: the exclusive prefix sum of `count[0..n]`, the last value the total
    /// (`bin_scan`, one block).
    fn scan(&self, count: &Buffer<i32>, start: &mut Buffer<i32>, n: usize) -> Result<(), GpuError> {
        assert_eq!(
            THREADS, 256,
            "bin_scan's shared array holds 256 partial sums"
        );
        if count.len() < n || start.len() < n + 1 {
            return Err(GpuError::Input(format!(
                "prefix sum of {n} values: buffers of {} and {}",
                count.len(),
                start.len()
            )));
        }
        // SAFETY: one block of THREADS = 256 threads (asserted, the size of its shared array):
        // reads count[0..n] and writes start[0..=n], both checked above.
        unsafe {
            self.dev.launch(
                THREADS as usize,
                signatures::CellScan {
                    count,
                    start,
                    nbins: int(n, "values")?,
                },
            )
        }
    }

    /// On the host emulation, run blocks in a random order at every launch (to expose races).
    pub fn shuffle_blocks(&self, seed: u64) -> bool {
        self.dev.shuffle_blocks(seed)
    }
}
