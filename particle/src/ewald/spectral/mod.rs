//! Fast periodic Stokes sums by spectral Ewald (docs/MODEL.md §1, §2): the Hasimoto split of
//! [`crate::ewald::kernels`], the short-ranged real-space part summed over neighbours from a point cell
//! list (`point_cells.rs`), the smooth Fourier part by Gaussian gridding
//! (the `gaussian_grid` module: spread the sources onto a uniform grid, real FFTs, a diagonal
//! multiplication, FFTs back, gather). `O(N log N)`.
//!
//! **The accuracy contract** (`docs/accuracy.md`). For every output a sum returns (RPY
//! velocities; stresslet velocities; stresslet velocity gradients), with `q_t` its exact
//! value at target `t` (the converged Ewald sum, [`crate::ewald::reference`]) and `|.|` the
//! Euclidean norm of a vector or matrix, both
//!
//! ```text
//! max_t |q^_t - q_t| <= tol max(max_t |q_t|, s)   and   ||q^ - q||_2 <= tol max(||q||_2, s sqrt(N))
//! ```
//!
//! where `s` is a floor for outputs that vanish by symmetry (an isolated stresslet's own
//! velocity): the flow of the strongest source at distance `L`, `max|sigma| / (8 pi mu L^2)`
//! for stresslet velocities, `max|sigma| / (8 pi mu L^3)` for their gradients, zero for RPY
//! velocities. The bound is relative to the output, not to the input: where the sources
//! nearly cancel (force-free rods, whose flow is a stresslet's; sparse boxes, where a body's
//! output is the weak flow of its images) the method must resolve far more finely than the
//! input's scale suggests.
//!
//! How it is kept. Each attempt runs at an internal tolerance `tol_i = tol 10^(-level/2)`,
//! whose parameters ([`EwaldParams::choose_for`]) leave a known error per source: every
//! truncation is sized against the output's own self-term scale (`crate::ewald::params`),
//! so the error at each target is within a calibrated multiple of `tol_i Phi sqrt(sum_j w(r_j)
//! s_j^2)` (own group and real-space neighbours, strengths `s_j`, weight decaying over two grid
//! spacings), an estimate computed alongside the real-space sum at almost no cost. After the
//! attempt that estimate is compared with the output it produced: if either bound above would
//! fail, the level rises by the factor missing (half decades) and the sum is done again. The
//! level is kept for the next sum (the products of a GMRES solve, the next step's sum) and
//! lowered only after many sums that needed ten times less; it is part of the adaptive state
//! a checkpoint saves ([`PeriodicStokes::adaptive_state`]), so resumed runs repeat the same
//! decisions. If the finest level (`tol_i = 1e-13`) still misses, the sum returns its result
//! and says so in [`SumReport::met`]: never a silent violation. With fixed parameters
//! ([`SpectralEwald::fixed`]) nothing is refined; the report still carries the estimate.
//!
//! Determinism: the real-space sum visits pairs in an order fixed by the cells and the
//! gridding is thread-count independent, so results, estimates and refinement decisions are
//! bit-identical for any rayon pool size.

pub(crate) mod device;
pub(crate) mod estimates;
pub(crate) mod real_space;
pub(crate) mod refinement;
#[cfg(feature = "gpu")]
pub mod resident;

use crate::ewald::gpu::GpuFourier;
use crate::ewald::grid::{GaussianGrid, GridPoints};
use crate::ewald::kernels::{rpy_fourier_mode_screened, stresslet_fourier_self_gradient};
use crate::ewald::params::{EwaldParams, PAIR_COST, STRESSLET_PAIR_COST, SumOutput};
use crate::ewald::periodic::{
    ErrorEstimate, PeriodicStokes, RpyGeometry, StressletField, SumError, SumReport, check_rpy,
};
use crate::ewald::point_cells::PointCells;
use crate::ewald::spectral::device::{Attempt, FourierDevice};
use crate::ewald::spectral::estimates::{
    Accepted, AttemptTolerance, ErrorScale, StressletOutputs, estimate, report_of,
    stresslet_estimates,
};
use crate::ewald::spectral::real_space::{RpyPairCache, rpy_assemble, rpy_real, stresslet_real};
use crate::ewald::spectral::refinement::{Refinement, check_tolerance};
use crate::model::geometry::{Vec3, dot};
use crate::model::units::VISCOSITY;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// Spectral Ewald with parameters chosen from one tolerance; keeps its grid and buffers.
#[derive(Debug)]
pub struct SpectralEwald {
    /// Requested relative accuracy (the contract of the module doc).
    pub tol: f64,
    /// Fixed parameters, overriding the automatic choice and the refinement (for tests and
    /// studies).
    pub fixed: Option<EwaldParams>,
    grid: Option<GaussianGrid>,
    /// Box length of the grid.
    grid_box: f64,
    /// The last sum's points, prepared (taken out during a sum).
    prepared: Option<Prepared>,
    last: Option<EwaldParams>,
    timing: SumTiming,
    refine: Refinement,
    report: Option<SumReport>,
    /// The device that does the real-space pairs and the Fourier part, if not the CPU (none
    /// can exist in a build without the `gpu` feature).
    gpu: Option<GpuFourier>,
    /// Counts the preparations of new points (a device keeps the points it was given, and the
    /// cell list, while this stays the same: the products of one GMRES solve).
    generation: u64,
}

/// Seconds spent in the stages of the last sum (its last attempt).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SumTiming {
    /// Parameter choice, grid plan and point sorting.
    pub setup: f64,
    /// Real-space pairs (cell list included).
    pub real: f64,
    /// Fourier part: spreading, transforms, multiplication, gathering.
    pub fourier: f64,
    /// Own-group corrections, assembly and the error estimate.
    pub corrections: f64,
}

/// Per-target sums of squared strengths weighted by the error model's `w(r)`.
type Weights = Vec<f64>;

impl SpectralEwald {
    /// A sum at relative tolerance `tol` (1e-10 ..= 1e-1: below 1e-10 the round-off of the
    /// cancelling parts of force-free data, about 1e-12 of their size, is no longer small
    /// against the bound).
    pub fn new(tol: f64) -> Result<Self, SumError> {
        check_tolerance(tol)?;
        Ok(Self {
            tol,
            fixed: None,
            grid: None,
            grid_box: 0.0,
            prepared: None,
            last: None,
            timing: SumTiming::default(),
            refine: Refinement::default(),
            report: None,
            gpu: None,
            generation: 0,
        })
    }

    /// A sum whose Fourier part (spreading, FFTs, the multiplication, the gather) and
    /// real-space pairs run on `device` ([`crate::ewald::gpu`]); everything else, and so the accuracy
    /// contract, as [`Self::new`].
    pub fn with_device(tol: f64, device: GpuFourier) -> Result<Self, SumError> {
        let mut s = Self::new(tol)?;
        s.gpu = Some(device);
        Ok(s)
    }

    /// Where the Fourier part runs: `"CPU"`, or the device's description.
    pub fn device(&self) -> String {
        match &self.gpu {
            Some(g) => g.describe(),
            None => "CPU".into(),
        }
    }

    /// Whether the Fourier part runs on a device (the CPU grid's sorted points are then not
    /// needed).
    pub(crate) fn on_device(&self) -> bool {
        self.gpu.is_some()
    }

    /// What a device sees of an attempt with parameters `params` in a box of side `box_length`.
    fn attempt<'a>(&self, params: &'a EwaldParams, box_length: f64) -> Attempt<'a> {
        Attempt {
            generation: self.generation,
            params,
            box_length,
        }
    }

    /// Seconds per stage of the last sum.
    pub fn last_timing(&self) -> SumTiming {
        self.timing
    }

    /// The parameters of the last sum.
    pub fn last_params(&self) -> Option<EwaldParams> {
        self.last
    }

    /// The current refinement level (internal tolerance `tol 10^(-level/2)`).
    pub fn level(&self) -> u32 {
        self.refine.level
    }

    /// Internal tolerance at the current level.
    fn internal_tolerance(&self) -> f64 {
        self.refine.internal_tolerance(self.tol)
    }

    /// After an attempt: whether it stands (see [`Refinement::accept`]).
    fn accept(&mut self, ratio: f64) -> Result<bool, SumError> {
        self.refine.accept(self.tol, ratio, self.fixed.is_some())
    }

    /// The grid for `p` in a box of side `l`, and the points prepared for both parts; a sum at
    /// the same points, box, group size and parameters as the last one (the products of one
    /// GMRES solve) reuses the sorted points, their windows and the cell list.
    fn prepare(
        &mut self,
        p: EwaldParams,
        l: f64,
        points: &[Vec3],
        group: usize,
    ) -> Result<Prepared, SumError> {
        check_params(&p, l)?;
        let rebuild = self.grid.is_none() || self.last != Some(p) || self.grid_box != l;
        if rebuild {
            self.grid = Some(GaussianGrid::new(l, p.xi, p.modes, p.support, p.shape));
            self.grid_box = l;
        }
        self.last = Some(p);
        let mut old = self.prepared.take();
        if let Some(prep) =
            old.take_if(|prep| !rebuild && prep.group == group && prep.points == points)
        {
            return Ok(prep);
        }
        self.generation += 1;
        if let Some(i) = points
            .par_iter()
            .position_first(|y| !y.iter().all(|c| c.is_finite()))
        {
            return Err(SumError::Input(format!(
                "point {i} has a non-finite coordinate {:?}",
                points[i]
            )));
        }
        // The old preparation's buffers are reused (fresh ones page-fault on every call).
        let (mut kept, old_grid) = match old {
            Some(prep) => (prep.points, prep.grid_points),
            None => (Vec::new(), GridPoints::default()),
        };
        let grid_points = if self.on_device() {
            old_grid
        } else {
            self.grid
                .as_ref()
                .expect("grid built above")
                .prepare_reusing(points, old_grid)
        };
        kept.clear();
        kept.extend_from_slice(points);
        Ok(Prepared {
            points: kept,
            group,
            grid_points,
            cells: PointCells::build(points, l, p.cutoff, group),
            rpy_pairs: RpyPairCache::default(),
        })
    }

    /// One attempt of the RPY sum with parameters `p`: velocities and the error model's
    /// weighted strengths per point.
    fn rpy_attempt(
        &mut self,
        p: EwaldParams,
        geometry: &RpyGeometry,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<(Vec<Vec3>, Weights), SumError> {
        let (l, a, g) = (geometry.box_length, geometry.radius, geometry.group);
        let t0 = Instant::now();
        let mut prep = self.prepare(p, l, points, g)?;
        let xi = p.xi;
        let t1 = Instant::now();
        let attempt = self.attempt(&p, l);
        let real = match self.gpu.as_mut() {
            Some(gpu) => gpu.rpy_real_part(attempt, &prep.cells, a, forces)?,
            None => rpy_real(&prep.cells, &mut prep.rpy_pairs, &p, a, l, forces),
        };
        let pts = &prep.grid_points;
        // Fourier space.
        let t2 = Instant::now();
        let uf: [Vec<f64>; 3] = match self.gpu.as_mut() {
            Some(gpu) => gpu.rpy_fourier_part(attempt, a, points, forces)?,
            None => {
                let grid = self.grid.as_mut().expect("prepared");
                let f: Vec<Vec<f64>> = (0..3)
                    .map(|d| forces.par_iter().map(|v| v[d]).collect())
                    .collect();
                let spread = grid.spread(pts, [&f[0], &f[1], &f[2]]);
                let vol = l * l * l;
                let conv = grid.convolve::<3, 3>(spread, |k, k2, screen, f| {
                    rpy_fourier_mode_screened(k, k2, screen, xi, a, vol, f)
                });
                grid.gather(pts, conv)
            }
        };
        let t3 = Instant::now();
        let (u, e2) = rpy_assemble(
            real,
            |t| [uf[0][t], uf[1][t], uf[2][t]],
            points,
            forces,
            &p,
            geometry,
        );
        self.prepared = Some(prep);
        self.timing = SumTiming {
            setup: (t1 - t0).as_secs_f64(),
            real: (t2 - t1).as_secs_f64(),
            fourier: (t3 - t2).as_secs_f64(),
            corrections: t3.elapsed().as_secs_f64(),
        };
        Ok((u, e2))
    }

    /// One attempt of the stresslet sum with parameters `prm`: velocities, gradients and the
    /// error model's weighted strengths per centre (neighbours only; the own strength is added
    /// for the gradient, whose self term is not zero).
    fn stresslet_attempt(
        &mut self,
        prm: EwaldParams,
        l: f64,
        x: &[Vec3],
        p: &[Vec3],
        sigma: &[f64],
    ) -> Result<(StressletField, Weights), SumError> {
        let t0 = Instant::now();
        let prep = self.prepare(prm, l, x, 1)?;
        let (pts, cells) = (&prep.grid_points, &prep.cells);
        let xi = prm.xi;
        let t1 = Instant::now();
        let attempt = self.attempt(&prm, l);
        let real = match self.gpu.as_mut() {
            Some(gpu) => gpu
                .stresslet_real_part(attempt, cells, p, sigma)?
                .into_iter()
                .map(|v| {
                    let g = std::array::from_fn(|i| std::array::from_fn(|m| v[3 + 3 * i + m]));
                    ([v[0], v[1], v[2]], g, v[12])
                })
                .collect(),
            None => stresslet_real(cells, &prm, l, p, sigma),
        };
        let t2 = Instant::now();
        let comp = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
        let s: Vec<Vec<f64>> = comp
            .iter()
            .map(|&(i, j)| {
                (0..x.len())
                    .into_par_iter()
                    .map(|n| sigma[n] * p[n][i] * p[n][j])
                    .collect()
            })
            .collect();
        let components = std::array::from_fn::<_, 6, _>(|c| s[c].as_slice());
        let back = match self.gpu.as_mut() {
            Some(gpu) => gpu.stresslet_fourier_part(attempt, x, components)?,
            None => {
                let grid = self.grid.as_mut().expect("prepared");
                let spread = grid.spread(pts, components);
                let vol = l * l * l;
                // Velocity only: the gradient comes from the window's derivative in the gather.
                let out = grid.convolve::<6, 3>(spread, |k, k2, screen, sh| {
                    let sm = |i: usize, j: usize| {
                        let c = match (i.min(j), i.max(j)) {
                            (0, 0) => 0,
                            (1, 1) => 1,
                            (2, 2) => 2,
                            (0, 1) => 3,
                            (0, 2) => 4,
                            _ => 5,
                        };
                        sh[c]
                    };
                    // Force density -i k . S, then the velocity of a point force (a = 0).
                    let f: [Complex64; 3] = std::array::from_fn(|i| {
                        -Complex64::i() * (sm(i, 0) * k[0] + sm(i, 1) * k[1] + sm(i, 2) * k[2])
                    });
                    rpy_fourier_mode_screened(k, k2, screen, xi, 0.0, vol, f)
                });
                grid.gather_gradient(pts, out)
            }
        };
        let t3 = Instant::now();
        type Split = ((Vec<Vec3>, Vec<[Vec3; 3]>), Weights);
        let ((u, grad), e2): Split = real
            .into_par_iter()
            .enumerate()
            .map(|(t, (mut u, mut g, e2))| {
                let own = stresslet_fourier_self_gradient(p[t], sigma[t], xi);
                for i in 0..3 {
                    u[i] = (u[i] + back[i][t]) / VISCOSITY;
                    for m in 0..3 {
                        g[i][m] = (g[i][m] + back[3 + 3 * i + m][t] - own[i][m]) / VISCOSITY;
                    }
                }
                ((u, g), e2)
            })
            .unzip();
        self.prepared = Some(prep);
        self.timing = SumTiming {
            setup: (t1 - t0).as_secs_f64(),
            real: (t2 - t1).as_secs_f64(),
            fourier: (t3 - t2).as_secs_f64(),
            corrections: t3.elapsed().as_secs_f64(),
        };
        Ok((StressletField { u, grad }, e2))
    }
}

/// Parameters a sum in a box of side `l` can use: a cutoff within half the box, an even grid
/// of at least the support.
fn check_params(p: &EwaldParams, l: f64) -> Result<(), SumError> {
    if p.cutoff > 0.5 * l * (1.0 + 1e-12) {
        return Err(SumError::Input(format!(
            "real-space cutoff {} exceeds half the box {}",
            p.cutoff,
            0.5 * l
        )));
    }
    if p.modes < p.support || p.support < 2 || !p.modes.is_multiple_of(2) {
        return Err(SumError::Input(format!(
            "Gaussian grid of {} points per axis with support {} (needs an even grid of at \
             least the support)",
            p.modes, p.support
        )));
    }
    Ok(())
}

/// The points of the last sum, prepared for its parameters.
#[derive(Debug)]
struct Prepared {
    points: Vec<Vec3>,
    group: usize,
    grid_points: GridPoints,
    cells: PointCells,
    /// The RPY real-space pairs, from the preparation's second sum on.
    rpy_pairs: RpyPairCache,
}

impl SpectralEwald {
    /// Record the accepted attempt.
    fn record(&mut self, internal: f64, attempts: u32, estimates: Vec<ErrorEstimate>) {
        let params = self.last.expect("an attempt ran");
        let accepted = Accepted {
            internal,
            level: self.refine.level,
            attempts,
        };
        self.report = Some(report_of(self.tol, accepted, params, estimates));
    }
}

impl PeriodicStokes for SpectralEwald {
    fn rpy(
        &mut self,
        geometry: &RpyGeometry,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<Vec<Vec3>, SumError> {
        check_rpy(geometry, points, forces)?;
        let l = geometry.box_length;
        let mut attempts = 0;
        loop {
            attempts += 1;
            let internal = self.internal_tolerance();
            let p = self.fixed.unwrap_or_else(|| {
                EwaldParams::choose_for(
                    internal,
                    points.len(),
                    l,
                    &[SumOutput::RpyVelocity],
                    PAIR_COST,
                )
            });
            let (u, e2) = self.rpy_attempt(p, geometry, points, forces)?;
            let scale = internal * SumOutput::RpyVelocity.self_scale(p.xi) / VISCOSITY;
            let est = estimate(
                SumOutput::RpyVelocity,
                ErrorScale { scale, internal },
                |t| e2[t],
                |t| dot(u[t], u[t]),
                u.len(),
                0.0,
            );
            let ratio = est.max_relative.max(est.l2_relative) / self.tol;
            if self.accept(ratio)? {
                self.record(internal, attempts, vec![est]);
                return Ok(u);
            }
        }
    }

    fn stresslets(
        &mut self,
        box_length: f64,
        x: &[Vec3],
        p: &[Vec3],
        sigma: &[f64],
    ) -> Result<StressletField, SumError> {
        let l = box_length;
        if x.len() != p.len() || x.len() != sigma.len() {
            return Err(SumError::Input(
                "stresslets: x, p, sigma lengths differ".into(),
            ));
        }
        let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
        let strongest = sigma.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        let floor = |k: i32| strongest / (8.0 * PI * VISCOSITY * l.powi(k));
        let mut attempts = 0;
        loop {
            attempts += 1;
            let internal = self.internal_tolerance();
            let prm = self.fixed.unwrap_or_else(|| {
                EwaldParams::choose_for(internal, x.len(), l, &outputs, STRESSLET_PAIR_COST)
            });
            let (field, e2) = self.stresslet_attempt(prm, l, x, p, sigma)?;
            let n = x.len();
            let (estimates, ratio) = stresslet_estimates(
                StressletOutputs {
                    field: &field,
                    e2: &e2,
                    sigma,
                },
                AttemptTolerance {
                    params: &prm,
                    internal,
                    tol: self.tol,
                },
                floor,
                |parts| parts,
                n,
            );
            if self.accept(ratio)? {
                self.record(internal, attempts, estimates);
                return Ok(field);
            }
        }
    }

    fn last_report(&self) -> Option<SumReport> {
        self.report.clone()
    }

    fn adaptive_state(&self) -> Vec<u32> {
        self.refine.state()
    }

    fn set_adaptive_state(&mut self, state: &[u32]) {
        self.refine.set_state(self.tol, state);
    }
}
