//! Three-dimensional non-uniform FFT on the periodic box (docs/MODEL.md §6).
//!
//! Type 1 (points to modes): `c(m) = sum_j f_j exp(-i k_m . x_j)`,
//! type 2 (modes to points): `f(x_j) = sum_m c(m) exp(+i k_m . x_j)`, with `k_m = 2 pi m / L`,
//! `m_d` in `-floor(M_d/2) ..= ceil(M_d/2) - 1`, modes stored with axis 0 fastest and the most
//! negative mode first. Type 2 is the adjoint of type 1.
//!
//! Method: spread with the prolate kernel (the `kernel` module) onto a fine grid upsampled by 2, FFT,
//! divide by the kernel's Fourier transform; type 2 runs the same steps backwards.
//!
//! Determinism: points are sorted once (stable counting sort by slab and bin). The fine grid
//! is cut into z-slabs whose thickness depends on the grid only; each slab spreads its points,
//! in sorted order, into a private padded buffer, and each grid plane then sums the slabs that
//! touch it in slab order. Nothing depends on which thread did what, so the result is
//! bit-identical for any rayon pool size.

use crate::fft3::{Direction, Fft3, next_smooth_even};
use crate::kernel::{MAX_WIDTH, SpreadKernel, with_kernel_width};
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Errors of the NUFFT.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum NufftError {
    /// Tolerance outside the supported range.
    #[error("NUFFT tolerance {0:e} outside the supported range [1e-15, 1e-1]")]
    Tolerance(f64),
    /// A mode count of zero.
    #[error("NUFFT mode counts must be positive, got {0:?}")]
    Modes([usize; 3]),
    /// Box length not positive and finite.
    #[error("box length must be positive and finite, got {0}")]
    BoxLength(f64),
    /// A point coordinate is NaN or infinite.
    #[error("point {index} has a non-finite coordinate {coord:?}")]
    NonFinitePoint {
        /// Index of the offending point.
        index: usize,
        /// Its coordinates.
        coord: [f64; 3],
    },
    /// A strength or coefficient vector of the wrong length.
    #[error("vector {which} has length {got}, expected {expected}")]
    Length {
        /// Which input vector.
        which: usize,
        /// Its length.
        got: usize,
        /// The length the plan expects.
        expected: usize,
    },
}

/// Fine-grid bin width (in grid points) used to sort points within a slab.
const SORT_BIN: usize = 16;

/// A 3D NUFFT plan: modes, tolerance, fine grid, kernel, and (after [`Self::set_points`]) the
/// sorted points.
#[derive(Debug, Clone)]
pub struct NufftPlan {
    /// Buffers kept between calls (slabs, fine grids, padded grids).
    scratch: ScratchPool,
    modes: [usize; 3],
    nf: [usize; 3],
    tol: f64,
    kernel: SpreadKernel,
    /// `1 / phihat(k)` per axis, indexed by mode position.
    deconv: [Vec<f64>; 3],
    fft: Fft3,
    slab: usize,
    /// Sorted fine-grid coordinates.
    grid_pts: Vec<[f64; 3]>,
    /// Original index of each sorted point.
    perm: Vec<usize>,
    /// Sorted position of each original point (inverse of `perm`).
    inv_perm: Vec<usize>,
    /// `slab_start[s]..slab_start[s + 1]` are the sorted points of slab `s`.
    slab_start: Vec<usize>,
}

impl NufftPlan {
    /// Plan transforms with `modes` Fourier modes per axis at relative tolerance `tol`.
    ///
    /// The tolerance bounds the relative L2 error of each transform's output against the
    /// direct sums ([`direct_type1`], [`direct_type2`]): `||c - c_exact||_2 <= tol ||c_exact||_2`
    /// over all modes (type 1) or all points (type 2), as FINUFFT defines it. Measured at
    /// 0.44-0.83 `tol` from 1e-1 to 1e-12 (`tests/nufft_accuracy.rs`, which asserts `<= tol`).
    /// Like any such bound it is relative to the output's norm as a whole: a mode (or point)
    /// whose exact value is far smaller than the norm gets no relative guarantee.
    pub fn new(modes: [usize; 3], tol: f64) -> Result<Self, NufftError> {
        if !(1e-15..=1e-1).contains(&tol) {
            return Err(NufftError::Tolerance(tol));
        }
        if modes.contains(&0) {
            return Err(NufftError::Modes(modes));
        }
        let kernel = SpreadKernel::for_tolerance(tol);
        let w = kernel.width;
        let nf = modes.map(|m| next_smooth_even((2 * m).max(2 * w)));
        let deconv = [0, 1, 2].map(|d| {
            let ks: Vec<f64> = (0..modes[d]).map(|i| mode_of(i, modes[d]) as f64).collect();
            kernel
                .fourier_transform(&ks, nf[d])
                .into_iter()
                .map(|f| 1.0 / f)
                .collect()
        });
        let slab = (nf[2] / 8).max(SORT_BIN).min(nf[2]);
        Ok(Self {
            modes,
            nf,
            tol,
            kernel,
            deconv,
            fft: Fft3::new(nf),
            slab,
            grid_pts: Vec::new(),
            perm: Vec::new(),
            inv_perm: Vec::new(),
            slab_start: vec![0; 1],
            scratch: ScratchPool::default(),
        })
    }

    /// Mode counts per axis.
    pub fn modes(&self) -> [usize; 3] {
        self.modes
    }

    /// Number of modes in total.
    pub fn num_modes(&self) -> usize {
        self.modes.iter().product()
    }

    /// Fine (upsampled) grid size per axis.
    pub fn fine_grid(&self) -> [usize; 3] {
        self.nf
    }

    /// Kernel width in fine-grid points.
    pub fn kernel_width(&self) -> usize {
        self.kernel.width
    }

    /// Requested tolerance.
    pub fn tolerance(&self) -> f64 {
        self.tol
    }

    /// Number of points currently set.
    pub fn num_points(&self) -> usize {
        self.perm.len()
    }

    /// Set the non-uniform points, in a periodic box `[0, L)^3` (points outside are wrapped).
    /// Sorts them once; any number of transforms may follow.
    pub fn set_points(&mut self, points: &[[f64; 3]], box_length: f64) -> Result<(), NufftError> {
        if !(box_length.is_finite() && box_length > 0.0) {
            return Err(NufftError::BoxLength(box_length));
        }
        if let Some(index) = points
            .par_iter()
            .position_first(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(NufftError::NonFinitePoint {
                index,
                coord: points[index],
            });
        }
        let nf = self.nf;
        let nslab = nf[2].div_ceil(self.slab);
        let nby = nf[1].div_ceil(SORT_BIN);
        let nbx = nf[0].div_ceil(SORT_BIN);
        let nbins = nslab * nby * nbx;
        let slab = self.slab;
        // Fine-grid coordinates and sort keys, in parallel.
        let inv_l = 1.0 / box_length;
        let keyed: Vec<([f64; 3], u32)> = points
            .par_iter()
            .map(|p| {
                let g = [0, 1, 2].map(|d| {
                    let f = p[d] * inv_l;
                    let g = (f - floor(f)) * nf[d] as f64;
                    if g >= nf[d] as f64 { 0.0 } else { g }
                });
                let s = (g[2] as usize / slab).min(nslab - 1);
                let y = (g[1] as usize / SORT_BIN).min(nby - 1);
                let x = (g[0] as usize / SORT_BIN).min(nbx - 1);
                (g, ((s * nby + y) * nbx + x) as u32)
            })
            .collect();
        // Stable counting sort by key (serial: cheap, and fixes the order for any thread count).
        let mut counts = vec![0usize; nbins + 1];
        for &(_, k) in &keyed {
            counts[k as usize + 1] += 1;
        }
        for b in 0..nbins {
            counts[b + 1] += counts[b];
        }
        self.slab_start = (0..=nslab).map(|s| counts[s * nby * nbx]).collect();
        let mut next = counts;
        let mut inv = vec![0; points.len()];
        self.perm = vec![0; points.len()];
        self.grid_pts = vec![[0.0; 3]; points.len()];
        // Writes go to one stream per bin, which caches well (a gather through perm would not).
        for (i, &(g, k)) in keyed.iter().enumerate() {
            let slot = &mut next[k as usize];
            self.perm[*slot] = i;
            self.grid_pts[*slot] = g;
            inv[i] = *slot;
            *slot += 1;
        }
        self.inv_perm = inv;
        Ok(())
    }

    /// Type 1 for several strength vectors at once (each of length [`Self::num_points`]).
    /// Returns one mode array per strength vector.
    pub fn type1(&self, strengths: &[&[Complex64]]) -> Result<Vec<Vec<Complex64>>, NufftError> {
        self.check_lengths(strengths, self.num_points())?;
        let mut grids = self.spread(strengths);
        let out = grids
            .iter_mut()
            .map(|g| {
                self.fft.process(g, Direction::Forward);
                Ok(self.extract_modes(g))
            })
            .collect();
        self.scratch.give_grids(grids);
        out
    }

    /// Type 1 for several real strength vectors (each of length [`Self::num_points`]), two to a
    /// transform: the pair `(a, b)` is spread as `a + i b`, whose coefficients `F` split by the
    /// Hermitian symmetry of real data, `A_k = (F_k + conj F_-k) / 2` and
    /// `B_k = (F_k - conj F_-k) / 2i` (the partner `-k` read from the fine grid, where every
    /// mode's partner lies). The spreading, transform and deconvolution are real-linear and
    /// real data give Hermitian grids, so the split is exact but for rounding: each vector's
    /// coefficients carry its own transform's error (the contract of [`Self::new`]) plus about
    /// 1e-16 of its partner's magnitude. Half the grids and transforms of [`Self::type1`].
    /// Returns one mode array per strength vector.
    pub fn type1_real(&self, strengths: &[&[f64]]) -> Result<Vec<Vec<Complex64>>, NufftError> {
        for (which, s) in strengths.iter().enumerate() {
            if s.len() != self.num_points() {
                return Err(NufftError::Length {
                    which,
                    got: s.len(),
                    expected: self.num_points(),
                });
            }
        }
        let packed: Vec<Vec<Complex64>> = strengths
            .chunks(2)
            .map(|pair| match pair {
                [a, b] => a
                    .iter()
                    .zip(*b)
                    .map(|(&x, &y)| Complex64::new(x, y))
                    .collect(),
                [a] => a.iter().map(|&x| Complex64::new(x, 0.0)).collect(),
                _ => unreachable!("chunks of two"),
            })
            .collect();
        let refs: Vec<&[Complex64]> = packed.iter().map(|v| v.as_slice()).collect();
        let mut grids = self.spread(&refs);
        let mut out = Vec::with_capacity(strengths.len());
        for (pair, g) in strengths.chunks(2).zip(grids.iter_mut()) {
            self.fft.process(g, Direction::Forward);
            let [a, b] = self.extract_split(g);
            out.push(a);
            if pair.len() == 2 {
                out.push(b);
            }
        }
        self.scratch.give_grids(grids);
        Ok(out)
    }

    /// [`Self::extract_modes`] of a transformed fine grid of `a + i b` for real `a` and `b`: the
    /// modes of `a` and of `b`, deconvolved.
    fn extract_split(&self, fine: &[Complex64]) -> [Vec<Complex64>; 2] {
        let [m0, m1, m2] = self.modes;
        let [n0, n1, n2] = self.nf;
        let at = |q: i64, n: usize| q.rem_euclid(n as i64) as usize;
        let mut a = vec![Complex64::default(); m0 * m1 * m2];
        let mut b = vec![Complex64::default(); m0 * m1 * m2];
        a.par_chunks_mut(m0 * m1)
            .zip(b.par_chunks_mut(m0 * m1))
            .enumerate()
            .for_each(|(i2, (pa, pb))| {
                let q2 = mode_of(i2, m2);
                for i1 in 0..m1 {
                    let q1 = mode_of(i1, m1);
                    let c21 = self.deconv[2][i2] * self.deconv[1][i1];
                    for i0 in 0..m0 {
                        let q0 = mode_of(i0, m0);
                        let f = fine[(at(q2, n2) * n1 + at(q1, n1)) * n0 + at(q0, n0)];
                        let g = fine[(at(-q2, n2) * n1 + at(-q1, n1)) * n0 + at(-q0, n0)].conj();
                        let d = 0.5 * c21 * self.deconv[0][i0];
                        pa[i1 * m0 + i0] = (f + g) * d;
                        // (f - g) / 2i = -i (f - g) / 2
                        let h = f - g;
                        pb[i1 * m0 + i0] = Complex64::new(h.im, -h.re) * d;
                    }
                }
            });
        [a, b]
    }

    /// Type 2 for several mode arrays at once (each of length [`Self::num_modes`]). Returns one
    /// vector of point values per mode array, in the caller's point order.
    pub fn type2(&self, coeffs: &[&[Complex64]]) -> Result<Vec<Vec<Complex64>>, NufftError> {
        self.check_lengths(coeffs, self.num_modes())?;
        let padded: Vec<Vec<Complex64>> = coeffs
            .iter()
            .map(|c| {
                let mut g = self.place_modes(c);
                self.fft.process(&mut g, Direction::Inverse);
                let p = self.pad_periodic(&g);
                self.scratch.give_grids(vec![g]);
                p
            })
            .collect();
        let out = self.interpolate(&padded);
        self.scratch.give_padded(padded);
        Ok(out)
    }

    fn check_lengths(&self, v: &[&[Complex64]], expected: usize) -> Result<(), NufftError> {
        for (which, s) in v.iter().enumerate() {
            if s.len() != expected {
                return Err(NufftError::Length {
                    which,
                    got: s.len(),
                    expected,
                });
            }
        }
        Ok(())
    }

    /// Padding (in grid points) on each side of the padded buffers.
    fn pad(&self) -> usize {
        // A kernel row starts at ceil(g - w/2) >= -w/2 and ends at most w/2 + 1 past the grid.
        self.kernel.width.div_ceil(2) + 1
    }

    /// Spread all strength vectors onto fine grids (one per vector).
    fn spread(&self, strengths: &[&[Complex64]]) -> Vec<Vec<Complex64>> {
        let [n0, n1, n2] = self.nf;
        let w = self.kernel.width;
        let pad = self.pad();
        let (xb, yb, zb) = (n0 + 2 * pad, n1 + 2 * pad, self.slab + 2 * pad);
        let ns = strengths.len();
        let nslab = self.slab_start.len() - 1;
        // Strengths in sorted point order: a gather loop overlaps its cache misses, which the
        // spreading loop cannot.
        let sorted: Vec<Vec<Complex64>> = strengths
            .iter()
            .map(|st| self.perm.par_iter().map(|&i| st[i]).collect())
            .collect();
        let sorted: Vec<&[Complex64]> = sorted.iter().map(|v| v.as_slice()).collect();
        // Each slab spreads into its own padded buffers (interleaved re/im), all strengths.
        let mut slabs = self.scratch.take_slabs(nslab, 2 * ns * zb * yb * xb);
        slabs.par_iter_mut().enumerate().for_each(|(s, buf)| {
            buf.fill(0.0);
            let z_origin = (s * self.slab) as i64 - pad as i64;
            let spot = Spot {
                ix: 0,
                iy: 0,
                iz: 0,
                yb,
                xb,
            };
            with_kernel_width!(w, self.spread_slab(s, z_origin, &spot, &sorted, buf));
        });
        // Fold the slabs into the periodic grid, plane by plane, slabs in order.
        let grids = self.scratch.take_grids(ns, n0 * n1 * n2);
        let grids = grids
            .into_iter()
            .enumerate()
            .map(|(si, mut grid)| {
                grid.par_chunks_mut(1 << 16)
                    .for_each(|c| c.fill(Complex64::default()));
                grid.par_chunks_mut(n0 * n1)
                    .enumerate()
                    .for_each(|(z, plane)| {
                        for (s, buf) in slabs.iter().enumerate() {
                            let b = &buf[2 * si * zb * yb * xb..2 * (si + 1) * zb * yb * xb];
                            let z_origin = (s * self.slab) as i64 - pad as i64;
                            for zl in 0..zb {
                                if (z_origin + zl as i64).rem_euclid(n2 as i64) as usize != z {
                                    continue;
                                }
                                for yl in 0..yb {
                                    let y = (yl as i64 - pad as i64).rem_euclid(n1 as i64) as usize;
                                    let src =
                                        &b[2 * (zl * yb + yl) * xb..2 * (zl * yb + yl + 1) * xb];
                                    let dst = &mut plane[y * n0..(y + 1) * n0];
                                    // Interior run, then the wrapped margins.
                                    for (x, d) in dst.iter_mut().enumerate() {
                                        *d += Complex64::new(
                                            src[2 * (x + pad)],
                                            src[2 * (x + pad) + 1],
                                        );
                                    }
                                    for xl in (0..pad).chain(n0 + pad..xb) {
                                        let x =
                                            (xl as i64 - pad as i64).rem_euclid(n0 as i64) as usize;
                                        dst[x] += Complex64::new(src[2 * xl], src[2 * xl + 1]);
                                    }
                                }
                            }
                        }
                    });
                grid
            })
            .collect();
        self.scratch.give_slabs(slabs);
        grids
    }

    /// Spread the points of slab `s` into its padded buffers (kernel width `W`); `strengths`
    /// are in sorted point order.
    fn spread_slab<const W: usize>(
        &self,
        s: usize,
        z_origin: i64,
        strides: &Spot,
        strengths: &[&[Complex64]],
        buf: &mut [f64],
    ) {
        let pad = self.pad() as i64;
        let block = 2 * (self.slab + 2 * self.pad()) * strides.yb * strides.xb;
        let (mut kx, mut ky, mut kz) = ([0.0; MAX_WIDTH], [0.0; MAX_WIDTH], [0.0; MAX_WIDTH]);
        for p in self.slab_start[s]..self.slab_start[s + 1] {
            let g = self.grid_pts[p];
            let at = Spot {
                ix: (self.kernel.eval_w::<W>(g[0], &mut kx) + pad) as usize,
                iy: (self.kernel.eval_w::<W>(g[1], &mut ky) + pad) as usize,
                iz: (self.kernel.eval_w::<W>(g[2], &mut kz) - z_origin) as usize,
                ..*strides
            };
            for (si, st) in strengths.iter().enumerate() {
                spread_point::<W>(
                    &mut buf[si * block..(si + 1) * block],
                    &at,
                    &kx,
                    &ky,
                    &kz,
                    st[p],
                );
            }
        }
    }

    /// Read the `modes` out of a transformed fine grid and deconvolve.
    fn extract_modes(&self, fine: &[Complex64]) -> Vec<Complex64> {
        let [m0, m1, m2] = self.modes;
        let [n0, n1, _] = self.nf;
        let mut out = vec![Complex64::default(); m0 * m1 * m2];
        out.par_chunks_mut(m0 * m1)
            .enumerate()
            .for_each(|(i2, plane)| {
                let k2 = fine_index(i2, m2, self.nf[2]);
                for i1 in 0..m1 {
                    let k1 = fine_index(i1, m1, n1);
                    let c21 = self.deconv[2][i2] * self.deconv[1][i1];
                    for i0 in 0..m0 {
                        let k0 = fine_index(i0, m0, n0);
                        plane[i1 * m0 + i0] =
                            fine[(k2 * n1 + k1) * n0 + k0] * (c21 * self.deconv[0][i0]);
                    }
                }
            });
        out
    }

    /// Place deconvolved modes on a zeroed fine grid (the first half of type 2).
    fn place_modes(&self, c: &[Complex64]) -> Vec<Complex64> {
        let [m0, m1, m2] = self.modes;
        let [n0, n1, n2] = self.nf;
        let mut fine = self
            .scratch
            .take_grids(1, n0 * n1 * n2)
            .pop()
            .expect("one grid");
        fine.par_chunks_mut(1 << 16)
            .for_each(|c| c.fill(Complex64::default()));
        for i2 in 0..m2 {
            let k2 = fine_index(i2, m2, n2);
            for i1 in 0..m1 {
                let k1 = fine_index(i1, m1, n1);
                let c21 = self.deconv[2][i2] * self.deconv[1][i1];
                for i0 in 0..m0 {
                    let k0 = fine_index(i0, m0, n0);
                    fine[(k2 * n1 + k1) * n0 + k0] =
                        c[(i2 * m1 + i1) * m0 + i0] * (c21 * self.deconv[0][i0]);
                }
            }
        }
        fine
    }

    /// Periodic copy of a fine grid with `pad` extra points on each side of every axis.
    fn pad_periodic(&self, g: &[Complex64]) -> Vec<Complex64> {
        let [n0, n1, n2] = self.nf;
        let pad = self.pad() as i64;
        let (x, y, z) = (
            n0 + 2 * pad as usize,
            n1 + 2 * pad as usize,
            n2 + 2 * pad as usize,
        );
        // Every entry is overwritten below: no zeroing needed.
        let mut out = self.scratch.take_padded(x * y * z);
        out.par_chunks_mut(x * y)
            .enumerate()
            .for_each(|(zl, plane)| {
                let gz = (zl as i64 - pad).rem_euclid(n2 as i64) as usize;
                for yl in 0..y {
                    let gy = (yl as i64 - pad).rem_euclid(n1 as i64) as usize;
                    let src = &g[(gz * n1 + gy) * n0..(gz * n1 + gy + 1) * n0];
                    for (xl, d) in plane[yl * x..(yl + 1) * x].iter_mut().enumerate() {
                        *d = src[(xl as i64 - pad).rem_euclid(n0 as i64) as usize];
                    }
                }
            });
        out
    }

    /// Interpolate the padded grids at the sorted points; results in the caller's order.
    fn interpolate(&self, padded: &[Vec<Complex64>]) -> Vec<Vec<Complex64>> {
        let [n0, n1, _] = self.nf;
        let w = self.kernel.width;
        let pad = self.pad() as i64;
        let (xb, yb) = (n0 + 2 * pad as usize, n1 + 2 * pad as usize);
        let ns = padded.len();
        let sorted: Vec<Complex64> = self
            .grid_pts
            .par_chunks(1024)
            .flat_map_iter(|chunk| {
                let (mut kx, mut ky, mut kz) =
                    ([0.0; MAX_WIDTH], [0.0; MAX_WIDTH], [0.0; MAX_WIDTH]);
                let mut vals = Vec::with_capacity(chunk.len() * ns);
                for g in chunk {
                    let ix = (self.kernel.eval(g[0], &mut kx) + pad) as usize;
                    let iy = (self.kernel.eval(g[1], &mut ky) + pad) as usize;
                    let iz = (self.kernel.eval(g[2], &mut kz) + pad) as usize;
                    for grid in padded {
                        let mut acc = Complex64::default();
                        for dz in 0..w {
                            let mut accz = Complex64::default();
                            for dy in 0..w {
                                let base = ((iz + dz) * yb + iy + dy) * xb + ix;
                                let row = &grid[base..base + w];
                                let mut accy = Complex64::default();
                                for dx in 0..w {
                                    accy += row[dx] * kx[dx];
                                }
                                accz += accy * ky[dy];
                            }
                            acc += accz * kz[dz];
                        }
                        vals.push(acc);
                    }
                }
                vals
            })
            .collect();
        // Back to the caller's order as a parallel gather (a scatter would be serial).
        (0..ns)
            .map(|s| {
                self.inv_perm
                    .par_iter()
                    .map(|&p| sorted[p * ns + s])
                    .collect()
            })
            .collect()
    }
}

/// Reusable buffers of a plan. Large transforms otherwise allocate (and the kernel page-faults)
/// hundreds of megabytes per call: measured on a 1e5-point spectral Ewald sum, the Fourier
/// stage went from 0.32-0.45 s to about 0.15 s with the memory kept. A clone starts empty.
#[derive(Debug, Default)]
struct ScratchPool(std::sync::Mutex<Scratch>);

#[derive(Debug, Default)]
struct Scratch {
    slabs: Vec<Vec<f64>>,
    grids: Vec<Vec<Complex64>>,
    padded: Vec<Vec<Complex64>>,
}

impl Clone for ScratchPool {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// `count` buffers of length `len` from `pool` (contents unspecified), allocating if short.
fn take<T: Clone + Default>(pool: &mut Vec<Vec<T>>, count: usize, len: usize) -> Vec<Vec<T>> {
    (0..count)
        .map(|_| {
            let mut v = pool.pop().unwrap_or_default();
            v.resize(len, T::default());
            v.truncate(len);
            v
        })
        .collect()
}

impl ScratchPool {
    fn lock(&self) -> std::sync::MutexGuard<'_, Scratch> {
        // A panic while holding the lock leaves only buffers behind: still usable.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
    fn take_slabs(&self, count: usize, len: usize) -> Vec<Vec<f64>> {
        take(&mut self.lock().slabs, count, len)
    }
    fn take_grids(&self, count: usize, len: usize) -> Vec<Vec<Complex64>> {
        take(&mut self.lock().grids, count, len)
    }
    fn take_padded(&self, len: usize) -> Vec<Complex64> {
        take(&mut self.lock().padded, 1, len)
            .pop()
            .expect("one buffer")
    }
    fn give_slabs(&self, v: Vec<Vec<f64>>) {
        self.lock().slabs.extend(v);
    }
    fn give_grids(&self, v: Vec<Vec<Complex64>>) {
        self.lock().grids.extend(v);
    }
    fn give_padded(&self, v: Vec<Vec<Complex64>>) {
        self.lock().padded.extend(v);
    }
}

/// Where a point's kernel footprint starts in a padded buffer, and the buffer's strides.
#[derive(Clone, Copy)]
struct Spot {
    ix: usize,
    iy: usize,
    iz: usize,
    yb: usize,
    xb: usize,
}

/// Add `c * kz[dz] ky[dy] kx[dx]` to the `W^3` footprint of one point in an interleaved
/// (re, im) buffer.
#[inline(always)]
fn spread_point<const W: usize>(
    b: &mut [f64],
    at: &Spot,
    kx: &[f64; MAX_WIDTH],
    ky: &[f64; MAX_WIDTH],
    kz: &[f64; MAX_WIDTH],
    c: Complex64,
) {
    // The strength times the x kernel, interleaved (re, im): each footprint row is then an
    // axpy of length 2W with one scalar, which vectorises at any SIMD width.
    let mut cx = [0.0; 2 * MAX_WIDTH];
    for j in 0..W {
        cx[2 * j] = c.re * kx[j];
        cx[2 * j + 1] = c.im * kx[j];
    }
    for dz in 0..W {
        for dy in 0..W {
            let s = kz[dz] * ky[dy];
            let base = 2 * (((at.iz + dz) * at.yb + at.iy + dy) * at.xb + at.ix);
            let row = &mut b[base..base + 2 * W];
            for i in 0..2 * W {
                row[i] += s * cx[i];
            }
        }
    }
}

/// `floor(x)` without a libm call (baseline x86-64 has no rounding instruction); exact for
/// `|x| < 2^52`, which box coordinates are.
#[inline(always)]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64; // truncates toward zero
    if t > x { t - 1.0 } else { t }
}

/// Signed mode number of position `i` among `m` modes.
pub fn mode_of(i: usize, m: usize) -> i64 {
    i as i64 - (m / 2) as i64
}

/// Fine-grid index of mode position `i` among `m` modes on a grid of `n`.
fn fine_index(i: usize, m: usize, n: usize) -> usize {
    mode_of(i, m).rem_euclid(n as i64) as usize
}

/// Slow twin of type 1: the direct sum, `O(N M^3)`. For tests and small problems.
pub fn direct_type1(
    points: &[[f64; 3]],
    box_length: f64,
    strengths: &[Complex64],
    modes: [usize; 3],
) -> Vec<Complex64> {
    let [m0, m1, m2] = modes;
    let s = 2.0 * PI / box_length;
    let mut out = vec![Complex64::default(); m0 * m1 * m2];
    out.par_iter_mut().enumerate().for_each(|(idx, o)| {
        let (i0, i1, i2) = (idx % m0, (idx / m0) % m1, idx / (m0 * m1));
        let k = [mode_of(i0, m0), mode_of(i1, m1), mode_of(i2, m2)].map(|m| m as f64 * s);
        *o = points
            .iter()
            .zip(strengths)
            .map(|(x, f)| {
                f * Complex64::from_polar(1.0, -(k[0] * x[0] + k[1] * x[1] + k[2] * x[2]))
            })
            .sum();
    });
    out
}

/// Slow twin of type 2: the direct sum.
pub fn direct_type2(
    points: &[[f64; 3]],
    box_length: f64,
    coeffs: &[Complex64],
    modes: [usize; 3],
) -> Vec<Complex64> {
    let [m0, m1, m2] = modes;
    let s = 2.0 * PI / box_length;
    points
        .par_iter()
        .map(|x| {
            let mut acc = Complex64::default();
            for (idx, c) in coeffs.iter().enumerate() {
                let (i0, i1, i2) = (idx % m0, (idx / m0) % m1, idx / (m0 * m1));
                let k = [mode_of(i0, m0), mode_of(i1, m1), mode_of(i2, m2)].map(|m| m as f64 * s);
                acc += c * Complex64::from_polar(1.0, k[0] * x[0] + k[1] * x[1] + k[2] * x[2]);
            }
            acc
        })
        .collect()
}
