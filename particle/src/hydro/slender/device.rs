//! [`SlenderBody`]'s solves of (P4) on the device of its resident sum (feature `gpu`): GMRES's
//! vectors and products there ([`crate::hydro::gpu`]), the host reading back per iteration
//! only the Hessenberg column and the sum's error reductions.

use super::SlenderBody;
use crate::ewald::periodic::{RpyGeometry, SumError};
use crate::ewald::spectral::resident::resident_sum;
use crate::hydro::gmres::GmresInfo;
use crate::hydro::gpu::{DeviceP4, P4Sum, SlenderDevice};
use crate::hydro::mobility::MobilityError;
use crate::model::geometry::Vec3;
use crate::model::units::{ROD_LENGTH, eta};

fn device_error(e: motile_gpu::GpuError) -> MobilityError {
    MobilityError::Sum(SumError::Device(e.to_string()))
}

impl SlenderBody {
    /// [`Self::solve`] on one process where the sum keeps its values on a device: the nodes
    /// `points` of the rods with axes `p` in a box of side `box_length`, the right-hand side
    /// and the warm start `x` uploaded, GMRES on the device, the solution and the flow at the
    /// nodes downloaded. `None` where the sum has no device.
    pub(super) fn solve_resident(
        &mut self,
        box_length: f64,
        (points, p): (&[Vec3], &[Vec3]),
        (rhs, x): (&[f64], &mut Vec<f64>),
        stage: &'static str,
    ) -> Option<Result<(GmresInfo, Vec<Vec3>), MobilityError>> {
        let sum = resident_sum(self.sum.as_mut())?;
        let mut run = || -> Result<_, MobilityError> {
            if self.device.is_none() {
                let backend = sum.device_sum()?.backend();
                self.device = Some(SlenderDevice::open(backend).map_err(device_error)?);
            }
            let kern = self.device.as_ref().expect("opened above");
            let up = |v: &[f64]| kern.upload(v).map_err(device_error);
            let rule = kern.rule((&self.s, &self.w)).map_err(device_error)?;
            let (nodes, axes, b) = (up(points.as_flattened())?, up(p.as_flattened())?, up(rhs)?);
            let mut xd = up(x)?;
            let op = DeviceP4 {
                sum: P4Sum::Resident(sum),
                geometry: RpyGeometry {
                    box_length,
                    radius: self.params.rpy_radius,
                    group: self.s.len(),
                },
                nodes: &nodes,
                p: &axes,
                rule: &rule,
                n: p.len(),
                eta: eta(self.params.diameter),
                l: ROD_LENGTH,
            };
            let solved = kern.solve(op, (&b, &mut xd), &self.params.gmres);
            // The last iterate is the next warm start, also after a failure (as on the host).
            *x = kern.download(&xd).map_err(device_error)?;
            let solved = solved.map_err(|source| MobilityError::Gmres { stage, source })?;
            let u = kern.download(&solved.u).map_err(device_error)?;
            let u = u.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            Ok((solved, u))
        };
        let result = run();
        Some(result.map(|(solved, u)| {
            self.fold_sums(&solved.accuracy, solved.seconds);
            (solved.info, u)
        }))
    }
}
