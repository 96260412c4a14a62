//! The back-end of a spectral sum's device parts ([`FourierDevice`]): the real-space pairs and
//! the Fourier part (spreading, transforms, the multiplication, the gather) of one attempt, given
//! what the host parts prepared (the cell list, the parameters). A sum without a device runs
//! the CPU's twins (`real_space.rs`, `crate::ewald::grid`); the parameter choice, corrections,
//! error estimate and refinement stay on the host either way, so the accuracy contract is the
//! same.

use crate::ewald::params::EwaldParams;
use crate::ewald::periodic::SumError;
use crate::ewald::point_cells::PointCells;
use crate::model::geometry::Vec3;

/// One attempt of a spectral sum, as its device sees it.
#[derive(Clone, Copy, Debug)]
// Read only by a device, which a build without the `gpu` feature cannot have.
#[cfg_attr(not(feature = "gpu"), allow(dead_code))]
pub(crate) struct Attempt<'a> {
    /// The sum's preparations of new points so far: while it is the same (the products of one
    /// GMRES solve) the device may keep the points and the cell list it was given.
    pub generation: u64,
    /// The attempt's parameters.
    pub params: &'a EwaldParams,
    /// The box side.
    pub box_length: f64,
}

/// What a device does of one attempt of a spectral sum.
pub(crate) trait FourierDevice {
    /// The real-space part of the RPY sum (radius `radius`) at every point of `cells`: `[u_0, u_1, u_2, e2]` per point in the points' own
    /// order, `e2` the error model's weighted strengths.
    fn rpy_real_part(
        &mut self,
        attempt: Attempt<'_>,
        cells: &PointCells,
        radius: f64,
        forces: &[Vec3],
    ) -> Result<Vec<[f64; 4]>, SumError>;

    /// The Fourier part of the RPY sum: three velocity components per point (before the
    /// division by the viscosity), in the points' order.
    fn rpy_fourier_part(
        &mut self,
        attempt: Attempt<'_>,
        radius: f64,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<[Vec<f64>; 3], SumError>;

    /// The real-space part of the stresslet sum of strengths `sigma` along `axes`: per point in
    /// its own order, velocity `0..3`, gradient `du_i/dx_m` at `3 + 3 i + m`, and the error
    /// model's weighted strengths at 12.
    fn stresslet_real_part(
        &mut self,
        attempt: Attempt<'_>,
        cells: &PointCells,
        axes: &[Vec3],
        sigma: &[f64],
    ) -> Result<Vec<[f64; 13]>, SumError>;

    /// The Fourier part of the stresslet sum: the six stresslet components per point
    /// (`xx, yy, zz, xy, xz, yz`) in, velocity and gradient out as the CPU grid's
    /// `gather_gradient` gives them (`3 + 3 i + m` is `du_i/dx_m`).
    fn stresslet_fourier_part(
        &mut self,
        attempt: Attempt<'_>,
        points: &[Vec3],
        components: [&[f64]; 6],
    ) -> Result<[Vec<f64>; 12], SumError>;
}
