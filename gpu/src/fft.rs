//! Batched 3D real FFTs on a device: cuFFT's `D2Z`/`Z2D` (unnormalised), or on the host
//! emulation [`motile_analysis::fft3::RealFft3`] in cuFFT's layout and scaling.

use crate::buffer::{Buffer, Data};
#[cfg(feature = "cuda")]
use crate::cuda;
use crate::device::{Device, Inner};
use crate::error::GpuError;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A plan for batches of 3D real transforms of `M^3` grids.
#[derive(Debug)]
pub struct Fft3 {
    m: usize,
    batch: usize,
    direction: Direction,
    inner: FftInner,
    work: usize,
    /// In place: each field's half spectrum over its real values, which lie in cuFFT's
    /// padded layout (rows of `2 (M/2 + 1)` values, the last `2 (M/2 + 1) - M` unused).
    in_place: bool,
}

/// Bytes of the work areas that the FFT plans alive in this process hold (cuFFT's; none on
/// the host emulation).
static WORK: AtomicUsize = AtomicUsize::new(0);

/// Bytes of the work areas of the FFT plans alive now (every device of the process).
pub fn fft_work_bytes() -> usize {
    WORK.load(Ordering::Relaxed)
}

impl Drop for Fft3 {
    fn drop(&mut self) {
        WORK.fetch_sub(self.work, Ordering::Relaxed);
    }
}

enum FftInner {
    Host(motile_analysis::fft3::RealFft3),
    #[cfg(feature = "cuda")]
    Cuda {
        forward: Option<cudarc::cufft::CudaFft>,
        inverse: Option<cudarc::cufft::CudaFft>,
    },
}

/// Which transforms a plan does (each cuFFT plan holds a work area about the size of its data,
/// so a plan is made only for the directions asked for).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Real to half spectrum.
    Forward,
    /// Half spectrum to real.
    Inverse,
    /// Both.
    Both,
}

impl std::fmt::Debug for FftInner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FftInner::Host(_) => f.write_str("Host"),
            #[cfg(feature = "cuda")]
            FftInner::Cuda { .. } => f.write_str("cuFFT"),
        }
    }
}

impl Fft3 {
    /// `f64` values of a batch of real fields, `batch M^3`.
    pub fn real_len(&self) -> usize {
        self.batch * self.m.pow(3)
    }

    /// `f64` values of a batch of half spectra, `2 batch M M (M/2 + 1)`.
    pub fn complex_len(&self) -> usize {
        2 * self.batch * self.spectrum_len()
    }

    /// `f64` values of one field in the in-place layout, `2 M M (M/2 + 1)`: its padded real
    /// values, or its half spectrum.
    pub fn padded_field_len(&self) -> usize {
        2 * self.spectrum_len()
    }

    /// `f64` values of an in-place plan's batch, `batch` padded fields.
    pub fn padded_len(&self) -> usize {
        self.batch * self.padded_field_len()
    }

    /// Bytes of the work areas cuFFT holds for this plan (0 on the host emulation).
    pub fn work_bytes(&self) -> usize {
        self.work
    }

    /// Complex values of one half spectrum, `M M (M/2 + 1)`.
    pub fn spectrum_len(&self) -> usize {
        self.m * self.m * (self.m / 2 + 1)
    }
}

impl Device {
    /// A plan for batches of `batch` real transforms of `m^3` grids in the directions asked for.
    pub fn fft3(&self, m: usize, batch: usize, direction: Direction) -> Result<Fft3, GpuError> {
        self.plan(m, batch, direction, false)
    }

    /// A plan for batches of `batch` in-place real transforms of `m^3` grids: each field's
    /// real values in the padded layout (`x` rows of `2 (m/2 + 1)` values, see
    /// [`Fft3::padded_field_len`]) and its half spectrum in the same memory, for
    /// [`Self::forward_in_place`] and [`Self::inverse_in_place`]. Half the memory of a field
    /// and its spectrum apart.
    pub fn fft3_in_place(
        &self,
        m: usize,
        batch: usize,
        direction: Direction,
    ) -> Result<Fft3, GpuError> {
        self.plan(m, batch, direction, true)
    }

    fn plan(
        &self,
        m: usize,
        batch: usize,
        direction: Direction,
        in_place: bool,
    ) -> Result<Fft3, GpuError> {
        if m < 2 || batch == 0 {
            return Err(GpuError::Input(format!(
                "an FFT plan of {batch} grids of {m}^3"
            )));
        }
        let (inner, work) = match &self.inner {
            Inner::Host(_) => (
                FftInner::Host(motile_analysis::fft3::RealFft3::new([m; 3])),
                0,
            ),
            #[cfg(feature = "cuda")]
            Inner::Cuda(c) => {
                let forward = direction != Direction::Inverse;
                let inverse = direction != Direction::Forward;
                let (forward, inverse) = c.fft3(m, batch, forward, inverse, in_place)?;
                let work = crate::cuda::work_size(forward.as_ref())?
                    + crate::cuda::work_size(inverse.as_ref())?;
                (FftInner::Cuda { forward, inverse }, work)
            }
        };
        WORK.fetch_add(work, Ordering::Relaxed);
        Ok(Fft3 {
            m,
            batch,
            direction,
            inner,
            work,
            in_place,
        })
    }

    /// Forward transforms (`sum_x f(x) exp(-i k x)`) of the batch of real fields at
    /// `real[real_at..]` into the half spectra at `spectra[spectra_at..]` (offsets in `f64`
    /// values; the complex offset must be even).
    pub fn forward(
        &self,
        plan: &Fft3,
        real: &Buffer,
        real_at: usize,
        spectra: &mut Buffer,
        spectra_at: usize,
    ) -> Result<(), GpuError> {
        check_fft(plan, real.len, real_at, spectra.len, spectra_at)?;
        if plan.in_place {
            return Err(GpuError::Input(
                "an out-of-place transform with an in-place plan".into(),
            ));
        }
        if plan.direction == Direction::Inverse {
            return Err(GpuError::Input(
                "a forward transform with an inverse-only plan".into(),
            ));
        }
        self.count(|c| c.forward += plan.batch as u64);
        let (n, s) = (plan.real_len(), plan.spectrum_len());
        let name = || format!("forward FFT {}^3 x {}", plan.m, plan.batch);
        self.timed(name, || {
            match (&plan.inner, &real.data, &mut spectra.data) {
                (FftInner::Host(fft), Data::Host(x), Data::Host(y)) => {
                    let m3 = plan.m.pow(3);
                    let mut out = vec![num_complex::Complex64::default(); s];
                    for b in 0..plan.batch {
                        fft.forward(&x[real_at + b * m3..real_at + (b + 1) * m3], &mut out);
                        let y = &mut y[spectra_at + 2 * b * s..spectra_at + 2 * (b + 1) * s];
                        for (j, z) in out.iter().enumerate() {
                            y[2 * j] = z.re;
                            y[2 * j + 1] = z.im;
                        }
                    }
                    Ok(())
                }
                #[cfg(feature = "cuda")]
                (
                    FftInner::Cuda {
                        forward: Some(forward),
                        ..
                    },
                    Data::Cuda(x),
                    Data::Cuda(y),
                ) => {
                    let sizes = cuda::BatchSizes {
                        real: n,
                        half: plan.batch * s,
                    };
                    cuda::forward(forward, x, real_at, y, spectra_at, sizes)
                }
                #[allow(unreachable_patterns)]
                _ => {
                    let _ = n;
                    Err(GpuError::foreign())
                }
            }
        })
    }

    /// Inverse transforms (`sum_k c(k) exp(+i k x)`, unnormalised) of the batch of half spectra
    /// at `spectra[spectra_at..]` (which may be overwritten, as cuFFT does) into the real
    /// fields at `real[real_at..]`.
    pub fn inverse(
        &self,
        plan: &Fft3,
        spectra: &mut Buffer,
        spectra_at: usize,
        real: &mut Buffer,
        real_at: usize,
    ) -> Result<(), GpuError> {
        check_fft(plan, real.len, real_at, spectra.len, spectra_at)?;
        if plan.in_place {
            return Err(GpuError::Input(
                "an out-of-place transform with an in-place plan".into(),
            ));
        }
        if plan.direction == Direction::Forward {
            return Err(GpuError::Input(
                "an inverse transform with a forward-only plan".into(),
            ));
        }
        self.count(|c| c.inverse += plan.batch as u64);
        let (n, s) = (plan.real_len(), plan.spectrum_len());
        let name = || format!("inverse FFT {}^3 x {}", plan.m, plan.batch);
        self.timed(name, || {
            match (&plan.inner, &mut spectra.data, &mut real.data) {
                (FftInner::Host(fft), Data::Host(y), Data::Host(x)) => {
                    let m3 = plan.m.pow(3);
                    let mut spec = vec![num_complex::Complex64::default(); s];
                    for b in 0..plan.batch {
                        let y = &y[spectra_at + 2 * b * s..spectra_at + 2 * (b + 1) * s];
                        for (j, z) in spec.iter_mut().enumerate() {
                            *z = num_complex::Complex64::new(y[2 * j], y[2 * j + 1]);
                        }
                        fft.inverse(&mut spec, &mut x[real_at + b * m3..real_at + (b + 1) * m3]);
                    }
                    Ok(())
                }
                #[cfg(feature = "cuda")]
                (
                    FftInner::Cuda {
                        inverse: Some(inverse),
                        ..
                    },
                    Data::Cuda(y),
                    Data::Cuda(x),
                ) => {
                    let sizes = cuda::BatchSizes {
                        real: n,
                        half: plan.batch * s,
                    };
                    cuda::inverse(inverse, y, spectra_at, x, real_at, sizes)
                }
                #[allow(unreachable_patterns)]
                _ => {
                    let _ = n;
                    Err(GpuError::foreign())
                }
            }
        })
    }
}

impl Device {
    /// Forward transforms of the batch of padded real fields at `buf[at..]` into their half
    /// spectra, in place (offset in `f64` values, even), with a plan of
    /// [`Self::fft3_in_place`].
    pub fn forward_in_place(
        &self,
        plan: &Fft3,
        buf: &mut Buffer,
        at: usize,
    ) -> Result<(), GpuError> {
        self.in_place(plan, buf, at, true)
    }

    /// Inverse transforms (unnormalised) of the batch of half spectra at `buf[at..]` into
    /// their padded real fields, in place, as [`Self::forward_in_place`].
    pub fn inverse_in_place(
        &self,
        plan: &Fft3,
        buf: &mut Buffer,
        at: usize,
    ) -> Result<(), GpuError> {
        self.in_place(plan, buf, at, false)
    }

    fn in_place(
        &self,
        plan: &Fft3,
        buf: &mut Buffer,
        at: usize,
        forward: bool,
    ) -> Result<(), GpuError> {
        let len = plan.padded_len();
        if !plan.in_place || at + len > buf.len || !at.is_multiple_of(2) {
            return Err(GpuError::Input(format!(
                "in-place FFT of {} grids of {}^3 needs an in-place plan and {len} values from \
                 {at} (even); the buffer holds {}",
                plan.batch, plan.m, buf.len
            )));
        }
        let wrong = if forward {
            Direction::Inverse
        } else {
            Direction::Forward
        };
        if plan.direction == wrong {
            return Err(GpuError::Input(format!(
                "an in-place {} transform with a plan for the other direction",
                if forward { "forward" } else { "inverse" }
            )));
        }
        self.count(|c| {
            if forward {
                c.forward += plan.batch as u64;
            } else {
                c.inverse += plan.batch as u64;
            }
        });
        let name = || {
            format!(
                "{} FFT {}^3 x {} in place",
                if forward { "forward" } else { "inverse" },
                plan.m,
                plan.batch
            )
        };
        self.timed(name, || match (&plan.inner, &mut buf.data) {
            (FftInner::Host(fft), Data::Host(x)) => {
                host_in_place(fft, plan, &mut x[at..at + len], forward);
                Ok(())
            }
            #[cfg(feature = "cuda")]
            (
                FftInner::Cuda {
                    forward: f,
                    inverse: i,
                },
                Data::Cuda(x),
            ) => match (&self.inner, forward) {
                (Inner::Cuda(c), true) => c.fft_in_place(f.as_ref(), x, at, len, true),
                (Inner::Cuda(c), false) => c.fft_in_place(i.as_ref(), x, at, len, false),
                _ => Err(GpuError::foreign()),
            },
            #[allow(unreachable_patterns)]
            _ => Err(GpuError::foreign()),
        })
    }
}

/// The host emulation's in-place transforms of `x`, the batch's padded fields.
fn host_in_place(fft: &motile_analysis::fft3::RealFft3, plan: &Fft3, x: &mut [f64], forward: bool) {
    let m = plan.m;
    let (row, s) = (2 * (m / 2 + 1), plan.spectrum_len());
    let mut real = vec![0.0; m * m * m];
    let mut spec = vec![num_complex::Complex64::default(); s];
    for field in x.chunks_exact_mut(plan.padded_field_len()) {
        if forward {
            for (dst, src) in real.chunks_exact_mut(m).zip(field.chunks_exact(row)) {
                dst.copy_from_slice(&src[..m]);
            }
            fft.forward(&real, &mut spec);
            for (j, z) in spec.iter().enumerate() {
                field[2 * j] = z.re;
                field[2 * j + 1] = z.im;
            }
        } else {
            for (j, z) in spec.iter_mut().enumerate() {
                *z = num_complex::Complex64::new(field[2 * j], field[2 * j + 1]);
            }
            fft.inverse(&mut spec, &mut real);
            for (dst, src) in field.chunks_exact_mut(row).zip(real.chunks_exact(m)) {
                dst[..m].copy_from_slice(src);
                dst[m..].fill(0.0);
            }
        }
    }
}

/// An out-of-place batch of `plan` fits: its real values from `real_at` in a buffer of `real`
/// values, its spectra from `complex_at` (even) in one of `complex`.
fn check_fft(
    plan: &Fft3,
    real: usize,
    real_at: usize,
    complex: usize,
    complex_at: usize,
) -> Result<(), GpuError> {
    if real_at + plan.real_len() > real
        || complex_at + plan.complex_len() > complex
        || !complex_at.is_multiple_of(2)
    {
        return Err(GpuError::Input(format!(
            "FFT of {} grids of {}^3 needs {} real values from {real_at} and {} complex-pair \
             values from {complex_at} (even); the buffers hold {real} and {complex}",
            plan.batch,
            plan.m,
            plan.real_len(),
            plan.complex_len()
        )));
    }
    Ok(())
}
