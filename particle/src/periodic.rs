//! The periodic Stokes sums every hydrodynamic model needs, behind one trait so that the fast
//! method ([`crate::spectral_ewald::SpectralEwald`]) and its slow twin
//! ([`crate::rpy_reference::EwaldReference`]) are interchangeable in the solvers and compared
//! in the tests (MODEL.md §1, §2).
//!
//! Points come in groups of `group` consecutive points (the quadrature points of one rod, or
//! single points): a point does not see the direct (image 0) contribution of its own group,
//! itself included, but it sees every periodic image of it, as (P1) requires.

use crate::geometry::Vec3;

/// Geometry of a periodic RPY sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RpyGeometry {
    /// Box side L.
    pub box_length: f64,
    /// RPY radius a.
    pub radius: f64,
    /// Points per group (consecutive); a point ignores its own group's direct terms.
    pub group: usize,
}

/// Errors of the periodic sums.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SumError {
    /// Input of the wrong shape or not finite.
    #[error("periodic sum: {0}")]
    Input(String),
}

/// The velocity/gradient produced by point stresslets at their centres (the dipole model).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StressletField {
    /// Velocity at each centre.
    pub u: Vec<Vec3>,
    /// Velocity gradient `grad[i][l] = d u_i / d x_l` at each centre.
    pub grad: Vec<[Vec3; 3]>,
}

/// A periodic Stokes summation with zero mean flow.
pub trait PeriodicStokes: Send + Sync + std::fmt::Debug {
    /// RPY mobility product: `u_i = sum_j sum_images M_RPY(y_i - y_j) f_j`, own group's direct
    /// terms excluded. `points` and `forces` have the same length, a multiple of the group.
    fn rpy(
        &mut self,
        geometry: &RpyGeometry,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<Vec<Vec3>, SumError>;

    /// Flow of point stresslets `sigma_n p_n p_n` at `x_n` (each point its own group, its own
    /// singular term excluded): velocity and gradient at every `x_n`.
    fn stresslets(
        &mut self,
        box_length: f64,
        x: &[Vec3],
        p: &[Vec3],
        sigma: &[f64],
    ) -> Result<StressletField, SumError>;
}

/// Shape checks shared by the implementations.
pub(crate) fn check_rpy(
    geometry: &RpyGeometry,
    points: &[Vec3],
    forces: &[Vec3],
) -> Result<(), SumError> {
    if points.len() != forces.len() {
        return Err(SumError::Input(format!(
            "{} points but {} forces",
            points.len(),
            forces.len()
        )));
    }
    if geometry.group == 0 || !points.len().is_multiple_of(geometry.group) {
        return Err(SumError::Input(format!(
            "{} points do not split into groups of {}",
            points.len(),
            geometry.group
        )));
    }
    if !(geometry.box_length.is_finite() && geometry.box_length > 0.0) {
        return Err(SumError::Input(format!(
            "box length {}",
            geometry.box_length
        )));
    }
    if !(geometry.radius.is_finite() && geometry.radius >= 0.0) {
        return Err(SumError::Input(format!("RPY radius {}", geometry.radius)));
    }
    Ok(())
}
