//! The particle step resident on a GPU for runs with `device = "gpu"` at the `none`, `dipole`,
//! `sbt-explicit` and `sbt` levels ([`motile_particle::step::gpu::DeviceStepper`]).

use motile_particle::model::rods::RodSet;
use motile_particle::step::contact::{ContactParams, WarmStart};

pub(crate) use motile_particle::step::gpu::DeviceStepper;

/// The device stepper for `rods` (`MOTILE_GPU_BACKEND` says which device, CUDA by default):
/// an error, never a CPU fallback, where there is none.
pub(crate) fn open(
    rods: &RodSet,
    contact: &ContactParams,
    warm: &WarmStart,
) -> anyhow::Result<DeviceStepper> {
    DeviceStepper::new(crate::run::gpu_backend()?, rods, contact.clone(), warm)
        .map_err(|e| anyhow::anyhow!("device = \"gpu\": {e}"))
}
