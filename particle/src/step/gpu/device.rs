//! The device the step's kernels run on ([`GpuStep`]): opened once, with the kernels of
//! `signatures.rs` compiled; the prefix sum the rooms share. See [`super`].
#![allow(unsafe_code)]

use super::signatures;
use motile_gpu::{Backend, Buffer, Device, GpuError, THREADS};

/// A device with the step's kernels compiled.
#[derive(Debug)]
pub struct GpuStep {
    pub(super) dev: Device,
}

pub(super) use motile_gpu::kernel_int as int;

impl GpuStep {
    /// The device `backend` names, with the kernels compiled.
    pub fn open(backend: Backend) -> Result<Self, GpuError> {
        Ok(Self {
            dev: Device::open(backend, &signatures::KERNELS)?,
        })
    }

    /// A buffer's values on the host (a buffer of this device, or of another opened on the
    /// same backend: CUDA opens device 0's primary context and its default stream for every
    /// [`Device`], so a resident sum's results are this device's too).
    pub fn download(&self, buf: &Buffer) -> Result<Vec<f64>, GpuError> {
        self.dev.download(buf)
    }

    /// What the device is, in words.
    pub fn describe(&self) -> String {
        self.dev.describe()
    }

    /// `start[0..=n]`: the exclusive prefix sum of `count[0..n]`, the last value the total
    /// (`bin_scan`, one block).
    pub(super) fn scan(
        &self,
        count: &Buffer<i32>,
        start: &mut Buffer<i32>,
        n: usize,
    ) -> Result<(), GpuError> {
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
