//! The mean-field step on a GPU for runs with `device = "gpu"`
//! ([`motile_meanfield::gpu::GpuMeanField`]): the state held on the device, downloaded into the
//! CPU stepper's form only for snapshots, diagnostics and checkpoints.

use super::step_error::EngineError;
use crate::run::memory::{GpuMemoryNeed, gpu_memory_limit};
use motile_meanfield::gpu::{GpuError, GpuMeanField};
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepReport, MeanFieldStepper};

/// Refuse a run whose GPU memory need exceeds the device's free memory (CUDA; probed before
/// anything is allocated) or `MOTILE_GPU_MEMORY_LIMIT` (also on the host emulation).
pub(super) fn check_memory(need: GpuMemoryNeed) -> anyhow::Result<()> {
    let device = match crate::run::gpu_backend()? {
        motile_gpu::Backend::Cuda => motile_gpu::probe()
            .ok()
            .map(|info| (info.free_memory, info.memory)),
        motile_gpu::Backend::HostEmulation => None,
    };
    need.check(device, gpu_memory_limit()?)
}

/// The GPU stepper of a mean-field run.
pub(super) struct GpuEngine(GpuMeanField);

impl GpuEngine {
    /// The GPU stepper (`MOTILE_GPU_BACKEND` says which device, CUDA by default) started from
    /// `cpu`'s state: an error, never a CPU fallback, where there is none.
    pub(super) fn open(rhs: &MeanFieldRhs, cpu: &MeanFieldStepper) -> anyhow::Result<Self> {
        GpuMeanField::open(crate::run::gpu_backend()?, rhs, cpu)
            .map(Self)
            .map_err(|e| anyhow::anyhow!("device = \"gpu\": {e}"))
    }

    /// What the device is.
    pub(super) fn describe(&self) -> String {
        self.0.describe()
    }

    /// One step of `dt` (with the entropy where `with_entropy`): its report and the time
    /// reached; nothing is committed when it fails.
    pub(super) fn step(
        &mut self,
        dt: f64,
        with_entropy: bool,
    ) -> Result<(MeanFieldStepReport, f64), EngineError> {
        match self.0.step(dt, with_entropy) {
            Ok(r) => Ok((r, self.0.t)),
            Err(GpuError::Step(e)) => Err(EngineError::Model(e)),
            Err(e) => Err(EngineError::Device(e.to_string())),
        }
    }

    /// The state, downloaded into `cpu`'s form.
    pub(super) fn synced(&self, cpu: &MeanFieldStepper) -> anyhow::Result<MeanFieldStepper> {
        let (t, q_hat, history, u_hat) = self
            .0
            .state()
            .map_err(|e| anyhow::anyhow!("downloading the state from the GPU: {e}"))?;
        let mut s = cpu.clone();
        s.restore(t, q_hat, history, u_hat);
        Ok(s)
    }
}
