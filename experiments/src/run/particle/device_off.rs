//! The particle step on a GPU in a build without the `gpu` feature: no device stepper exists
//! (its type has no values), and a run with `device = "gpu"` is refused with how to build it.

use motile_particle::model::rods::RodSet;
use motile_particle::step::contact::{ContactParams, WarmStart};

/// Per rod: velocities, angular velocities and contact forces.
type RodKinematics = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>);

/// Without the `gpu` feature no device stepper exists (the type has no values).
#[derive(Debug)]
pub(crate) enum DeviceStepper {}

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

/// A run with `device = "gpu"`: refused, with how to build a motile that has it.
pub(crate) fn open(
    _rods: &RodSet,
    _contact: &ContactParams,
    _warm: &WarmStart,
    _need: crate::run::memory::GpuMemoryNeed,
) -> anyhow::Result<DeviceStepper> {
    anyhow::bail!(
        "device = \"gpu\": this motile was built without GPU support; build it with `cargo install --path experiments --features gpu` (CUDA is loaded when a run starts: the build needs nothing but cargo)"
    )
}
