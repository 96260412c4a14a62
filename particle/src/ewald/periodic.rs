//! The periodic Stokes sums every hydrodynamic model needs, behind one trait so that the fast
//! method ([`crate::ewald::spectral::SpectralEwald`]) and its slow twin
//! ([`crate::ewald::reference::EwaldReference`]) are interchangeable in the solvers and compared
//! in the tests (docs/MODEL.md §1, §2).
//!
//! Points come in groups of `group` consecutive points (the quadrature points of one rod, or
//! single points): a point does not see the direct (image 0) contribution of its own group,
//! itself included, but it sees every periodic image of it, as (P1) requires.

use crate::ewald::params::{EwaldParams, SumOutput};
use crate::model::geometry::Vec3;

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
    /// The device that does part of the sum failed (or is missing).
    #[error("periodic sum on the device: {0}")]
    Device(String),
}

/// The velocity/gradient produced by point stresslets at their centres (the dipole model).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StressletField {
    /// Velocity at each centre.
    pub u: Vec<Vec3>,
    /// Velocity gradient `grad[i][l] = d u_i / d x_l` at each centre.
    pub grad: Vec<[Vec3; 3]>,
}

/// The estimated error of one output of a sum, relative to the output (the contract of
/// [`crate::ewald::spectral`]: max-relative and relative-L2, each to be at most the tolerance).
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorEstimate {
    /// Which output.
    pub output: SumOutput,
    /// `max_t est_t / max(max_t |q_t|, floor)`.
    pub max_relative: f64,
    /// `||est||_2 / max(||q||_2, floor sqrt(N))`.
    pub l2_relative: f64,
}

/// What a sum reports about its accuracy.
#[derive(Clone, Debug, PartialEq)]
pub struct SumReport {
    /// The requested tolerance.
    pub tolerance: f64,
    /// The internal tolerance of the accepted attempt.
    pub internal_tolerance: f64,
    /// Its refinement level (internal tolerance `tolerance 10^(-level/2)`, floored).
    pub level: u32,
    /// Attempts this sum took (1 when the level in force sufficed).
    pub attempts: u32,
    /// The accepted attempt's parameters.
    pub params: EwaldParams,
    /// Estimated errors per output.
    pub estimates: Vec<ErrorEstimate>,
    /// Whether every estimate is within the tolerance; `false` only when even the finest level
    /// misses (or parameters were fixed).
    pub met: bool,
}

impl SumReport {
    /// The largest estimate relative to the tolerance.
    pub fn worst_ratio(&self) -> f64 {
        self.estimates
            .iter()
            .map(|e| e.max_relative.max(e.l2_relative))
            .fold(0.0, f64::max)
            / self.tolerance
    }
}

/// A periodic Stokes summation with zero mean flow.
///
/// Fast implementations promise, for each output separately, a max-relative and a
/// relative-L2 error at most their tolerance relative to the exact output (not to the input's
/// scale), with a floor only where an output vanishes by symmetry: the contract of
/// [`crate::ewald::spectral`], stated in `docs/accuracy.md`.
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

    /// What the last sum reported about its accuracy; `None` for sums without an estimate
    /// (the direct reference).
    fn last_report(&self) -> Option<SumReport> {
        None
    }

    /// State carried from sum to sum that shapes the next one (a refinement level), for
    /// checkpoints: restoring it makes a resumed run repeat the same decisions. Empty if none.
    fn adaptive_state(&self) -> Vec<u32> {
        Vec::new()
    }

    /// Restore what [`Self::adaptive_state`] returned (ignored if it does not fit).
    fn set_adaptive_state(&mut self, _state: &[u32]) {}
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
