//! The spectral grid of the mean-field solver (docs/MODEL.md §4) on the periodic unit cube:
//! wavenumbers, real-to-complex transforms of the half spectrum, dealiasing by the 2/3 rule
//! (after each forward transform of a product, modes with any `|m_d| > n/3` are zeroed), and
//! sums over the spectrum in fixed blocks.

use motile_analysis::fft3::RealFft3;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;

use crate::solver::params::sym_index;

/// What a row of the half spectrum (fixed axis-1 and axis-2 indices) shares.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RowWavenumbers {
    /// The row's index, `i2 n + i1`.
    pub(crate) row: usize,
    /// `(2 pi m_1)^2` and `(2 pi m_2)^2`.
    pub(crate) k_sq: [f64; 2],
    /// Whether the row survives the 2/3 rule.
    pub(crate) keep: bool,
}

/// Spectral grid on the unit cube: wavenumbers, real-to-complex transforms, dealiasing.
///
/// Coefficients are stored as the half spectrum of real fields: index
/// `(i2 * n + i1) * h + i0` with `h = n / 2 + 1`, axis 0 holding `m_0 = 0..=n/2` only (the
/// other half is the complex conjugate). Sums over the full spectrum weigh each stored mode
/// by [`SpectralGrid::weight`].
#[derive(Debug, Clone)]
pub struct SpectralGrid {
    /// Points per dimension.
    pub n: usize,
    /// Stored modes along axis 0, `n / 2 + 1`.
    pub(crate) h: usize,
    fft: RealFft3,
    /// `2 pi m` per FFT index, Nyquist zeroed (first derivatives); axes 1 and 2.
    k1: Vec<f64>,
    /// `(2 pi m)^2` per FFT index (second derivatives keep the Nyquist mode); axes 1 and 2.
    pub(crate) k2: Vec<f64>,
    /// Whether the index survives the 2/3 rule; axes 1 and 2.
    keep: Vec<bool>,
}

impl SpectralGrid {
    /// Grid of `n^3` points (`n` even, at least 4).
    pub fn new(n: usize) -> Self {
        assert!(
            n >= 4 && n.is_multiple_of(2),
            "grid size must be even and at least 4, got {n}"
        );
        let m = |i: usize| {
            if i <= n / 2 {
                i as i64
            } else {
                i as i64 - n as i64
            }
        };
        let k1 = (0..n)
            .map(|i| {
                if i == n / 2 {
                    0.0
                } else {
                    2.0 * PI * m(i) as f64
                }
            })
            .collect();
        let k2 = (0..n).map(|i| (2.0 * PI * m(i) as f64).powi(2)).collect();
        let keep = (0..n)
            .map(|i| 3 * m(i).unsigned_abs() as usize <= n)
            .collect();
        Self {
            n,
            h: n / 2 + 1,
            fft: RealFft3::new([n; 3]),
            k1,
            k2,
            keep,
        }
    }

    /// The wavenumber tables per FFT index: `2 pi m` with the Nyquist mode zeroed (first
    /// derivatives), `(2 pi m)^2`, and whether the index survives the 2/3 rule.
    #[cfg(feature = "gpu")]
    pub(crate) fn wavenumber_tables(&self) -> (&[f64], &[f64], &[bool]) {
        (&self.k1, &self.k2, &self.keep)
    }

    /// Grid points in total, `n^3`.
    pub fn len(&self) -> usize {
        self.n.pow(3)
    }

    /// Stored Fourier coefficients per field, `(n / 2 + 1) n^2`.
    pub fn spectral_len(&self) -> usize {
        self.h * self.n * self.n
    }

    /// True for an empty grid (never).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// FFT indices `[i0, i1, i2]` of a stored coefficient (`i0 < n / 2 + 1`).
    fn idx3(&self, idx: usize) -> [usize; 3] {
        [
            idx % self.h,
            (idx / self.h) % self.n,
            idx / (self.h * self.n),
        ]
    }

    /// Weight of a stored coefficient in sums over the full spectrum: 1 on the planes
    /// `m_0 = 0` and `m_0 = n/2`, whose conjugates are stored themselves, 2 elsewhere.
    pub fn weight(&self, idx: usize) -> f64 {
        let i0 = idx % self.h;
        if i0 == 0 || i0 == self.n / 2 {
            1.0
        } else {
            2.0
        }
    }

    /// `sum_k |c_k|^2` over the full spectrum (the mean square of the field, by Parseval).
    /// Summed in fixed blocks of rows, so the result does not depend on the thread count.
    pub fn norm_sqr(&self, c: &[Complex64]) -> f64 {
        self.sum_rows(|row, a| [self.weight_of(a) * c[row * self.h + a].norm_sqr()])[0]
    }

    /// Weight of the axis-0 index `a` ([`Self::weight`]).
    pub(crate) fn weight_of(&self, a: usize) -> f64 {
        if a == 0 || a == self.n / 2 { 1.0 } else { 2.0 }
    }

    /// `K` sums over the stored coefficients of `f(row, a)` (`row = i2 n + i1`, `a` the axis-0
    /// index) in one pass, in parallel over fixed blocks of rows and then in block order:
    /// deterministic.
    pub(crate) fn sum_rows<const K: usize>(
        &self,
        f: impl Fn(usize, usize) -> [f64; K] + Sync + Send,
    ) -> [f64; K] {
        const ROWS: usize = 64;
        let rows = self.n * self.n;
        let blocks: Vec<[f64; K]> = (0..rows.div_ceil(ROWS))
            .into_par_iter()
            .map(|b| {
                let mut acc = [0.0; K];
                for row in b * ROWS..((b + 1) * ROWS).min(rows) {
                    for a in 0..self.h {
                        for (s, v) in acc.iter_mut().zip(f(row, a)) {
                            *s += v;
                        }
                    }
                }
                acc
            })
            .collect();
        let mut total = [0.0; K];
        for b in &blocks {
            for (t, v) in total.iter_mut().zip(b) {
                *t += v;
            }
        }
        total
    }

    /// `f(k_row, a, value)` for every stored coefficient, in parallel by rows: `k_row` holds
    /// the row's index, its axis-1 and axis-2 squared wavenumbers and whether it survives the
    /// 2/3 rule; `a` is the axis-0 index.
    pub(crate) fn for_each_row<T: Send>(
        &self,
        data: &mut [T],
        f: impl Fn(RowWavenumbers, usize, &mut T) + Sync + Send,
    ) {
        let n = self.n;
        data.par_chunks_mut(self.h)
            .enumerate()
            .for_each(|(row, line)| {
                let (b, d) = (row % n, row / n);
                let k = RowWavenumbers {
                    row,
                    k_sq: [self.k2[b], self.k2[d]],
                    keep: self.keep[b] && self.keep[d],
                };
                for (a, v) in line.iter_mut().enumerate() {
                    f(k, a, v);
                }
            });
    }

    /// Fourier coefficients of a real field (forward FFT / n^3), dealiased if asked.
    pub fn forward(&self, f: &[f64], dealias: bool) -> Vec<Complex64> {
        let mut c = vec![Complex64::default(); self.spectral_len()];
        self.forward_into(f, dealias, &mut c);
        c
    }

    /// [`Self::forward`] into a caller's buffer.
    pub fn forward_into(&self, f: &[f64], dealias: bool, c: &mut [Complex64]) {
        self.fft.forward(f, c);
        let scale = 1.0 / self.len() as f64;
        let n = self.n;
        self.for_each_row(c, |k, a, v| {
            *v = if !dealias || (k.keep && 3 * a <= n) {
                *v * scale
            } else {
                Complex64::default()
            };
        });
    }

    /// Grid values of a real field from its coefficients.
    pub fn inverse(&self, c: &[Complex64]) -> Vec<f64> {
        let mut g = vec![0.0; self.len()];
        let mut work = c.to_vec();
        self.fft.inverse(&mut work, &mut g);
        g
    }

    /// [`Self::inverse`] into `out`, with `work` (spectral length) as scratch.
    pub fn inverse_into(&self, c: &[Complex64], work: &mut [Complex64], out: &mut [f64]) {
        work.par_iter_mut().zip(c).for_each(|(w, v)| *w = *v);
        self.fft.inverse(work, out);
    }

    /// Grid values of `d_dir f` from the coefficients of `f`.
    pub fn inverse_derivative(&self, c: &[Complex64], dir: usize) -> Vec<f64> {
        let mut work = vec![Complex64::default(); self.spectral_len()];
        let mut g = vec![0.0; self.len()];
        self.inverse_derivative_into(c, dir, &mut work, &mut g);
        g
    }

    /// [`Self::inverse_derivative`] into `out`, with `work` (spectral length) as scratch.
    pub fn inverse_derivative_into(
        &self,
        c: &[Complex64],
        dir: usize,
        work: &mut [Complex64],
        out: &mut [f64],
    ) {
        let h = self.h;
        let k1 = &self.k1;
        work.par_chunks_mut(h)
            .zip(c.par_chunks(h))
            .enumerate()
            .for_each(|(row, (w, line))| {
                let kr = [0.0, self.k1[row % self.n], self.k1[row / self.n]];
                for (a, (w, v)) in w.iter_mut().zip(line).enumerate() {
                    let k = if dir == 0 { k1[a] } else { kr[dir] };
                    *w = v * Complex64::new(0.0, k);
                }
            });
        self.fft.inverse(work, out);
    }

    /// Grid values of the symmetric gradient `(d_j u_i + d_i u_j) / 2` of velocity
    /// coefficients `u`, component `(i, j)`.
    pub fn inverse_strain(&self, u: &[Vec<Complex64>; 3], i: usize, j: usize) -> Vec<f64> {
        let mut work = vec![Complex64::default(); self.spectral_len()];
        let mut g = vec![0.0; self.len()];
        self.inverse_strain_into(u, i, j, &mut work, &mut g);
        g
    }

    /// [`Self::inverse_strain`] into `out`, with `work` (spectral length) as scratch.
    pub fn inverse_strain_into(
        &self,
        u: &[Vec<Complex64>; 3],
        i: usize,
        j: usize,
        work: &mut [Complex64],
        out: &mut [f64],
    ) {
        let h = self.h;
        work.par_chunks_mut(h).enumerate().for_each(|(row, w)| {
            let kr = [0.0, self.k1[row % self.n], self.k1[row / self.n]];
            let (ui, uj) = (&u[i][row * h..], &u[j][row * h..]);
            for (a, w) in w.iter_mut().enumerate() {
                let k = [self.k1[a], kr[1], kr[2]];
                *w = Complex64::new(0.0, 0.5) * (ui[a] * k[j] + uj[a] * k[i]);
            }
        });
        self.fft.inverse(work, out);
    }

    /// Coefficients of `d_dir f`.
    pub fn derivative(&self, c: &[Complex64], dir: usize) -> Vec<Complex64> {
        c.par_iter()
            .enumerate()
            .map(|(idx, v)| {
                let k = self.k_vector(idx)[dir];
                v * Complex64::new(0.0, k)
            })
            .collect()
    }

    /// Coefficients on this grid of a field given by its coefficients `c` on grid `from`
    /// (spectral interpolation): modes with every `|m_d| < min(n, n_from) / 2` are copied,
    /// the others (those beyond the coarser grid, and its Nyquist modes) are zero.
    pub fn resample(&self, c: &[Complex64], from: &SpectralGrid) -> Vec<Complex64> {
        assert_eq!(c.len(), from.spectral_len(), "resample: coefficient count");
        let lim = (self.n.min(from.n) / 2) as i64;
        let signed = |i: usize, n: usize| {
            if i <= n / 2 {
                i as i64
            } else {
                i as i64 - n as i64
            }
        };
        let wrap = |m: i64, n: usize| m.rem_euclid(n as i64) as usize;
        let mut out = vec![Complex64::default(); self.spectral_len()];
        for (idx, v) in c.iter().enumerate() {
            let [a, b, d] = from.idx3(idx);
            let m = [a as i64, signed(b, from.n), signed(d, from.n)];
            if m.iter().all(|x| x.abs() < lim) {
                let j = (wrap(m[2], self.n) * self.n + wrap(m[1], self.n)) * self.h + a;
                out[j] = *v;
            }
        }
        out
    }

    /// `|k|^2` at a coefficient index.
    pub fn k_squared(&self, idx: usize) -> f64 {
        let [a, b, d] = self.idx3(idx);
        // Axis 0 stores m_0 = a >= 0 only, so (2 pi a)^2 is k2[a] as on the other axes.
        self.k2[a] + self.k2[b] + self.k2[d]
    }

    /// First-derivative wavevector at a coefficient index.
    pub fn k_vector(&self, idx: usize) -> [f64; 3] {
        let [a, b, d] = self.idx3(idx);
        [self.k1[a], self.k1[b], self.k1[d]]
    }

    /// Zero-mean Stokes velocity from the coefficients of a symmetric stress `sigma`:
    /// `u = (I - kk/k^2)/k^2 . (i k . sigma)`.
    pub fn stokes(&self, sigma: &[Vec<Complex64>; 6]) -> [Vec<Complex64>; 3] {
        let mut u: [Vec<Complex64>; 3] =
            std::array::from_fn(|_| vec![Complex64::default(); self.spectral_len()]);
        self.stokes_into(sigma, &mut u);
        u
    }

    /// [`Self::stokes`] into `u` (three spectral-length buffers).
    pub fn stokes_into(&self, sigma: &[Vec<Complex64>; 6], u: &mut [Vec<Complex64>; 3]) {
        let h = self.h;
        let [u0, u1, u2] = u;
        u0.par_chunks_mut(h)
            .zip(u1.par_chunks_mut(h))
            .zip(u2.par_chunks_mut(h))
            .enumerate()
            .for_each(|(row, ((l0, l1), l2))| {
                let (b, d) = (row % self.n, row / self.n);
                let kr = [self.k1[b], self.k1[d]];
                for a in 0..h {
                    let idx = row * h + a;
                    let kk = self.k2[a] + self.k2[b] + self.k2[d];
                    if kk == 0.0 {
                        l0[a] = Complex64::default();
                        l1[a] = Complex64::default();
                        l2[a] = Complex64::default();
                        continue;
                    }
                    let k = [self.k1[a], kr[0], kr[1]];
                    let s = |i: usize, j: usize| sigma[sym_index(i, j)][idx];
                    let f: [Complex64; 3] = std::array::from_fn(|i| {
                        Complex64::new(0.0, 1.0)
                            * (k[0] * s(i, 0) + k[1] * s(i, 1) + k[2] * s(i, 2))
                    });
                    let kf = k[0] * f[0] + k[1] * f[1] + k[2] * f[2];
                    let k1sq = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
                    let proj = |i: usize| (f[i] - kf * (k[i] / k1sq.max(1e-300))) / kk;
                    l0[a] = proj(0);
                    l1[a] = proj(1);
                    l2[a] = proj(2);
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// A real field with modes up to |m| = 3 on every axis, including m_0 = 0 and m_0 > 0.
    pub(crate) fn field(n: usize) -> Vec<f64> {
        (0..n * n * n)
            .map(|idx| {
                let x =
                    [idx % n, (idx / n) % n, idx / (n * n)].map(|i| 2.0 * PI * i as f64 / n as f64);
                0.3 + (x[0] + 2.0 * x[1]).cos()
                    + 0.5 * (3.0 * x[2] - x[1]).sin()
                    + 0.25 * (2.0 * x[0] - 3.0 * x[1] + x[2]).cos()
            })
            .collect()
    }

    #[test]
    fn half_spectrum_parseval_and_round_trip() {
        let grid = SpectralGrid::new(10);
        let f = field(10);
        let c = grid.forward(&f, false);
        let mean_sq = f.iter().map(|v| v * v).sum::<f64>() / f.len() as f64;
        let parseval = grid.norm_sqr(&c);
        assert!(
            (parseval - mean_sq).abs() < 1e-13,
            "Parseval: {parseval} vs mean square {mean_sq}"
        );
        let back = grid.inverse(&c);
        let err = f
            .iter()
            .zip(&back)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-13, "round trip error {err:.2e}");
    }

    #[test]
    fn resampling_a_band_limited_field_is_exact() {
        for (from, to) in [(8, 14), (14, 8), (10, 10)] {
            let (gf, gt) = (SpectralGrid::new(from), SpectralGrid::new(to));
            let c = gt.resample(&gf.forward(&field(from), false), &gf);
            let got = gt.inverse(&c);
            let err = got
                .iter()
                .zip(field(to))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-13, "{from} -> {to}: max error {err:.2e}");
        }
    }
}
