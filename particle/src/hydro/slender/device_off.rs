//! The slender-body level's device path in a build without the `gpu` feature: (P4) is never
//! solved on a device, and nothing is kept there to bring back.

use super::SlenderBody;
use crate::hydro::gmres::GmresInfo;
use crate::hydro::mobility::MobilityError;
use crate::model::geometry::Vec3;

impl SlenderBody {
    /// (P4) on a device: never here.
    pub(super) fn solve_resident(
        &mut self,
        _box_length: f64,
        _points: &[Vec3],
        _axes: &[Vec3],
        _rhs: &[f64],
        _start: &mut Vec<f64>,
        _stage: &'static str,
    ) -> Option<Result<(GmresInfo, Vec<Vec3>), MobilityError>> {
        None
    }

    /// The device's state brought to the host: there is none.
    pub(super) fn device_to_host(&mut self) -> Result<(), MobilityError> {
        Ok(())
    }
}
