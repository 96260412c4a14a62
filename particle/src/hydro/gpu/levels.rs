//! The point-stresslet and explicit slender-body levels' paths on a device
//! ([`ResidentMobility`]): one resident sum per step, the rods' axes, node values and
//! velocities from kernels beside it.

use super::resident::{DeviceVelocities, ResidentMobility, RodsOnDevice, on_resident_sum};
use crate::ewald::gpu::resident::{Rule, Swimming};
use crate::ewald::gpu::{OrientedPoints, PointForces};
use crate::hydro::dipole::{Dipole, stresslet_strength};
use crate::hydro::explicit::ExplicitSlender;
use crate::hydro::report::MobilityError;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED, eta};
use motile_gpu::Counters;

impl ResidentMobility for Dipole {
    fn sum_counters(&mut self) -> Option<Counters> {
        self.sum.resident().and_then(|s| s.device_counters())
    }

    fn flows_on_device(&mut self) -> bool {
        self.shared.is_none() && self.sum.resident().is_some()
    }

    fn free_velocities_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
    ) -> Option<Result<DeviceVelocities, MobilityError>> {
        let sigma = stresslet_strength(self.diameter);
        let shared = self.shared.is_some();
        on_resident_sum(self.sum.as_mut(), shared, &mut self.report, |sum| {
            let n = rods.len;
            let p = sum
                .device_sum()?
                .rod_axes(rods.q, n)
                .map_err(MobilityError::from)?;
            let stresslets = OrientedPoints {
                centres: rods.x,
                axes: &p,
            };
            let field = sum.stresslets_resident(rods.box_length, stresslets, sigma, n)?;
            let gpu = sum.device_sum()?;
            gpu.jeffery_velocities(&p, &field.u, &field.grad, n, SWIM_SPEED)
                .map_err(MobilityError::from)
        })
        .map(|done| done.map(DeviceVelocities::from))
    }
}

impl ResidentMobility for ExplicitSlender {
    fn sum_counters(&mut self) -> Option<Counters> {
        self.sum.resident().and_then(|s| s.device_counters())
    }

    fn flows_on_device(&mut self) -> bool {
        self.shared.is_none() && self.sum.resident().is_some()
    }

    fn free_velocities_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
    ) -> Option<Result<DeviceVelocities, MobilityError>> {
        let geometry = self.geometry(rods.box_length);
        let c = SWIM_SPEED / (2.0 * eta(self.diameter));
        let (s, w) = (&self.s, &self.w);
        let rule = Rule { s, w };
        let shared = self.shared.is_some();
        on_resident_sum(self.sum.as_mut(), shared, &mut self.report, |sum| {
            let n = rods.len;
            let gpu = sum.device_sum()?;
            let p = gpu.rod_axes(rods.q, n).map_err(MobilityError::from)?;
            let rod_frames = OrientedPoints {
                centres: rods.x,
                axes: &p,
            };
            let (nodes, force, fields) = gpu
                .node_values(rod_frames, rule, n, c)
                .map_err(MobilityError::from)?;
            let sources = PointForces {
                points: &nodes,
                forces: &force,
                fields: &fields,
            };
            let u = sum.rpy_resident(&geometry, sources, n * s.len())?;
            drop((nodes, force, fields));
            sum.device_sum()?
                .rod_flow_velocities(
                    &p,
                    &u,
                    rule,
                    n,
                    Swimming {
                        speed: SWIM_SPEED,
                        length: ROD_LENGTH,
                    },
                )
                .map_err(MobilityError::from)
        })
        .map(|done| done.map(DeviceVelocities::from))
    }
}
