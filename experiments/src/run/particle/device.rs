//! The particle step resident on a GPU for runs with `device = "gpu"` at the `none`, `dipole`,
//! `sbt-explicit` and `sbt` levels ([`motile_particle::step::gpu::DeviceStepper`]).

use motile_particle::model::rods::RodSet;
use motile_particle::step::contact::{ContactParams, WarmStart};

use crate::run::memory::{GpuMemoryNeed, gpu_memory_limit};

pub(crate) use motile_particle::step::gpu::DeviceStepper;

/// The device stepper for `rods` (`MOTILE_GPU_BACKEND` says which device, CUDA by default):
/// an error, never a CPU fallback, where there is none.
/// Checked before the first step allocates its buffers (only the rods are on the device by
/// then): a run whose measured need ([`GpuMemoryNeed`]) exceeds the device's free memory, or
/// `MOTILE_GPU_MEMORY_LIMIT` bytes where that is set (a shared GPU; the host emulation), is
/// refused with the figures.
pub(crate) fn open(
    rods: &RodSet,
    contact: &ContactParams,
    warm: &WarmStart,
    need: GpuMemoryNeed,
) -> anyhow::Result<DeviceStepper> {
    let stepper = DeviceStepper::new(crate::run::gpu_backend()?, rods, contact.clone(), warm)
        .map_err(|e| anyhow::anyhow!("device = \"gpu\": {e}"))?;
    let device = stepper
        .memory()
        .map_err(|e| anyhow::anyhow!("device = \"gpu\": {e}"))?
        .map(|(used, total)| (total.saturating_sub(used), total));
    need.check(device, gpu_memory_limit()?)?;
    Ok(stepper)
}
