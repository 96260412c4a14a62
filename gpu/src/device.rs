//! An open device (CUDA or the host emulation), its compiled kernels, and buffers on it.

use crate::buffer::{Buffer, Data, Element};
use crate::counters::Counters;
#[cfg(feature = "cuda")]
use crate::cuda;
use crate::error::GpuError;
use crate::host;
use crate::kernel::KernelSet;
use std::sync::Mutex;

/// Which device to open: the one way both models open theirs ([`Device::open`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// CUDA device 0 ([`GpuError::NoDevice`] where there is none, or without the `cuda`
    /// feature).
    Cuda,
    /// The host emulation of the same kernels (slow: for tests on machines without a GPU).
    HostEmulation,
}

impl Backend {
    /// `MOTILE_GPU_BACKEND`: unset or `cuda` for [`Backend::Cuda`], `emulation` for
    /// [`Backend::HostEmulation`]; any other value is an error naming the allowed ones.
    pub fn from_env() -> Result<Self, GpuError> {
        match std::env::var("MOTILE_GPU_BACKEND").as_deref() {
            Err(_) | Ok("") | Ok("cuda") => Ok(Backend::Cuda),
            Ok("emulation") => Ok(Backend::HostEmulation),
            Ok(other) => Err(GpuError::Input(format!(
                "MOTILE_GPU_BACKEND = \"{other}\": allowed \"cuda\" (the default) or \"emulation\""
            ))),
        }
    }
}

/// An open device and its compiled kernels.
#[derive(Debug)]
pub struct Device {
    pub(crate) inner: Inner,
    /// What it has been asked to do ([`Device::counters`]).
    counters: Mutex<Counters>,
}

#[derive(Debug)]
pub(crate) enum Inner {
    Host(host::Host),
    #[cfg(feature = "cuda")]
    Cuda(cuda::Cuda),
}

impl Device {
    /// Open `backend` with the kernels of `set` compiled (NVRTC, or the C++ compiler for the
    /// emulation), after checking each kernel's declaration against the source
    /// ([`KernelSet::check`]).
    pub fn open(backend: Backend, set: &KernelSet) -> Result<Self, GpuError> {
        set.check().map_err(GpuError::Input)?;
        let names = set.names();
        let inner = match backend {
            Backend::HostEmulation => Inner::Host(host::Host::compile(set.source, &names)?),
            #[cfg(feature = "cuda")]
            Backend::Cuda => Inner::Cuda(cuda::Cuda::open(set.source, &names)?),
            #[cfg(not(feature = "cuda"))]
            Backend::Cuda => {
                return Err(GpuError::NoDevice(
                    "built without CUDA support (feature `cuda`)".into(),
                ));
            }
        };
        Ok(Self {
            inner,
            counters: Mutex::new(Counters::default()),
        })
    }

    /// What this device has been asked to do since it was opened: launches, transforms and
    /// transfers ([`Counters::since`] for a part of the work).
    pub fn counters(&self) -> Counters {
        self.counters
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// Wait for the device's queued work (nothing to wait for on the host emulation).
    pub(crate) fn wait(&self) -> Result<(), GpuError> {
        match &self.inner {
            Inner::Host(_) => Ok(()),
            #[cfg(feature = "cuda")]
            Inner::Cuda(c) => c.wait(),
        }
    }

    /// Run `op` timed under `name` where profiling is on ([`crate::profile`]).
    pub(crate) fn timed<R>(
        &self,
        name: impl FnOnce() -> String,
        op: impl FnOnce() -> Result<R, GpuError>,
    ) -> Result<R, GpuError> {
        crate::fault::unusable()?;
        crate::profile::timed(name, || self.wait(), op)
    }

    /// Add to the counts.
    pub(crate) fn count(&self, f: impl FnOnce(&mut Counters)) {
        f(&mut self
            .counters
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner));
    }

    /// On the host emulation, run the blocks of every later launch in a new random order (`seed`
    /// nonzero; 0 restores the order in turn), so that a race between blocks shows as results
    /// that vary from launch to launch; returns whether it applies (not on CUDA, where the
    /// hardware chooses the order).
    pub fn shuffle_blocks(&self, seed: u64) -> bool {
        match &self.inner {
            Inner::Host(h) => {
                h.shuffle_blocks(seed);
                true
            }
            #[cfg(feature = "cuda")]
            Inner::Cuda(_) => false,
        }
    }

    /// The backend this device was opened on (to open another set of kernels beside it: CUDA
    /// opens device 0's primary context for every [`Device`], so their buffers are shared).
    pub fn backend(&self) -> Backend {
        match &self.inner {
            Inner::Host(_) => Backend::HostEmulation,
            #[cfg(feature = "cuda")]
            Inner::Cuda(_) => Backend::Cuda,
        }
    }

    /// What this device is, for logs and reports.
    pub fn describe(&self) -> String {
        match &self.inner {
            Inner::Host(h) => h.describe(),
            #[cfg(feature = "cuda")]
            Inner::Cuda(c) => c.describe(),
        }
    }

    /// `(bytes in use, total bytes)` of the device's memory (all processes), or `None` on the
    /// host emulation.
    pub fn memory(&self) -> Result<Option<(usize, usize)>, GpuError> {
        match &self.inner {
            Inner::Host(_) => Ok(None),
            #[cfg(feature = "cuda")]
            Inner::Cuda(c) => c.memory().map(Some),
        }
    }

    /// A buffer holding a copy of `data`.
    pub fn upload<T: Element>(&self, data: &[T]) -> Result<Buffer<T>, GpuError> {
        let len = data.len();
        self.count_upload::<T>(len);
        let data = self.timed(
            || "upload".into(),
            || {
                Ok(match &self.inner {
                    Inner::Host(_) => Data::Host(data.to_vec()),
                    #[cfg(feature = "cuda")]
                    Inner::Cuda(c) => Data::Cuda(c.upload(data)?),
                })
            },
        )?;
        Ok(Buffer::new(len, data))
    }

    /// Copy `data` into `buf`, which must have its length.
    pub fn upload_into<T: Element>(&self, data: &[T], buf: &mut Buffer<T>) -> Result<(), GpuError> {
        if data.len() != buf.len {
            return Err(GpuError::Input(format!(
                "{} values into a buffer of {}",
                data.len(),
                buf.len
            )));
        }
        self.count_upload::<T>(data.len());
        self.timed(
            || "upload".into(),
            || {
                match (&self.inner, &mut buf.data) {
                    (Inner::Host(_), Data::Host(v)) => v.copy_from_slice(data),
                    #[cfg(feature = "cuda")]
                    (Inner::Cuda(c), Data::Cuda(s)) => c.upload_into(data, s)?,
                    #[allow(unreachable_patterns)]
                    _ => return Err(GpuError::foreign()),
                }
                Ok(())
            },
        )
    }

    fn count_upload<T>(&self, len: usize) {
        self.count(|c| {
            c.uploads += 1;
            c.upload_bytes += (len * std::mem::size_of::<T>()) as u64;
        });
    }

    fn count_download<T>(&self, len: usize) {
        self.count(|c| {
            c.downloads += 1;
            c.download_bytes += (len * std::mem::size_of::<T>()) as u64;
        });
    }

    /// A buffer of `len` zeros.
    pub fn zeros<T: Element>(&self, len: usize) -> Result<Buffer<T>, GpuError> {
        let data = match &self.inner {
            Inner::Host(_) => Data::Host(vec![T::default(); len]),
            #[cfg(feature = "cuda")]
            Inner::Cuda(c) => Data::Cuda(c.zeros(len)?),
        };
        Ok(Buffer::new(len, data))
    }

    /// Set every value of `buf` to zero.
    pub fn zero<T: Element>(&self, buf: &mut Buffer<T>) -> Result<(), GpuError> {
        self.timed(
            || "zero".into(),
            || {
                match (&self.inner, &mut buf.data) {
                    (Inner::Host(_), Data::Host(v)) => v.fill(T::default()),
                    #[cfg(feature = "cuda")]
                    (Inner::Cuda(c), Data::Cuda(s)) => c.zero(s)?,
                    #[allow(unreachable_patterns)]
                    _ => return Err(GpuError::foreign()),
                }
                Ok(())
            },
        )
    }

    /// The values of `buf` (waits for the device's queued work).
    pub fn download<T: Element>(&self, buf: &Buffer<T>) -> Result<Vec<T>, GpuError> {
        if buf.len == 0 {
            return Ok(Vec::new());
        }
        self.count_download::<T>(buf.len);
        self.timed(
            || "download".into(),
            || match (&self.inner, &buf.data) {
                (Inner::Host(_), Data::Host(v)) => Ok(v.clone()),
                #[cfg(feature = "cuda")]
                (Inner::Cuda(c), Data::Cuda(s)) => c.download(s),
                #[allow(unreachable_patterns)]
                _ => Err(GpuError::foreign()),
            },
        )
    }

    /// `len` values of `buf` from `at` (waits for the device's queued work).
    pub fn download_range<T: Element>(
        &self,
        buf: &Buffer<T>,
        at: usize,
        len: usize,
    ) -> Result<Vec<T>, GpuError> {
        if at + len > buf.len {
            return Err(GpuError::Input(format!(
                "{len} values from {at} of a buffer of {}",
                buf.len
            )));
        }
        if len == 0 {
            return Ok(Vec::new());
        }
        self.count_download::<T>(len);
        self.timed(
            || "download".into(),
            || match (&self.inner, &buf.data) {
                (Inner::Host(_), Data::Host(v)) => Ok(v[at..at + len].to_vec()),
                #[cfg(feature = "cuda")]
                (Inner::Cuda(c), Data::Cuda(s)) => c.download_range(s, at, len),
                #[allow(unreachable_patterns)]
                _ => Err(GpuError::foreign()),
            },
        )
    }

    /// Copy `len` values of `src` from `src_at` into `dst` from `dst_at`.
    pub fn copy<T: Element>(
        &self,
        (src, src_at): (&Buffer<T>, usize),
        (dst, dst_at): (&mut Buffer<T>, usize),
        len: usize,
    ) -> Result<(), GpuError> {
        if src_at + len > src.len || dst_at + len > dst.len {
            return Err(GpuError::Input(format!(
                "copying {len} values from {src_at} of {} into {dst_at} of {}",
                src.len, dst.len
            )));
        }
        self.count(|c| {
            c.copies += 1;
            c.copy_bytes += (len * std::mem::size_of::<T>()) as u64;
        });
        self.timed(
            || "copy".into(),
            || match (&self.inner, &src.data, &mut dst.data) {
                (Inner::Host(_), Data::Host(a), Data::Host(b)) => {
                    b[dst_at..dst_at + len].copy_from_slice(&a[src_at..src_at + len]);
                    Ok(())
                }
                #[cfg(feature = "cuda")]
                (Inner::Cuda(c), Data::Cuda(a), Data::Cuda(b)) => {
                    cuda::copy(c, a, src_at, b, dst_at, len)
                }
                #[allow(unreachable_patterns)]
                _ => Err(GpuError::foreign()),
            },
        )
    }
}

/// Look for a CUDA device without using it: the driver library, NVRTC and cuFFT must load and
/// device 0 must answer. Without the `cuda` feature: [`GpuError::NoDevice`].
pub fn probe() -> Result<crate::error::DeviceInfo, GpuError> {
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

/// For tests: what `opened` holds (a device, or something opened on one of `backend`), or
/// `None` after printing why the test is skipped where there is no such device
/// ([`GpuError::NoDevice`]: no C++ compiler for the host emulation, no CUDA driver or GPU) and
/// the variable that requires one is unset: `MOTILE_REQUIRE_CXX` for the host emulation,
/// `MOTILE_REQUIRE_GPU` for CUDA. Any other failure, or a missing device that is required,
/// panics with the error.
pub fn open_or_skip<T>(opened: Result<T, GpuError>, backend: Backend) -> Option<T> {
    let required = match backend {
        Backend::HostEmulation => "MOTILE_REQUIRE_CXX",
        Backend::Cuda => "MOTILE_REQUIRE_GPU",
    };
    match opened {
        Ok(t) => Some(t),
        Err(GpuError::NoDevice(why)) if std::env::var_os(required).is_none() => {
            eprintln!("skipped ({why}); set {required}=1 to make this a failure");
            None
        }
        Err(e) => panic!("{backend:?}: {e} (set {required}=1 requires the device)"),
    }
}
