//! Kernel launches: one thread per element in blocks of [`THREADS`].
#![allow(unsafe_code)]

use crate::{Arg, Backend, Device, GpuError};

/// Threads per block of every launch.
pub const THREADS: u32 = 256;

impl Device {
    /// Run `kernel` with at least `threads` threads (`ceil(threads / THREADS)` blocks of
    /// [`THREADS`]; the kernel returns early for indices at or past its element count).
    ///
    /// On the host emulation the arguments are checked against the kernel's parameter types
    /// (an error, not undefined behaviour, if they differ); the CUDA driver cannot check them.
    ///
    /// # Safety
    /// `args` must match the kernel's parameters in number, order and type (`In` a `const
    /// double*`, `Out` a `double*`, `Int` an `int`, `Real` a `double`), and every index the
    /// kernel reads or writes for thread indices below the launched count must lie inside the
    /// buffer it indexes.
    pub unsafe fn launch(
        &self,
        kernel: &str,
        threads: usize,
        args: &mut [Arg<'_>],
    ) -> Result<(), GpuError> {
        let blocks = threads.div_ceil(THREADS as usize).max(1);
        let blocks = u32::try_from(blocks)
            .map_err(|_| GpuError::Input(format!("{threads} threads for {kernel}")))?;
        match &self.backend {
            // SAFETY: passed on from this function's contract.
            Backend::Host(h) => unsafe { h.launch(kernel, blocks, args) },
            #[cfg(feature = "cuda")]
            // SAFETY: passed on from this function's contract.
            Backend::Cuda(c) => unsafe { c.launch(kernel, blocks, args) },
        }
    }
}
