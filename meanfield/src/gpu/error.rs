//! Why the GPU mean-field step is unavailable or failed.

use crate::solver::params::MeanFieldError;

/// Why the GPU path is unavailable or failed: the device's error, or the step's own (as it
/// would fail on the CPU).
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// The device: no GPU, a driver, compiler or FFT failure, or a call that does not fit.
    #[error(transparent)]
    Device(#[from] motile_gpu::GpuError),
    /// The step itself failed, as it would on the CPU.
    #[error(transparent)]
    Step(#[from] MeanFieldError),
}
