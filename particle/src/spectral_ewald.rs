//! Fast periodic Stokes sums by spectral Ewald (MODEL.md §1, §2): the Hasimoto split of
//! [`crate::ewald`], the short-ranged real-space part summed over neighbours from a point cell
//! list, the smooth Fourier part through the NUFFT of the analysis crate (type 1 to spread the
//! forces onto modes, a diagonal multiplication, type 2 back to the points). `O(N log N)`.
//!
//! Parameters come from one requested tolerance `tol` ([`EwaldParams::choose`]): with
//! `c = sqrt(ln(1/tol))`, the real-space cutoff is `r_c = c/xi` and the largest wavenumber
//! `k_max = 2 xi c` (both truncated parts are then about `exp(-c^2) = tol` of the kernel);
//! `xi` minimises a cost model of pair work against grid work, with `r_c <= L/2` so the
//! minimum image is exact. The NUFFT runs at `tol / 2`. Measured against the reference: the
//! relative L2 error is 0.3-0.7 times `tol` from 1e-2 to 1e-8.
//!
//! Determinism: the real-space sum is a gather (each target adds its neighbours in cell order,
//! no shared accumulators) and the NUFFT is thread-count independent, so results are
//! bit-identical for any rayon pool size.

use crate::ewald::{
    RealSpaceTable, StressletTable, apply_radial, rpy_fourier_free_apply, rpy_fourier_mode,
    rpy_overlap_correction, stresslet_fourier_mode, stresslet_fourier_self_gradient,
    stresslet_from_derivatives,
};
use crate::geometry::{Vec3, dot, min_image};
use crate::periodic::{PeriodicStokes, RpyGeometry, StressletField, SumError, check_rpy};
use crate::units::VISCOSITY;
use motile_analysis::nufft::{NufftPlan, mode_of};
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// Cost of one real-space pair visit relative to one grid point of one FFT pass (calibrated
/// at 1e5 points, tolerance 1e-4, with the NUFFT keeping its buffers: the measured total is
/// flat between 6 and 12).
const PAIR_COST: f64 = 8.0;

/// The same for a stresslet pair (velocity and gradient from a table) against its
/// Fourier side (9 transforms instead of 4); calibrated at 78 125 centres, tolerance 1e-4.
const STRESSLET_PAIR_COST: f64 = 8.0;

/// The resolved parameters of one spectral Ewald sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EwaldParams {
    /// Splitting parameter xi (1/length).
    pub xi: f64,
    /// Real-space cutoff.
    pub cutoff: f64,
    /// Fourier modes per dimension (even).
    pub modes: usize,
    /// NUFFT tolerance.
    pub nufft_tol: f64,
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
        let make = |xi: f64| {
            let kmax = 2.0 * xi * c;
            let modes = 2 * ((kmax * l / (2.0 * PI)).ceil() as usize + 1);
            Self {
                xi,
                cutoff: c / xi,
                modes,
                nufft_tol: (tol / 2.0).max(1e-14),
            }
        };
        let cost = |p: &Self| {
            let pairs = n as f64 * density * 4.0 / 3.0 * PI * p.cutoff.powi(3);
            let grid = (2 * p.modes).pow(3) as f64;
            pair_cost * pairs + 6.0 * grid * grid.log2().max(1.0) / 3.0
        };
        let xi_min = 2.0 * c / l;
        let mut best = make(xi_min);
        let mut xi = xi_min;
        for _ in 0..80 {
            xi *= 1.05;
            let p = make(xi);
            if cost(&p) < cost(&best) {
                best = p;
            }
        }
        best
    }
}

/// Spectral Ewald with parameters chosen from one tolerance; caches the NUFFT plan.
#[derive(Debug)]
pub struct SpectralEwald {
    /// Requested relative accuracy.
    pub tol: f64,
    /// Fixed parameters, overriding the automatic choice (for tests and studies).
    pub fixed: Option<EwaldParams>,
    plan: Option<NufftPlan>,
    last: Option<EwaldParams>,
    timing: SumTiming,
}

/// Seconds spent in the stages of the last sum.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SumTiming {
    /// Parameter choice, NUFFT plan and point sorting.
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
            plan: None,
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

    fn prepare(
        &mut self,
        n: usize,
        l: f64,
        points: &[Vec3],
        pair_cost: f64,
    ) -> Result<EwaldParams, SumError> {
        let p = self
            .fixed
            .unwrap_or_else(|| EwaldParams::choose_with(self.tol, n, l, pair_cost));
        if p.cutoff > 0.5 * l * (1.0 + 1e-12) {
            return Err(SumError::Input(format!(
                "real-space cutoff {} exceeds half the box {}",
                p.cutoff,
                0.5 * l
            )));
        }
        let rebuild = match (&self.plan, &self.last) {
            (Some(_), Some(last)) => last.modes != p.modes || last.nufft_tol != p.nufft_tol,
            _ => true,
        };
        if rebuild {
            self.plan = Some(NufftPlan::new([p.modes; 3], p.nufft_tol)?);
        }
        self.plan
            .as_mut()
            .expect("plan built above")
            .set_points(points, l)?;
        self.last = Some(p);
        Ok(p)
    }

    /// The Fourier multiplication on packed spectra. The `I` input fields are real and come
    /// packed two to a complex transform (`C_q = F_2q + i F_2q+1`); their spectra are unpacked
    /// with Hermitian symmetry, `F_2q(k) = (C_q(k) + conj C_q(-k))/2`,
    /// `F_2q+1(k) = (C_q(k) - conj C_q(-k))/(2i)`. The `O` output fields are real too and are
    /// packed the same way, so type 2 returns two of them as the real and imaginary parts.
    /// `k = 0` and the unpaired `-K/2` modes are set to zero.
    fn multiply<const I: usize, const O: usize>(
        &self,
        l: f64,
        modes: usize,
        packed: &[Vec<Complex64>],
        g: impl Fn(Vec3, f64, [Complex64; I]) -> [Complex64; O] + Sync,
    ) -> Vec<Vec<Complex64>> {
        let m = modes;
        let s = 2.0 * PI / l;
        let total = m * m * m;
        let half_i = Complex64::new(0.0, -0.5);
        // At most 12 real outputs, 6 packed; fixed-size rows, no allocation per mode.
        let np = O.div_ceil(2);
        assert!(np <= 6, "at most 12 output fields");
        let vals: Vec<[Complex64; 6]> = (0..total)
            .into_par_iter()
            .map(|idx| {
                let i = [idx % m, (idx / m) % m, idx / (m * m)];
                let mut row = [Complex64::default(); 6];
                if i.contains(&0) {
                    return row;
                }
                let k = i.map(|c| mode_of(c, m) as f64 * s);
                let k2 = dot(k, k);
                if k2 == 0.0 {
                    return row;
                }
                let mirror = (m - i[0]) + m * ((m - i[1]) + m * (m - i[2]));
                let f: [Complex64; I] = std::array::from_fn(|c| {
                    let (a, b) = (packed[c / 2][idx], packed[c / 2][mirror].conj());
                    if c.is_multiple_of(2) {
                        0.5 * (a + b)
                    } else {
                        half_i * (a - b)
                    }
                });
                let o = g(k, k2, f);
                for (q, r) in row.iter_mut().enumerate().take(np) {
                    let im = if 2 * q + 1 < O {
                        o[2 * q + 1]
                    } else {
                        Complex64::default()
                    };
                    *r = o[2 * q] + Complex64::i() * im;
                }
                row
            })
            .collect();
        (0..np)
            .map(|c| vals.par_iter().map(|v| v[c]).collect())
            .collect()
    }
}

/// Real fields packed two to a complex vector (`a + i b`).
fn pack(fields: &[Vec<f64>]) -> Vec<Vec<Complex64>> {
    fields
        .chunks(2)
        .map(|c| match c {
            [a, b] => a
                .par_iter()
                .zip(b)
                .map(|(x, y)| Complex64::new(*x, *y))
                .collect(),
            [a] => a.par_iter().map(|x| Complex64::new(*x, 0.0)).collect(),
            _ => unreachable!("chunks of two"),
        })
        .collect()
}

/// Real field `c` out of packed type-2 results.
#[inline]
fn unpacked(out: &[Vec<Complex64>], c: usize, t: usize) -> f64 {
    let v = out[c / 2][t];
    if c.is_multiple_of(2) { v.re } else { v.im }
}

/// Points sorted into cells of side at least half the cutoff (a 5^3 stencil then covers the
/// cutoff sphere with 3.7 times its volume, against 6.4 for cells of the full cutoff), with a
/// cell-ordered copy of the positions so the inner loop streams through memory.
struct PointCells {
    n: usize,
    l: f64,
    start: Vec<usize>,
    members: Vec<u32>,
    sorted: Vec<Vec3>,
    /// Group of each point, in cell order.
    group: Vec<u32>,
}

impl PointCells {
    fn build(y: &[Vec3], l: f64, cutoff: f64, group: usize) -> Self {
        let n = ((2.0 * l / cutoff).floor() as usize).max(1);
        let cell_of: Vec<u32> = y
            .par_iter()
            .map(|p| {
                let idx = p.map(|c| {
                    let f = c / l;
                    let f = f - f.floor();
                    ((f * n as f64) as usize).min(n - 1)
                });
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
        let sorted = members
            .par_iter()
            .map(|&i| {
                y[i as usize].map(|c| {
                    let f = c - l * (c / l).floor();
                    if f >= l { 0.0 } else { f }
                })
            })
            .collect();
        let group = members
            .iter()
            .map(|&i| (i as usize / group) as u32)
            .collect();
        Self {
            n,
            l,
            start,
            members,
            sorted,
            group,
        }
    }

    /// Values in cell order (`members()[k]`'s value at `k`), for streaming in [`Self::gather`].
    fn sorted_values<T: Copy + Send + Sync>(&self, v: &[T]) -> Vec<T> {
        self.members.par_iter().map(|&i| v[i as usize]).collect()
    }

    /// For each target, `f(acc, same_group, k, r, |r|)` over every point `k` (cell order, see
    /// [`Self::sorted_values`]) with the minimum-image `r = y_t - y_k`, `0 < |r| < cutoff`, in
    /// an order fixed by the cells; results in the targets' own order.
    fn gather<A: Send + Default + Clone>(
        &self,
        cutoff: f64,
        f: impl Fn(&mut A, bool, usize, Vec3, f64) + Sync,
    ) -> Vec<A> {
        let c2 = cutoff * cutoff;
        let n = self.n as i64;
        let l = self.l;
        let all = self.n < 5;
        let per_cell: Vec<Vec<A>> = (0..self.n * self.n * self.n)
            .into_par_iter()
            .map(|c| {
                let range = self.start[c]..self.start[c + 1];
                let mut out = vec![A::default(); range.len()];
                if range.is_empty() {
                    return out;
                }
                let visit_cell = |cell: usize, shift: Vec3, out: &mut [A]| {
                    let (s0, s1) = (self.start[cell], self.start[cell + 1]);
                    for (k, acc) in out.iter_mut().enumerate() {
                        let tk = range.start + k;
                        let yt = self.sorted[tk];
                        let yt = [yt[0] - shift[0], yt[1] - shift[1], yt[2] - shift[2]];
                        let gt = self.group[tk];
                        for jk in s0..s1 {
                            let yj = self.sorted[jk];
                            let r = [yt[0] - yj[0], yt[1] - yj[1], yt[2] - yj[2]];
                            let r2 = dot(r, r);
                            if r2 < c2 && r2 > 0.0 {
                                f(acc, self.group[jk] == gt, jk, r, r2.sqrt());
                            }
                        }
                    }
                };
                if all {
                    // Few cells: every point, minimum image per pair.
                    for (k, acc) in out.iter_mut().enumerate() {
                        let tk = range.start + k;
                        let yt = self.sorted[tk];
                        let gt = self.group[tk];
                        for (jk, yj) in self.sorted.iter().enumerate() {
                            let r = min_image([yt[0] - yj[0], yt[1] - yj[1], yt[2] - yj[2]], l);
                            let r2 = dot(r, r);
                            if r2 < c2 && r2 > 0.0 {
                                f(acc, self.group[jk] == gt, jk, r, r2.sqrt());
                            }
                        }
                    }
                } else {
                    let c = c as i64;
                    let (cx, cy, cz) = (c % n, (c / n) % n, c / (n * n));
                    for dz in -2..=2 {
                        for dy in -2..=2 {
                            for dx in -2..=2 {
                                let (ux, uy, uz) = (cx + dx, cy + dy, cz + dz);
                                let cell = ((uz.rem_euclid(n) * n + uy.rem_euclid(n)) * n
                                    + ux.rem_euclid(n))
                                    as usize;
                                // The image of the neighbour cell next to this one.
                                let shift = [ux, uy, uz].map(|u| {
                                    if u < 0 {
                                        -l
                                    } else if u >= n {
                                        l
                                    } else {
                                        0.0
                                    }
                                });
                                visit_cell(cell, shift, &mut out);
                            }
                        }
                    }
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
        let p = self.prepare(points.len(), l, points, PAIR_COST)?;
        let xi = p.xi;
        let t1 = Instant::now();
        // Real space: every neighbour outside the own group, plus the overlap correction.
        let cells = PointCells::build(points, l, p.cutoff, g);
        let table = RealSpaceTable::new(p.cutoff, xi, a);
        let two_a = 2.0 * a;
        let sorted_forces = cells.sorted_values(forces);
        let mut u = cells.gather(p.cutoff, |acc: &mut Vec3, same, j, r, rn| {
            if same {
                return;
            }
            let inv = 1.0 / rn;
            let rh = r.map(|c| c * inv);
            let (mut ar, mut br) = table.eval_inv(rn, inv);
            if rn < two_a {
                let (ac, bc) = rpy_overlap_correction(rn, a);
                ar += ac;
                br += bc;
            }
            let v = apply_radial(ar, br, rh, sorted_forces[j]);
            for d in 0..3 {
                acc[d] += v[d];
            }
        });
        // Fourier space.
        let t2 = Instant::now();
        let plan = self.plan.as_ref().expect("prepared");
        let f = pack(
            &(0..3)
                .map(|d| forces.iter().map(|v| v[d]).collect())
                .collect::<Vec<_>>(),
        );
        let fhat = plan.type1(&[&f[0], &f[1]])?;
        let vol = l * l * l;
        let uhat = self.multiply::<3, 3>(l, p.modes, &fhat, |k, k2, f| {
            rpy_fourier_mode(k, k2, xi, a, vol, f)
        });
        let uf = plan.type2(&[&uhat[0], &uhat[1]])?;
        let t3 = Instant::now();
        // Own group's direct Fourier-part terms come out (the point itself included).
        u.par_iter_mut().enumerate().for_each(|(t, ut)| {
            let base = (t / g) * g;
            for d in 0..3 {
                ut[d] += unpacked(&uf, d, t);
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
        let prm = self.prepare(x.len(), l, x, STRESSLET_PAIR_COST)?;
        let xi = prm.xi;
        let t1 = Instant::now();
        let cells = PointCells::build(x, l, prm.cutoff, 1);
        let (ps, ss) = (cells.sorted_values(p), cells.sorted_values(sigma));
        let table = StressletTable::new(prm.cutoff, xi);
        let real = cells.gather(
            prm.cutoff,
            |acc: &mut (Vec3, [Vec3; 3]), _same, j, r, rn| {
                let dv = table.eval(rn);
                let (du, dg) = stresslet_from_derivatives(r, rn, ps[j], ss[j], &dv);
                for i in 0..3 {
                    acc.0[i] += du[i];
                    for m in 0..3 {
                        acc.1[i][m] += dg[i][m];
                    }
                }
            },
        );
        let t2 = Instant::now();
        let plan = self.plan.as_ref().expect("prepared");
        let comp = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
        let s = pack(
            &comp
                .iter()
                .map(|&(i, j)| (0..x.len()).map(|n| sigma[n] * p[n][i] * p[n][j]).collect())
                .collect::<Vec<_>>(),
        );
        let refs: Vec<&[Complex64]> = s.iter().map(|v| v.as_slice()).collect();
        let shat = plan.type1(&refs)?;
        let vol = l * l * l;
        let out = self.multiply::<6, 12>(l, prm.modes, &shat, |k, k2, sh| {
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
            stresslet_fourier_mode(k, k2, xi, vol, sm)
        });
        let refs: Vec<&[Complex64]> = out.iter().map(|v| v.as_slice()).collect();
        let back = plan.type2(&refs)?;
        let t3 = Instant::now();
        let (u, grad): (Vec<Vec3>, Vec<[Vec3; 3]>) = real
            .into_par_iter()
            .enumerate()
            .map(|(t, (mut u, mut g))| {
                let own = stresslet_fourier_self_gradient(p[t], sigma[t], xi);
                for i in 0..3 {
                    u[i] = (u[i] + unpacked(&back, i, t)) / VISCOSITY;
                    for m in 0..3 {
                        g[i][m] =
                            (g[i][m] + unpacked(&back, 3 + 3 * i + m, t) - own[i][m]) / VISCOSITY;
                    }
                }
                (u, g)
            })
            .unzip();
        self.timing = SumTiming {
            setup: (t1 - t0).as_secs_f64(),
            real: (t2 - t1).as_secs_f64(),
            fourier: (t3 - t2).as_secs_f64(),
            corrections: t3.elapsed().as_secs_f64(),
        };
        Ok(StressletField { u, grad })
    }
}
