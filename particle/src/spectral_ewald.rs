//! Fast periodic Stokes sums by spectral Ewald (docs/MODEL.md §1, §2): the Hasimoto split of
//! [`crate::ewald`], the short-ranged real-space part summed over neighbours from a point cell
//! list (`point_cells.rs`), the smooth Fourier part by Gaussian gridding
//! (the `gaussian_grid` module: spread the sources onto a uniform grid, real FFTs, a diagonal
//! multiplication, FFTs back, gather). `O(N log N)`.
//!
//! **The accuracy contract** (`docs/accuracy.md`). For every output a sum returns (RPY
//! velocities; stresslet velocities; stresslet velocity gradients), with `q_t` its exact
//! value at target `t` (the converged Ewald sum, [`crate::rpy_reference`]) and `|.|` the
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
//! truncation is sized against the output's own self-term scale (`crate::ewald_params`),
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

use crate::ewald::{
    RealSpaceTable, StressletTable, rpy_fourier_free_apply, rpy_fourier_mode_screened,
    rpy_overlap_correction, stresslet_fourier_self_gradient, stresslet_from_derivatives,
};
use crate::ewald_params::{
    ERROR_MODEL_RANGE, PAIR_COST, STRESSLET_PAIR_COST, error_model_constants,
};
pub use crate::ewald_params::{EwaldParams, SumOutput};
use crate::gaussian_grid::{GaussianGrid, GridPoints};
use crate::geometry::{Vec3, dot, min_image};
use crate::periodic::{
    ErrorEstimate, PeriodicStokes, RpyGeometry, StressletField, SumError, SumReport, check_rpy,
};
use crate::point_cells::{Hits, PointCells};
use crate::units::VISCOSITY;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// The finest internal tolerance an attempt uses (the windows reach their widest support
/// there; beyond it round-off of the cancelling parts takes over).
pub const MIN_INTERNAL_TOLERANCE: f64 = 1e-13;

/// Relative error of an output allowed for in the estimate beside the near-field model (see
/// [`estimate`]): the Fourier part's error from far sources, measured at 0.02-0.1 of the
/// internal tolerance relative to their flow.
const FAR_FIELD_SHARE: f64 = 0.25;

/// Sums in a row that met the contract with ten times room before the level is lowered by one.
const CALM_SUMS: u32 = 50;

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
    /// The device that does the Fourier part, if not the CPU.
    #[cfg(feature = "gpu")]
    gpu: Option<crate::gpu::GpuFourier>,
    /// Counts the preparations of new points (a device keeps the points it was given, and the
    /// cell list, while this stays the same: the products of one GMRES solve).
    #[cfg(feature = "gpu")]
    generation: u64,
}

/// The adaptive level of a sum (shared by [`SpectralEwald`] and the sum shared among ranks,
/// [`crate::shared_ewald`]): internal tolerance `tol 10^(-level/2)`, raised by the half decades
/// an attempt missed, lowered after [`CALM_SUMS`] sums in a row with ten times room.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Refinement {
    /// Refinement level.
    pub(crate) level: u32,
    /// Sums in a row with ten times room at the current level.
    pub(crate) calm: u32,
}

impl Refinement {
    /// Internal tolerance at the current level.
    pub(crate) fn internal_tolerance(&self, tol: f64) -> f64 {
        (tol * 10f64.powf(-0.5 * self.level as f64)).max(MIN_INTERNAL_TOLERANCE)
    }

    /// The highest level (internal tolerance [`MIN_INTERNAL_TOLERANCE`]).
    pub(crate) fn max_level(tol: f64) -> u32 {
        (2.0 * (tol / MIN_INTERNAL_TOLERANCE).log10())
            .ceil()
            .max(0.0) as u32
    }

    /// After an attempt with worst estimate/bound ratio `ratio`: `true` if it stands (met,
    /// nothing finer to try, or `fixed` parameters), else the level rises by the half decades
    /// missing.
    pub(crate) fn accept(&mut self, tol: f64, ratio: f64, fixed: bool) -> bool {
        let max = Self::max_level(tol);
        if fixed || ratio <= 1.0 || self.level >= max {
            if ratio <= 0.1 {
                self.calm += 1;
                if self.calm >= CALM_SUMS && self.level > 0 {
                    self.level -= 1;
                    self.calm = 0;
                }
            } else {
                self.calm = 0;
            }
            return true;
        }
        let steps = (2.0 * ratio.log10()).ceil().max(1.0) as u32;
        self.level = (self.level + steps).min(max);
        self.calm = 0;
        false
    }

    /// As a checkpoint keeps it.
    pub(crate) fn state(&self) -> Vec<u32> {
        vec![self.level, self.calm]
    }

    /// Restore what [`Self::state`] returned (ignored if it does not fit).
    pub(crate) fn set_state(&mut self, tol: f64, state: &[u32]) {
        if let [level, calm] = *state {
            self.level = level.min(Self::max_level(tol));
            self.calm = calm;
        }
    }
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
            #[cfg(feature = "gpu")]
            gpu: None,
            #[cfg(feature = "gpu")]
            generation: 0,
        })
    }

    /// A sum whose Fourier part (spreading, FFTs, the multiplication, the gather) and
    /// real-space pairs run on `device` ([`crate::gpu`]); everything else, and so the accuracy
    /// contract, as [`Self::new`].
    #[cfg(feature = "gpu")]
    pub fn with_device(tol: f64, device: crate::gpu::GpuFourier) -> Result<Self, SumError> {
        let mut s = Self::new(tol)?;
        s.gpu = Some(device);
        Ok(s)
    }

    /// Where the Fourier part runs: `"CPU"`, or the device's description.
    pub fn device(&self) -> String {
        #[cfg(feature = "gpu")]
        if let Some(g) = &self.gpu {
            return g.describe();
        }
        "CPU".into()
    }

    /// Whether the Fourier part runs on a device (the CPU grid's sorted points are then not
    /// needed).
    fn on_device(&self) -> bool {
        #[cfg(feature = "gpu")]
        {
            self.gpu.is_some()
        }
        #[cfg(not(feature = "gpu"))]
        {
            false
        }
    }

    /// The device's view of the sum with parameters `p` in a box of side `l`.
    #[cfg(feature = "gpu")]
    fn device_geometry(p: &EwaldParams, l: f64) -> crate::gpu::Geometry {
        crate::gpu::Geometry {
            window: crate::gaussian_grid::Window::new(l, p.xi, p.modes, p.support, p.shape),
            m: p.modes,
            l,
            xi: p.xi,
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
    fn accept(&mut self, ratio: f64) -> bool {
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
        #[cfg(feature = "gpu")]
        {
            self.generation += 1;
        }
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
        let prep = self.prepare(p, l, points, g)?;
        let (pts, cells) = (&prep.grid_points, &prep.cells);
        let xi = p.xi;
        let t1 = Instant::now();
        #[cfg(feature = "gpu")]
        let real = match self.gpu.as_mut() {
            Some(gpu) => {
                let table = RealSpaceTable::new(p.cutoff, p.xi, a);
                let r0 = ERROR_MODEL_RANGE * p.spacing(l);
                gpu.rpy_real(self.generation, cells, &table, (p.cutoff, a, r0), forces)
                    .map_err(|e| SumError::Device(e.to_string()))?
            }
            None => rpy_real(cells, &p, a, l, forces),
        };
        #[cfg(not(feature = "gpu"))]
        let real = rpy_real(cells, &p, a, l, forces);
        // Fourier space.
        let t2 = Instant::now();
        #[cfg(feature = "gpu")]
        let on_device = match self.gpu.as_mut() {
            Some(gpu) => Some(
                gpu.rpy(
                    self.generation,
                    &Self::device_geometry(&p, l),
                    a,
                    points,
                    forces,
                )
                .map_err(|e| SumError::Device(e.to_string()))?,
            ),
            None => None,
        };
        #[cfg(not(feature = "gpu"))]
        let on_device: Option<[Vec<f64>; 3]> = None;
        let uf: [Vec<f64>; 3] = match on_device {
            Some(uf) => uf,
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
            (points, forces),
            (&p, geometry),
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
        #[cfg(feature = "gpu")]
        let real = match self.gpu.as_mut() {
            Some(gpu) => {
                let table = StressletTable::new(prm.cutoff, prm.xi);
                let r0 = ERROR_MODEL_RANGE * prm.spacing(l);
                gpu.stresslet_real(self.generation, cells, &table, (prm.cutoff, r0), (p, sigma))
                    .map_err(|e| SumError::Device(e.to_string()))?
                    .into_iter()
                    .map(|v| {
                        let g = std::array::from_fn(|i| std::array::from_fn(|m| v[3 + 3 * i + m]));
                        ([v[0], v[1], v[2]], g, v[12])
                    })
                    .collect()
            }
            None => stresslet_real(cells, &prm, l, p, sigma),
        };
        #[cfg(not(feature = "gpu"))]
        let real = stresslet_real(cells, &prm, l, p, sigma);
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
        #[cfg(feature = "gpu")]
        let on_device = match self.gpu.as_mut() {
            Some(gpu) => Some(
                gpu.stresslet(
                    self.generation,
                    &Self::device_geometry(&prm, l),
                    x,
                    components,
                )
                .map_err(|e| SumError::Device(e.to_string()))?,
            ),
            None => None,
        };
        #[cfg(not(feature = "gpu"))]
        let on_device: Option<[Vec<f64>; 12]> = None;
        let back = match on_device {
            Some(back) => back,
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

/// The real-space part of the RPY sum at every point of `cells` (forces `forces` in the points'
/// order): every neighbour outside the own group plus the overlap correction, and the error
/// model's weighted squared strengths, `[u_0, u_1, u_2, e2]` per point.
pub(crate) fn rpy_real(
    cells: &PointCells,
    p: &EwaldParams,
    a: f64,
    l: f64,
    forces: &[Vec3],
) -> Vec<[f64; 4]> {
    let xi = p.xi;
    let table = RealSpaceTable::new(p.cutoff, xi, a);
    let sorted_forces = cells.sorted_values(forces);
    let sorted_f2: Vec<f64> = sorted_forces.par_iter().map(|f| dot(*f, *f)).collect();
    let r0 = ERROR_MODEL_RANGE * p.spacing(l);
    let r02 = r0 * r0;
    // Distances first, in a loop of independent iterations (square roots and divisions
    // overlap), then the table: `(A, B / r^2)` per hit.
    let distances = |hits: &mut Hits| {
        let n = hits.len;
        hits.dist.resize(hits.x.len(), 0.0);
        hits.inv.resize(hits.x.len(), 0.0);
        for h in 0..n {
            let r2 = hits.x[h] * hits.x[h] + hits.y[h] * hits.y[h] + hits.z[h] * hits.z[h];
            let rn = r2.sqrt();
            hits.dist[h] = rn;
            hits.inv[h] = 1.0 / rn;
        }
    };
    let kernel = |hits: &Hits, h: usize| {
        let rn = hits.dist[h];
        let (mut ar, mut br2) = table.eval_a_b_r2(rn, hits.inv[h]);
        if rn < 2.0 * a {
            let (ac, bc) = rpy_overlap_correction(rn, a);
            ar += ac;
            br2 += bc / (rn * rn);
        }
        let rn2 = rn * rn;
        (ar, br2, r02 / (r02 + rn2))
    };
    // Per point: velocity and the weighted squared strengths of its neighbours.
    if cells.n >= 5 {
        // Both points of a pair get A f + (B / r^2)(r . f) r of the other's force.
        let f = &sorted_forces;
        cells.symmetric(
            p.cutoff,
            distances,
            |hits, h, own: &mut [f64; 4], other: &mut [f64; 4]| {
                let (ar, br2, w) = kernel(hits, h);
                let r = [hits.x[h], hits.y[h], hits.z[h]];
                let (j, t) = (hits.index[h] as usize, hits.target);
                let (fj, ft) = (f[j], f[t]);
                let (sj, st) = (br2 * dot(r, fj), br2 * dot(r, ft));
                for d in 0..3 {
                    own[d] += ar * fj[d] + sj * r[d];
                    other[d] += ar * ft[d] + st * r[d];
                }
                own[3] += w * sorted_f2[j];
                other[3] += w * sorted_f2[t];
            },
            |a, b| {
                for d in 0..4 {
                    a[d] += b[d];
                }
            },
        )
    } else {
        cells.gather(p.cutoff, |acc: &mut [f64; 4], hits| {
            distances(hits);
            for h in 0..hits.len {
                let (ar, br2, w) = kernel(hits, h);
                let r = [hits.x[h], hits.y[h], hits.z[h]];
                let j = hits.index[h] as usize;
                let f = sorted_forces[j];
                let s = br2 * dot(r, f);
                for d in 0..3 {
                    acc[d] += ar * f[d] + s * r[d];
                }
                acc[3] += w * sorted_f2[j];
            }
        })
    }
}

/// The RPY velocities of the first `real.len()` points from their real-space parts `real`
/// ([`rpy_real`]) and Fourier parts `fourier(t)`: the own group's direct Fourier-part terms come
/// out (the point itself included), and the own group enters the error model with the same
/// weights. Returns the velocities and the error model's weighted strengths.
pub(crate) fn rpy_assemble(
    real: Vec<[f64; 4]>,
    fourier: impl Fn(usize) -> Vec3 + Sync,
    (points, forces): (&[Vec3], &[Vec3]),
    (p, geometry): (&EwaldParams, &RpyGeometry),
) -> (Vec<Vec3>, Vec<f64>) {
    let (l, a, g, xi) = (geometry.box_length, geometry.radius, geometry.group, p.xi);
    let r0 = ERROR_MODEL_RANGE * p.spacing(l);
    let r02 = r0 * r0;
    real.into_par_iter()
        .enumerate()
        .map(|(t, acc)| {
            let base = (t / g) * g;
            let uf = fourier(t);
            let mut ut = [acc[0] + uf[0], acc[1] + uf[1], acc[2] + uf[2]];
            let mut e2 = acc[3];
            for j in base..base + g {
                let r = min_image(
                    [
                        points[t][0] - points[j][0],
                        points[t][1] - points[j][1],
                        points[t][2] - points[j][2],
                    ],
                    l,
                );
                let v = rpy_fourier_free_apply(r, forces[j], xi, a);
                for d in 0..3 {
                    ut[d] -= v[d];
                }
                e2 += r02 / (r02 + dot(r, r)) * dot(forces[j], forces[j]);
            }
            (ut.map(|c| c / VISCOSITY), e2)
        })
        .unzip()
}

/// Per point of `cells`: the real-space stresslet velocity, gradient, and the error model's
/// weighted squared strengths of its neighbours (`p`, `sigma` in the points' order).
pub(crate) fn stresslet_real(
    cells: &PointCells,
    prm: &EwaldParams,
    l: f64,
    p: &[Vec3],
    sigma: &[f64],
) -> Vec<(Vec3, [Vec3; 3], f64)> {
    let (ps, ss) = (cells.sorted_values(p), cells.sorted_values(sigma));
    let table = StressletTable::new(prm.cutoff, prm.xi);
    let r0 = ERROR_MODEL_RANGE * prm.spacing(l);
    let r02 = r0 * r0;
    type Acc = (Vec3, [Vec3; 3], f64);
    // The full stencil: a symmetric sum would share the table but not the contractions,
    // which dominate here (measured: no faster).
    cells.gather(prm.cutoff, |acc: &mut Acc, hits| {
        for h in 0..hits.len {
            let j = hits.index[h] as usize;
            let r = [hits.x[h], hits.y[h], hits.z[h]];
            let r2 = dot(r, r);
            let rn = r2.sqrt();
            let dv = table.eval(rn);
            let (du, dg) = stresslet_from_derivatives(r, rn, ps[j], ss[j], &dv);
            for i in 0..3 {
                acc.0[i] += du[i];
                for m in 0..3 {
                    acc.1[i][m] += dg[i][m];
                }
            }
            acc.2 += r02 / (r02 + r2) * ss[j] * ss[j];
        }
    })
}

/// The points of the last sum, prepared for its parameters.
#[derive(Debug)]
struct Prepared {
    points: Vec<Vec3>,
    group: usize,
    grid_points: GridPoints,
    cells: PointCells,
}

/// The error model's estimate for one output of an attempt (see the module doc): per target
/// `est_t^2 = (C scale)^2 e2_t + (FAR_FIELD_SHARE tol_i)^2 |q_t|^2`, the model near the target
/// (`scale = tol_i Phi / mu`, `C` the output's calibrated constant for each metric) plus a
/// small relative error of the output itself, which covers the far sources the model leaves
/// out (two stresslets further apart than the real-space cutoff: the model alone gave zero,
/// the error was 0.02 tol); against the outputs' squared norms `out2`, as max-relative and
/// relative-L2 ratios (the floor `floor` in place of outputs below it). Sums in fixed chunks,
/// so the result does not depend on the thread count.
fn estimate(
    output: SumOutput,
    (scale, internal): (f64, f64),
    e2: impl Fn(usize) -> f64 + Sync,
    out2: impl Fn(usize) -> f64 + Sync,
    n: usize,
    floor: f64,
) -> ErrorEstimate {
    let tot = estimate_parts(output, (scale, internal), e2, out2, n);
    estimate_from(output, tot, n, floor)
}

/// The estimate's four reductions over targets `0..n`: `[max est^2, sum est^2, max |q|^2,
/// sum |q|^2]` (sums in fixed chunks: the same bits for any thread count).
pub(crate) fn estimate_parts(
    output: SumOutput,
    (scale, internal): (f64, f64),
    e2: impl Fn(usize) -> f64 + Sync,
    out2: impl Fn(usize) -> f64 + Sync,
    n: usize,
) -> [f64; 4] {
    const CHUNK: usize = 4096;
    let (c_max, c_2) = error_model_constants(output, internal);
    let (a_max, a_2) = ((c_max * scale).powi(2), (c_2 * scale).powi(2));
    let far = (FAR_FIELD_SHARE * internal).powi(2);
    let parts: Vec<[f64; 4]> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut acc = [0.0f64; 4];
            for t in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let (e, o) = (e2(t), out2(t));
                acc[0] = acc[0].max(a_max * e + far * o);
                acc[1] += a_2 * e + far * o;
                acc[2] = acc[2].max(o);
                acc[3] += o;
            }
            acc
        })
        .collect();
    let mut tot = [0.0f64; 4];
    for a in &parts {
        tot[0] = tot[0].max(a[0]);
        tot[1] += a[1];
        tot[2] = tot[2].max(a[2]);
        tot[3] += a[3];
    }
    tot
}

/// Refuse tolerances outside `[1e-10, 1e-1]`.
pub(crate) fn check_tolerance(tol: f64) -> Result<(), SumError> {
    if !(1e-10..=1e-1).contains(&tol) {
        return Err(SumError::Input(format!(
            "fast-sum tolerance {tol:e} outside [1e-10, 1e-1]"
        )));
    }
    Ok(())
}

/// The report of an accepted attempt (`(internal tolerance, level, attempts)`).
pub(crate) fn report_of(
    tol: f64,
    (internal, level, attempts): (f64, u32, u32),
    params: EwaldParams,
    estimates: Vec<ErrorEstimate>,
) -> SumReport {
    let met = estimates
        .iter()
        .all(|e| e.max_relative <= tol && e.l2_relative <= tol);
    SumReport {
        tolerance: tol,
        internal_tolerance: internal,
        level,
        attempts,
        params,
        estimates,
        met,
    }
}

/// The estimates of a stresslet attempt (velocity, gradient) and the worst estimate/bound
/// ratio, from its `(field, weighted strengths, sigma)` over `n` targets in all; `reduce`
/// turns the local reductions into the whole box's (the identity for one process).
pub(crate) fn stresslet_estimates(
    (field, e2, sigma): (&StressletField, &[f64], &[f64]),
    (prm, internal, tol): (&EwaldParams, f64, f64),
    floor: impl Fn(i32) -> f64,
    reduce: impl Fn([f64; 4]) -> [f64; 4],
    n: usize,
) -> (Vec<ErrorEstimate>, f64) {
    let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
    let scale = |o: SumOutput| internal * o.self_scale(prm.xi) / VISCOSITY;
    let local = field.u.len();
    let u = estimate_parts(
        outputs[0],
        (scale(outputs[0]), internal),
        |t| e2[t],
        |t| dot(field.u[t], field.u[t]),
        local,
    );
    let g = estimate_parts(
        outputs[1],
        (scale(outputs[1]), internal),
        |t| e2[t] + sigma[t] * sigma[t],
        |t| field.grad[t].iter().map(|r| dot(*r, *r)).sum(),
        local,
    );
    let estimates = vec![
        estimate_from(outputs[0], reduce(u), n, floor(2)),
        estimate_from(outputs[1], reduce(g), n, floor(3)),
    ];
    let ratio = estimates
        .iter()
        .map(|e| e.max_relative.max(e.l2_relative))
        .fold(0.0, f64::max)
        / tol;
    (estimates, ratio)
}

/// The estimate from [`estimate_parts`] over `n` targets in all (relative to the output, with
/// `floor` where it vanishes).
pub(crate) fn estimate_from(
    output: SumOutput,
    tot: [f64; 4],
    n: usize,
    floor: f64,
) -> ErrorEstimate {
    let ratio = |est: f64, out: f64| {
        if est == 0.0 {
            0.0
        } else if out > 0.0 {
            est / out
        } else {
            f64::INFINITY
        }
    };
    ErrorEstimate {
        output,
        max_relative: ratio(tot[0].sqrt(), tot[2].sqrt().max(floor)),
        l2_relative: ratio(tot[1].sqrt(), tot[3].sqrt().max(floor * (n as f64).sqrt())),
    }
}

impl SpectralEwald {
    /// Record the accepted attempt.
    fn record(&mut self, internal: f64, attempts: u32, estimates: Vec<ErrorEstimate>) {
        let params = self.last.expect("an attempt ran");
        self.report = Some(report_of(
            self.tol,
            (internal, self.refine.level, attempts),
            params,
            estimates,
        ));
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
                (scale, internal),
                |t| e2[t],
                |t| dot(u[t], u[t]),
                u.len(),
                0.0,
            );
            let ratio = est.max_relative.max(est.l2_relative) / self.tol;
            if self.accept(ratio) {
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
                (&field, &e2, sigma),
                (&prm, internal, self.tol),
                floor,
                |parts| parts,
                n,
            );
            if self.accept(ratio) {
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
