//! Devices for motile's GPU back-ends: typed device buffers (`f64`, `i32`, `u32`), kernels
//! compiled at run time and launched through typed argument structs, batched 3D real FFTs, in
//! two implementations of one interface, opened one way ([`Device::open`] with a [`Backend`]).
//!
//! - **CUDA** (feature `cuda`): the driver, NVRTC and cuFFT are loaded when a device is opened
//!   (cudarc's dynamic loading), so a build needs no CUDA toolkit, and a machine without a GPU
//!   gets [`GpuError::NoDevice`] instead of a panic. Kernels are CUDA C compiled by NVRTC;
//!   transforms are cuFFT's (`D2Z`/`Z2D`, unnormalised).
//! - **Host emulation** ([`Backend::HostEmulation`]): the *same kernel source* compiled by the
//!   system's C++ compiler with a small prelude that defines CUDA's thread indices and
//!   `atomicAdd`, every thread of every block run one after another on one CPU thread, and the
//!   transforms done by [`motile_analysis::fft3::RealFft3`] in cuFFT's layout and scaling. It is
//!   slow; it exists so that kernels, their argument lists and the host code around them are
//!   tested on machines without a GPU (where CI runs). It also checks every launch's argument
//!   list against the kernel's parameter types, which the CUDA driver cannot. A source that
//!   uses `__syncthreads` (block reductions in shared memory) runs each block's threads as OS
//!   threads with a barrier, one block at a time.
//!
//! - **A CUDA compile check without a GPU** ([`frontend`]): a kernel set compiled as CUDA
//!   device code by clang, which refuses what only a C++ compiler takes, and each kernel's
//!   stack read off the PTX.
//!
//! Layouts: a real field of an `M^3` grid is `M^3` values, x fastest (`(z M + y) M + x`); its
//! half spectrum `M M (M/2 + 1)` complex values as interleaved `(re, im)` pairs, the x mode
//! fastest (`((kz M + ky)(M/2 + 1) + kx)`); a batch stores its fields one after another.
//!
//! Kernels are declared with [`kernels!`]: one struct of named, typed arguments per kernel,
//! beside its CUDA source, checked against the source's signatures when a device opens it, so a
//! launch with a wrong argument does not compile and a declaration that drifts from the source
//! is refused.
//!
//! Device failures can be injected ([`inject_failure`], `MOTILE_GPU_INJECT_FAILURE`) to test
//! what the code around the kernels does when a device fails mid-step.
//!
//! The only unsafe code of the crate is in the modules that load libraries and launch kernels;
//! [`Device::launch`] itself is `unsafe`: nothing can check that a kernel indexes inside the
//! buffers it is given.

mod buffer;
mod counters;
#[cfg(feature = "cuda")]
mod cuda;
mod device;
mod error;
mod fault;
mod fft;
pub mod frontend;
mod host;
mod kernel;
mod launch;
pub mod profile;

pub use buffer::{Buffer, Element, check_len, live_bytes, peak_bytes, reset_peak};
pub use counters::Counters;
pub use device::{Backend, Device, open_or_skip, probe};
pub use error::{DeviceInfo, GpuError, kernel_int};
pub use fault::{Injection, inject_failure};
pub use fft::{Direction, Fft3, fft_work_bytes};
#[doc(hidden)]
pub use kernel::Arg;
pub use kernel::{Kernel, KernelArg, KernelSet, THREADS, c_type_code};
