//! The device path's names in a build without the `gpu` feature: no mobility has a flow on a
//! device, so [`ResidentMobility`] says so for every type, and the slender-body level keeps
//! nothing on a device ([`SlenderState`]). The CPU code names them as in a GPU build.

/// A mobility's path on a device; in a build without the `gpu` feature, nothing is on a
/// device. (A GPU build also has the methods that take device buffers.)
pub trait ResidentMobility {
    /// Whether the flow is summed on the device the rods are on: never here.
    fn flows_on_device(&mut self) -> bool {
        false
    }

    /// Whether the step's velocities come from the contact forces on the device: never here.
    fn finishes_on_device(&self) -> bool {
        false
    }

    /// The warm state kept on a device: none here.
    fn resident_warm_state(&self) -> Option<Result<Vec<f64>, crate::hydro::report::MobilityError>> {
        None
    }

    /// Bring the host's copies up to date: they are the only copies here.
    fn sync_resident(&mut self) -> Result<(), crate::hydro::report::MobilityError> {
        Ok(())
    }

    /// Restore what the device keeps after a failed step: nothing here.
    fn rollback_resident(&mut self) {}
}

impl<T: ?Sized> ResidentMobility for T {}

/// What the slender-body level keeps on a device: nothing in a build without the `gpu`
/// feature.
#[derive(Debug, Default)]
pub struct SlenderState {
    _nothing: (),
}

impl SlenderState {
    /// Drop the resident state: there is none.
    pub fn forget(&mut self) {}
}
