//! The distributed 3D FFT of the shared spectral Ewald grid (docs/MODEL.md §3a): an `M^3`
//! grid cut into slabs of z planes, one slab per rank. Forward: real-to-complex FFTs along x
//! (`M/2 + 1` modes kept) and complex ones along y of the owned planes, an all-to-all transpose
//! to slabs of y rows, FFTs along z; the inverse runs back the same way. A hand-written
//! transpose over [`Comm::exchange`] with rustfft/realfft (FFTW's MPI interface would need its
//! C library, GPL, and unsafe FFI).

use crate::parallel::comm::Comm;
use num_complex::Complex64;
use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// A block of a transpose: a range of planes (z) and a range of rows (y).
type Block = (std::ops::Range<usize>, std::ops::Range<usize>);

/// One side of a transpose: the block of each rank's message (its `z` and `y` ranges), and
/// where element `(z, y, x)` lies in this side's fields.
struct Side<B, I> {
    /// The block of rank `r`.
    block: B,
    /// The index of element `(z, y, x)` in a field.
    index: I,
}

/// The planes of each rank and the plans of the distributed FFT of an `M^3` grid.
pub(crate) struct SlabFft {
    pub(crate) m: usize,
    pub(crate) ranks: usize,
    pub(crate) me: usize,
    /// Modes kept along x: `M/2 + 1` (real fields: the others are their conjugates).
    pub(crate) mx: usize,
    fft: Arc<dyn Fft<f64>>,
    ifft: Arc<dyn Fft<f64>>,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
}

impl SlabFft {
    /// The FFT of an `m^3` grid shared by the ranks of `comm`.
    pub(crate) fn new(m: usize, comm: &dyn Comm) -> Self {
        let mut planner = FftPlanner::new();
        let mut real = RealFftPlanner::new();
        Self {
            m,
            ranks: comm.size(),
            me: comm.rank(),
            mx: m / 2 + 1,
            fft: planner.plan_fft_forward(m),
            ifft: planner.plan_fft_inverse(m),
            r2c: real.plan_fft_forward(m),
            c2r: real.plan_fft_inverse(m),
        }
    }

    /// Rank `r`'s planes (or rows): `[r M / P, (r + 1) M / P)`.
    pub(crate) fn share(&self, r: usize) -> std::ops::Range<usize> {
        r * self.m / self.ranks..(r + 1) * self.m / self.ranks
    }

    pub(crate) fn owner(&self, plane: usize) -> usize {
        (0..self.ranks)
            .rfind(|&r| r * self.m / self.ranks <= plane)
            .expect("rank 0 starts at plane 0")
    }

    /// Real planes `[z][y][x]` to their spectra along x (half, `mx` modes) and y:
    /// `[z][y][kx]`.
    fn forward_xy(&self, real: &mut [f64]) -> Vec<Complex64> {
        let (m, mx) = (self.m, self.mx);
        let mut out = vec![Complex64::default(); real.len() / m * mx];
        real.par_chunks_mut(m * m)
            .zip(out.par_chunks_mut(m * mx))
            .for_each_init(
                || {
                    let t = vec![Complex64::default(); m * mx];
                    (self.r2c.make_scratch_vec(), t)
                },
                |(scratch, t), (pl, spec)| {
                    for (row, srow) in pl.chunks_mut(m).zip(spec.chunks_mut(mx)) {
                        self.r2c
                            .process_with_scratch(row, srow, scratch)
                            .expect("r2c lengths");
                    }
                    self.along_y(spec, &self.fft, t);
                },
            );
        out
    }

    /// [`Self::forward_xy`] undone: spectra `[z][y][kx]` (overwritten) to real planes.
    fn inverse_xy(&self, spec: &mut [Complex64]) -> Vec<f64> {
        let (m, mx) = (self.m, self.mx);
        let mut out = vec![0.0; spec.len() / mx * m];
        spec.par_chunks_mut(m * mx)
            .zip(out.par_chunks_mut(m * m))
            .for_each_init(
                || {
                    let t = vec![Complex64::default(); m * mx];
                    (self.c2r.make_scratch_vec(), t)
                },
                |(scratch, t), (sp, pl)| {
                    self.along_y(sp, &self.ifft, t);
                    for (srow, row) in sp.chunks_mut(mx).zip(pl.chunks_mut(m)) {
                        // Imaginary parts a real field cannot have (kx = 0 and M/2) are
                        // round-off here and dropped, as the real part of a complex inverse
                        // would drop them.
                        match self.c2r.process_with_scratch(srow, row, scratch) {
                            Ok(()) | Err(realfft::FftError::InputValues(..)) => {}
                            Err(e) => panic!("shared grid c2r: {e}"),
                        }
                    }
                },
            );
        out
    }

    /// FFTs along y of one plane `[y][kx]` (in place), through `t` (`M mx` values).
    fn along_y(&self, pl: &mut [Complex64], f: &Arc<dyn Fft<f64>>, t: &mut [Complex64]) {
        let (m, mx) = (self.m, self.mx);
        for y in 0..m {
            for x in 0..mx {
                t[x * m + y] = pl[y * mx + x];
            }
        }
        f.process(t);
        for y in 0..m {
            for x in 0..mx {
                pl[y * mx + x] = t[x * m + y];
            }
        }
    }

    /// z slabs `[z][y][kx]` of `fields` to y slabs `[y][kx][z]` (all-to-all).
    fn to_rows(&self, comm: &dyn Comm, fields: &[Vec<Complex64>]) -> Vec<Vec<Complex64>> {
        let (m, mx) = (self.m, self.mx);
        let (zs, ys) = (self.share(self.me), self.share(self.me));
        self.transpose(
            comm,
            fields,
            ys.len(),
            Side {
                block: |r| (0..zs.len(), self.share(r)),
                index: |z, y, x| (z * m + y) * mx + x,
            },
            Side {
                block: |r| (self.share(r), 0..ys.len()),
                index: |z, y, x| (y * mx + x) * m + z,
            },
        )
    }

    /// y slabs `[y][kx][z]` back to z slabs `[z][y][kx]` (all-to-all).
    fn to_planes(&self, comm: &dyn Comm, fields: &[Vec<Complex64>]) -> Vec<Vec<Complex64>> {
        let (m, mx) = (self.m, self.mx);
        let (zs, ys) = (self.share(self.me), self.share(self.me));
        self.transpose(
            comm,
            fields,
            zs.len(),
            Side {
                block: |r| (self.share(r), 0..ys.len()),
                index: |z, y, x| (y * mx + x) * m + z,
            },
            Side {
                block: |r| (0..zs.len(), self.share(r)),
                index: |z, y, x| (z * m + y) * mx + x,
            },
        )
    }

    /// All-to-all of blocks: to rank `r` the elements `src(z, y, x)` for `(z, y)` in
    /// `send(r)` (z outer) and every `x < mx`; from rank `r` into `dst(z, y, x)` over `recv(r)`
    /// in the same order (`send` and `src` the sending side's block and index, `recv` and `dst`
    /// the receiving side's). The result holds `len M mx` elements per field.
    fn transpose(
        &self,
        comm: &dyn Comm,
        fields: &[Vec<Complex64>],
        len: usize,
        sending: Side<impl Fn(usize) -> Block + Sync, impl Fn(usize, usize, usize) -> usize + Sync>,
        receiving: Side<
            impl Fn(usize) -> Block + Sync,
            impl Fn(usize, usize, usize) -> usize + Sync,
        >,
    ) -> Vec<Vec<Complex64>> {
        let Side {
            block: send,
            index: src,
        } = sending;
        let Side {
            block: recv,
            index: dst,
        } = receiving;
        let (m, mx, me) = (self.m, self.mx, self.me);
        // This rank's own block is copied directly below, not sent to itself.
        let messages = (0..self.ranks)
            .into_par_iter()
            .map(|r| {
                if r == me {
                    return Vec::new();
                }
                let (zr, yr) = send(r);
                let mut v = Vec::with_capacity(fields.len() * zr.len() * yr.len() * mx * 2);
                for f in fields {
                    for z in zr.clone() {
                        for y in yr.clone() {
                            for x in 0..mx {
                                let c = f[src(z, y, x)];
                                v.extend([c.re, c.im]);
                            }
                        }
                    }
                }
                v
            })
            .collect();
        let got = comm.exchange(messages);
        let mut out = vec![vec![Complex64::default(); len * m * mx]; fields.len()];
        out.par_iter_mut().enumerate().for_each(|(k, f)| {
            let (zs, ys) = send(me);
            let (zd, yd) = recv(me);
            for (z0, z1) in zs.zip(zd) {
                for (y0, y1) in ys.clone().zip(yd.clone()) {
                    for x in 0..mx {
                        f[dst(z1, y1, x)] = fields[k][src(z0, y0, x)];
                    }
                }
            }
            for (r, msg) in got.iter().enumerate() {
                if r == me {
                    continue;
                }
                let (zr, yr) = recv(r);
                let block = 2 * zr.len() * yr.len() * mx;
                let mut it = msg[k * block..(k + 1) * block].chunks_exact(2);
                for z in zr {
                    for y in yr.clone() {
                        for x in 0..mx {
                            let c = it.next().expect("a full block");
                            f[dst(z, y, x)] = Complex64::new(c[0], c[1]);
                        }
                    }
                }
            }
        });
        out
    }

    /// The distributed forward FFT: real fields on this rank's planes (`[z][y][x]`, overwritten)
    /// to their half spectra on its y rows (`[y][kx][z]`, unnormalised).
    pub(crate) fn forward(&self, comm: &dyn Comm, fields: &mut [Vec<f64>]) -> Vec<Vec<Complex64>> {
        let spectra: Vec<Vec<Complex64>> = fields.iter_mut().map(|f| self.forward_xy(f)).collect();
        let mut rows = self.to_rows(comm, &spectra);
        drop(spectra);
        let fz = &self.fft;
        for f in rows.iter_mut() {
            f.par_chunks_mut(self.m).for_each(|line| fz.process(line));
        }
        rows
    }

    /// [`Self::forward`] undone (unnormalised: `M^3` times the field).
    pub(crate) fn inverse(&self, comm: &dyn Comm, mut rows: Vec<Vec<Complex64>>) -> Vec<Vec<f64>> {
        let fi = &self.ifft;
        for f in rows.iter_mut() {
            f.par_chunks_mut(self.m).for_each(|line| fi.process(line));
        }
        let mut planes = self.to_planes(comm, &rows);
        drop(rows);
        planes.iter_mut().map(|f| self.inverse_xy(f)).collect()
    }
}

/// The distributed FFT alone, as the shared sums use it, for benchmarks (BENCHMARKS.md compares it with
/// FFTW's MPI interface): `reps` round trips (forward, then inverse) of `fields` real fields
/// on an `m^3` grid split among the ranks of `comm` as the shared sums split it (collective).
/// Returns this rank's median seconds per round trip and the largest error of the round trip
/// against the input (scaled by `m^3`), relative to the input's largest value, over this
/// rank's planes.
pub fn fft_round_trip(comm: &dyn Comm, m: usize, fields: usize, reps: usize) -> (f64, f64) {
    let grid = SlabFft::new(m, comm);
    let own = grid.share(grid.me);
    let plane = m * m;
    // A deterministic field of every global index, the same on any rank count.
    let input: Vec<Vec<f64>> = (0..fields)
        .map(|f| {
            (own.start * plane..own.end * plane)
                .map(|k| ((k * 7 + f * 13) as f64 * 0.618_033_988_7).fract() - 0.5)
                .collect()
        })
        .collect();
    let mut times = Vec::with_capacity(reps);
    let mut error = 0.0f64;
    for _ in 0..reps.max(1) {
        let mut data = input.clone();
        // Every rank starts together (a reduction as a barrier), as FFTW's twin does.
        comm.max(&mut [0.0]);
        let t = std::time::Instant::now();
        let rows = grid.forward(comm, &mut data);
        let back = grid.inverse(comm, rows);
        times.push(t.elapsed().as_secs_f64());
        let scale = 1.0 / (m * m * m) as f64;
        for (a, b) in back.iter().zip(&input) {
            for (x, y) in a.iter().zip(b) {
                error = error.max((x * scale - y).abs() / 0.5);
            }
        }
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], error)
}
