//! The device the step's kernels run on ([`GpuStep`]): opened once, with the kernels of
//! `signatures.rs` compiled; the prefix sum the rooms share. See [`super`].
#![allow(unsafe_code)]

use super::signatures;
use motile_gpu::{Backend, Buffer, Device, GpuError};

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

    /// What the device has been asked to do so far: launches, transfers.
    pub fn counters(&self) -> motile_gpu::Counters {
        self.dev.counters()
    }

    /// What the device is, in words.
    pub fn describe(&self) -> String {
        self.dev.describe()
    }

    /// `start[0..=n]`: the exclusive prefix sum of `count[0..n]`, the last value the total
    /// (the sums' `prefix_sum`: scan.cu is in this set too).
    pub(super) fn scan(
        &self,
        count: &Buffer<i32>,
        start: &mut Buffer<i32>,
        n: usize,
    ) -> Result<(), GpuError> {
        crate::ewald::gpu::prefix_sum(&self.dev, count, start, n)
    }

    /// On the host emulation, run blocks in a random order at every launch (to expose races).
    pub fn shuffle_blocks(&self, seed: u64) -> bool {
        self.dev.shuffle_blocks(seed)
    }
}
