//! The CUDA device: cudarc over the driver, NVRTC and cuFFT, each loaded at run time.
#![allow(unsafe_code)]

use crate::buffer::{Data, Element};
use crate::error::{DeviceInfo, GpuError};
use crate::kernel::{Arg, THREADS};
use cudarc::cufft::{CudaFft, sys::cufftType, sys::double2};
use cudarc::driver::{
    CudaContext, CudaFunction, CudaSlice, CudaStream, DevicePtrMut, LaunchConfig, PushKernelArg,
};
use std::collections::HashMap;
use std::sync::Arc;

fn driver(e: impl std::fmt::Debug) -> GpuError {
    GpuError::Driver(format!("{e:?}"))
}

fn fft(e: impl std::fmt::Debug) -> GpuError {
    GpuError::Fft(format!("{e:?}"))
}

/// Whether the driver library, NVRTC and cuFFT load. cudarc panics on the first call into a
/// library it cannot load, so this runs before any such call.
fn libraries_present() -> Result<(), GpuError> {
    // SAFETY: these functions only try to open shared libraries by name (dlopen) and close
    // them again; they call no CUDA function.
    let (cuda, nvrtc, cufft) = unsafe {
        (
            cudarc::driver::sys::is_culib_present(),
            cudarc::nvrtc::sys::is_culib_present(),
            cudarc::cufft::sys::is_culib_present(),
        )
    };
    let missing: Vec<&str> = [
        (cuda, "the driver library libcuda"),
        (nvrtc, "NVRTC (libnvrtc)"),
        (cufft, "cuFFT (libcufft)"),
    ]
    .iter()
    .filter(|(ok, _)| !ok)
    .map(|(_, name)| *name)
    .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(GpuError::NoDevice(format!(
            "{} could not be loaded (a driver and the CUDA toolkit's libraries are needed at \
             run time)",
            missing.join(", ")
        )))
    }
}

pub(crate) fn probe() -> Result<DeviceInfo, GpuError> {
    libraries_present()?;
    let count = CudaContext::device_count().map_err(|e| GpuError::NoDevice(format!("{e:?}")))?;
    if count < 1 {
        return Err(GpuError::NoDevice("the driver reports no device".into()));
    }
    let ctx = CudaContext::new(0).map_err(|e| GpuError::NoDevice(format!("{e:?}")))?;
    ctx.bind_to_thread().map_err(driver)?;
    let (free_memory, _) = cudarc::driver::result::mem_get_info().map_err(driver)?;
    Ok(DeviceInfo {
        name: ctx.name().map_err(driver)?,
        memory: ctx.total_mem().map_err(driver)?,
        free_memory,
        compute_capability: ctx.compute_capability().map_err(driver)?,
    })
}

/// Device 0, its stream and the compiled kernels.
pub(crate) struct Cuda {
    name: String,
    stream: Arc<CudaStream>,
    functions: HashMap<String, CudaFunction>,
}

impl std::fmt::Debug for Cuda {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl Cuda {
    pub(crate) fn open(source: &str, kernels: &[&str]) -> Result<Self, GpuError> {
        let info = probe()?;
        let ctx = CudaContext::new(0).map_err(|e| GpuError::NoDevice(format!("{e:?}")))?;
        let stream = ctx.default_stream();
        // No fused multiply-adds: each a b + c rounds as on the CPU. The device's own virtual
        // architecture: NVRTC 12 defaults to compute_52, where atomicAdd on doubles (sm_60 and
        // later) does not exist.
        let (major, minor) = info.compute_capability;
        let opts = cudarc::nvrtc::CompileOptions {
            fmad: Some(false),
            options: vec![format!("--gpu-architecture=compute_{major}{minor}")],
            ..Default::default()
        };
        let ptx = cudarc::nvrtc::compile_ptx_with_opts(source, opts)
            .map_err(|e| GpuError::Compile(format!("{e:?}")))?;
        let module = ctx.load_module(ptx).map_err(|e| {
            GpuError::Driver(format!(
                "loading the kernels compiled for compute_{major}{minor}: {e:?} (a driver older \
                 than the NVRTC library refuses its PTX: update the driver)"
            ))
        })?;
        let mut functions = HashMap::new();
        for k in kernels {
            functions.insert(
                (*k).to_string(),
                module
                    .load_function(k)
                    .map_err(|e| GpuError::Compile(format!("kernel {k}: {e:?}")))?,
            );
        }
        Ok(Self {
            name: format!(
                "{} (compute capability {}.{}, {:.1} GiB)",
                info.name,
                info.compute_capability.0,
                info.compute_capability.1,
                info.memory as f64 / (1u64 << 30) as f64
            ),
            stream,
            functions,
        })
    }

    pub(crate) fn describe(&self) -> String {
        format!("CUDA device 0: {}", self.name)
    }

    /// Wait for the stream's queued work.
    pub(crate) fn wait(&self) -> Result<(), GpuError> {
        self.stream.synchronize().map_err(driver)
    }

    /// `(bytes in use, total bytes)`.
    pub(crate) fn memory(&self) -> Result<(usize, usize), GpuError> {
        self.stream.context().bind_to_thread().map_err(driver)?;
        // Freed buffers go back to the driver's pool at a synchronisation (its release
        // threshold is 0), so what is in use is read after one.
        self.stream.synchronize().map_err(driver)?;
        let (free, total) = cudarc::driver::result::mem_get_info().map_err(driver)?;
        Ok((total - free, total))
    }

    pub(crate) fn upload<T: Element>(&self, data: &[T]) -> Result<CudaSlice<T>, GpuError> {
        if data.is_empty() {
            return self.zeros(0);
        }
        self.stream.clone_htod(data).map_err(driver)
    }

    pub(crate) fn upload_into<T: Element>(
        &self,
        data: &[T],
        s: &mut CudaSlice<T>,
    ) -> Result<(), GpuError> {
        if data.is_empty() {
            return Ok(());
        }
        self.stream.memcpy_htod(data, s).map_err(driver)
    }

    pub(crate) fn zeros<T: Element>(&self, len: usize) -> Result<CudaSlice<T>, GpuError> {
        // A zero-length allocation is refused by the driver: one value stands behind an empty
        // buffer (its `Buffer::len` stays 0).
        self.stream.alloc_zeros::<T>(len.max(1)).map_err(driver)
    }

    pub(crate) fn zero<T: Element>(&self, s: &mut CudaSlice<T>) -> Result<(), GpuError> {
        self.stream.memset_zeros(s).map_err(driver)
    }

    pub(crate) fn download<T: Element>(&self, s: &CudaSlice<T>) -> Result<Vec<T>, GpuError> {
        self.stream.clone_dtoh(s).map_err(driver)
    }

    pub(crate) fn download_range<T: Element>(
        &self,
        s: &CudaSlice<T>,
        at: usize,
        len: usize,
    ) -> Result<Vec<T>, GpuError> {
        self.stream
            .clone_dtoh(&s.slice(at..at + len))
            .map_err(driver)
    }

    /// cuFFT plans of `batch` transforms of `m^3` grids: forward (D2Z) where `forward`, inverse
    /// (Z2D) where `inverse`.
    pub(crate) fn fft3(
        &self,
        m: usize,
        batch: usize,
        forward: bool,
        inverse: bool,
        in_place: bool,
    ) -> Result<(Option<CudaFft>, Option<CudaFft>), GpuError> {
        let int = |v: usize, what: &str| {
            i32::try_from(v).map_err(|_| GpuError::Input(format!("{what} {v} exceeds cuFFT's int")))
        };
        let n = [int(m, "grid size")?; 3];
        let real = int(m * m * m, "grid points")?;
        let half = int(m * m * (m / 2 + 1), "half-spectrum size")?;
        // In place: each field's real values padded to rows of 2 (m/2 + 1), its half spectrum
        // over them (cuFFT's layout for in-place real transforms), the padded dimensions given
        // to the plan.
        let b = int(batch, "batch")?;
        let padded = int(2 * m * m * (m / 2 + 1), "padded grid values")?;
        let real_embed = [n[0], n[1], int(2 * (m / 2 + 1), "padded row")?];
        let half_embed = [n[0], n[1], int(m / 2 + 1, "half row")?];
        let plan = |kind, (inembed, idist): (Option<&[i32]>, i32), (onembed, odist)| {
            CudaFft::plan_many(
                &n,
                inembed,
                1,
                idist,
                onembed,
                1,
                odist,
                kind,
                b,
                self.stream.clone(),
            )
            .map_err(fft)
        };
        let (real, half) = if in_place {
            (
                (Some(&real_embed[..]), padded),
                (Some(&half_embed[..]), half),
            )
        } else {
            ((None, real), (None, half))
        };
        Ok((
            if forward {
                Some(plan(cufftType::CUFFT_D2Z, real, half)?)
            } else {
                None
            },
            if inverse {
                Some(plan(cufftType::CUFFT_Z2D, half, real)?)
            } else {
                None
            },
        ))
    }

    /// An in-place batch of `plan` over `len` values of `buf` from `at` (the padded fields,
    /// or their spectra): forward (D2Z) or inverse (Z2D).
    pub(crate) fn fft_in_place(
        &self,
        plan: Option<&CudaFft>,
        buf: &mut CudaSlice<f64>,
        at: usize,
        len: usize,
        forward: bool,
    ) -> Result<(), GpuError> {
        let plan = plan.ok_or_else(|| GpuError::Input("no plan for this direction".into()))?;
        let mut view = buf.slice_mut(at..at + len);
        let (ptr, _record) = view.device_ptr_mut(&self.stream);
        // SAFETY: the plan was made for in-place transforms of the batch's padded fields
        // (fft3 with in_place), exactly `len` values from `at` inside the caller's checked
        // range; the pointer is this view's, valid while `_record` lives, on the plan's
        // stream; an even f64 offset keeps double2's alignment.
        unsafe {
            if forward {
                cudarc::cufft::result::exec_d2z(plan.handle(), ptr as *mut f64, ptr as *mut double2)
            } else {
                cudarc::cufft::result::exec_z2d(plan.handle(), ptr as *mut double2, ptr as *mut f64)
            }
        }
        .map_err(fft)
    }

    /// # Safety
    /// As `Device::launch`.
    pub(crate) unsafe fn launch(
        &self,
        kernel: &str,
        blocks: u32,
        args: &mut [Arg<'_>],
    ) -> Result<(), GpuError> {
        let f = self
            .functions
            .get(kernel)
            .ok_or_else(|| GpuError::Input(format!("no kernel {kernel} was compiled")))?;
        let mut b = self.stream.launch_builder(f);
        for a in args.iter_mut() {
            match a {
                Arg::InF64(buf) => push_in(&mut b, &buf.data)?,
                Arg::OutF64(buf) => push_out(&mut b, &mut buf.data)?,
                Arg::InI32(buf) => push_in(&mut b, &buf.data)?,
                Arg::OutI32(buf) => push_out(&mut b, &mut buf.data)?,
                Arg::InU32(buf) => push_in(&mut b, &buf.data)?,
                Arg::OutU32(buf) => push_out(&mut b, &mut buf.data)?,
                Arg::Int(i) => {
                    b.arg(&*i);
                }
                Arg::Long(i) => {
                    b.arg(&*i);
                }
                Arg::Real(x) => {
                    b.arg(&*x);
                }
            }
        }
        let cfg = LaunchConfig {
            grid_dim: (blocks, 1, 1),
            block_dim: (THREADS, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: the arguments match the kernel's parameters and its indices stay inside
        // the buffers: the caller's contract.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(())
    }
}

/// Bytes of the work area cuFFT holds for `plan` (0 for none).
pub(crate) fn work_size(plan: Option<&CudaFft>) -> Result<usize, GpuError> {
    match plan {
        // SAFETY: the handle is a live plan (the CudaFft owns it); cufftGetSize only reads it.
        Some(p) => unsafe { cudarc::cufft::result::get_size(p.handle()) }.map_err(fft),
        None => Ok(0),
    }
}

/// What one execution of a plan covers: its batch's real values and half-spectrum values.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BatchSizes {
    /// `f64` values of the batch's real fields.
    pub(crate) real: usize,
    /// Complex values of the batch's half spectra (`2 half` values of `f64`).
    pub(crate) half: usize,
}

/// The batch of forward transforms of a plan: `sizes.real` real values from `real_at`, into
/// the half spectra from `spectra_at` (`2 sizes.half` values).
pub(crate) fn forward(
    plan: &CudaFft,
    real: &CudaSlice<f64>,
    real_at: usize,
    spectra: &mut CudaSlice<f64>,
    spectra_at: usize,
    sizes: BatchSizes,
) -> Result<(), GpuError> {
    let BatchSizes { real: len, half } = sizes;
    let src = real.slice(real_at..real_at + len);
    let mut dst = spectra.slice_mut(spectra_at..spectra_at + 2 * half);
    // SAFETY: double2 is two f64 (no padding, the alignment of an f64 pair: the offsets are
    // even counts of f64 from a cudaMalloc'd base); the view covers exactly 2 half values.
    let mut view = unsafe { dst.transmute_mut::<double2>(half) }
        .ok_or_else(|| GpuError::Input("a spectrum buffer too short".into()))?;
    plan.exec_d2z(&src, &mut view).map_err(fft)
}

/// The batch of inverse transforms of a plan (the spectra are overwritten), as [`forward`].
pub(crate) fn inverse(
    plan: &CudaFft,
    spectra: &mut CudaSlice<f64>,
    spectra_at: usize,
    real: &mut CudaSlice<f64>,
    real_at: usize,
    sizes: BatchSizes,
) -> Result<(), GpuError> {
    let BatchSizes { real: len, half } = sizes;
    let mut src = spectra.slice_mut(spectra_at..spectra_at + 2 * half);
    let mut dst = real.slice_mut(real_at..real_at + len);
    // SAFETY: as in `forward`.
    let mut view = unsafe { src.transmute_mut::<double2>(half) }
        .ok_or_else(|| GpuError::Input("a spectrum buffer too short".into()))?;
    plan.exec_z2d(&mut view, &mut dst).map_err(fft)
}

/// Copy `len` values of `src` from `src_at` into `dst` from `dst_at`.
pub(crate) fn copy<T: Element>(
    c: &Cuda,
    src: &CudaSlice<T>,
    src_at: usize,
    dst: &mut CudaSlice<T>,
    dst_at: usize,
    len: usize,
) -> Result<(), GpuError> {
    let from = src.slice(src_at..src_at + len);
    let mut to = dst.slice_mut(dst_at..dst_at + len);
    c.stream.memcpy_dtod(&from, &mut to).map_err(driver)
}

/// Push a buffer the kernel reads.
fn push_in<'a, T: Element>(
    b: &mut cudarc::driver::LaunchArgs<'a>,
    d: &'a Data<T>,
) -> Result<(), GpuError> {
    match d {
        Data::Cuda(s) => {
            b.arg(s);
            Ok(())
        }
        _ => Err(GpuError::foreign()),
    }
}

/// Push a buffer the kernel writes.
fn push_out<'a, T: Element>(
    b: &mut cudarc::driver::LaunchArgs<'a>,
    d: &'a mut Data<T>,
) -> Result<(), GpuError> {
    match d {
        Data::Cuda(s) => {
            b.arg(s);
            Ok(())
        }
        _ => Err(GpuError::foreign()),
    }
}
