//! The mean-field model's parameters, failures and the fixed point's report (docs/MODEL.md §4),
//! and the component order of symmetric tensors.

use motile_analysis::params::{InvalidParameter, check_range};

/// Component order of symmetric tensors.
pub const SYM: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// Index into [`SYM`] of the pair `(i, j)`.
pub(crate) fn sym_index(i: usize, j: usize) -> usize {
    let (a, b) = if i <= j { (i, j) } else { (j, i) };
    match (a, b) {
        (0, 0) => 0,
        (0, 1) => 1,
        (0, 2) => 2,
        (1, 1) => 3,
        (1, 2) => 4,
        _ => 5,
    }
}

/// Physical parameters of the mean-field model.
#[derive(Clone, Debug, PartialEq)]
pub struct MeanFieldParams {
    /// `zeta = sigma_b / mu` (0.1421 at nu = 0.625).
    pub zeta: f64,
    /// Diffusion `D` (default 1e-4).
    pub diffusion: f64,
    /// Relative tolerance of the Stokes fixed point (default 1e-8).
    pub fixed_point_tolerance: f64,
    /// Iteration cap of the fixed point (default 50).
    pub fixed_point_max_iterations: usize,
    /// Run exactly this many fixed-point iterations whatever the change (`None`, the default:
    /// iterate to the tolerance). For comparisons between implementations, whose round-off
    /// could otherwise stop them one iteration apart.
    pub fixed_point_iterations: Option<usize>,
}

impl MeanFieldParams {
    /// Check every field (the error names it, its value, the allowed range and the unit).
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        check_range(
            "zeta",
            self.zeta,
            0.0,
            10.0,
            false,
            "sigma_b/mu, dimensionless",
        )?;
        check_range(
            "diffusion",
            self.diffusion,
            0.0,
            1.0,
            false,
            "L^2 |sigma_a|/mu",
        )?;
        check_range(
            "fixed_point_tolerance",
            self.fixed_point_tolerance,
            0.0,
            1e-2,
            true,
            "relative change of u",
        )?;
        if let Some(k) = self.fixed_point_iterations {
            check_range(
                "fixed_point_iterations",
                k as f64,
                1.0,
                1e4,
                false,
                "iterations",
            )?;
        }
        check_range(
            "fixed_point_max_iterations",
            self.fixed_point_max_iterations as f64,
            1.0,
            1e4,
            false,
            "iterations",
        )
    }
}

impl MeanFieldParams {
    /// Whether the Stokes fixed point stops after the iteration `report` describes: the
    /// pinned count reached, or the change within the tolerance (at once when `zeta = 0`, where
    /// the stress does not depend on the flow); an error when the cap is reached or the change
    /// is not finite. The CPU and GPU steppers share it.
    pub fn fixed_point_done(&self, report: &RhsReport) -> Result<bool, MeanFieldError> {
        if let Some(k) = self.fixed_point_iterations {
            return Ok(report.iterations >= k);
        }
        if self.zeta == 0.0 || report.residual <= self.fixed_point_tolerance {
            return Ok(true);
        }
        if report.iterations >= self.fixed_point_max_iterations || !report.residual.is_finite() {
            return Err(MeanFieldError::FixedPoint {
                iterations: report.iterations,
                residual: report.residual,
                tolerance: self.fixed_point_tolerance,
            });
        }
        Ok(false)
    }
}

impl Default for MeanFieldParams {
    fn default() -> Self {
        Self {
            zeta: 0.1421,
            diffusion: 1e-4,
            fixed_point_tolerance: 1e-8,
            fixed_point_max_iterations: 50,
            fixed_point_iterations: None,
        }
    }
}

/// Mean-field failures.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeanFieldError {
    /// The Stokes fixed point did not converge.
    #[error(
        "Stokes fixed point did not converge: relative change {residual:.2e} after {iterations} iterations (tolerance {tolerance:.1e})"
    )]
    FixedPoint {
        /// Iterations done.
        iterations: usize,
        /// Last relative change.
        residual: f64,
        /// Tolerance.
        tolerance: f64,
    },
    /// A non-finite value.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
}

/// Report of one right-hand-side evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RhsReport {
    /// Fixed-point iterations.
    pub iterations: usize,
    /// Final relative change of `u`.
    pub residual: f64,
}
