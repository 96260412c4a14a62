//! What a mobility returns: the rods' velocities, the report of a step's hydrodynamics, the
//! force density of the last solve, and its failures.

use crate::model::geometry::Vec3;
use crate::model::rods::RodSet;
use serde::{Deserialize, Serialize};

/// Velocities of all rods.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RodVelocities {
    /// Centre velocities.
    pub v: Vec<Vec3>,
    /// Angular velocities.
    pub w: Vec<Vec3>,
}

impl RodVelocities {
    /// Zero velocities for `n` rods.
    pub fn zeros(n: usize) -> Self {
        Self {
            v: vec![[0.0; 3]; n],
            w: vec![[0.0; 3]; n],
        }
    }
}

/// What the hydrodynamic part of a step did.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HydroReport {
    /// GMRES iterations of the step's solve; 0 for models without GMRES.
    pub gmres_iterations: usize,
    /// Its final relative residual.
    pub gmres_residual: f64,
    /// Seconds in the periodic sums (all products of the step).
    pub seconds_sums: f64,
    /// Number of periodic sums (mobility products) in the step.
    pub sums: usize,
    /// The largest estimated error of the step's sums relative to their tolerance
    /// ([`crate::ewald::periodic::SumReport::worst_ratio`]); 0 without estimates.
    pub sum_error_ratio: f64,
    /// Whether every sum of the step met its tolerance by its own estimate.
    pub sum_tolerance_met: bool,
    /// The fast sum's refinement level after the step.
    pub sum_level: u32,
}

impl HydroReport {
    /// Fold one sum's accuracy report into the step's.
    pub fn add_sum(&mut self, report: Option<crate::ewald::periodic::SumReport>) {
        if self.sums == 0 {
            self.sum_tolerance_met = true;
        }
        self.sums += 1;
        if let Some(r) = report {
            self.sum_error_ratio = self.sum_error_ratio.max(r.worst_ratio());
            self.sum_tolerance_met &= r.met;
            self.sum_level = r.level;
        }
    }
}

/// The force density of the last solve, for output and the velocity spectrum.
#[derive(Clone, Copy, Debug)]
pub struct ForceDensity<'a> {
    /// Quadrature nodes `s_j` along a rod.
    pub s: &'a [f64],
    /// Quadrature weights `w_j`.
    pub w: &'a [f64],
    /// `f_n(s_j)` for rod n, node j at index `n * s.len() + j` (free plus contact solve).
    pub f: &'a [Vec3],
}

impl ForceDensity<'_> {
    /// Node positions `x_n + s_j p_n` (of the configuration `rods`, `p` its orientations) and
    /// the weighted forces `f_n(s_j) w_j` there: the point forces of the velocity spectrum.
    pub fn point_forces(&self, rods: &RodSet, p: &[Vec3]) -> (Vec<Vec3>, Vec<Vec3>) {
        let m = self.s.len();
        let n = self.f.len().min(rods.len() * m);
        (0..n)
            .map(|k| {
                let (r, j) = (k / m, k % m);
                (
                    [0, 1, 2].map(|d| rods.x[r][d] + self.s[j] * p[r][d]),
                    self.f[k].map(|c| c * self.w[j]),
                )
            })
            .unzip()
    }
}

/// Failures of a hydrodynamic solve.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MobilityError {
    /// GMRES on (P4) failed.
    #[error("slender-body GMRES ({stage} solve): {source}")]
    Gmres {
        /// `"free"` (swimming only) or `"swimming + contact"`.
        stage: &'static str,
        /// What GMRES reported.
        source: crate::hydro::gmres::GmresError<crate::ewald::periodic::SumError>,
    },
    /// A periodic sum failed.
    #[error(transparent)]
    Sum(#[from] crate::ewald::periodic::SumError),
    /// A step shared among ranks asked a mobility that was not built to share.
    #[error("the {0} mobility was not built for a box shared among ranks")]
    NotShared(&'static str),
}
