//! Three-dimensional complex FFT on a contiguous array, parallel over lines with rayon.
//!
//! Layout: index `(i2 * n1 + i1) * n0 + i0`, axis 0 fastest. Unnormalised in both directions
//! (`Forward` uses `exp(-i k x)`, `Inverse` `exp(+i k x)`), like FFTW. Each 1D line is
//! transformed by rustfft independently of how the lines are split among threads, so the result
//! is bit-identical for any thread count.
//!
//! Axis 0 is transformed in place; axes 1 and 2 are gathered into contiguous scratch lines in
//! blocks, transformed, and scattered back.

use num_complex::Complex64;
use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftDirection, FftPlanner};
use std::sync::Arc;

/// Direction of a transform.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// `sum_x f(x) exp(-i k x)`.
    Forward,
    /// `sum_k F(k) exp(+i k x)`.
    Inverse,
}

/// A planned 3D complex FFT of fixed shape.
pub struct Fft3 {
    shape: [usize; 3],
    fwd: [Arc<dyn Fft<f64>>; 3],
    inv: [Arc<dyn Fft<f64>>; 3],
    /// Reused transpose buffer for the slowest axis: a fresh full-size allocation per call was
    /// page-faulted anew each time, and page faults serialise across threads. Taken out for
    /// the duration of a transform (a concurrent caller allocates its own).
    scratch: std::sync::Mutex<Vec<Complex64>>,
}

impl Clone for Fft3 {
    fn clone(&self) -> Self {
        Self {
            shape: self.shape,
            fwd: self.fwd.clone(),
            inv: self.inv.clone(),
            scratch: Default::default(),
        }
    }
}

impl std::fmt::Debug for Fft3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fft3").field("shape", &self.shape).finish()
    }
}

/// Number of lines gathered together for the strided axes (keeps the gather cache-friendly).
const LINE_BLOCK: usize = 16;

impl Fft3 {
    /// Plan transforms of shape `[n0, n1, n2]` (axis 0 fastest).
    pub fn new(shape: [usize; 3]) -> Self {
        let mut planner = FftPlanner::new();
        let fwd = shape.map(|n| planner.plan_fft(n, FftDirection::Forward));
        let inv = shape.map(|n| planner.plan_fft(n, FftDirection::Inverse));
        Self {
            shape,
            fwd,
            inv,
            scratch: Default::default(),
        }
    }

    /// Shape `[n0, n1, n2]`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// Total number of elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// True for an empty shape.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Transform `data` in place.
    pub fn process(&self, data: &mut [Complex64], dir: Direction) {
        assert_eq!(
            data.len(),
            self.len(),
            "Fft3: buffer length does not match shape {:?}",
            self.shape
        );
        let [n0, n1, _] = self.shape;
        let plans = match dir {
            Direction::Forward => &self.fwd,
            Direction::Inverse => &self.inv,
        };
        // Axis 0: contiguous lines, one z-plane per task.
        let p0 = &plans[0];
        data.par_chunks_mut(n0 * n1).for_each_init(
            || vec![Complex64::default(); p0.get_inplace_scratch_len()],
            |scratch, plane| p0.process_with_scratch(plane, scratch),
        );
        self.process_strided_axes(data, dir);
    }

    /// Transform axes 1 and 2 only (the strided ones), in place.
    fn process_strided_axes(&self, data: &mut [Complex64], dir: Direction) {
        let [n0, n1, n2] = self.shape;
        let plans = match dir {
            Direction::Forward => &self.fwd,
            Direction::Inverse => &self.inv,
        };
        // Axis 1: lines of stride n0 inside each z-plane.
        let p1 = &plans[1];
        data.par_chunks_mut(n0 * n1).for_each_init(
            || {
                (
                    vec![Complex64::default(); n1 * LINE_BLOCK],
                    vec![Complex64::default(); p1.get_inplace_scratch_len()],
                )
            },
            |(lines, scratch), plane| {
                for b0 in (0..n0).step_by(LINE_BLOCK) {
                    let nb = LINE_BLOCK.min(n0 - b0);
                    for i1 in 0..n1 {
                        let row = &plane[i1 * n0 + b0..i1 * n0 + b0 + nb];
                        for (k, v) in row.iter().enumerate() {
                            lines[k * n1 + i1] = *v;
                        }
                    }
                    p1.process_with_scratch(&mut lines[..nb * n1], scratch);
                    for i1 in 0..n1 {
                        let row = &mut plane[i1 * n0 + b0..i1 * n0 + b0 + nb];
                        for (k, v) in row.iter_mut().enumerate() {
                            *v = lines[k * n1 + i1];
                        }
                    }
                }
            },
        );
        // Axis 2: lines of stride n0*n1. Each task gathers the lines of one (i1, i0-block) into
        // a local buffer (runs of LINE_BLOCK contiguous values per plane), transforms them and
        // stores them transposed back into runs in `t`, laid out (i1, block, i2, k); each plane
        // then copies its runs back. Every access is a contiguous run: scattering single values
        // with a stride of n2 (an earlier layout) missed the cache and the TLB on every value.
        let p2 = &plans[2];
        let plane_len = n0 * n1;
        let nb = n0.div_ceil(LINE_BLOCK);
        let run = n2 * LINE_BLOCK;
        let mut t = std::mem::take(&mut *self.scratch.lock().unwrap_or_else(|e| e.into_inner()));
        t.resize(n1 * nb * run, Complex64::default());
        {
            let src = &*data;
            t.par_chunks_mut(run).enumerate().for_each_init(
                || {
                    (
                        vec![Complex64::default(); run],
                        vec![Complex64::default(); p2.get_inplace_scratch_len()],
                    )
                },
                |(lines, scratch), (task, out)| {
                    let (i1, b0) = (task / nb, (task % nb) * LINE_BLOCK);
                    let w = LINE_BLOCK.min(n0 - b0);
                    for i2 in 0..n2 {
                        let at = i2 * plane_len + i1 * n0 + b0;
                        for (k, v) in src[at..at + w].iter().enumerate() {
                            lines[k * n2 + i2] = *v;
                        }
                    }
                    p2.process_with_scratch(&mut lines[..w * n2], scratch);
                    for i2 in 0..n2 {
                        for k in 0..w {
                            out[i2 * LINE_BLOCK + k] = lines[k * n2 + i2];
                        }
                    }
                },
            );
        }
        data.par_chunks_mut(plane_len)
            .enumerate()
            .for_each(|(i2, plane)| {
                for i1 in 0..n1 {
                    for blk in 0..nb {
                        let b0 = blk * LINE_BLOCK;
                        let w = LINE_BLOCK.min(n0 - b0);
                        let at = ((i1 * nb + blk) * n2 + i2) * LINE_BLOCK;
                        plane[i1 * n0 + b0..i1 * n0 + b0 + w].copy_from_slice(&t[at..at + w]);
                    }
                }
            });
        *self.scratch.lock().unwrap_or_else(|e| e.into_inner()) = t;
    }
}

/// A planned 3D real-to-complex FFT: a real array of shape `[n0, n1, n2]` (axis 0 fastest) and
/// its half spectrum of shape `[n0 / 2 + 1, n1, n2]` (the other half is the complex conjugate).
/// Axis 0 by realfft, axes 1 and 2 by the complex machinery of [`Fft3`]; unnormalised, and
/// bit-identical for any thread count like [`Fft3`].
pub struct RealFft3 {
    shape: [usize; 3],
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    half: Fft3,
}

impl std::fmt::Debug for RealFft3 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RealFft3")
            .field("shape", &self.shape)
            .finish()
    }
}

impl Clone for RealFft3 {
    fn clone(&self) -> Self {
        Self {
            shape: self.shape,
            r2c: self.r2c.clone(),
            c2r: self.c2r.clone(),
            half: self.half.clone(),
        }
    }
}

impl RealFft3 {
    /// Plan transforms of real shape `[n0, n1, n2]`.
    pub fn new(shape: [usize; 3]) -> Self {
        let mut planner = RealFftPlanner::<f64>::new();
        Self {
            shape,
            r2c: planner.plan_fft_forward(shape[0]),
            c2r: planner.plan_fft_inverse(shape[0]),
            half: Fft3::new([shape[0] / 2 + 1, shape[1], shape[2]]),
        }
    }

    /// Real shape `[n0, n1, n2]`.
    pub fn shape(&self) -> [usize; 3] {
        self.shape
    }

    /// Shape of the half spectrum, `[n0 / 2 + 1, n1, n2]`.
    pub fn complex_shape(&self) -> [usize; 3] {
        self.half.shape()
    }

    /// Number of real values.
    pub fn real_len(&self) -> usize {
        self.shape.iter().product()
    }

    /// Number of half-spectrum coefficients.
    pub fn complex_len(&self) -> usize {
        self.half.len()
    }

    /// `output = sum_x input(x) exp(-i k x)` on the half spectrum.
    pub fn forward(&self, input: &[f64], output: &mut [Complex64]) {
        assert_eq!(input.len(), self.real_len(), "RealFft3: real buffer length");
        let [n0, n1, _] = self.shape;
        self.forward_rows(
            |z, y, line| line.copy_from_slice(&input[(z * n1 + y) * n0..(z * n1 + y + 1) * n0]),
            output,
        );
    }

    /// [`Self::forward`] of the real array whose line `(z, y)` (`n0` values along axis 0)
    /// `row(z, y, line)` writes: lets a caller transform data in its own layout without a
    /// full copy first.
    pub fn forward_rows(
        &self,
        row: impl Fn(usize, usize, &mut [f64]) + Sync,
        output: &mut [Complex64],
    ) {
        assert_eq!(
            output.len(),
            self.complex_len(),
            "RealFft3: complex buffer length"
        );
        let [n0, n1, _] = self.shape;
        let h = n0 / 2 + 1;
        let r2c = &self.r2c;
        output.par_chunks_mut(h * n1).enumerate().for_each_init(
            || (vec![0.0; n0], r2c.make_scratch_vec()),
            |(line, scratch), (z, plane_out)| {
                for (y, row_out) in plane_out.chunks_mut(h).enumerate() {
                    row(z, y, line);
                    r2c.process_with_scratch(line, row_out, scratch)
                        .expect("RealFft3: buffer lengths are fixed by the plan");
                }
            },
        );
        self.half.process_strided_axes(output, Direction::Forward);
    }

    /// `output = sum_k input(k) exp(+i k x)` over the full spectrum that the half spectrum
    /// `input` stands for; `input` is overwritten. Imaginary parts that a real field cannot
    /// have (at `k0 = 0` and the Nyquist plane after the strided axes) are dropped, as taking
    /// the real part of a complex inverse would.
    pub fn inverse(&self, input: &mut [Complex64], output: &mut [f64]) {
        assert_eq!(
            output.len(),
            self.real_len(),
            "RealFft3: real buffer length"
        );
        assert_eq!(
            input.len(),
            self.complex_len(),
            "RealFft3: complex buffer length"
        );
        self.half.process_strided_axes(input, Direction::Inverse);
        let [n0, n1, _] = self.shape;
        let h = n0 / 2 + 1;
        let c2r = &self.c2r;
        input
            .par_chunks_mut(h * n1)
            .zip(output.par_chunks_mut(n0 * n1))
            .for_each_init(
                || c2r.make_scratch_vec(),
                |scratch, (plane_in, plane_out)| {
                    for (row_in, row_out) in plane_in.chunks_mut(h).zip(plane_out.chunks_mut(n0)) {
                        match c2r.process_with_scratch(row_in, row_out, scratch) {
                            Ok(()) | Err(realfft::FftError::InputValues(..)) => {}
                            Err(e) => panic!("RealFft3: {e}"),
                        }
                    }
                },
            );
    }

    /// [`Self::inverse`] handing each line `(z, y)` of the result to `put(y, line, plane)`,
    /// where `plane` is the `z`-th chunk of `plane_len` values of `out`: lets a caller store
    /// the result in its own layout without a full copy after.
    pub fn inverse_rows<T: Send>(
        &self,
        input: &mut [Complex64],
        out: &mut [T],
        plane_len: usize,
        put: impl Fn(usize, &[f64], &mut [T]) + Sync,
    ) {
        assert_eq!(
            input.len(),
            self.complex_len(),
            "RealFft3: complex buffer length"
        );
        let [n0, n1, n2] = self.shape;
        assert_eq!(out.len(), n2 * plane_len, "RealFft3: output planes");
        self.half.process_strided_axes(input, Direction::Inverse);
        let h = n0 / 2 + 1;
        let c2r = &self.c2r;
        input
            .par_chunks_mut(h * n1)
            .zip(out.par_chunks_mut(plane_len))
            .for_each_init(
                || (vec![0.0; n0], c2r.make_scratch_vec()),
                |(line, scratch), (plane_in, plane_out)| {
                    for (y, row_in) in plane_in.chunks_mut(h).enumerate() {
                        match c2r.process_with_scratch(row_in, line, scratch) {
                            Ok(()) | Err(realfft::FftError::InputValues(..)) => {}
                            Err(e) => panic!("RealFft3: {e}"),
                        }
                        put(y, line, plane_out);
                    }
                },
            );
    }
}

/// Smallest `n >= target` of the form `2^a 3^b 5^c`, even.
pub fn next_smooth_even(target: usize) -> usize {
    let mut n = target.max(2);
    if n % 2 == 1 {
        n += 1;
    }
    loop {
        let mut m = n;
        for p in [2, 3, 5] {
            while m.is_multiple_of(p) {
                m /= p;
            }
        }
        if m == 1 {
            return n;
        }
        n += 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn direct_dft(data: &[Complex64], shape: [usize; 3], sign: f64) -> Vec<Complex64> {
        let [n0, n1, n2] = shape;
        let mut out = vec![Complex64::default(); data.len()];
        for k2 in 0..n2 {
            for k1 in 0..n1 {
                for k0 in 0..n0 {
                    let mut acc = Complex64::default();
                    for x2 in 0..n2 {
                        for x1 in 0..n1 {
                            for x0 in 0..n0 {
                                let ph = sign
                                    * 2.0
                                    * PI
                                    * ((k0 * x0) as f64 / n0 as f64
                                        + (k1 * x1) as f64 / n1 as f64
                                        + (k2 * x2) as f64 / n2 as f64);
                                acc +=
                                    data[(x2 * n1 + x1) * n0 + x0] * Complex64::from_polar(1.0, ph);
                            }
                        }
                    }
                    out[(k2 * n1 + k1) * n0 + k0] = acc;
                }
            }
        }
        out
    }

    #[test]
    fn matches_direct_dft_on_odd_and_even_shapes() {
        for shape in [[4, 6, 5], [8, 3, 10], [1, 7, 2]] {
            let n: usize = shape.iter().product();
            let data: Vec<Complex64> = (0..n)
                .map(|i| Complex64::new((i as f64 * 0.37).sin(), (i as f64 * 1.3).cos()))
                .collect();
            let fft = Fft3::new(shape);
            for (dir, sign) in [(Direction::Forward, -1.0), (Direction::Inverse, 1.0)] {
                let mut fast = data.clone();
                fft.process(&mut fast, dir);
                let slow = direct_dft(&data, shape, sign);
                let err = fast
                    .iter()
                    .zip(&slow)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                assert!(
                    err < 1e-12 * n as f64,
                    "shape {shape:?} {dir:?}: max error {err:.2e}"
                );
            }
        }
    }

    #[test]
    fn real_transform_matches_complex_transform() {
        for shape in [[8, 6, 5], [6, 4, 4], [7, 3, 2]] {
            let n: usize = shape.iter().product();
            let real: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() + 0.1).collect();
            let mut full: Vec<Complex64> = real.iter().map(|&v| Complex64::new(v, 0.0)).collect();
            Fft3::new(shape).process(&mut full, Direction::Forward);
            let rfft = RealFft3::new(shape);
            let [h, n1, n2] = rfft.complex_shape();
            let mut half = vec![Complex64::default(); rfft.complex_len()];
            rfft.forward(&real, &mut half);
            let mut err: f64 = 0.0;
            for i2 in 0..n2 {
                for i1 in 0..n1 {
                    for i0 in 0..h {
                        let a = half[(i2 * n1 + i1) * h + i0];
                        let b = full[(i2 * n1 + i1) * shape[0] + i0];
                        err = err.max((a - b).norm());
                    }
                }
            }
            assert!(
                err < 1e-13 * n as f64,
                "shape {shape:?}: forward error {err:.2e}"
            );
            let mut back = vec![0.0; n];
            rfft.inverse(&mut half, &mut back);
            let err = real
                .iter()
                .zip(&back)
                .map(|(a, b)| (a * n as f64 - b).abs())
                .fold(0.0, f64::max);
            assert!(
                err < 1e-12 * n as f64,
                "shape {shape:?}: round trip error {err:.2e}"
            );
        }
    }

    #[test]
    fn smooth_sizes() {
        assert_eq!(next_smooth_even(1), 2);
        assert_eq!(next_smooth_even(14), 16);
        assert_eq!(next_smooth_even(98), 100);
        assert_eq!(next_smooth_even(129), 144);
    }
}
