//! Devices for motile's GPU back-ends: device buffers of `f64`, kernels compiled at run time,
//! batched 3D real FFTs, in two implementations of one interface.
//!
//! - **CUDA** (feature `cuda`): the driver, NVRTC and cuFFT are loaded when a device is opened
//!   (cudarc's dynamic loading), so a build needs no CUDA toolkit, and a machine without a GPU
//!   gets [`GpuError::NoDevice`] instead of a panic. Kernels are CUDA C compiled by NVRTC;
//!   transforms are cuFFT's (`D2Z`/`Z2D`, unnormalised).
//! - **Host emulation** ([`Device::host_emulation`]): the *same kernel source* compiled by the
//!   system's C++ compiler with a small prelude that defines CUDA's thread indices and
//!   `atomicAdd`, every thread of every block run one after another on one CPU thread, and the
//!   transforms done by [`motile_analysis::fft3::RealFft3`] in cuFFT's layout and scaling. It is
//!   slow; it exists so that kernels, their argument lists and the host code around them are
//!   tested on machines without a GPU (where CI runs). It also checks every launch's argument
//!   list against the kernel's parameter types, which the CUDA driver cannot. A source that
//!   uses `__syncthreads` (block reductions in shared memory) runs each block's threads as OS
//!   threads with a barrier, one block at a time.
//!
//! Layouts: a real field of an `M^3` grid is `M^3` values, x fastest (`(z M + y) M + x`); its
//! half spectrum `M M (M/2 + 1)` complex values as interleaved `(re, im)` pairs, the x mode
//! fastest (`((kz M + ky)(M/2 + 1) + kx)`); a batch stores its fields one after another.
//!
//! The only unsafe code of the crate is in the modules that load libraries and launch kernels;
//! [`Device::launch`] itself is `unsafe`: nothing can check that a kernel indexes inside the
//! buffers it is given.

mod host;
mod launch;

#[cfg(feature = "cuda")]
mod cuda;

pub use launch::THREADS;

/// Why a device is unavailable or an operation on it failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No CUDA driver library, or no device, or (host emulation) no C++ compiler.
    #[error("no CUDA device found: {0}")]
    NoDevice(String),
    /// A driver call failed.
    #[error("CUDA driver: {0}")]
    Driver(String),
    /// The kernels did not compile (NVRTC, or the host compiler for the emulation).
    #[error("compiling the kernels: {0}")]
    Compile(String),
    /// A transform failed.
    #[error("FFT: {0}")]
    Fft(String),
    /// A call that does not fit: an unknown kernel, arguments that do not match its
    /// parameters, a buffer of another device or of the wrong length.
    #[error("{0}")]
    Input(String),
}

/// What [`probe`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    /// The device's name.
    pub name: String,
    /// Its memory in bytes.
    pub memory: usize,
    /// Compute capability (major, minor).
    pub compute_capability: (i32, i32),
}

/// Look for a CUDA device without using it: the driver library, NVRTC and cuFFT must load and
/// device 0 must answer. Without the `cuda` feature: [`GpuError::NoDevice`].
pub fn probe() -> Result<DeviceInfo, GpuError> {
    #[cfg(feature = "cuda")]
    {
        cuda::probe()
    }
    #[cfg(not(feature = "cuda"))]
    {
        Err(GpuError::NoDevice(
            "built without CUDA support (feature `cuda`)".into(),
        ))
    }
}

/// A buffer of `f64` on a device (complex values as interleaved pairs).
#[derive(Debug)]
pub struct Buffer {
    len: usize,
    data: Data,
}

#[derive(Debug)]
enum Data {
    Host(Vec<f64>),
    #[cfg(feature = "cuda")]
    Cuda(cudarc::driver::CudaSlice<f64>),
}

impl Buffer {
    /// Number of `f64` values.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds no values.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// One argument of a kernel launch, in the kernel's parameter order: `In` for a `const
/// double*` (or `const double2*`) parameter, `Out` for a `double*` (or `double2*`), `Int` for
/// an `int`, `Long` for a `long long`, `Real` for a `double`.
#[derive(Debug)]
pub enum Arg<'a> {
    /// A buffer the kernel only reads.
    In(&'a Buffer),
    /// A buffer the kernel writes.
    Out(&'a mut Buffer),
    /// An `int`.
    Int(i32),
    /// A `long long`.
    Long(i64),
    /// A `double`.
    Real(f64),
}

impl Arg<'_> {
    /// The host emulation's code for the parameter type this argument fits.
    fn code(&self) -> char {
        match self {
            Arg::In(_) => 'i',
            Arg::Out(_) => 'o',
            Arg::Int(_) => 'n',
            Arg::Long(_) => 'l',
            Arg::Real(_) => 'r',
        }
    }
}

/// A plan for batches of 3D real transforms of `M^3` grids.
#[derive(Debug)]
pub struct Fft3 {
    m: usize,
    batch: usize,
    direction: Direction,
    inner: FftInner,
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

    /// Complex values of one half spectrum, `M M (M/2 + 1)`.
    pub fn spectrum_len(&self) -> usize {
        self.m * self.m * (self.m / 2 + 1)
    }
}

/// An open device and its compiled kernels.
#[derive(Debug)]
pub struct Device {
    backend: Backend,
}

#[derive(Debug)]
enum Backend {
    Host(host::Host),
    #[cfg(feature = "cuda")]
    Cuda(cuda::Cuda),
}

fn foreign() -> GpuError {
    GpuError::Input("a buffer or plan of another device".into())
}

impl Device {
    /// CUDA device 0, with `kernels` (the names of `extern "C"` kernels in `source`) compiled
    /// by NVRTC.
    pub fn cuda(source: &str, kernels: &[&str]) -> Result<Self, GpuError> {
        #[cfg(feature = "cuda")]
        {
            Ok(Self {
                backend: Backend::Cuda(cuda::Cuda::open(source, kernels)?),
            })
        }
        #[cfg(not(feature = "cuda"))]
        {
            let _ = (source, kernels);
            Err(GpuError::NoDevice(
                "built without CUDA support (feature `cuda`)".into(),
            ))
        }
    }

    /// The host emulation (see the crate doc): `source` compiled by the C++ compiler named by
    /// `$CXX`, else the first of `c++`, `g++`, `clang++` found.
    pub fn host_emulation(source: &str, kernels: &[&str]) -> Result<Self, GpuError> {
        Ok(Self {
            backend: Backend::Host(host::Host::compile(source, kernels)?),
        })
    }

    /// What this device is, for logs and reports.
    pub fn describe(&self) -> String {
        match &self.backend {
            Backend::Host(h) => h.describe(),
            #[cfg(feature = "cuda")]
            Backend::Cuda(c) => c.describe(),
        }
    }

    /// `(bytes in use, total bytes)` of the device's memory (all processes), or `None` on the
    /// host emulation.
    pub fn memory(&self) -> Result<Option<(usize, usize)>, GpuError> {
        match &self.backend {
            Backend::Host(_) => Ok(None),
            #[cfg(feature = "cuda")]
            Backend::Cuda(c) => c.memory().map(Some),
        }
    }

    /// A buffer holding a copy of `data`.
    pub fn upload(&self, data: &[f64]) -> Result<Buffer, GpuError> {
        let len = data.len();
        let data = match &self.backend {
            Backend::Host(_) => Data::Host(data.to_vec()),
            #[cfg(feature = "cuda")]
            Backend::Cuda(c) => Data::Cuda(c.upload(data)?),
        };
        Ok(Buffer { len, data })
    }

    /// Copy `data` into `buf`, which must have its length.
    pub fn upload_into(&self, data: &[f64], buf: &mut Buffer) -> Result<(), GpuError> {
        if data.len() != buf.len {
            return Err(GpuError::Input(format!(
                "{} values into a buffer of {}",
                data.len(),
                buf.len
            )));
        }
        match (&self.backend, &mut buf.data) {
            (Backend::Host(_), Data::Host(v)) => v.copy_from_slice(data),
            #[cfg(feature = "cuda")]
            (Backend::Cuda(c), Data::Cuda(s)) => c.upload_into(data, s)?,
            #[allow(unreachable_patterns)]
            _ => return Err(foreign()),
        }
        Ok(())
    }

    /// A buffer of `len` zeros.
    pub fn zeros(&self, len: usize) -> Result<Buffer, GpuError> {
        let data = match &self.backend {
            Backend::Host(_) => Data::Host(vec![0.0; len]),
            #[cfg(feature = "cuda")]
            Backend::Cuda(c) => Data::Cuda(c.zeros(len)?),
        };
        Ok(Buffer { len, data })
    }

    /// Set every value of `buf` to zero.
    pub fn zero(&self, buf: &mut Buffer) -> Result<(), GpuError> {
        match (&self.backend, &mut buf.data) {
            (Backend::Host(_), Data::Host(v)) => v.fill(0.0),
            #[cfg(feature = "cuda")]
            (Backend::Cuda(c), Data::Cuda(s)) => c.zero(s)?,
            #[allow(unreachable_patterns)]
            _ => return Err(foreign()),
        }
        Ok(())
    }

    /// The values of `buf` (waits for the device's queued work).
    pub fn download(&self, buf: &Buffer) -> Result<Vec<f64>, GpuError> {
        if buf.len == 0 {
            return Ok(Vec::new());
        }
        match (&self.backend, &buf.data) {
            (Backend::Host(_), Data::Host(v)) => Ok(v.clone()),
            #[cfg(feature = "cuda")]
            (Backend::Cuda(c), Data::Cuda(s)) => c.download(s),
            #[allow(unreachable_patterns)]
            _ => Err(foreign()),
        }
    }

    /// `len` values of `buf` from `at` (waits for the device's queued work).
    pub fn download_range(
        &self,
        buf: &Buffer,
        at: usize,
        len: usize,
    ) -> Result<Vec<f64>, GpuError> {
        if at + len > buf.len {
            return Err(GpuError::Input(format!(
                "{len} values from {at} of a buffer of {}",
                buf.len
            )));
        }
        if len == 0 {
            return Ok(Vec::new());
        }
        match (&self.backend, &buf.data) {
            (Backend::Host(_), Data::Host(v)) => Ok(v[at..at + len].to_vec()),
            #[cfg(feature = "cuda")]
            (Backend::Cuda(c), Data::Cuda(s)) => c.download_range(s, at, len),
            #[allow(unreachable_patterns)]
            _ => Err(foreign()),
        }
    }

    /// A plan for batches of `batch` real transforms of `m^3` grids in the directions asked for.
    pub fn fft3(&self, m: usize, batch: usize, direction: Direction) -> Result<Fft3, GpuError> {
        if m < 2 || batch == 0 {
            return Err(GpuError::Input(format!(
                "an FFT plan of {batch} grids of {m}^3"
            )));
        }
        let inner = match &self.backend {
            Backend::Host(_) => FftInner::Host(motile_analysis::fft3::RealFft3::new([m; 3])),
            #[cfg(feature = "cuda")]
            Backend::Cuda(c) => {
                let (forward, inverse) = c.fft3(
                    m,
                    batch,
                    (
                        direction != Direction::Inverse,
                        direction != Direction::Forward,
                    ),
                )?;
                FftInner::Cuda { forward, inverse }
            }
        };
        Ok(Fft3 {
            m,
            batch,
            direction,
            inner,
        })
    }

    /// Forward transforms (`sum_x f(x) exp(-i k x)`) of the batch of real fields at
    /// `real[real_at..]` into the half spectra at `spectra[spectra_at..]` (offsets in `f64`
    /// values; the complex offset must be even).
    pub fn forward(
        &self,
        plan: &Fft3,
        (real, real_at): (&Buffer, usize),
        (spectra, spectra_at): (&mut Buffer, usize),
    ) -> Result<(), GpuError> {
        check_fft(plan, (real.len, real_at), (spectra.len, spectra_at))?;
        if plan.direction == Direction::Inverse {
            return Err(GpuError::Input(
                "a forward transform with an inverse-only plan".into(),
            ));
        }
        let (n, s) = (plan.real_len(), plan.spectrum_len());
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
            ) => cuda::forward(forward, (x, real_at, n), (y, spectra_at, plan.batch * s)),
            #[allow(unreachable_patterns)]
            _ => {
                let _ = n;
                Err(foreign())
            }
        }
    }

    /// Inverse transforms (`sum_k c(k) exp(+i k x)`, unnormalised) of the batch of half spectra
    /// at `spectra[spectra_at..]` (which may be overwritten, as cuFFT does) into the real
    /// fields at `real[real_at..]`.
    pub fn inverse(
        &self,
        plan: &Fft3,
        (spectra, spectra_at): (&mut Buffer, usize),
        (real, real_at): (&mut Buffer, usize),
    ) -> Result<(), GpuError> {
        check_fft(plan, (real.len, real_at), (spectra.len, spectra_at))?;
        if plan.direction == Direction::Forward {
            return Err(GpuError::Input(
                "an inverse transform with a forward-only plan".into(),
            ));
        }
        let (n, s) = (plan.real_len(), plan.spectrum_len());
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
            ) => cuda::inverse(inverse, (y, spectra_at, plan.batch * s), (x, real_at, n)),
            #[allow(unreachable_patterns)]
            _ => {
                let _ = n;
                Err(foreign())
            }
        }
    }

    /// Copy `len` values of `src` from `src_at` into `dst` from `dst_at`.
    pub fn copy(
        &self,
        (src, src_at): (&Buffer, usize),
        (dst, dst_at): (&mut Buffer, usize),
        len: usize,
    ) -> Result<(), GpuError> {
        if src_at + len > src.len || dst_at + len > dst.len {
            return Err(GpuError::Input(format!(
                "copying {len} values from {src_at} of {} into {dst_at} of {}",
                src.len, dst.len
            )));
        }
        match (&self.backend, &src.data, &mut dst.data) {
            (Backend::Host(_), Data::Host(a), Data::Host(b)) => {
                b[dst_at..dst_at + len].copy_from_slice(&a[src_at..src_at + len]);
                Ok(())
            }
            #[cfg(feature = "cuda")]
            (Backend::Cuda(c), Data::Cuda(a), Data::Cuda(b)) => {
                cuda::copy(c, (a, src_at), (b, dst_at), len)
            }
            #[allow(unreachable_patterns)]
            _ => Err(foreign()),
        }
    }
}

fn check_fft(
    plan: &Fft3,
    (real, real_at): (usize, usize),
    (complex, complex_at): (usize, usize),
) -> Result<(), GpuError> {
    if real_at + plan.real_len() > real
        || complex_at + plan.complex_len() > complex
        || complex_at % 2 != 0
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
