//! Why a mean-field step failed ([`EngineError`]): the model's own failure, which the run
//! retries with a smaller step or reports as the model's, or the device's.

use motile_meanfield::solver::params::MeanFieldError;

/// A failed step: the model's own failure, or the device's.
pub(super) enum EngineError {
    /// The model's (a value that blew up, a fixed point that did not converge).
    Model(MeanFieldError),
    /// The device's, in words. Made only by a device, which a build without the `gpu` feature
    /// cannot have.
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    Device(String),
}
