//! Why a device is unavailable or an operation on it failed, and what a probe finds.

/// Why a device is unavailable or an operation on it failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No CUDA driver library, or no device, or (host emulation) no C++ compiler.
    #[error("no CUDA device found: {0}")]
    NoDevice(String),
    /// A driver call failed.
    #[error("CUDA driver: {0}")]
    Driver(String),
    /// The kernels did not compile (NVRTC, or the host compiler for the emulation).
    #[error("compiling the kernels: {0}")]
    Compile(String),
    /// A transform failed.
    #[error("FFT: {0}")]
    Fft(String),
    /// A call that does not fit: an unknown kernel, a kernel declaration that does not match
    /// its source, a buffer of another device or of the wrong length.
    #[error("{0}")]
    Input(String),
}

impl GpuError {
    /// A buffer or plan of another device was given.
    pub(crate) fn foreign() -> Self {
        GpuError::Input("a buffer or plan of another device".into())
    }
}

/// `v` as a kernel's `int` (sizes, indices, counts), or an error naming `what` where it does
/// not fit.
pub fn kernel_int(v: usize, what: &str) -> Result<i32, GpuError> {
    i32::try_from(v).map_err(|_| GpuError::Input(format!("{what} {v} exceeds an int")))
}

/// What [`crate::probe`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// The device's name.
    pub name: String,
    /// Its memory in bytes.
    pub memory: usize,
    /// Its free memory in bytes when probed (all processes' use subtracted).
    pub free_memory: usize,
    /// Compute capability (major, minor).
    pub compute_capability: (i32, i32),
}
