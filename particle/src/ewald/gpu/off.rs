//! The spectral sums' device in a build without the `gpu` feature: a type with no values, so
//! that a sum names its device as in a GPU build and the compiler knows that none is there.

use crate::ewald::periodic::SumError;
use crate::ewald::point_cells::PointCells;
use crate::ewald::spectral::device::{Attempt, FourierDevice};
use crate::model::geometry::Vec3;

/// A GPU for the spectral sums: none can exist in a build without the `gpu` feature.
#[derive(Debug)]
pub enum GpuFourier {}

impl GpuFourier {
    /// What the device is.
    pub fn describe(&self) -> String {
        match *self {}
    }
}

impl FourierDevice for GpuFourier {
    fn rpy_real_part(
        &mut self,
        _: Attempt<'_>,
        _: &PointCells,
        _: f64,
        _: &[Vec3],
    ) -> Result<Vec<[f64; 4]>, SumError> {
        match *self {}
    }

    fn rpy_fourier_part(
        &mut self,
        _: Attempt<'_>,
        _: f64,
        _: &[Vec3],
        _: &[Vec3],
    ) -> Result<[Vec<f64>; 3], SumError> {
        match *self {}
    }

    fn stresslet_real_part(
        &mut self,
        _: Attempt<'_>,
        _: &PointCells,
        _: &[Vec3],
        _: &[f64],
    ) -> Result<Vec<[f64; 13]>, SumError> {
        match *self {}
    }

    fn stresslet_fourier_part(
        &mut self,
        _: Attempt<'_>,
        _: &[Vec3],
        _: [&[f64]; 6],
    ) -> Result<[Vec<f64>; 12], SumError> {
        match *self {}
    }
}
