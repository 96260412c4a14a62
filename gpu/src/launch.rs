//! Kernel launches: one thread per element in blocks of [`THREADS`], arguments from a typed
//! [`Kernel`] struct.
#![allow(unsafe_code)]

use crate::device::{Device, Inner};
use crate::error::GpuError;
use crate::kernel::{Kernel, THREADS};

impl Device {
    /// Run kernel `K` with at least `threads` threads (`ceil(threads / THREADS)` blocks of
    /// [`THREADS`]; the kernel returns early for indices at or past its element count), with
    /// the arguments `kernel` holds.
    ///
    /// The arguments' number, order and types are those the kernel's declaration states
    /// ([`crate::kernels!`]), checked against its source when the device was opened; the
    /// host emulation also checks them against the compiled kernel's parameter types.
    ///
    /// # Safety
    /// Every index the kernel reads or writes for thread indices below the launched count
    /// must lie inside the buffer it indexes: nothing can check that.
    pub unsafe fn launch<K: Kernel>(&self, threads: usize, mut kernel: K) -> Result<(), GpuError> {
        let name = K::NAME;
        let blocks = threads.div_ceil(THREADS as usize).max(1);
        let blocks = u32::try_from(blocks)
            .map_err(|_| GpuError::Input(format!("{threads} threads for {name}")))?;
        let mut args = kernel.args();
        crate::fault::on_launch(name)?;
        self.count(|c| {
            c.launches += 1;
            *c.by_kernel.entry(name).or_default() += 1;
        });
        self.timed(
            || name.into(),
            || match &self.inner {
                // SAFETY: passed on from this function's contract; the types are the kernel's.
                Inner::Host(h) => unsafe { h.launch(name, blocks, &mut args) },
                #[cfg(feature = "cuda")]
                // SAFETY: passed on from this function's contract; the types are the kernel's.
                Inner::Cuda(c) => unsafe { c.launch(name, blocks, &mut args) },
            },
        )
    }
}
