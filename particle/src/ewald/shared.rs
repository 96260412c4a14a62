//! The spectral Ewald stresslet sum of [`crate::ewald::spectral`] shared among ranks
//! (docs/MODEL.md §3a): each rank holds its own points and copies of the others' within the
//! real-space cutoff ([`crate::parallel::halo::Halo`]).
//!
//! - Real space: every rank sums over the neighbours of its own points (own points and copies),
//!   from the same cell list and tables as one process, skipping pairs of two copies; the
//!   cutoff is capped at the copies' reach ([`EwaldParams`] chosen with that cap, a finer grid
//!   making up for it).
//! - Fourier space: the `M^3` grid is cut into slabs of planes along z. Each rank spreads its
//!   own points (the same Gaussian window as one process) into the planes their windows touch
//!   and sends each plane to its owner, which adds the contributions in rank order. The 3D FFT
//!   is distributed: real-to-complex FFTs along x (`M/2 + 1` modes kept) and complex ones along
//!   y of the owned planes, an all-to-all transpose to slabs of y rows, FFTs along z; the
//!   kernel multiplies the modes a rank holds; the inverse runs back the same way. Each rank
//!   then fetches the planes its points' windows need and gathers velocities (and, for
//!   stresslets, gradients from the window's derivative), as one process does. A hand-written
//!   transpose over the all-to-all exchange with rustfft/realfft (FFTW's MPI interface would
//!   need its C library, GPL, and unsafe FFI).
//! - The error estimate and the refinement are those of one process, with the maxima and sums
//!   over all ranks, so every rank takes the same decisions.
//!
//! Results agree with the single-process sum within the tolerance (both are within it of the
//! exact sum); the FFTs' factorisation along y and z and the per-plane addition order differ
//! from the single process's, so the bits do not.

use crate::ewald::kernels::{rpy_fourier_mode_screened, stresslet_fourier_self_gradient};
use crate::ewald::params::{EwaldParams, PAIR_COST, STRESSLET_PAIR_COST, SumOutput};
use crate::ewald::periodic::{
    ErrorEstimate, RpyGeometry, StressletField, SumError, SumReport, check_rpy,
};
use crate::ewald::point_cells::PointCells;
use crate::ewald::spectral::estimates::{
    Accepted, AttemptTolerance, ErrorScale, StressletOutputs, estimate_from, estimate_parts,
    report_of, stresslet_estimates,
};
use crate::ewald::spectral::real_space::{RpyPairCache, rpy_assemble, rpy_real, stresslet_real};
use crate::ewald::spectral::refinement::{Refinement, check_tolerance};
use crate::ewald::window::{MAX_SUPPORT, Window};
use crate::model::geometry::{Vec3, dot, floor_i64, wrap_position};
use crate::model::units::VISCOSITY;
use crate::parallel::comm::Comm;
use crate::parallel::slab_fft::SlabFft;
use num_complex::Complex64;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Stresslet components in the spread: `S_00, S_11, S_22, S_01, S_02, S_12`.
const COMPONENTS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
/// The component of `S_ij` in [`COMPONENTS`], row by row.
const SYMMETRIC: [[usize; 3]; 3] = [[0, 3, 4], [3, 1, 5], [4, 5, 2]];

/// One rank's share of a sum over all ranks: its own points (first in its arrays), the points
/// in the whole box, and how far the copies of other ranks' points reach beyond its own.
#[derive(Clone, Copy, Debug)]
pub struct RankShare {
    /// This rank's own points, first in its arrays.
    pub owned: usize,
    /// Points in the whole box.
    pub total: usize,
    /// How far the copies of other ranks' points reach: the real-space cutoff's bound.
    pub reach: f64,
}

/// The stresslet sum shared among ranks, with the adaptive level of one process.
#[derive(Debug)]
pub struct SharedEwald {
    /// Requested relative accuracy (the contract of [`crate::ewald::spectral`]).
    pub tol: f64,
    refine: Refinement,
    report: Option<SumReport>,
}

/// `first..first + P` grid indices and window values along one axis, with the window's
/// derivative.
struct Axis {
    first: usize,
    w: [f64; MAX_SUPPORT],
    dw: [f64; MAX_SUPPORT],
}

/// The grid of one attempt: size, window, slabs.
struct Grid {
    m: usize,
    p: usize,
    h: f64,
    win: Window,
    xi: f64,
    l: f64,
    /// The planes of each rank and the distributed FFT.
    slab: SlabFft,
}

impl Grid {
    fn new(prm: &EwaldParams, l: f64, comm: &dyn Comm) -> Self {
        let m = prm.modes;
        let win = Window::new(l, prm.xi, m, prm.support, prm.shape);
        Self {
            m,
            p: win.p,
            h: win.h,
            win,
            xi: prm.xi,
            l,
            slab: SlabFft::new(m, comm),
        }
    }

    /// The window of a point along each axis (as the single-process grid computes it).
    fn axes(&self, y: Vec3) -> [Axis; 3] {
        let y = wrap_position(y, self.l);
        let (m, p, h) = (self.m, self.p, self.h);
        std::array::from_fn(|d| {
            let t = y[d] / h;
            let i0 = -floor_i64(p as f64 / 2.0 - t);
            let d0 = (i0 as f64 - t) * h;
            let mut a = Axis {
                first: i0.rem_euclid(m as i64) as usize,
                w: [0.0; MAX_SUPPORT],
                dw: [0.0; MAX_SUPPORT],
            };
            for q in 0..p {
                let r = d0 + q as f64 * h;
                a.w[q] = self.win.norm * (-self.win.alpha * r * r).exp();
                a.dw[q] = 2.0 * self.win.alpha * r * a.w[q];
            }
            a
        })
    }

    /// Spread `NF` values per point at `x` (own points) onto the planes their windows touch,
    /// then onto the owners' planes: this rank's planes, `[z][y][x]` per component.
    fn spread<const NF: usize>(
        &self,
        comm: &dyn Comm,
        x: &[Vec3],
        values: &[[f64; NF]],
    ) -> [Vec<f64>; NF] {
        let (m, pp) = (self.m, self.p);
        let plane = m * m;
        let axes: Vec<[Axis; 3]> = x.par_iter().map(|y| self.axes(*y)).collect();
        // Points by the first plane of their window; each touched plane is then filled on
        // its own (in parallel), from the buckets of the planes below it within the support,
        // in a fixed order.
        let mut bucket: Vec<Vec<u32>> = vec![Vec::new(); m];
        for (n, a) in axes.iter().enumerate() {
            bucket[a[2].first].push(n as u32);
        }
        let planes: Vec<usize> = (0..m)
            .filter(|&z| (0..pp).any(|q| !bucket[(z + m - q) % m].is_empty()))
            .collect();
        let touched: Vec<(usize, Vec<f64>)> = planes
            .par_iter()
            .map(|&z| {
                let mut buf = vec![0.0; plane * NF];
                for qz in 0..pp {
                    for &n in &bucket[(z + m - qz) % m] {
                        let n = n as usize;
                        let [ax, ay, az] = &axes[n];
                        let s = values[n];
                        for qy in 0..pp {
                            let mut y = ay.first + qy;
                            if y >= m {
                                y -= m;
                            }
                            let wzy = az.w[qz] * ay.w[qy];
                            let sw: [f64; NF] = s.map(|v| wzy * v);
                            let row = &mut buf[y * m * NF..(y + 1) * m * NF];
                            for qx in 0..pp {
                                let mut xi = ax.first + qx;
                                if xi >= m {
                                    xi -= m;
                                }
                                let w = ax.w[qx];
                                let cell = &mut row[xi * NF..xi * NF + NF];
                                for c in 0..NF {
                                    cell[c] += w * sw[c];
                                }
                            }
                        }
                    }
                }
                (z, buf)
            })
            .collect();
        // Planes to their owners: [plane index, values...] per plane.
        let mut send = vec![Vec::new(); self.slab.ranks];
        for (z, buf) in &touched {
            let msg = &mut send[self.slab.owner(*z)];
            let z = *z;
            msg.push(z as f64);
            msg.extend_from_slice(buf);
        }
        let got = comm.exchange(send);
        let own = self.slab.share(self.slab.me);
        let mut out: [Vec<f64>; NF] = std::array::from_fn(|_| vec![0.0; own.len() * plane]);
        for msg in &got {
            for chunk in msg.chunks_exact(1 + plane * NF) {
                let z = chunk[0] as usize - own.start;
                for (k, v) in chunk[1..].chunks_exact(NF).enumerate() {
                    for c in 0..NF {
                        out[c][z * plane + k] += v[c];
                    }
                }
            }
        }
        out
    }

    /// The velocity field on this rank's planes (real, `[z][y][x]` per component) of the
    /// spread sources `s`: their spectra, `kernel(k, |k|^2, exp(-|k|^2 / 4 xi^2), spectra)` at
    /// every kept mode with the window divided out twice, back.
    fn velocity_planes<const NF: usize>(
        &self,
        comm: &dyn Comm,
        mut s: [Vec<f64>; NF],
        kernel: impl Fn(Vec3, f64, f64, [Complex64; NF]) -> [Complex64; 3] + Sync,
    ) -> [Vec<f64>; 3] {
        let (m, mx) = (self.m, self.slab.mx);
        let rows = self.slab.forward(comm, &mut s);
        drop(s);
        let scale = 2.0 * PI / self.l;
        let x = 1.0 / (4.0 * self.xi * self.xi);
        let h3 = self.h.powi(3);
        let axis: Vec<(f64, f64, f64)> = (0..m)
            .map(|i| {
                let mode = if i < m.div_ceil(2) {
                    i as f64
                } else {
                    i as f64 - m as f64
                };
                let k = mode * scale;
                (k, (-x * k * k).exp(), (self.win.eta * x * k * k).exp())
            })
            .collect();
        let ys = self.slab.share(self.slab.me);
        let mut u = vec![vec![Complex64::default(); ys.len() * mx * m]; 3];
        let (u0, rest) = u.split_at_mut(1);
        let (u1, u2) = rest.split_at_mut(1);
        u0[0]
            .par_chunks_mut(m)
            .zip(u1[0].par_chunks_mut(m))
            .zip(u2[0].par_chunks_mut(m))
            .enumerate()
            .for_each(|(line, ((o0, o1), o2))| {
                let (yl, i0) = (line / mx, line % mx);
                let i1 = ys.start + yl;
                for i2 in 0..m {
                    if i0 == m / 2 || i1 == m / 2 || i2 == m / 2 {
                        continue;
                    }
                    let (a0, a1, a2) = (axis[i0], axis[i1], axis[i2]);
                    let k = [a0.0, a1.0, a2.0];
                    let k2 = dot(k, k);
                    if k2 == 0.0 {
                        continue;
                    }
                    let at = line * m + i2;
                    let sh: [Complex64; NF] = std::array::from_fn(|c| rows[c][at]);
                    let w = h3 * a0.2 * a1.2 * a2.2;
                    let v = kernel(k, k2, a0.1 * a1.1 * a2.1, sh);
                    o0[i2] = v[0] * w;
                    o1[i2] = v[1] * w;
                    o2[i2] = v[2] * w;
                }
            });
        drop(rows);
        let mut it = self.slab.inverse(comm, u).into_iter();
        std::array::from_fn(|_| it.next().expect("three components"))
    }

    /// Velocity and, with `GRAD`, gradient (`[u_0..2, du_i/dx_l at 3 + 3 i + l]`; zeros
    /// without) at `points` from the field on the owners' planes (each rank fetches the planes
    /// its windows need).
    fn gather<const GRAD: bool>(
        &self,
        comm: &dyn Comm,
        field: &[Vec<f64>; 3],
        x: &[Vec3],
    ) -> Vec<[f64; 12]> {
        let (m, pp) = (self.m, self.p);
        let plane = m * m;
        let axes: Vec<[Axis; 3]> = x.par_iter().map(|y| self.axes(*y)).collect();
        let mut need = std::collections::BTreeSet::new();
        for a in &axes {
            for qz in 0..pp {
                need.insert((a[2].first + qz) % m);
            }
        }
        // Requests to owners, then the planes back.
        let mut ask = vec![Vec::new(); self.slab.ranks];
        for &z in &need {
            ask[self.slab.owner(z)].push(z as f64);
        }
        let asked = comm.exchange(ask);
        let own = self.slab.share(self.slab.me);
        let send = asked
            .iter()
            .map(|list| {
                let mut v = Vec::with_capacity(list.len() * plane * 3);
                for &z in list {
                    let z = z as usize - own.start;
                    for k in 0..plane {
                        v.extend([
                            field[0][z * plane + k],
                            field[1][z * plane + k],
                            field[2][z * plane + k],
                        ]);
                    }
                }
                v
            })
            .collect();
        let got = comm.exchange(send);
        let mut planes: BTreeMap<usize, &[f64]> = BTreeMap::new();
        let mut by_owner = vec![Vec::new(); self.slab.ranks];
        for &z in &need {
            by_owner[self.slab.owner(z)].push(z);
        }
        for (r, list) in by_owner.iter().enumerate() {
            for (k, &z) in list.iter().enumerate() {
                planes.insert(z, &got[r][k * plane * 3..(k + 1) * plane * 3]);
            }
        }
        let h3 = self.h.powi(3);
        axes.par_iter()
            .map(|[ax, ay, az]| {
                let mut out = [0.0; 12];
                for qz in 0..pp {
                    let pl = planes[&((az.first + qz) % m)];
                    for qy in 0..pp {
                        let mut y = ay.first + qy;
                        if y >= m {
                            y -= m;
                        }
                        for qx in 0..pp {
                            let mut xi = ax.first + qx;
                            if xi >= m {
                                xi -= m;
                            }
                            let v = &pl[(y * m + xi) * 3..(y * m + xi) * 3 + 3];
                            let w = az.w[qz] * ay.w[qy] * ax.w[qx];
                            for c in 0..3 {
                                out[c] += w * v[c];
                            }
                            if GRAD {
                                let d = [
                                    az.w[qz] * ay.w[qy] * ax.dw[qx],
                                    az.w[qz] * ay.dw[qy] * ax.w[qx],
                                    az.dw[qz] * ay.w[qy] * ax.w[qx],
                                ];
                                for c in 0..3 {
                                    for l in 0..3 {
                                        out[3 + 3 * c + l] += d[l] * v[c];
                                    }
                                }
                            }
                        }
                    }
                }
                out.map(|v| h3 * v)
            })
            .collect()
    }
}

impl SharedEwald {
    /// A shared sum at relative tolerance `tol` (1e-10 ..= 1e-1, as one process).
    pub fn new(tol: f64) -> Result<Self, SumError> {
        check_tolerance(tol)?;
        Ok(Self {
            tol,
            refine: Refinement::default(),
            report: None,
        })
    }

    /// The real-space cutoff one process would choose for `total` points in a box of side
    /// `l` at the current level: the reach of copies that keeps the grid as coarse as one
    /// process's (a smaller reach caps the cutoff and refines the grid instead).
    pub fn preferred_reach(&self, total: usize, l: f64) -> f64 {
        EwaldParams::choose_for(
            self.refine.internal_tolerance(self.tol),
            total,
            l,
            &[SumOutput::StressletVelocity, SumOutput::StressletGradient],
            STRESSLET_PAIR_COST,
        )
        .cutoff
    }

    /// What the last sum reported (the whole box's estimate).
    pub fn last_report(&self) -> Option<SumReport> {
        self.report.clone()
    }

    /// The refinement level and calm count, for checkpoints.
    pub fn adaptive_state(&self) -> Vec<u32> {
        self.refine.state()
    }

    /// Restore what [`Self::adaptive_state`] returned.
    pub fn set_adaptive_state(&mut self, state: &[u32]) {
        self.refine.set_state(self.tol, state);
    }

    /// The flow of point stresslets `sigma_n p_n p_n` at `x_n` over all ranks (collective):
    /// `x` holds this rank's `owned` points first, then copies of other ranks' points within
    /// `reach` of them (`total` points in the whole box); returns velocity and gradient at the
    /// own points.
    pub fn stresslets(
        &mut self,
        comm: &dyn Comm,
        share: RankShare,
        l: f64,
        x: &[Vec3],
        p: &[Vec3],
        sigma: &[f64],
    ) -> Result<StressletField, SumError> {
        let RankShare { owned, total, .. } = share;
        if x.len() != p.len() || x.len() != sigma.len() || owned > x.len() {
            return Err(SumError::Input(
                "shared stresslets: x, p, sigma lengths differ".into(),
            ));
        }
        let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
        let mut strongest = [sigma.iter().fold(0.0f64, |m, s| m.max(s.abs()))];
        comm.max(&mut strongest);
        let floor = |k: i32| strongest[0] / (8.0 * PI * VISCOSITY * l.powi(k));
        let tol = self.tol;
        self.refined(share, l, &outputs, STRESSLET_PAIR_COST, |prm, internal| {
            let (field, e2) = attempt(comm, prm, l, owned, x, p, sigma)?;
            let (estimates, ratio) = stresslet_estimates(
                StressletOutputs {
                    field: &field,
                    e2: &e2,
                    sigma,
                },
                AttemptTolerance {
                    params: prm,
                    internal,
                    tol,
                },
                floor,
                |mine| over_ranks(comm, mine),
                total,
            );
            Ok((field, estimates, ratio))
        })
    }

    /// The refinement loop of one process: attempts at the current level's parameters (the
    /// cutoff at most the `share`'s reach, for its total points in a box of side `l`) until
    /// `attempt`'s estimate/bound ratio stands; records the report.
    fn refined<T>(
        &mut self,
        share: RankShare,
        l: f64,
        outputs: &[SumOutput],
        pair_cost: f64,
        mut attempt: impl FnMut(&EwaldParams, f64) -> Result<(T, Vec<ErrorEstimate>, f64), SumError>,
    ) -> Result<T, SumError> {
        let RankShare { total, reach, .. } = share;
        let mut attempts = 0;
        loop {
            attempts += 1;
            let internal = self.refine.internal_tolerance(self.tol);
            let prm = EwaldParams::choose_within(internal, total, l, outputs, pair_cost, reach);
            let (out, estimates, ratio) = attempt(&prm, internal)?;
            if self.refine.accept(self.tol, ratio, false)? {
                let accepted = Accepted {
                    internal,
                    level: self.refine.level,
                    attempts,
                };
                self.report = Some(report_of(self.tol, accepted, prm, estimates));
                return Ok(out);
            }
        }
    }
}

/// The estimate's reductions ([`estimate_parts`]) over all ranks (collective).
fn over_ranks(comm: &dyn Comm, mine: [f64; 4]) -> [f64; 4] {
    comm.all_gather(&mine).iter().fold([0.0f64; 4], |t, a| {
        [t[0].max(a[0]), t[1] + a[1], t[2].max(a[2]), t[3] + a[3]]
    })
}

impl SharedEwald {
    /// The RPY mobility product over all ranks (collective): `points` holds this rank's
    /// `owned` points first, then copies of other ranks' points within `reach` of them, both in
    /// whole groups of `geometry.group` (a point does not see its own group's direct terms);
    /// `total` points in the whole box. Returns the velocities at the own points.
    pub fn rpy(
        &mut self,
        comm: &dyn Comm,
        share: RankShare,
        geometry: &RpyGeometry,
        points: &[Vec3],
        forces: &[Vec3],
    ) -> Result<Vec<Vec3>, SumError> {
        let RankShare { owned, total, .. } = share;
        check_rpy(geometry, points, forces)?;
        if !owned.is_multiple_of(geometry.group) || owned > points.len() {
            return Err(SumError::Input(format!(
                "{owned} own points of {} do not split into groups of {}",
                points.len(),
                geometry.group
            )));
        }
        let output = SumOutput::RpyVelocity;
        let tol = self.tol;
        self.refined(
            share,
            geometry.box_length,
            &[output],
            PAIR_COST,
            |prm, internal| {
                let (u, e2) = rpy_attempt(comm, prm, geometry, owned, points, forces)?;
                let scale = internal * output.self_scale(prm.xi) / VISCOSITY;
                let mine = estimate_parts(
                    output,
                    ErrorScale { scale, internal },
                    |t| e2[t],
                    |t| dot(u[t], u[t]),
                    owned,
                );
                let est = estimate_from(output, over_ranks(comm, mine), total, 0.0);
                let ratio = est.max_relative.max(est.l2_relative) / tol;
                Ok((u, vec![est], ratio))
            },
        )
    }

    /// The real-space cutoff one process would choose for an RPY sum of `total` points in a
    /// box of side `l` at the current level (see [`Self::preferred_reach`]).
    pub fn preferred_rpy_reach(&self, total: usize, l: f64) -> f64 {
        EwaldParams::choose_for(
            self.refine.internal_tolerance(self.tol),
            total,
            l,
            &[SumOutput::RpyVelocity],
            PAIR_COST,
        )
        .cutoff
    }
}

/// Refuse non-finite points on any rank, on every rank (collective: a rank that returned alone
/// would leave the others waiting in the sum's exchanges).
fn all_finite(comm: &dyn Comm, x: &[Vec3]) -> Result<(), SumError> {
    let bad = x.iter().position(|y| !y.iter().all(|c| c.is_finite()));
    let mut flag = [if bad.is_some() { 1.0 } else { 0.0 }];
    comm.max(&mut flag);
    match bad {
        Some(i) => Err(SumError::Input(format!(
            "point {i} of rank {} has a non-finite coordinate {:?}",
            comm.rank(),
            x[i]
        ))),
        None if flag[0] > 0.0 => Err(SumError::Input(
            "another rank has a point with a non-finite coordinate".into(),
        )),
        None => Ok(()),
    }
}

/// One attempt of the shared RPY sum: velocities at the own points and the error model's
/// weighted strengths.
fn rpy_attempt(
    comm: &dyn Comm,
    prm: &EwaldParams,
    geometry: &RpyGeometry,
    owned: usize,
    points: &[Vec3],
    forces: &[Vec3],
) -> Result<(Vec<Vec3>, Vec<f64>), SumError> {
    all_finite(comm, points)?;
    let (l, a) = (geometry.box_length, geometry.radius);
    let cells = PointCells::build(points, l, prm.cutoff, geometry.group).own_first(owned);
    let mut real = rpy_real(&cells, &mut RpyPairCache::default(), prm, a, l, forces);
    real.truncate(owned);
    let grid = Grid::new(prm, l, comm);
    let spread = grid.spread(comm, &points[..owned], &forces[..owned]);
    let (xi, vol) = (prm.xi, l.powi(3));
    let field = grid.velocity_planes(comm, spread, |k, k2, screen, f| {
        rpy_fourier_mode_screened(k, k2, screen, xi, a, vol, f)
    });
    let back = grid.gather::<false>(comm, &field, &points[..owned]);
    Ok(rpy_assemble(
        real,
        |t| [back[t][0], back[t][1], back[t][2]],
        points,
        forces,
        prm,
        geometry,
    ))
}

/// One attempt: velocities and gradients at the own points, and the error model's weighted
/// strengths per own point.
fn attempt(
    comm: &dyn Comm,
    prm: &EwaldParams,
    l: f64,
    owned: usize,
    x: &[Vec3],
    p: &[Vec3],
    sigma: &[f64],
) -> Result<(StressletField, Vec<f64>), SumError> {
    all_finite(comm, x)?;
    let xi = prm.xi;
    // Real space over own points and copies, as one process.
    let cells = PointCells::build(x, l, prm.cutoff, 1).own_first(owned);
    let real = stresslet_real(&cells, prm, l, p, sigma);
    // Fourier space over the ranks' slabs of the grid.
    let grid = Grid::new(prm, l, comm);
    let s6: Vec<[f64; 6]> = (0..owned)
        .map(|n| COMPONENTS.map(|(i, j)| sigma[n] * p[n][i] * p[n][j]))
        .collect();
    let spread = grid.spread(comm, &x[..owned], &s6);
    let vol = l.powi(3);
    let field = grid.velocity_planes(comm, spread, |k, k2, screen, sh| {
        // Force density -i k . S, then the velocity of a point force (a = 0).
        let f: [Complex64; 3] = std::array::from_fn(|i| {
            let [a, b, c] = SYMMETRIC[i];
            -Complex64::i() * (sh[a] * k[0] + sh[b] * k[1] + sh[c] * k[2])
        });
        rpy_fourier_mode_screened(k, k2, screen, xi, 0.0, vol, f)
    });
    let back = grid.gather::<true>(comm, &field, &x[..owned]);
    let mut u = Vec::with_capacity(owned);
    let mut grad = Vec::with_capacity(owned);
    let mut e2 = Vec::with_capacity(owned);
    for t in 0..owned {
        let (ur, gr, w) = &real[t];
        let own = stresslet_fourier_self_gradient(p[t], sigma[t], xi);
        let b = &back[t];
        u.push([0, 1, 2].map(|i| (ur[i] + b[i]) / VISCOSITY));
        grad.push(std::array::from_fn(|i| {
            std::array::from_fn(|m| (gr[i][m] + b[3 + 3 * i + m] - own[i][m]) / VISCOSITY)
        }));
        e2.push(*w);
    }
    Ok((StressletField { u, grad }, e2))
}
