//! Gaussian gridding for the Fourier part of spectral Ewald sums (the SE method of Lindbo and
//! Tornberg, J. Comput. Phys. 229, 2010): point values are spread onto a uniform `M^3` grid
//! with a truncated Gaussian, transformed by real FFTs, multiplied by the Ewald kernel with the
//! Gaussian's transform divided out twice, transformed back and gathered with the same
//! Gaussian. Unlike a general NUFFT, the grid is not upsampled: the Ewald kernel's own factor
//! `exp(-k^2 / 4 xi^2)` keeps the deconvolution bounded, so the grid only needs the modes the
//! sum keeps (`M >= k_max L / pi`), eight times fewer grid points than a NUFFT at upsampling 2.
//!
//! With `h = L/M`, support `P` points per axis (half-width `w = P h / 2`) and shape `m`
//! (the Gaussian is `m` standard deviations wide at `w`), the window is
//! `g(r) = (2 xi^2 / (pi eta))^(3/2) exp(-2 xi^2 r^2 / eta)` with `eta = (2 w xi / m)^2`, whose
//! transform is `exp(-eta k^2 / 8 xi^2)`; [`window_for`] chooses `P`, `m` and the grid's
//! oversampling from the tolerance. Velocity gradients (stresslet sums) come from the
//! window's derivative in the gather, with no extra transforms.
//!
//! Determinism: points are sorted by z-slab (a grid-only partition, slabs at least `P` planes
//! thick); the even slabs spread in parallel straight into the grid, then the odd ones, so
//! every grid value receives its contributions in an order fixed by the sort. The gather is
//! independent per point. Results are bit-identical for any rayon pool size.

use crate::ewald::phased_writes::{self, phased};
use crate::ewald::window::Window;
use crate::model::geometry::{Vec3, dot, floor_i64, wrap_position};
use motile_analysis::fft3::RealFft3;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Bin width (grid points) of the points' sort within a slab.
const SORT_BIN: usize = 4;

/// A planned Gaussian grid: box, grid size, support, window, FFT plan.
#[derive(Debug, Clone)]
pub(crate) struct GaussianGrid {
    l: f64,
    m: usize,
    p: usize,
    h: f64,
    /// Window exponent `2 xi^2 / eta` and 1D normalisation `sqrt(2 xi^2 / (pi eta))`.
    alpha: f64,
    norm: f64,
    eta: f64,
    xi: f64,
    fft: RealFft3,
    pool: Pool,
}

/// Points prepared for one sum: sorted by slab, with their first grid index and window values
/// along each axis.
#[derive(Debug, Clone, Default)]
pub(crate) struct GridPoints {
    /// Original index of each sorted point.
    perm: Vec<u32>,
    /// First grid index of the support per axis, in `0..M`.
    first: Vec<[u32; 3]>,
    /// Window values, `3 P` per point (x, y, z).
    weights: Vec<f64>,
    /// Offset of each point's first support point from the point, per axis.
    offset: Vec<[f64; 3]>,
    /// `slab_start[s]..slab_start[s + 1]` are the sorted points of slab `s`.
    slab_start: Vec<usize>,
    /// Slab `s` holds the points whose window starts on planes `slab_bounds[s]..slab_bounds[s + 1]`.
    slab_bounds: Vec<usize>,
}

impl GridPoints {
    /// Sorted point `k`'s first grid index per axis and its window values along x, y, z.
    #[inline]
    fn footprint<const P: usize>(&self, k: usize) -> ([usize; 3], [&[f64]; 3]) {
        let w = &self.weights[3 * P * k..3 * P * (k + 1)];
        (
            self.first[k].map(|c| c as usize),
            [&w[..P], &w[P..2 * P], &w[2 * P..3 * P]],
        )
    }
}

impl GaussianGrid {
    /// A grid of `m^3` points on a box of side `l`, splitting parameter `xi`, support `p`,
    /// window `shape` standard deviations wide at the support's edge.
    pub(crate) fn new(l: f64, xi: f64, m: usize, p: usize, shape: f64) -> Self {
        let w = Window::new(l, xi, m, p, shape);
        Self {
            l,
            m,
            p: w.p,
            h: w.h,
            alpha: w.alpha,
            norm: w.norm,
            eta: w.eta,
            xi,
            fft: RealFft3::new([m; 3]),
            pool: Pool::default(),
        }
    }

    /// Sort `points` by slab and evaluate their windows (fast Gaussian gridding: two
    /// exponentials per axis, the rest by products). The sums use [`Self::prepare_reusing`].
    #[cfg(test)]
    pub(crate) fn prepare(&self, points: &[Vec3]) -> GridPoints {
        self.prepare_reusing(points, GridPoints::default())
    }

    /// [`Self::prepare`] writing into the buffers of earlier prepared points (fresh buffers of
    /// this size were page-faulted anew on every call: most of the preparation's time).
    pub(crate) fn prepare_reusing(&self, points: &[Vec3], old: GridPoints) -> GridPoints {
        let (m, p, h) = (self.m, self.p, self.h);
        // Slabs at least P planes thick: a footprint reaches P planes.
        let bounds = phased_writes::bounds(self.m, self.p);
        let nslab = bounds.len() - 1;
        // e^{-alpha q^2 h^2}, q = 0..P.
        let tail: Vec<f64> = (0..p)
            .map(|q| (-self.alpha * (q as f64 * h).powi(2)).exp())
            .collect();
        // Sort key: slab, then bins of SORT_BIN planes in z, y and x (so consecutive points
        // share most of their footprint in cache).
        let nb = m.div_ceil(SORT_BIN);
        let per_point: Vec<([u32; 3], usize)> = points
            .par_iter()
            .map(|y| {
                // Wrapped first: the grid coordinate of an unwrapped position far outside the
                // box (1e19 and more) overflows the integer floor.
                let y = wrap_position(*y, self.l);
                let first = [0, 1, 2].map(|d| {
                    let t = y[d] / h;
                    let i0 = -floor_i64(p as f64 / 2.0 - t);
                    i0.rem_euclid(m as i64) as u32
                });
                let [fx, fy, fz] = first.map(|c| c as usize);
                let s = (bounds.partition_point(|&b| b <= fz) - 1).min(nslab - 1);
                let key = ((s * nb + (fz - bounds[s]) / SORT_BIN) * nb + fy / SORT_BIN) * nb
                    + fx / SORT_BIN;
                (first, key)
            })
            .collect();
        let nkeys = nslab * nb * nb * nb;
        let mut count = vec![0usize; nkeys + 1];
        for &(_, k) in &per_point {
            count[k + 1] += 1;
        }
        for k in 0..nkeys {
            count[k + 1] += count[k];
        }
        let start: Vec<usize> = (0..=nslab).map(|s| count[s * nb * nb * nb]).collect();
        let mut next = count;
        let GridPoints {
            mut perm,
            mut first,
            mut weights,
            mut offset,
            ..
        } = old;
        // Every entry is overwritten below.
        perm.resize(points.len(), 0);
        first.resize(points.len(), [0; 3]);
        weights.resize(3 * p * points.len(), 0.0);
        offset.resize(points.len(), [0.0; 3]);
        for (i, &(_, k)) in per_point.iter().enumerate() {
            perm[next[k]] = i as u32;
            next[k] += 1;
        }
        first
            .par_iter_mut()
            .zip(perm.par_iter())
            .for_each(|(f, &i)| *f = per_point[i as usize].0);
        weights
            .par_chunks_mut(3 * p)
            .zip(offset.par_iter_mut())
            .zip(perm.par_iter())
            .for_each(|((w, off), &i)| {
                let y = wrap_position(points[i as usize], self.l);
                for d in 0..3 {
                    let t = y[d] / h;
                    let i0 = -floor_i64(p as f64 / 2.0 - t) as f64;
                    // Offset of the first support point from the point, in [-w, -w + h).
                    let d0 = (i0 - t) * h;
                    off[d] = d0;
                    let mut e = self.norm * (-self.alpha * d0 * d0).exp();
                    let step = (-2.0 * self.alpha * d0 * h).exp();
                    let wd = &mut w[d * p..(d + 1) * p];
                    for q in 0..p {
                        wd[q] = e * tail[q];
                        e *= step;
                    }
                }
            });
        GridPoints {
            perm,
            first,
            weights,
            offset,
            slab_start: start,
            slab_bounds: bounds,
        }
    }

    /// Spread `NF` real fields (indexed like the points given to [`Self::prepare`]) onto the
    /// grid.
    ///
    /// The fields are spread together into one grid with the fields innermost and `P` extra
    /// x points (so a window row is one contiguous run of `P NF` values, and y and z wrap per
    /// row), in two phases: the even slabs in parallel, then the odd ones. Every slab is at
    /// least `P` planes thick, so slabs of one phase never write the same plane; each grid
    /// value receives its contributions in an order fixed by the sort.
    pub(crate) fn spread<const NF: usize>(
        &mut self,
        pts: &GridPoints,
        fields: [&[f64]; NF],
    ) -> Spread {
        let (m, p) = (self.m, self.p);
        let xb = m + p;
        let plane = m * xb * NF;
        let mut work = self.pool.real(1, 0).pop().expect("one buffer");
        work.clear();
        work.resize(m * plane, 0.0);
        let bounds = &pts.slab_bounds;
        let spread_slab = |s: usize, main: &mut [f64], main_start: usize, wrap: &mut [f64]| {
            let slab = Slab {
                points: pts.slab_start[s]..pts.slab_start[s + 1],
                m,
                plane,
                main_start,
            };
            with_support!(p, spread_slab::<NF>(pts, &slab, fields, main, wrap));
        };
        phased(
            &mut work,
            bounds,
            p,
            |z| z * plane,
            |s, win, a, wrap| spread_slab(s, win, a / plane, wrap),
        );
        Spread(Interleaved {
            m,
            p,
            nf: NF,
            data: work,
        })
    }

    /// Gather `NF` fields back to the points: `h^3 sum_grid G(x_m) g(y - x_m)` per field,
    /// results in the points' own order.
    pub(crate) fn gather<const NF: usize>(
        &mut self,
        pts: &GridPoints,
        field: Field,
    ) -> [Vec<f64>; NF] {
        let (m, p) = (self.m, self.p);
        let work = field.0.check(m, p, NF).data;
        let plane = m * (m + p) * NF;
        let h3 = self.h.powi(3);
        let sorted: Vec<[f64; NF]> = (0..pts.perm.len())
            .into_par_iter()
            .map_init(
                || vec![0.0; p * NF],
                |rows, k| with_support!(p, gather_point::<NF>(pts, k, m, plane, &work, rows)),
            )
            .map(|acc| acc.map(|v| h3 * v))
            .collect();
        self.pool.give_real(vec![work]);
        unsort(pts, &sorted)
    }

    /// Gather three fields and their gradients: `[u_0, u_1, u_2, du_0/dx_0, du_0/dx_1, ...,
    /// du_2/dx_2]` (`3 + 3 i + m` is `du_i/dx_m`), the gradient from the derivative of the
    /// window (`g_1'(d) = -2 alpha d g_1(d)`), which equals multiplying the spectrum by `i k`
    /// and costs no extra transforms.
    pub(crate) fn gather_gradient(&mut self, pts: &GridPoints, field: Field) -> [Vec<f64>; 12] {
        let (m, p) = (self.m, self.p);
        let work = field.0.check(m, p, 3).data;
        let plane = m * (m + p) * 3;
        let h3 = self.h.powi(3);
        let (alpha, h) = (self.alpha, self.h);
        let sorted: Vec<[f64; 12]> = (0..pts.perm.len())
            .into_par_iter()
            .map_init(
                || vec![0.0; 3 * p * 3],
                |rows, k| {
                    with_support!(
                        p,
                        gather_gradient_point::<3>(pts, k, (m, plane), (&work, rows), (alpha, h))
                    )
                },
            )
            .map(|acc| acc.map(|v| h3 * v))
            .collect();
        self.pool.give_real(vec![work]);
        unsort(pts, &sorted)
    }

    /// The Fourier stage between spread and gather: real FFTs of the `I` input grids, at every
    /// kept mode `outputs = g(k, |k|^2, exp(-|k|^2 / 4 xi^2), inputs)` times the window
    /// correction `h^3 / g^(k)^2` (both exponentials from per-axis factors),
    /// inverse FFTs of the `O` outputs (unnormalised, `sum_k c(k) exp(+i k x)`). `g` sees the
    /// spectra `sum_grid G exp(-i k x)`; `k = 0` and the unpaired Nyquist modes are dropped.
    /// `g` must map real fields to real fields (Hermitian in, Hermitian out).
    pub(crate) fn convolve<const I: usize, const O: usize>(
        &mut self,
        spread: Spread,
        g: impl Fn(Vec3, f64, f64, [Complex64; I]) -> [Complex64; O] + Sync,
    ) -> Field {
        let (m, p) = (self.m, self.p);
        let xb = m + p;
        let input = spread.0.check(m, p, I).data;
        let hlen = self.fft.complex_len();
        let mut spectra = self.pool.complex(I, hlen);
        for (c, sp) in spectra.iter_mut().enumerate() {
            // Field c out of the interleaved grid, its x padding folded back.
            self.fft.forward_rows(
                |z, y, line| {
                    let row = &input[((z * m + y) * xb) * I..((z * m + y + 1) * xb) * I];
                    for (x, v) in line.iter_mut().enumerate() {
                        *v = row[x * I + c];
                    }
                    for x in m..xb {
                        line[x - m] += row[x * I + c];
                    }
                },
                sp,
            );
        }
        self.pool.give_real(vec![input]);
        let h0 = m / 2 + 1;
        let scale = 2.0 * PI / self.l;
        let h3 = self.h.powi(3);
        let x = 1.0 / (4.0 * self.xi * self.xi);
        // Per axis and index: k, exp(-k^2 / 4 xi^2) and exp(eta k^2 / 4 xi^2).
        let axis: Vec<(f64, f64, f64)> = (0..m)
            .map(|i| {
                let k = mode_of_full(i, m) as f64 * scale;
                (k, (-x * k * k).exp(), (self.eta * x * k * k).exp())
            })
            .collect();
        // In place, a row of modes at a time: the outputs overwrite the first O spectra (every
        // input of a mode is read before its outputs are written).
        assert!(O <= I, "at most as many outputs as inputs");
        let mut rows: Vec<Vec<&mut [Complex64]>> = (0..m * m).map(|_| Vec::new()).collect();
        for spectrum in spectra.iter_mut() {
            for (row, chunk) in rows.iter_mut().zip(spectrum.chunks_mut(h0)) {
                row.push(chunk);
            }
        }
        rows.into_par_iter()
            .enumerate()
            .for_each(|(row, mut fields)| {
                let (i1, i2) = (row % m, row / m);
                for i0 in 0..h0 {
                    let mut out = [Complex64::default(); O];
                    let (a0, a1, a2) = (axis[i0], axis[i1], axis[i2]);
                    let k = [a0.0, a1.0, a2.0];
                    let k2 = dot(k, k);
                    if i0 != m / 2 && i1 != m / 2 && i2 != m / 2 && k2 != 0.0 {
                        let f: [Complex64; I] = std::array::from_fn(|c| fields[c][i0]);
                        let w = h3 * a0.2 * a1.2 * a2.2;
                        out = g(k, k2, a0.1 * a1.1 * a2.1, f).map(|v| v * w);
                    }
                    for (c, v) in out.into_iter().enumerate() {
                        fields[c][i0] = v;
                    }
                }
            });
        // Back into one interleaved grid, periodically extended along x for the gather.
        let mut out = self.pool.real(1, 0).pop().expect("one buffer");
        out.resize(m * m * xb * O, 0.0);
        for (c, spec) in spectra.iter_mut().take(O).enumerate() {
            self.fft
                .inverse_rows(spec, &mut out, m * xb * O, |y, line, plane| {
                    let row = &mut plane[y * xb * O..(y + 1) * xb * O];
                    for x in 0..xb {
                        row[x * O + c] = line[if x >= m { x - m } else { x }];
                    }
                });
        }
        self.pool.give_complex(spectra);
        Field(Interleaved {
            m,
            p,
            nf: O,
            data: out,
        })
    }
}

/// Values of `nf` fields on an `M^3` grid, interleaved (fields innermost) and with `P` extra
/// points along x, so a window row is one contiguous run: index `((z M + y)(M + P) + x) nf + c`.
#[derive(Debug, Clone)]
struct Interleaved {
    m: usize,
    p: usize,
    nf: usize,
    data: Vec<f64>,
}

impl Interleaved {
    fn check(self, m: usize, p: usize, nf: usize) -> Self {
        assert_eq!(
            (self.m, self.p, self.nf),
            (m, p, nf),
            "grid values of another grid or field count"
        );
        self
    }
}

/// What [`GaussianGrid::spread`] leaves: the extra x points hold contributions that wrap
/// around the box (folded back by [`GaussianGrid::convolve`]).
#[derive(Debug, Clone)]
pub(crate) struct Spread(Interleaved);

impl Spread {
    /// The fields as plain periodic grids (axis 0 fastest), padding folded back (for the tests'
    /// slow twins).
    #[cfg(test)]
    pub(crate) fn to_grids(&self) -> Vec<Vec<f64>> {
        let Interleaved { m, p, nf, ref data } = self.0;
        let xb = m + p;
        (0..nf)
            .map(|c| {
                let mut g = vec![0.0; m * m * m];
                for (r, row) in g.chunks_mut(m).enumerate() {
                    let src = &data[r * xb * nf..(r + 1) * xb * nf];
                    for x in 0..xb {
                        row[x % m] += src[x * nf + c];
                    }
                }
                g
            })
            .collect()
    }
}

/// What [`GaussianGrid::convolve`] returns for the gather: the extra x points are periodic
/// copies.
#[derive(Debug, Clone)]
pub(crate) struct Field(Interleaved);

impl Field {
    /// Plain periodic grids (axis 0 fastest) of one grid `m^3`, as a field for the gather of a
    /// grid with support `p` (for the tests' slow twins).
    #[cfg(test)]
    pub(crate) fn from_grids(grids: &[Vec<f64>], m: usize, p: usize) -> Self {
        let (nf, xb) = (grids.len(), m + p);
        let mut data = vec![0.0; m * m * xb * nf];
        for (r, row) in data.chunks_mut(xb * nf).enumerate() {
            for (c, g) in grids.iter().enumerate() {
                for x in 0..xb {
                    row[x * nf + c] = g[r * m + x % m];
                }
            }
        }
        Self(Interleaved { m, p, nf, data })
    }
}

/// Buffers kept between sums (fresh multi-megabyte allocations page-fault on every call).
#[derive(Debug, Clone, Default)]
struct Pool {
    real: Vec<Vec<f64>>,
    complex: Vec<Vec<Complex64>>,
}

impl Pool {
    /// `count` real buffers of `len` values (contents unspecified).
    fn real(&mut self, count: usize, len: usize) -> Vec<Vec<f64>> {
        (0..count)
            .map(|_| {
                let mut v = self.real.pop().unwrap_or_default();
                v.resize(len, 0.0);
                v
            })
            .collect()
    }

    /// `count` complex buffers of `len` values (contents unspecified).
    fn complex(&mut self, count: usize, len: usize) -> Vec<Vec<Complex64>> {
        (0..count)
            .map(|_| {
                let mut v = self.complex.pop().unwrap_or_default();
                v.resize(len, Complex64::default());
                v
            })
            .collect()
    }

    fn give_real(&mut self, v: Vec<Vec<f64>>) {
        self.real.extend(v);
    }

    fn give_complex(&mut self, v: Vec<Vec<Complex64>>) {
        self.complex.extend(v);
    }
}

/// Values per sorted point back into the points' own order, one vector per component.
fn unsort<const R: usize>(pts: &GridPoints, sorted: &[[f64; R]]) -> [Vec<f64>; R] {
    std::array::from_fn(|c| {
        let mut out = vec![0.0; pts.perm.len()];
        for (k, &i) in pts.perm.iter().enumerate() {
            out[i as usize] = sorted[k][c];
        }
        out
    })
}

/// Signed mode of grid index `i` on an `m`-point axis stored from 0 (`0, 1, ..., -1`).
fn mode_of_full(i: usize, m: usize) -> i64 {
    if i < m.div_ceil(2) {
        i as i64
    } else {
        i as i64 - m as i64
    }
}

/// Dispatch on the support `P` to a function generic over it (`P` from 2 to
/// [`MAX_SUPPORT`]), so the footprint loops have fixed lengths.
macro_rules! with_support {
    ($p:expr, $f:ident::<$nf:tt>($($arg:expr),*)) => {
        match $p {
            2 => $f::<$nf, 2>($($arg),*),
            3 => $f::<$nf, 3>($($arg),*),
            4 => $f::<$nf, 4>($($arg),*),
            5 => $f::<$nf, 5>($($arg),*),
            6 => $f::<$nf, 6>($($arg),*),
            7 => $f::<$nf, 7>($($arg),*),
            8 => $f::<$nf, 8>($($arg),*),
            9 => $f::<$nf, 9>($($arg),*),
            10 => $f::<$nf, 10>($($arg),*),
            11 => $f::<$nf, 11>($($arg),*),
            12 => $f::<$nf, 12>($($arg),*),
            13 => $f::<$nf, 13>($($arg),*),
            14 => $f::<$nf, 14>($($arg),*),
            15 => $f::<$nf, 15>($($arg),*),
            16 => $f::<$nf, 16>($($arg),*),
            17 => $f::<$nf, 17>($($arg),*),
            18 => $f::<$nf, 18>($($arg),*),
            19 => $f::<$nf, 19>($($arg),*),
            20 => $f::<$nf, 20>($($arg),*),
            21 => $f::<$nf, 21>($($arg),*),
            22 => $f::<$nf, 22>($($arg),*),
            23 => $f::<$nf, 23>($($arg),*),
            24 => $f::<$nf, 24>($($arg),*),
            _ => unreachable!("support outside 2..=MAX_SUPPORT"),
        }
    };
}
use with_support;

/// One slab's points and where its planes live.
struct Slab {
    points: std::ops::Range<usize>,
    m: usize,
    /// Values per grid plane (`M (M + P) NF`).
    plane: usize,
    /// First plane of the main window.
    main_start: usize,
}

/// Spread one slab's points into its windows: `main` (planes from `main_start`) and `wrap`
/// (planes from 0, for footprints that wrap past the last plane).
fn spread_slab<const NF: usize, const P: usize>(
    pts: &GridPoints,
    slab: &Slab,
    fields: [&[f64]; NF],
    main: &mut [f64],
    wrap: &mut [f64],
) {
    let (m, plane) = (slab.m, slab.plane);
    let xb = m + P;
    let main_planes = main.len() / plane;
    // One window row times the fields, interleaved like the grid: each row of the footprint
    // is then one contiguous axpy of fixed length.
    let mut wf = [[0.0; NF]; P];
    for k in slab.points.clone() {
        let i = pts.perm[k] as usize;
        let ([fx, fy, fz], [wx, wy, wz]) = pts.footprint::<P>(k);
        for (c, field) in fields.iter().enumerate() {
            let v = field[i];
            for q in 0..P {
                wf[q][c] = wx[q] * v;
            }
        }
        for (qz, &wzq) in wz.iter().enumerate() {
            let mut z = fz + qz;
            if z >= m {
                z -= m;
            }
            let dst = if z >= slab.main_start && z - slab.main_start < main_planes {
                &mut main[(z - slab.main_start) * plane..(z - slab.main_start + 1) * plane]
            } else {
                &mut wrap[z * plane..(z + 1) * plane]
            };
            for (qy, &wyq) in wy.iter().enumerate() {
                let mut y = fy + qy;
                if y >= m {
                    y -= m;
                }
                let wzy = wzq * wyq;
                let start = (y * xb + fx) * NF;
                let row: &mut [f64] = &mut dst[start..start + P * NF];
                for q in 0..P {
                    for c in 0..NF {
                        row[q * NF + c] += wzy * wf[q][c];
                    }
                }
            }
        }
    }
}

/// Gather point `k` (sorted order) from the interleaved, x-padded grid `work`: the
/// footprint's rows weighted by `wz wy` and summed (fixed-length axpys), then the x window
/// applied once. `rows` is scratch of `P NF` values.
fn gather_point<const NF: usize, const P: usize>(
    pts: &GridPoints,
    k: usize,
    m: usize,
    plane: usize,
    work: &[f64],
    rows: &mut [f64],
) -> [f64; NF] {
    let xb = m + P;
    let ([fx, fy, fz], [wx, wy, wz]) = pts.footprint::<P>(k);
    let rows = &mut rows[..P * NF];
    rows.fill(0.0);
    for (qz, &wzq) in wz.iter().enumerate() {
        let mut z = fz + qz;
        if z >= m {
            z -= m;
        }
        for (qy, &wyq) in wy.iter().enumerate() {
            let mut y = fy + qy;
            if y >= m {
                y -= m;
            }
            let start = z * plane + (y * xb + fx) * NF;
            let row = &work[start..start + P * NF];
            let wzy = wzq * wyq;
            for q in 0..P * NF {
                rows[q] += wzy * row[q];
            }
        }
    }
    let mut acc = [0.0; NF];
    for q in 0..P {
        for c in 0..NF {
            acc[c] += wx[q] * rows[q * NF + c];
        }
    }
    acc
}

/// [`gather_point`] with the gradient: the footprint rows weighted by `wz wy`, `wz wy'` and
/// `wz' wy`, then the x window and its derivative. Returns `[u_c, then du_c/dx_m at
/// 3 + 3 c + m]` for `NF = 3`; `(m, plane)` the grid's size and plane stride, `work` the
/// field, `rows` scratch of `3 P NF` values, `(alpha, h)` the window's exponent and spacing.
fn gather_gradient_point<const NF: usize, const P: usize>(
    pts: &GridPoints,
    k: usize,
    (m, plane): (usize, usize),
    (work, rows): (&[f64], &mut [f64]),
    (alpha, h): (f64, f64),
) -> [f64; 12] {
    assert_eq!(NF, 3, "gradients of three fields");
    let xb = m + P;
    let ([fx, fy, fz], [wx, wy, wz]) = pts.footprint::<P>(k);
    // d/dy of the point's window: g_1'(y - x_q) = 2 alpha (x_q - y) g_1 = 2 alpha (d0 + q h) g_1.
    let off = pts.offset[k];
    let deriv = |wd: &[f64], d0: f64| -> [f64; P] {
        std::array::from_fn(|q| 2.0 * alpha * (d0 + q as f64 * h) * wd[q])
    };
    let (dx, dy, dz) = (deriv(wx, off[0]), deriv(wy, off[1]), deriv(wz, off[2]));
    let rows = &mut rows[..3 * P * NF];
    rows.fill(0.0);
    let (rv, rest) = rows.split_at_mut(P * NF);
    let (ry, rz) = rest.split_at_mut(P * NF);
    for qz in 0..P {
        let mut z = fz + qz;
        if z >= m {
            z -= m;
        }
        for qy in 0..P {
            let mut y = fy + qy;
            if y >= m {
                y -= m;
            }
            let start = z * plane + (y * xb + fx) * NF;
            let row = &work[start..start + P * NF];
            let (a, b, c) = (wz[qz] * wy[qy], wz[qz] * dy[qy], dz[qz] * wy[qy]);
            for q in 0..P * NF {
                rv[q] += a * row[q];
                ry[q] += b * row[q];
                rz[q] += c * row[q];
            }
        }
    }
    let mut out = [0.0; 12];
    for q in 0..P {
        for c in 0..NF {
            out[c] += wx[q] * rv[q * NF + c];
            out[3 + 3 * c] += dx[q] * rv[q * NF + c];
            out[3 + 3 * c + 1] += wx[q] * ry[q * NF + c];
            out[3 + 3 * c + 2] += wx[q] * rz[q * NF + c];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ewald::window::window_for;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn windows_match_the_documented_table() {
        let got: Vec<usize> = [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
            .iter()
            .map(|&t| window_for(t).0)
            .collect();
        assert_eq!(got, [3, 5, 6, 8, 12, 15, 18, 22], "supports per tolerance");
        for tol in [1e-1, 1e-2, 1e-4, 1e-8, 1e-12] {
            let (p, m, r) = window_for(tol);
            assert!((1.0..1.2).contains(&r), "tol {tol:e}: oversampling {r}");
            assert!(
                libm::erfc(m / std::f64::consts::SQRT_2) <= 1.0001 * tol / 10.0,
                "tol {tol:e}: truncation at {m} standard deviations (P = {p})"
            );
        }
    }

    /// Spreading is the adjoint of gathering: `<gather(G), f> = h^3 <G, spread(f)>` for any
    /// grid values and point values, to round-off. Checks the indexing, the periodic wrap,
    /// the slab phases (or the single slab of a small grid) and the sort.
    #[test]
    fn spread_is_the_adjoint_of_gather() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (m, p, n) in [(8usize, 5usize, 40usize), (40, 8, 2000), (36, 6, 500)] {
            let l = 3.7;
            let mut grid = GaussianGrid::new(l, 2.0, m, p, 4.0);
            // Points everywhere, a few on the box faces and past them.
            let mut y: Vec<Vec3> = (0..n)
                .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
                .collect();
            y[0] = [0.0, 0.0, 0.0];
            y[1] = [l - 1e-12, l * 0.5, 1e-13];
            y[2] = [-0.3, l + 0.2, 2.0 * l - 0.1];
            let pts = grid.prepare(&y);
            let f: [Vec<f64>; 2] =
                std::array::from_fn(|_| (0..n).map(|_| rng.random_range(-1.0..1.0)).collect());
            let g: Vec<Vec<f64>> = (0..2)
                .map(|_| {
                    (0..m * m * m)
                        .map(|_| rng.random_range(-1.0..1.0))
                        .collect()
                })
                .collect();
            let spread = grid.spread(&pts, [&f[0], &f[1]]).to_grids();
            let gathered: [Vec<f64>; 2] = grid.gather(&pts, Field::from_grids(&g, m, p));
            let h3 = (l / m as f64).powi(3);
            for c in 0..2 {
                let lhs: f64 = gathered[c].iter().zip(&f[c]).map(|(a, b)| a * b).sum();
                let rhs: f64 = h3 * g[c].iter().zip(&spread[c]).map(|(a, b)| a * b).sum::<f64>();
                let scale: f64 = gathered[c].iter().map(|v| v.abs()).sum::<f64>();
                assert!(
                    (lhs - rhs).abs() <= 1e-13 * scale,
                    "M {m}, P {p}, field {c}: <gather G, f> = {lhs}, h^3 <G, spread f> = {rhs}"
                );
            }
        }
    }
}
