//! A mobility's path on a device ([`ResidentMobility`]): its flow summed on the device the
//! rods are on (the rods' centres and quaternions never leaving it), and what the resident
//! steps keep there.

use crate::ewald::spectral::SpectralEwald;
use crate::hydro::report::{HydroReport, MobilityError};
use crate::hydro::sum::FlowSum;
use motile_gpu::{Buffer, Counters, GpuError};

/// Rods resident on a device, as a mobility's flow on that device reads them: centres
/// (triples, in `[0, L)^3`) and unit quaternions (`w, x, y, z`) of `len` rods in a box of side
/// `box_length`.
#[derive(Clone, Copy, Debug)]
pub struct RodsOnDevice<'a> {
    /// Centres.
    pub x: &'a Buffer,
    /// Quaternions.
    pub q: &'a Buffer,
    /// How many rods.
    pub len: usize,
    /// The box side.
    pub box_length: f64,
}

/// Velocities and angular velocities (triples per rod) left on a device.
#[derive(Debug)]
pub struct DeviceVelocities {
    /// Centre velocities.
    pub v: Buffer,
    /// Angular velocities.
    pub w: Buffer,
}

impl From<(Buffer, Buffer)> for DeviceVelocities {
    fn from((v, w): (Buffer, Buffer)) -> Self {
        Self { v, w }
    }
}

/// A mobility's path on a device ([`crate::hydro::mobility::Mobility::resident`]). The
/// defaults are a mobility whose flow is not on a device.
pub trait ResidentMobility {
    /// What the device of this mobility's sum has been asked to do so far (`None` without a
    /// sum on a device): for counting a resident step's work with its flow.
    fn sum_counters(&mut self) -> Option<Counters> {
        None
    }

    /// Whether [`Self::free_velocities_resident`] can run: the flow summed on the device the
    /// rods are on, without their round trip through the host.
    fn flows_on_device(&mut self) -> bool {
        false
    }

    /// The free velocities of the rods resident on a device, on that device; the report as
    /// the host's. The force density for outputs is not set
    /// ([`crate::hydro::mobility::Mobility::density_for`] sets it from the rods downloaded).
    /// `None` where this mobility has no such path ([`Self::flows_on_device`]).
    fn free_velocities_resident(
        &mut self,
        _rods: RodsOnDevice<'_>,
    ) -> Option<Result<DeviceVelocities, MobilityError>> {
        None
    }

    /// The velocities the contact solver plans with, of the rods resident on a device, on that
    /// device; by default [`Self::free_velocities_resident`].
    fn predicted_velocities_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
    ) -> Option<Result<DeviceVelocities, MobilityError>> {
        self.free_velocities_resident(rods)
    }

    /// Whether the step's velocities come from its contact forces through this mobility's
    /// full hydrodynamics on the device ([`Self::final_velocities_resident`]: `sbt`), not
    /// from the prediction plus their local drag.
    fn finishes_on_device(&self) -> bool {
        false
    }

    /// The step's velocities on the device, after [`Self::predicted_velocities_resident`] of
    /// the same rods: from each rod's contact force and torque `contact` (6 values per rod;
    /// `None` where no constraint is active), the velocities that replace the planned ones, or
    /// `None` where the prediction stands.
    fn final_velocities_resident(
        &mut self,
        _rods: RodsOnDevice<'_>,
        _contact: Option<&Buffer>,
    ) -> Result<Option<DeviceVelocities>, MobilityError> {
        Ok(None)
    }

    /// [`crate::hydro::mobility::MobilityState::warm_state`] where resident steps keep it on a
    /// device (`sbt`'s last solution and flow velocities), downloaded; `None` where the host's
    /// copy is current.
    fn resident_warm_state(&self) -> Option<Result<Vec<f64>, MobilityError>> {
        None
    }

    /// Bring the host's copies of what resident steps keep on a device (the warm state, the
    /// force density for outputs) up to date.
    fn sync_resident(&mut self) -> Result<(), MobilityError> {
        Ok(())
    }

    /// After a failed resident step: what this mobility keeps on the device restored to its
    /// state before the step (as the rods are), so that the state saved is the last good one.
    fn rollback_resident(&mut self) {}
}

/// The shell of [`ResidentMobility::free_velocities_resident`] for a mobility on the sum
/// `sum`: `None` where the sum is shared among ranks or not on a device, else `run` on the
/// resident sum, timed into a fresh `report` with the sum's accuracy report.
pub(crate) fn on_resident_sum<T>(
    sum: &mut dyn FlowSum,
    shared: bool,
    report: &mut HydroReport,
    run: impl FnOnce(&mut SpectralEwald) -> Result<T, MobilityError>,
) -> Option<Result<T, MobilityError>> {
    if shared {
        return None;
    }
    let resident = sum.resident()?;
    let t = std::time::Instant::now();
    let out = run(resident);
    *report = HydroReport {
        seconds_sums: t.elapsed().as_secs_f64(),
        ..HydroReport::default()
    };
    report.add_sum(sum.last_report());
    Some(out)
}

/// A device's failure as the mobility's (its sum's: [`crate::ewald::periodic::SumError`]'s
/// mapping).
impl From<GpuError> for MobilityError {
    fn from(e: GpuError) -> Self {
        MobilityError::Sum(e.into())
    }
}
