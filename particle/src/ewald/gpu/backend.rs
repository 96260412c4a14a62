//! [`GpuFourier`] as a spectral sum's device ([`FourierDevice`]): the host's parameters turned
//! into the device's geometry and tables, its errors into the sum's.

use super::{GpuFourier, RealSpaceReach, launch::Geometry};
use crate::ewald::kernels::{RealSpaceTable, StressletTable};
use crate::ewald::params::{ERROR_MODEL_RANGE, EwaldParams};
use crate::ewald::periodic::SumError;
use crate::ewald::point_cells::PointCells;
use crate::ewald::spectral::device::{Attempt, FourierDevice};
use crate::ewald::window::Window;
use crate::model::geometry::Vec3;
use motile_gpu::GpuError;

/// A device's failure as the sum's: the one mapping from a [`GpuError`] to the sums' errors
/// (and through them to the mobilities').
impl From<GpuError> for SumError {
    fn from(e: GpuError) -> Self {
        SumError::Device(e.to_string())
    }
}

/// The device's view of the sum with parameters `p` in a box of side `l`.
pub(crate) fn geometry(p: &EwaldParams, l: f64) -> Geometry {
    Geometry {
        window: Window::new(l, p.xi, p.modes, p.support, p.shape),
        m: p.modes,
        l,
        xi: p.xi,
    }
}

impl FourierDevice for GpuFourier {
    fn rpy_real_part(
        &mut self,
        at: Attempt<'_>,
        cells: &PointCells,
        radius: f64,
        forces: &[Vec3],
    ) -> Result<Vec<[f64; 4]>, SumError> {
        let table = RealSpaceTable::new(at.params.cutoff, at.params.xi, radius);
        let r0 = ERROR_MODEL_RANGE * at.params.spacing(at.box_length);
        let reach = RealSpaceReach {
            cutoff: at.params.cutoff,
            error_range: r0,
        };
        GpuFourier::rpy_real(self, at.generation, cells, &table, reach, radius, forces)
            .map_err(SumError::from)
    }

    fn rpy_fourier_part(
        &mut self,
        at: Attempt<'_>,
        radius: f64,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<[Vec<f64>; 3], SumError> {
        let geo = geometry(at.params, at.box_length);
        self.rpy(at.generation, &geo, radius, points, forces)
            .map_err(SumError::from)
    }

    fn stresslet_real_part(
        &mut self,
        at: Attempt<'_>,
        cells: &PointCells,
        axes: &[Vec3],
        sigma: &[f64],
    ) -> Result<Vec<[f64; 13]>, SumError> {
        let table = StressletTable::new(at.params.cutoff, at.params.xi);
        let r0 = ERROR_MODEL_RANGE * at.params.spacing(at.box_length);
        let reach = RealSpaceReach {
            cutoff: at.params.cutoff,
            error_range: r0,
        };
        GpuFourier::stresslet_real(self, at.generation, cells, &table, reach, axes, sigma)
            .map_err(SumError::from)
    }

    fn stresslet_fourier_part(
        &mut self,
        at: Attempt<'_>,
        points: &[Vec3],
        components: [&[f64]; 6],
    ) -> Result<[Vec<f64>; 12], SumError> {
        let geo = geometry(at.params, at.box_length);
        self.stresslet(at.generation, &geo, points, components)
            .map_err(SumError::from)
    }
}
