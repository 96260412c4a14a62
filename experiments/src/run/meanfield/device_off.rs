//! The mean-field step on a GPU in a build without the `gpu` feature: no GPU stepper exists
//! (its type has no values), and a run with `device = "gpu"` is refused with how to build it.

use super::step_error::EngineError;
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepReport, MeanFieldStepper};

/// Without a device only `MOTILE_GPU_MEMORY_LIMIT` can refuse a run's need (the run itself is
/// refused when it opens the device).
pub(super) fn check_memory(need: crate::run::memory::GpuMemoryNeed) -> anyhow::Result<()> {
    need.check(None, crate::run::memory::gpu_memory_limit()?)
}

/// The GPU stepper of a mean-field run: none in this build.
pub(super) enum GpuEngine {}

impl GpuEngine {
    /// A run with `device = "gpu"`: refused, with how to build a motile that has it.
    pub(super) fn open(_rhs: &MeanFieldRhs, _cpu: &MeanFieldStepper) -> anyhow::Result<Self> {
        anyhow::bail!(
            "device = \"gpu\": this motile was built without GPU support; build it with `cargo install --path experiments --features gpu` (CUDA is loaded when a run starts: the build needs nothing but cargo)"
        )
    }

    pub(super) fn describe(&self) -> String {
        match *self {}
    }

    pub(super) fn step(
        &mut self,
        _dt: f64,
        _with_entropy: bool,
    ) -> Result<(MeanFieldStepReport, f64), EngineError> {
        match *self {}
    }

    pub(super) fn synced(&self, _cpu: &MeanFieldStepper) -> anyhow::Result<MeanFieldStepper> {
        match *self {}
    }
}
