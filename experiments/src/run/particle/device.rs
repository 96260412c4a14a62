//! The particle step resident on a GPU for runs with `device = "gpu"` at the `none`, `dipole`,
//! `sbt-explicit` and `sbt` levels ([`motile_particle::step::gpu::DeviceStepper`], feature `gpu`);
//! without the feature, such a run is refused with how to build it.

use motile_particle::model::rods::RodSet;
use motile_particle::step::contact::{ContactParams, WarmStart};

#[cfg(feature = "gpu")]
pub(crate) use motile_particle::step::gpu::DeviceStepper;

/// Per rod: velocities, angular velocities and contact forces.
#[cfg(not(feature = "gpu"))]
type RodKinematics = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>);

/// Without the `gpu` feature no device stepper exists (the type has no values).
#[cfg(not(feature = "gpu"))]
#[derive(Debug)]
pub(crate) enum DeviceStepper {}

#[cfg(not(feature = "gpu"))]
impl DeviceStepper {
    pub(crate) fn step(
        &mut self,
        _dt: f64,
    ) -> Result<motile_particle::step::report::StepReport, motile_particle::step::report::StepError>
    {
        match *self {}
    }
    pub(crate) fn step_with_flow(
        &mut self,
        _dt: f64,
        _mobility: &mut dyn motile_particle::hydro::mobility::Mobility,
        _at: &RodSet,
    ) -> Result<motile_particle::step::report::StepReport, motile_particle::step::report::StepError>
    {
        match *self {}
    }
    pub(crate) fn download(&self, _rods: &mut RodSet) -> anyhow::Result<()> {
        match *self {}
    }
    pub(crate) fn download_before(&self, _rods: &mut RodSet) -> anyhow::Result<()> {
        match *self {}
    }
    pub(crate) fn kinematics(&self) -> anyhow::Result<RodKinematics> {
        match *self {}
    }
    pub(crate) fn warm_start(&self) -> anyhow::Result<WarmStart> {
        match *self {}
    }
}

/// The device stepper for `rods` (`MOTILE_GPU_BACKEND` says which device, CUDA by default):
/// an error, never a CPU fallback, where there is none.
#[cfg(feature = "gpu")]
pub(crate) fn open(
    rods: &RodSet,
    contact: &ContactParams,
    warm: &WarmStart,
) -> anyhow::Result<DeviceStepper> {
    DeviceStepper::new(crate::run::gpu_backend()?, rods, contact.clone(), warm)
        .map_err(|e| anyhow::anyhow!("device = \"gpu\": {e}"))
}

#[cfg(not(feature = "gpu"))]
pub(crate) fn open(
    _rods: &RodSet,
    _contact: &ContactParams,
    _warm: &WarmStart,
) -> anyhow::Result<DeviceStepper> {
    anyhow::bail!(
        "device = \"gpu\": this motile was built without GPU support; build it with `cargo install --path experiments --features gpu` (CUDA is loaded when a run starts: the build needs nothing but cargo)"
    )
}

/// Whether `mobility` sums its flow on the device the rods are on
/// ([`motile_particle::hydro::mobility::Mobility::flows_on_device`]); never without the `gpu`
/// feature.
pub(crate) fn flows_on_device(
    mobility: &mut dyn motile_particle::hydro::mobility::Mobility,
) -> bool {
    #[cfg(feature = "gpu")]
    {
        mobility.flows_on_device()
    }
    #[cfg(not(feature = "gpu"))]
    {
        let _ = mobility;
        false
    }
}

/// Bring the host's copies of what resident steps keep on the device (the slender-body
/// solution: the outputs' force density) up to date
/// ([`motile_particle::hydro::mobility::Mobility::sync_resident`]); nothing without the `gpu`
/// feature.
pub(crate) fn sync_resident(
    mobility: &mut dyn motile_particle::hydro::mobility::Mobility,
) -> anyhow::Result<()> {
    #[cfg(feature = "gpu")]
    mobility.sync_resident()?;
    #[cfg(not(feature = "gpu"))]
    let _ = mobility;
    Ok(())
}

/// The mobility's warm state for a checkpoint, downloaded where resident steps keep it on the
/// device ([`motile_particle::hydro::mobility::Mobility::resident_warm_state`]).
pub(crate) fn warm_state(
    mobility: &dyn motile_particle::hydro::mobility::Mobility,
) -> anyhow::Result<Vec<f64>> {
    #[cfg(feature = "gpu")]
    if let Some(state) = mobility.resident_warm_state() {
        return Ok(state?);
    }
    Ok(mobility.warm_state())
}
