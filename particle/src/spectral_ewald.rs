//! Fast periodic Stokes sums by spectral Ewald (MODEL.md §1, §2): the Hasimoto split of
//! [`crate::ewald`], the short-ranged real-space part summed over neighbours from a point cell
//! list, the smooth Fourier part by Gaussian gridding ([`crate::gaussian_grid`]: spread the
//! forces onto a uniform grid, real FFTs, a diagonal multiplication, FFTs back, gather).
//! `O(N log N)`.
//!
//! Parameters come from one requested tolerance `tol` ([`EwaldParams::choose`]): with
//! `c = sqrt(ln(1/tol))`, the real-space cutoff is `r_c = c/xi` and the largest wavenumber
//! `k_max = 2 xi c` (both truncated parts are then about `exp(-c^2) = tol` of the kernel); the
//! Gaussian window's support, shape and the grid's oversampling come from
//! [`crate::gaussian_grid::window_for`]. Each FFT-friendly grid size fixes the largest `xi` it
//! resolves, and a cost model of pair work against grid work picks the grid, with `r_c <= L/2`
//! so the minimum image is exact. Measured against the reference: the relative L2 error is
//! 0.55-0.95 times `tol` from 1e-2 to 1e-8 (`tests/periodic_sums.rs`).
//!
//! Determinism: the real-space sum is a gather (each target adds its neighbours in cell order,
//! no shared accumulators) and the gridding is thread-count independent, so results are
//! bit-identical for any rayon pool size.

use crate::ewald::{
    RealSpaceTable, StressletTable, rpy_fourier_free_apply, rpy_fourier_mode_screened,
    rpy_overlap_correction, stresslet_fourier_self_gradient, stresslet_from_derivatives,
};
use crate::gaussian_grid::{GaussianGrid, GridPoints, window_for};
use crate::geometry::{Vec3, dot, floor_i64, min_image, wrap_position};
use crate::periodic::{PeriodicStokes, RpyGeometry, StressletField, SumError, check_rpy};
use crate::slabs::{self, phased};
use crate::units::VISCOSITY;
use motile_analysis::fft3::next_smooth_even;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// Cost of one real-space pair relative to one grid point of the Fourier stage (its six
/// real FFTs and the multiplication); calibrated at 1e5 points, tolerance 1e-4, where the
/// measured total is flat within the machine's noise from 0.09 to 0.2 (grids 100-108).
const PAIR_COST: f64 = 0.14;

/// The same for a stresslet pair (velocity and gradient from a table) against its Fourier
/// side (nine transforms instead of six, six fields spread, the gradient gathered);
/// calibrated at 78 125 centres, tolerance 1e-4 (flat from 0.15 to 0.45: grids 100-120).
const STRESSLET_PAIR_COST: f64 = 0.3;

/// The resolved parameters of one spectral Ewald sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EwaldParams {
    /// Splitting parameter xi (1/length).
    pub xi: f64,
    /// Real-space cutoff.
    pub cutoff: f64,
    /// Fourier modes per dimension, the Gaussian grid's size (even).
    pub modes: usize,
    /// Gaussian support per axis, in grid points.
    pub support: usize,
    /// Gaussian shape: standard deviations at the support's edge.
    pub shape: f64,
}

impl EwaldParams {
    /// Parameters for tolerance `tol`, `n` points in a box of side `l`.
    pub fn choose(tol: f64, n: usize, l: f64) -> Self {
        Self::choose_with(tol, n, l, PAIR_COST)
    }

    /// As [`Self::choose`] with a given cost of a real-space pair.
    pub fn choose_with(tol: f64, n: usize, l: f64, pair_cost: f64) -> Self {
        let c = (1.0 / tol).ln().sqrt();
        let density = n as f64 / (l * l * l);
        let (support, shape, over) = window_for(tol);
        // Each FFT-friendly grid size M fixes the largest xi it resolves,
        // M = over k_max L / pi with k_max = 2 xi c (which also keeps every |k| <= k_max);
        // the cost model then weighs the real-space pairs of that xi against the grid.
        let mut best: Option<(f64, Self)> = None;
        let mut m = next_smooth_even(support.max(4));
        while m <= 4096 {
            let xi = m as f64 * PI / (2.0 * c * l * over);
            let p = Self {
                xi,
                cutoff: c / xi,
                modes: m,
                support,
                shape,
            };
            let grid = (m * m * m) as f64;
            if best.as_ref().is_some_and(|(b, _)| grid > *b) {
                break;
            }
            if p.cutoff <= 0.5 * l {
                let pairs = n as f64 * density * 4.0 / 3.0 * PI * p.cutoff.powi(3);
                let cost = pair_cost * pairs + grid;
                if best.as_ref().is_none_or(|(b, _)| cost < *b) {
                    best = Some((cost, p));
                }
            }
            m = next_smooth_even(m + 1);
        }
        best.expect("a grid of 4096^3 or less resolves any supported tolerance")
            .1
    }
}

/// Spectral Ewald with parameters chosen from one tolerance; keeps its grid and buffers.
#[derive(Debug)]
pub struct SpectralEwald {
    /// Requested relative accuracy.
    pub tol: f64,
    /// Fixed parameters, overriding the automatic choice (for tests and studies).
    pub fixed: Option<EwaldParams>,
    grid: Option<GaussianGrid>,
    /// Box length of the grid.
    grid_box: f64,
    /// The last sum's points, prepared (taken out during a sum).
    prepared: Option<Prepared>,
    last: Option<EwaldParams>,
    timing: SumTiming,
}

/// Seconds spent in the stages of the last sum.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SumTiming {
    /// Parameter choice, grid plan and point sorting.
    pub setup: f64,
    /// Real-space pairs (cell list included).
    pub real: f64,
    /// Fourier part: type 1, multiplication, type 2.
    pub fourier: f64,
    /// Own-group corrections and assembly.
    pub corrections: f64,
}

impl SpectralEwald {
    /// A sum at relative tolerance `tol` (1e-12 ..= 1e-1).
    pub fn new(tol: f64) -> Result<Self, SumError> {
        if !(1e-12..=1e-1).contains(&tol) {
            return Err(SumError::Input(format!(
                "fast-sum tolerance {tol:e} outside [1e-12, 1e-1]"
            )));
        }
        Ok(Self {
            tol,
            fixed: None,
            grid: None,
            grid_box: 0.0,
            prepared: None,
            last: None,
            timing: SumTiming::default(),
        })
    }

    /// Seconds per stage of the last sum.
    pub fn last_timing(&self) -> SumTiming {
        self.timing
    }

    /// The parameters of the last sum.
    pub fn last_params(&self) -> Option<EwaldParams> {
        self.last
    }

    /// Parameters, grid, and the points prepared for both parts; a sum at the same points,
    /// box, group size and parameters as the last one (the products of one GMRES solve)
    /// reuses the sorted points, their windows and the cell list.
    fn prepare(
        &mut self,
        l: f64,
        points: &[Vec3],
        group: usize,
        pair_cost: f64,
    ) -> Result<Prepared, SumError> {
        let p = self
            .fixed
            .unwrap_or_else(|| EwaldParams::choose_with(self.tol, points.len(), l, pair_cost));
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
        let grid_points = self
            .grid
            .as_ref()
            .expect("grid built above")
            .prepare_reusing(points, old_grid);
        kept.clear();
        kept.extend_from_slice(points);
        Ok(Prepared {
            points: kept,
            group,
            params: p,
            grid_points,
            cells: PointCells::build(points, l, p.cutoff, group),
        })
    }
}

/// The points of the last sum, prepared for its parameters.
#[derive(Debug)]
struct Prepared {
    points: Vec<Vec3>,
    group: usize,
    params: EwaldParams,
    grid_points: GridPoints,
    cells: PointCells,
}

/// Points sorted into cells of side at least half the cutoff (a 5^3 stencil then covers the
/// cutoff sphere with 3.7 times its volume, against 6.4 for cells of the full cutoff), with a
/// cell-ordered copy of the positions so the inner loop streams through memory.
#[derive(Debug)]
struct PointCells {
    n: usize,
    l: f64,
    start: Vec<usize>,
    members: Vec<u32>,
    sorted: Vec<Vec3>,
    /// The same, by coordinate.
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    /// Group of each point, in cell order.
    group: Vec<u32>,
}

impl PointCells {
    fn build(y: &[Vec3], l: f64, cutoff: f64, group: usize) -> Self {
        let n = ((2.0 * l / cutoff).floor() as usize).max(1);
        // The cell comes from the wrapped position itself, so a point and its cell always
        // agree: a coordinate just below 0 wraps to L by rounding and is stored as 0, and a
        // cell computed from the unwrapped fraction (1.0 after rounding) put it in the last
        // cell, about L from its stored position, losing all its real-space pairs.
        let scale = n as f64 / l;
        let cell_of: Vec<u32> = y
            .par_iter()
            .map(|p| {
                let idx = wrap_position(*p, l).map(|c| ((c * scale) as usize).min(n - 1));
                ((idx[2] * n + idx[1]) * n + idx[0]) as u32
            })
            .collect();
        let mut start = vec![0usize; n * n * n + 1];
        for &k in &cell_of {
            start[k as usize + 1] += 1;
        }
        for c in 0..n * n * n {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut members = vec![0u32; y.len()];
        for (i, &k) in cell_of.iter().enumerate() {
            members[next[k as usize]] = i as u32;
            next[k as usize] += 1;
        }
        // Wrapped into [0, L) so that a neighbour cell's periodic shift is one vector per cell.
        let sorted: Vec<Vec3> = members
            .par_iter()
            .map(|&i| wrap_position(y[i as usize], l))
            .collect();
        let group = members
            .iter()
            .map(|&i| (i as usize / group) as u32)
            .collect();
        let (xs, ys, zs) = (
            sorted.iter().map(|p: &Vec3| p[0]).collect(),
            sorted.iter().map(|p: &Vec3| p[1]).collect(),
            sorted.iter().map(|p: &Vec3| p[2]).collect(),
        );
        Self {
            n,
            l,
            start,
            members,
            sorted,
            xs,
            ys,
            zs,
            group,
        }
    }

    /// Values in cell order (`members()[k]`'s value at `k`), for streaming in [`Self::gather`].
    fn sorted_values<T: Copy + Send + Sync>(&self, v: &[T]) -> Vec<T> {
        self.members.par_iter().map(|&i| v[i as usize]).collect()
    }

    /// For each target, `f(acc, hits)` with its hits: every point `k` of another group (cell
    /// order, see [`Self::sorted_values`]) with the minimum-image `r = y_t - y_k`,
    /// `0 < |r| < cutoff`, in an order fixed by the cells; results in the targets' own order.
    ///
    /// Each target visits the 5 x 5 rows of neighbour cells along x, skips a row whose
    /// y-z distance exceeds the cutoff and takes from the others only the cells its cutoff
    /// sphere reaches (one or two contiguous runs of points, cells being ordered x fastest).
    /// The runs are filtered without branches (distances in a straight loop, hits compacted),
    /// then `f` runs on the hits. A distance test that branched mispredicted on about a third
    /// of the candidates, and a fixed 5^3 stencil visited 3.7 times the cutoff sphere.
    fn gather<A: Send + Default + Clone>(
        &self,
        cutoff: f64,
        f: impl Fn(&mut A, &mut Hits) + Sync,
    ) -> Vec<A> {
        let c2 = cutoff * cutoff;
        let n = self.n as i64;
        let l = self.l;
        let per_cell: Vec<Vec<A>> = (0..self.n * self.n * self.n)
            .into_par_iter()
            .map_init(Hits::default, |hits, c| {
                let range = self.start[c]..self.start[c + 1];
                let mut out = vec![A::default(); range.len()];
                if range.is_empty() {
                    return out;
                }
                if self.n < 5 {
                    // Few cells: every point, minimum image per pair.
                    for (k, acc) in out.iter_mut().enumerate() {
                        let tk = range.start + k;
                        let yt = self.sorted[tk];
                        let gt = self.group[tk];
                        hits.clear();
                        for (jk, yj) in self.sorted.iter().enumerate() {
                            let r = min_image([yt[0] - yj[0], yt[1] - yj[1], yt[2] - yj[2]], l);
                            let r2 = dot(r, r);
                            hits.push(r, jk, r2 < c2 && r2 > 0.0 && self.group[jk] != gt);
                        }
                        f(acc, hits);
                    }
                    return out;
                }
                let c = c as i64;
                let (cx, cy, cz) = (c % n, (c / n) % n, c / (n * n));
                for (k, acc) in out.iter_mut().enumerate() {
                    let tk = range.start + k;
                    hits.clear();
                    self.collect_hits(tk, [cx, cy, cz], cutoff, false, hits);
                    f(acc, hits);
                }
                out
            })
            .collect();
        let mut result = vec![A::default(); self.members.len()];
        for (k, a) in per_cell.into_iter().flatten().enumerate() {
            result[self.members[k] as usize] = a;
        }
        result
    }

    /// The hits of sorted point `tk` in cell `[cx, cy, cz]` (needs at least 5 cells per
    /// axis): the 5 x 5 rows of neighbour cells along x, a row skipped when its y-z distance
    /// exceeds the cutoff, and from the others only the cells the cutoff sphere reaches (one or
    /// two contiguous runs of points, cells being ordered x fastest). With `half`, only the
    /// forward half of the stencil: rows with `(dz, dy) > (0, 0)`, and in the target's own
    /// row the points after it (its own cell included), so each pair is found once.
    fn collect_hits(
        &self,
        tk: usize,
        [cx, cy, cz]: [i64; 3],
        cutoff: f64,
        half: bool,
        hits: &mut Hits,
    ) {
        let c2 = cutoff * cutoff;
        let n = self.n as i64;
        let l = self.l;
        let side = l / self.n as f64;
        let inv_side = 1.0 / side;
        let (xs, ys, zs) = (&self.xs, &self.ys, &self.zs);
        let yt = self.sorted[tk];
        let gt = self.group[tk];
        hits.target = tk;
        for dz in if half { 0..=2 } else { -2..=2 } {
            let uz = cz + dz;
            let gz = gap(yt[2], uz as f64 * side, side);
            if gz >= cutoff {
                continue;
            }
            let (wz, sz) = wrap(uz, n, l);
            for dy in if half && dz == 0 { 0..=2 } else { -2..=2 } {
                let uy = cy + dy;
                let gy = gap(yt[1], uy as f64 * side, side);
                let g2 = gy * gy + gz * gz;
                if g2 >= c2 {
                    continue;
                }
                let own_row = half && dz == 0 && dy == 0;
                let (wy, sy) = wrap(uy, n, l);
                let rx = (c2 - g2).sqrt();
                let lo = if own_row {
                    cx
                } else {
                    floor_i64((yt[0] - rx) * inv_side).max(cx - 2)
                };
                let hi = floor_i64((yt[0] + rx) * inv_side).min(cx + 2);
                let row = (wz * n + wy) * n;
                // The run of cells lo..=hi, cut where it wraps around the box.
                let mut ux = lo;
                while ux <= hi {
                    let (wx, sx) = wrap(ux, n, l);
                    let last = if ux < 0 {
                        hi.min(-1)
                    } else if ux < n {
                        hi.min(n - 1)
                    } else {
                        hi
                    };
                    let mut a = self.start[(row + wx) as usize];
                    if own_row && ux == cx {
                        a = tk + 1;
                    }
                    let b = self.start[(row + wx + last - ux) as usize + 1];
                    let t = [yt[0] - sx, yt[1] - sy, yt[2] - sz];
                    hits.push_run(t, gt, a..b, [xs, ys, zs], &self.group, c2);
                    ux = last + 1;
                }
            }
        }
    }

    /// Symmetric pair sum (at least 5 cells per axis): every pair of points of different
    /// groups within the cutoff once: after `prepare(hits)` for a target's hits,
    /// `pair(hits, h, target, other)` adds hit `h`'s contributions to the target's and the
    /// other point's accumulators (`hits.index[h]` in cell order, `r = y_target - y_other`);
    /// a target's own sum is added with `add` when its hits are done. Results in the points'
    /// own order.
    ///
    /// Each target looks at the forward half of its stencil (see [`Self::collect_hits`]), so
    /// it writes to points up to two cell planes further in z. The z-planes are cut into an
    /// even number of slabs of at least two planes (a function of the cell grid only); the even
    /// slabs run in parallel, then the odd ones, each writing only its own planes and the two
    /// after them (the last slab also the first two planes). Every point then receives its
    /// contributions in an order fixed by the cells, for any thread count.
    fn symmetric<A: Send + Default + Clone>(
        &self,
        cutoff: f64,
        prepare: impl Fn(&mut Hits) + Sync,
        pair: impl Fn(&Hits, usize, &mut A, &mut A) + Sync,
        add: impl Fn(&mut A, &A) + Sync,
    ) -> Vec<A> {
        let n = self.n;
        assert!(n >= 5, "the symmetric sum needs at least 5 cells per axis");
        let nn = n * n;
        let plane_start = |z: usize| self.start[z * nn];
        // Slabs at least two cell planes thick: a target writes up to two planes ahead.
        let bounds = slabs::bounds(n, 2);
        let mut acc = vec![A::default(); self.members.len()];
        let task = |s: usize, main: &mut [A], main_start: usize, wrap: &mut [A]| {
            let mut hits = Hits::default();
            for z in bounds[s]..bounds[s + 1] {
                for c in z * nn..(z + 1) * nn {
                    let c3 = [(c % n) as i64, ((c / n) % n) as i64, z as i64];
                    for tk in self.start[c]..self.start[c + 1] {
                        hits.clear();
                        self.collect_hits(tk, c3, cutoff, true, &mut hits);
                        prepare(&mut hits);
                        let mut own = A::default();
                        for h in 0..hits.len {
                            let j = hits.index[h] as usize;
                            let other = if j >= main_start && j - main_start < main.len() {
                                &mut main[j - main_start]
                            } else {
                                &mut wrap[j]
                            };
                            pair(&hits, h, &mut own, other);
                        }
                        add(&mut main[tk - main_start], &own);
                    }
                }
            }
        };
        phased(&mut acc, &bounds, 2, plane_start, task);
        let mut result = vec![A::default(); self.members.len()];
        for (k, v) in acc.into_iter().enumerate() {
            result[self.members[k] as usize] = v;
        }
        result
    }
}

/// Distance along one axis from `x` to the interval `[lo, lo + side)`.
#[inline]
fn gap(x: f64, lo: f64, side: f64) -> f64 {
    (lo - x).max(x - lo - side).max(0.0)
}

/// Cell coordinate `u` (possibly one box outside) wrapped into `0..n`, and the shift that
/// moves the wrapped cell's points next to the target (subtracted from the target instead).
#[inline]
fn wrap(u: i64, n: i64, l: f64) -> (i64, f64) {
    if u < 0 {
        (u + n, -l)
    } else if u >= n {
        (u - n, l)
    } else {
        (u, 0.0)
    }
}

/// The hits of one target: separation vectors and point indices (cell order), `len` of them.
#[derive(Default)]
struct Hits {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    index: Vec<u32>,
    len: usize,
    /// The target (cell order).
    target: usize,
    /// Scratch for the caller: distances and their inverses.
    dist: Vec<f64>,
    inv: Vec<f64>,
}

impl Hits {
    fn clear(&mut self) {
        self.len = 0;
    }

    fn reserve(&mut self, extra: usize) {
        let need = self.len + extra;
        if self.x.len() < need {
            let size = need.next_power_of_two();
            self.x.resize(size, 0.0);
            self.y.resize(size, 0.0);
            self.z.resize(size, 0.0);
            self.index.resize(size, 0);
        }
    }

    /// Append `(r, k)` if `keep`.
    fn push(&mut self, r: Vec3, k: usize, keep: bool) {
        self.reserve(1);
        self.x[self.len] = r[0];
        self.y[self.len] = r[1];
        self.z[self.len] = r[2];
        self.index[self.len] = k as u32;
        self.len += usize::from(keep);
    }

    /// Append the points `run` of groups other than `gt` within the cutoff of `t` (shifted
    /// target) and not on it (a coincident point has no defined direction; such pairs were
    /// always left out), without branches: every candidate is written at `len`, which
    /// advances only for hits.
    #[inline]
    fn push_run(
        &mut self,
        t: Vec3,
        gt: u32,
        run: std::ops::Range<usize>,
        [xs, ys, zs]: [&[f64]; 3],
        group: &[u32],
        c2: f64,
    ) {
        let n = run.len();
        if n == 0 {
            return;
        }
        self.reserve(n);
        let (px, py, pz) = (&xs[run.clone()], &ys[run.clone()], &zs[run.clone()]);
        let pg = &group[run.clone()];
        // Local windows of the hit arrays: the write position `k <= i < n` is clamped to `n - 1`
        // (a no-op) so the compiler drops the bounds checks.
        let base = self.len;
        let (hx, hy, hz) = (
            &mut self.x[base..base + n],
            &mut self.y[base..base + n],
            &mut self.z[base..base + n],
        );
        let hi = &mut self.index[base..base + n];
        let mut k = 0;
        for i in 0..n {
            let r = [t[0] - px[i], t[1] - py[i], t[2] - pz[i]];
            let r2 = dot(r, r);
            let slot = k.min(n - 1);
            hx[slot] = r[0];
            hy[slot] = r[1];
            hz[slot] = r[2];
            hi[slot] = (run.start + i) as u32;
            k += usize::from((r2 < c2) & (r2 > 0.0) & (pg[i] != gt));
        }
        self.len = base + k;
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
        let (l, a, g) = (geometry.box_length, geometry.radius, geometry.group);
        let t0 = Instant::now();
        let prep = self.prepare(l, points, g, PAIR_COST)?;
        let (p, pts, cells) = (prep.params, &prep.grid_points, &prep.cells);
        let xi = p.xi;
        let t1 = Instant::now();
        // Real space: every neighbour outside the own group, plus the overlap correction.
        let table = RealSpaceTable::new(p.cutoff, xi, a);
        let sorted_forces = cells.sorted_values(forces);
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
            (ar, br2)
        };
        let mut u = if cells.n >= 5 {
            // Both points of a pair get A f + (B / r^2)(r . f) r of the other's force.
            let f = &sorted_forces;
            cells.symmetric(
                p.cutoff,
                distances,
                |hits, h, own: &mut Vec3, other: &mut Vec3| {
                    let (ar, br2) = kernel(hits, h);
                    let r = [hits.x[h], hits.y[h], hits.z[h]];
                    let (fj, ft) = (f[hits.index[h] as usize], f[hits.target]);
                    let (sj, st) = (br2 * dot(r, fj), br2 * dot(r, ft));
                    for d in 0..3 {
                        own[d] += ar * fj[d] + sj * r[d];
                        other[d] += ar * ft[d] + st * r[d];
                    }
                },
                |a, b| {
                    for d in 0..3 {
                        a[d] += b[d];
                    }
                },
            )
        } else {
            cells.gather(p.cutoff, |acc: &mut Vec3, hits| {
                distances(hits);
                for h in 0..hits.len {
                    let (ar, br2) = kernel(hits, h);
                    let r = [hits.x[h], hits.y[h], hits.z[h]];
                    let f = sorted_forces[hits.index[h] as usize];
                    let s = br2 * dot(r, f);
                    for d in 0..3 {
                        acc[d] += ar * f[d] + s * r[d];
                    }
                }
            })
        };
        // Fourier space.
        let t2 = Instant::now();
        let grid = self.grid.as_mut().expect("prepared");
        let f: Vec<Vec<f64>> = (0..3)
            .map(|d| forces.par_iter().map(|v| v[d]).collect())
            .collect();
        let spread = grid.spread(pts, [&f[0], &f[1], &f[2]]);
        let vol = l * l * l;
        let conv = grid.convolve::<3, 3>(spread, |k, k2, screen, f| {
            rpy_fourier_mode_screened(k, k2, screen, xi, a, vol, f)
        });
        let uf: [Vec<f64>; 3] = grid.gather(pts, conv);
        let t3 = Instant::now();
        // Own group's direct Fourier-part terms come out (the point itself included).
        u.par_iter_mut().enumerate().for_each(|(t, ut)| {
            let base = (t / g) * g;
            for d in 0..3 {
                ut[d] += uf[d][t];
            }
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
            }
            *ut = ut.map(|c| c / VISCOSITY);
        });
        self.prepared = Some(prep);
        self.timing = SumTiming {
            setup: (t1 - t0).as_secs_f64(),
            real: (t2 - t1).as_secs_f64(),
            fourier: (t3 - t2).as_secs_f64(),
            corrections: t3.elapsed().as_secs_f64(),
        };
        Ok(u)
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
        let t0 = Instant::now();
        let prep = self.prepare(l, x, 1, STRESSLET_PAIR_COST)?;
        let (prm, pts, cells) = (prep.params, &prep.grid_points, &prep.cells);
        let xi = prm.xi;
        let t1 = Instant::now();
        let (ps, ss) = (cells.sorted_values(p), cells.sorted_values(sigma));
        let table = StressletTable::new(prm.cutoff, xi);
        type Acc = (Vec3, [Vec3; 3]);
        let add = |acc: &mut Acc, (du, dg): &Acc| {
            for i in 0..3 {
                acc.0[i] += du[i];
                for m in 0..3 {
                    acc.1[i][m] += dg[i][m];
                }
            }
        };
        // The full stencil: a symmetric sum would share the table but not the contractions,
        // which dominate here (measured: no faster).
        let real = cells.gather(prm.cutoff, |acc: &mut Acc, hits| {
            for h in 0..hits.len {
                let j = hits.index[h] as usize;
                let r = [hits.x[h], hits.y[h], hits.z[h]];
                let rn = dot(r, r).sqrt();
                let dv = table.eval(rn);
                add(acc, &stresslet_from_derivatives(r, rn, ps[j], ss[j], &dv));
            }
        });
        let t2 = Instant::now();
        let grid = self.grid.as_mut().expect("prepared");
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
        let spread = grid.spread(pts, std::array::from_fn::<_, 6, _>(|c| s[c].as_slice()));
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
        let back = grid.gather_gradient(pts, out);
        let t3 = Instant::now();
        let (u, grad): (Vec<Vec3>, Vec<[Vec3; 3]>) = real
            .into_par_iter()
            .enumerate()
            .map(|(t, (mut u, mut g))| {
                let own = stresslet_fourier_self_gradient(p[t], sigma[t], xi);
                for i in 0..3 {
                    u[i] = (u[i] + back[i][t]) / VISCOSITY;
                    for m in 0..3 {
                        g[i][m] = (g[i][m] + back[3 + 3 * i + m][t] - own[i][m]) / VISCOSITY;
                    }
                }
                (u, g)
            })
            .unzip();
        self.prepared = Some(prep);
        self.timing = SumTiming {
            setup: (t1 - t0).as_secs_f64(),
            real: (t2 - t1).as_secs_f64(),
            fourier: (t3 - t2).as_secs_f64(),
            corrections: t3.elapsed().as_secs_f64(),
        };
        Ok(StressletField { u, grad })
    }
}
