//! The device side of [`super::GpuMeanField`]: loading CUDA, compiling the kernels, the
//! buffers, cuFFT plans and every kernel launch. The only module of the crate that allows
//! `unsafe`: a kernel launch cannot be checked by the compiler, so each one states why its
//! arguments match the kernel's signature in `kernels.cu` and why every index it touches lies
//! inside the buffers it is given.
#![allow(unsafe_code)]

use super::{DeviceInfo, GpuError, THREADS};
use crate::solver::{History, SpectralGrid};
use cudarc::cufft::{CudaFft, sys::cufftType, sys::double2};
use cudarc::driver::{
    CudaContext, CudaFunction, CudaSlice, CudaStream, LaunchConfig, PushKernelArg,
};
use num_complex::Complex64;
use std::sync::Arc;

/// The kernels' source (compiled by NVRTC when a device is opened).
const SOURCE: &str = include_str!("kernels.cu");

/// Flow speed below which the fixed point's change is measured absolutely (solver.rs
/// `FLOW_FLOOR`).
const FLOW_FLOOR: f64 = 1e-14;

fn driver(e: impl std::fmt::Debug) -> GpuError {
    GpuError::Driver(format!("{e:?}"))
}

fn fft(e: impl std::fmt::Debug) -> GpuError {
    GpuError::Fft(format!("{e:?}"))
}

/// Whether the CUDA driver, NVRTC and cuFFT libraries load. cudarc panics on the first call
/// into a library it cannot load, so this runs before any such call.
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
            "{} could not be loaded (a driver and the CUDA toolkit's libraries are needed at run time)",
            missing.join(", ")
        )))
    }
}

pub(super) fn probe() -> Result<DeviceInfo, GpuError> {
    libraries_present()?;
    let count = CudaContext::device_count().map_err(|e| GpuError::NoDevice(format!("{e:?}")))?;
    if count < 1 {
        return Err(GpuError::NoDevice("the driver reports no device".into()));
    }
    let ctx = CudaContext::new(0).map_err(|e| GpuError::NoDevice(format!("{e:?}")))?;
    Ok(DeviceInfo {
        name: ctx.name().map_err(driver)?,
        memory: ctx.total_mem().map_err(driver)?,
        compute_capability: ctx.compute_capability().map_err(driver)?,
    })
}

/// An open device: its context and the stream every operation runs on.
pub(super) struct Device {
    ctx: Arc<CudaContext>,
    stream: Arc<CudaStream>,
}

/// The compiled kernels.
pub(super) struct Kernels {
    scale_dealias: CudaFunction,
    strain_spectra: CudaFunction,
    derivative_spectra: CudaFunction,
    stokes: CudaFunction,
    imex_update: CudaFunction,
    change_partials: CudaFunction,
    norm_partials: CudaFunction,
    report_partials: CudaFunction,
    nonfinite_partials: CudaFunction,
    strain_from_gradient: CudaFunction,
    contract: CudaFunction,
    explicit_terms: CudaFunction,
    closure_field: CudaFunction,
}

impl Device {
    pub(super) fn open() -> Result<Self, GpuError> {
        probe()?;
        let ctx = CudaContext::new(0).map_err(|e| GpuError::NoDevice(format!("{e:?}")))?;
        let stream = ctx.default_stream();
        Ok(Self { ctx, stream })
    }

    pub(super) fn compile(&self) -> Result<Kernels, GpuError> {
        // No fused multiply-adds: each a b + c rounds as it does on the CPU, so the parity
        // with the CPU step is limited by the transforms and the math library only.
        let opts = cudarc::nvrtc::CompileOptions {
            fmad: Some(false),
            ..Default::default()
        };
        let ptx = cudarc::nvrtc::compile_ptx_with_opts(SOURCE, opts)
            .map_err(|e| GpuError::Compile(format!("{e:?}")))?;
        let module = self.ctx.load_module(ptx).map_err(driver)?;
        let f = |name: &str| module.load_function(name).map_err(driver);
        Ok(Kernels {
            scale_dealias: f("scale_dealias")?,
            strain_spectra: f("strain_spectra")?,
            derivative_spectra: f("derivative_spectra")?,
            stokes: f("stokes")?,
            imex_update: f("imex_update")?,
            change_partials: f("change_partials")?,
            norm_partials: f("norm_partials")?,
            report_partials: f("report_partials")?,
            nonfinite_partials: f("nonfinite_partials")?,
            strain_from_gradient: f("strain_from_gradient")?,
            contract: f("contract")?,
            explicit_terms: f("explicit_terms")?,
            closure_field: f("closure_field")?,
        })
    }
}

/// One thread per element, in blocks of [`THREADS`] (the reductions' tree assumes exactly
/// that block size).
fn config(elements: usize) -> (LaunchConfig, usize) {
    let blocks = elements.div_ceil(THREADS as usize).max(1);
    (
        LaunchConfig {
            grid_dim: (blocks as u32, 1, 1),
            block_dim: (THREADS, 1, 1),
            shared_mem_bytes: 0,
        },
        blocks,
    )
}

/// The grid's wavenumber tables (solver.rs `SpectralGrid`).
pub(super) struct Wavenumbers {
    k1: Vec<f64>,
    k2: Vec<f64>,
    keep: Vec<i32>,
}

impl Wavenumbers {
    pub(super) fn of(grid: &SpectralGrid) -> Self {
        let (k1, k2, keep) = grid.wavenumber_tables();
        Self {
            k1: k1.to_vec(),
            k2: k2.to_vec(),
            keep: keep.iter().map(|&k| k as i32).collect(),
        }
    }
}

fn to_device(c: &[Complex64]) -> Vec<double2> {
    c.iter().map(|z| double2 { x: z.re, y: z.im }).collect()
}

fn from_device(c: &[double2]) -> Vec<Complex64> {
    c.iter().map(|z| Complex64::new(z.x, z.y)).collect()
}

/// Every device buffer of the step. Spectra hold `S = n n (n/2 + 1)` values per component,
/// grid fields `N = n^3`.
pub(super) struct Buffers {
    n: usize,
    s_len: usize,
    n_len: usize,
    fwd: CudaFft,
    inv: CudaFft,
    k1: CudaSlice<f64>,
    k2: CudaSlice<f64>,
    keep: CudaSlice<i32>,
    coef: CudaSlice<f64>,
    q_hat: CudaSlice<double2>,
    q_prev: CudaSlice<double2>,
    q_new: CudaSlice<double2>,
    nl: CudaSlice<double2>,
    nl_prev: CudaSlice<double2>,
    has_prev: bool,
    /// The last accepted step's velocity (the warm start); untouched by a failing step.
    u_hat: CudaSlice<double2>,
    /// The fixed point's current iterate, and its next one.
    u_work: CudaSlice<double2>,
    u_new: CudaSlice<double2>,
    spec: CudaSlice<double2>,
    q: CudaSlice<f64>,
    e: CudaSlice<f64>,
    se: CudaSlice<f64>,
    ug: CudaSlice<f64>,
    g: CudaSlice<f64>,
    dq: CudaSlice<f64>,
    vals: CudaSlice<f64>,
    s21: CudaSlice<f64>,
    partial: CudaSlice<f64>,
}

impl Buffers {
    pub(super) fn new(
        dev: &Device,
        n: usize,
        coef: &[f64],
        w: &Wavenumbers,
    ) -> Result<Self, GpuError> {
        let st = &dev.stream;
        let (s_len, n_len) = (n * n * (n / 2 + 1), n * n * n);
        let cplx = |k: usize| st.alloc_zeros::<double2>(k * s_len).map_err(driver);
        let real = |k: usize| st.alloc_zeros::<f64>(k * n_len).map_err(driver);
        let ni = n as i32;
        Ok(Self {
            n,
            s_len,
            n_len,
            fwd: CudaFft::plan_3d(ni, ni, ni, cufftType::CUFFT_D2Z, st.clone()).map_err(fft)?,
            inv: CudaFft::plan_3d(ni, ni, ni, cufftType::CUFFT_Z2D, st.clone()).map_err(fft)?,
            k1: st.clone_htod(&w.k1).map_err(driver)?,
            k2: st.clone_htod(&w.k2).map_err(driver)?,
            keep: st.clone_htod(&w.keep).map_err(driver)?,
            coef: st.clone_htod(coef).map_err(driver)?,
            q_hat: cplx(6)?,
            q_prev: cplx(6)?,
            q_new: cplx(6)?,
            nl: cplx(6)?,
            nl_prev: cplx(6)?,
            has_prev: false,
            u_hat: cplx(3)?,
            u_work: cplx(3)?,
            u_new: cplx(3)?,
            spec: cplx(18)?,
            q: real(6)?,
            e: real(6)?,
            se: real(6)?,
            ug: real(3)?,
            g: real(9)?,
            dq: real(18)?,
            vals: real(6)?,
            s21: real(21)?,
            // The largest reduction: four partials per block over 2 * 6 S doubles.
            partial: st
                .alloc_zeros::<f64>(4 * (12 * s_len).div_ceil(THREADS as usize) + 8)
                .map_err(driver)?,
        })
    }

    pub(super) fn upload_state(
        &mut self,
        dev: &Device,
        q_hat: &[Vec<Complex64>; 6],
        history: Option<&History>,
        u_hat: &[Vec<Complex64>; 3],
    ) -> Result<(), GpuError> {
        let st = &dev.stream;
        let flat = |c: &[Vec<Complex64>]| -> Vec<double2> {
            c.iter().flat_map(|v| to_device(v)).collect()
        };
        st.memcpy_htod(&flat(q_hat), &mut self.q_hat)
            .map_err(driver)?;
        st.memcpy_htod(&flat(u_hat), &mut self.u_hat)
            .map_err(driver)?;
        if let Some(h) = history {
            st.memcpy_htod(&flat(&h.q_hat), &mut self.q_prev)
                .map_err(driver)?;
            st.memcpy_htod(&flat(&h.nonlinear), &mut self.nl_prev)
                .map_err(driver)?;
            self.has_prev = true;
        }
        Ok(())
    }

    /// `(Q coefficients, Some((previous Q, previous explicit terms)), u coefficients)`.
    #[allow(clippy::type_complexity)]
    pub(super) fn download_state(
        &self,
        dev: &Device,
    ) -> Result<
        (
            [Vec<Complex64>; 6],
            Option<([Vec<Complex64>; 6], [Vec<Complex64>; 6])>,
            [Vec<Complex64>; 3],
        ),
        GpuError,
    > {
        let st = &dev.stream;
        let s = self.s_len;
        let get = |b: &CudaSlice<double2>| -> Result<Vec<Complex64>, GpuError> {
            Ok(from_device(&st.clone_dtoh(b).map_err(driver)?))
        };
        let split6 = |v: Vec<Complex64>| -> [Vec<Complex64>; 6] {
            std::array::from_fn(|c| v[c * s..(c + 1) * s].to_vec())
        };
        let q = split6(get(&self.q_hat)?);
        let u_all = get(&self.u_hat)?;
        let u: [Vec<Complex64>; 3] = std::array::from_fn(|c| u_all[c * s..(c + 1) * s].to_vec());
        let hist = if self.has_prev {
            Some((split6(get(&self.q_prev)?), split6(get(&self.nl_prev)?)))
        } else {
            None
        };
        Ok((q, hist, u))
    }

    /// Sum of the first `blocks * stride` partials, `stride` per block: per slot, the block
    /// values in block order (max for the slots in `max_slots`).
    fn reduce(
        &self,
        dev: &Device,
        blocks: usize,
        stride: usize,
        max_slots: &[usize],
    ) -> Result<Vec<f64>, GpuError> {
        let host = dev
            .stream
            .clone_dtoh(&self.partial.slice(0..blocks * stride))
            .map_err(driver)?;
        Ok((0..stride)
            .map(|slot| {
                let vals = (0..blocks).map(|b| host[b * stride + slot]);
                if max_slots.contains(&slot) {
                    vals.fold(f64::NEG_INFINITY, f64::max)
                } else {
                    vals.sum()
                }
            })
            .collect())
    }

    /// `count` real fields from the first `count` spectra of `spec` (destroyed) into `out`.
    fn inverse_many(&mut self, count: usize, out: Field) -> Result<(), GpuError> {
        let (s, n) = (self.s_len, self.n_len);
        for c in 0..count {
            let mut src = self.spec.slice_mut(c * s..(c + 1) * s);
            let dst = match out {
                Field::Q => &mut self.q,
                Field::E => &mut self.e,
                Field::Ug => &mut self.ug,
                Field::G => &mut self.g,
                Field::Dq => &mut self.dq,
            };
            let mut dst = dst.slice_mut(c * n..(c + 1) * n);
            self.inv.exec_z2d(&mut src, &mut dst).map_err(fft)?;
        }
        Ok(())
    }

    /// Q's six spectra to the grid, and the fixed point's iterate set to the last accepted
    /// velocity.
    pub(super) fn inverse_q(&mut self, dev: &Device) -> Result<(), GpuError> {
        let s = self.s_len;
        dev.stream
            .memcpy_dtod(&self.u_hat, &mut self.u_work)
            .map_err(driver)?;
        dev.stream
            .memcpy_dtod(&self.q_hat, &mut self.spec.slice_mut(0..6 * s))
            .map_err(driver)?;
        self.inverse_many(6, Field::Q)
    }

    /// The closure field; returns (smallest eigenvalue, largest eigenvalue, entropy sum).
    pub(super) fn closure(
        &mut self,
        dev: &Device,
        k: &Kernels,
        deg: usize,
        with_entropy: bool,
    ) -> Result<(f64, f64, f64), GpuError> {
        let (cfg, blocks) = config(self.n_len);
        let (deg, ent, n) = (deg as i32, with_entropy as i32, self.n_len as i64);
        let mut b = dev.stream.launch_builder(&k.closure_field);
        b.arg(&self.q)
            .arg(&mut self.s21)
            .arg(&self.coef)
            .arg(&deg)
            .arg(&ent)
            .arg(&n)
            .arg(&mut self.partial);
        // SAFETY: closure_field(const double* q, double* s21, const double* coef, int deg,
        // int with_entropy, long long N, double* partial): q holds 6 N doubles, s21 21 N, coef
        // the 4 (deg + 1)^2 table coefficients uploaded for this degree, partial at least
        // 3 blocks; each thread reads point p < N and writes s21[21 p..21 p + 21] and its
        // block's three partials.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        let r = self.reduce(dev, blocks, 3, &[0, 1])?;
        Ok((-r[0], r[1], r[2]))
    }

    /// E of the current u on the grid (6 strain spectra, 6 inverse transforms).
    pub(super) fn strain_to_grid(&mut self, dev: &Device, k: &Kernels) -> Result<(), GpuError> {
        let (cfg, _) = config(self.s_len);
        let n = self.n as i32;
        let mut b = dev.stream.launch_builder(&k.strain_spectra);
        b.arg(&self.u_work)
            .arg(&mut self.spec)
            .arg(&n)
            .arg(&self.k1);
        // SAFETY: strain_spectra(const double2* u, double2* out, int n, const double* k1):
        // u_work holds 3 S values, spec 18 S >= 6 S, k1 n; thread s < S reads u[i S + s] and writes
        // out[c S + s] for c < 6.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        self.inverse_many(6, Field::E)
    }

    /// The active stress -Q + zeta S:E, forward transformed and dealiased into the first six
    /// spectra of `spec`.
    pub(super) fn stress(&mut self, dev: &Device, k: &Kernels, zeta: f64) -> Result<(), GpuError> {
        self.contract(dev, k, zeta, true)?;
        let (s, n) = (self.s_len, self.n_len);
        for c in 0..6 {
            let src = self.se.slice(c * n..(c + 1) * n);
            let mut dst = self.spec.slice_mut(c * s..(c + 1) * s);
            self.fwd.exec_d2z(&src, &mut dst).map_err(fft)?;
        }
        self.scale_dealias(dev, k, Spectra::Spec, 6, true)
    }

    /// `S:E` (or the stress with `stress`) of the grid E into `se`.
    fn contract(
        &mut self,
        dev: &Device,
        k: &Kernels,
        zeta: f64,
        stress: bool,
    ) -> Result<(), GpuError> {
        let (cfg, _) = config(self.n_len);
        let (n, st) = (self.n_len as i64, stress as i32);
        let mut b = dev.stream.launch_builder(&k.contract);
        b.arg(&self.s21)
            .arg(&self.e)
            .arg(&self.q)
            .arg(&zeta)
            .arg(&mut self.se)
            .arg(&n)
            .arg(&st);
        // SAFETY: contract(const double* s21, const double* e, const double* q, double zeta,
        // double* out, long long N, int stress): s21 holds 21 N doubles, e, q and se 6 N each;
        // thread p < N reads and writes index c N + p for c < 6 and s21[21 p..21 p + 21].
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(())
    }

    /// Scale by 1/n^3 and dealias `count` spectra of `which`.
    fn scale_dealias(
        &mut self,
        dev: &Device,
        k: &Kernels,
        which: Spectra,
        count: usize,
        dealias: bool,
    ) -> Result<(), GpuError> {
        let total = count * self.s_len;
        let (cfg, _) = config(total);
        let (total, n, scale, de) = (
            total as i64,
            self.n as i32,
            1.0 / self.n_len as f64,
            dealias as i32,
        );
        let target = match which {
            Spectra::Spec => &mut self.spec,
            Spectra::Nonlinear => &mut self.nl,
        };
        let mut b = dev.stream.launch_builder(&k.scale_dealias);
        b.arg(target)
            .arg(&total)
            .arg(&n)
            .arg(&scale)
            .arg(&self.keep)
            .arg(&de);
        // SAFETY: scale_dealias(double2* c, long long count, int n, double scale,
        // const int* keep, int dealias): the target holds at least `count` values (6 S for the
        // explicit terms, 18 S for spec), keep n ints; thread t < count touches c[t] only.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(())
    }

    /// The Stokes velocity of the stress spectra into `u_new`.
    pub(super) fn stokes(&mut self, dev: &Device, k: &Kernels) -> Result<(), GpuError> {
        let (cfg, _) = config(self.s_len);
        let n = self.n as i32;
        let mut b = dev.stream.launch_builder(&k.stokes);
        b.arg(&self.spec)
            .arg(&mut self.u_new)
            .arg(&n)
            .arg(&self.k1)
            .arg(&self.k2);
        // SAFETY: stokes(const double2* sigma, double2* u, int n, const double* k1,
        // const double* k2): spec holds 18 S >= 6 S values, u_new 3 S, k1 and k2 n; thread
        // s < S reads sigma[c S + s] and writes u[i S + s].
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(())
    }

    /// The fixed point's relative change between `u_new` and `u_work` (solver.rs rel_change).
    pub(super) fn change(&mut self, dev: &Device, k: &Kernels) -> Result<f64, GpuError> {
        let (cfg, blocks) = config(self.s_len);
        let n = self.n as i32;
        let mut b = dev.stream.launch_builder(&k.change_partials);
        b.arg(&self.u_new)
            .arg(&self.u_work)
            .arg(&n)
            .arg(&mut self.partial);
        // SAFETY: change_partials(const double2* a, const double2* b, int n, double* partial):
        // both hold 3 S values, partial at least 2 blocks; thread s < S reads index c S + s.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        let r = self.reduce(dev, blocks, 2, &[])?;
        Ok((r[0] / r[1].max(FLOW_FLOOR * FLOW_FLOOR)).sqrt())
    }

    /// The new iterate becomes the current one.
    pub(super) fn accept_u(&mut self) {
        std::mem::swap(&mut self.u_work, &mut self.u_new);
    }

    /// u and grad u on the grid, E from grad u and S:E (the explicit terms' inputs).
    pub(super) fn gradients(&mut self, dev: &Device, k: &Kernels) -> Result<(), GpuError> {
        let s = self.s_len;
        dev.stream
            .memcpy_dtod(&self.u_work, &mut self.spec.slice_mut(0..3 * s))
            .map_err(driver)?;
        self.inverse_many(3, Field::Ug)?;
        self.derivatives(dev, k, 3)?;
        self.inverse_many(9, Field::G)?;
        let (cfg, _) = config(self.n_len);
        let n = self.n_len as i64;
        let mut b = dev.stream.launch_builder(&k.strain_from_gradient);
        b.arg(&self.g).arg(&mut self.e).arg(&n);
        // SAFETY: strain_from_gradient(const double* g, double* e, long long N): g holds 9 N,
        // e 6 N doubles; thread p < N touches index c N + p only.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        self.contract(dev, k, 0.0, false)
    }

    /// Derivative spectra of `comps` inputs (u: 3 from u_work, Q: 6 from q_hat) into spec.
    fn derivatives(&mut self, dev: &Device, k: &Kernels, comps: usize) -> Result<(), GpuError> {
        let (cfg, _) = config(self.s_len);
        let (c, n) = (comps as i32, self.n as i32);
        let input = if comps == 3 {
            &self.u_work
        } else {
            &self.q_hat
        };
        let mut b = dev.stream.launch_builder(&k.derivative_spectra);
        b.arg(input)
            .arg(&mut self.spec)
            .arg(&c)
            .arg(&n)
            .arg(&self.k1);
        // SAFETY: derivative_spectra(const double2* c, double2* out, int comps, int n,
        // const double* k1): the input holds comps S values (u_work 3 S, q_hat 6 S), spec 18 S
        // >= 3 comps S; thread s < S writes out[(m 3 + dir) S + s] for m < comps.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(())
    }

    /// The explicit terms' spectra into `nl` (grad Q to the grid, the products, forward,
    /// dealiased).
    pub(super) fn explicit_terms(&mut self, dev: &Device, k: &Kernels) -> Result<(), GpuError> {
        self.derivatives(dev, k, 6)?;
        self.inverse_many(18, Field::Dq)?;
        let (cfg, _) = config(self.n_len);
        let n = self.n_len as i64;
        let mut b = dev.stream.launch_builder(&k.explicit_terms);
        b.arg(&self.ug)
            .arg(&self.g)
            .arg(&self.q)
            .arg(&self.dq)
            .arg(&self.se)
            .arg(&mut self.vals)
            .arg(&n);
        // SAFETY: explicit_terms(const double* ug, const double* g, const double* q,
        // const double* dq, const double* se, double* out, long long N): ug 3 N, g 9 N, q 6 N,
        // dq 18 N, se 6 N, vals 6 N doubles; thread p < N touches index m N + p only.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        let (s, nn) = (self.s_len, self.n_len);
        for c in 0..6 {
            let src = self.vals.slice(c * nn..(c + 1) * nn);
            let mut dst = self.nl.slice_mut(c * s..(c + 1) * s);
            self.fwd.exec_d2z(&src, &mut dst).map_err(fft)?;
        }
        self.scale_dealias(dev, k, Spectra::Nonlinear, 6, true)
    }

    /// Whether the explicit terms (or, with `update`, the updated Q) hold a non-finite value.
    fn nonfinite(&mut self, dev: &Device, k: &Kernels, update: bool) -> Result<bool, GpuError> {
        let count = 2 * 6 * self.s_len;
        let (cfg, blocks) = config(count);
        let c = count as i64;
        let src = if update { &self.q_new } else { &self.nl };
        let mut b = dev.stream.launch_builder(&k.nonfinite_partials);
        b.arg(src).arg(&c).arg(&mut self.partial);
        // SAFETY: nonfinite_partials(const double* v, long long count, double* partial): the
        // spectra hold 6 S complex values = 12 S doubles, read as doubles (double2 is two
        // doubles, no padding); partial holds at least one value per block.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(self.reduce(dev, blocks, 1, &[])?[0] > 0.0)
    }

    pub(super) fn nonfinite_nonlinear(
        &mut self,
        dev: &Device,
        k: &Kernels,
    ) -> Result<bool, GpuError> {
        self.nonfinite(dev, k, false)
    }

    pub(super) fn nonfinite_update(&mut self, dev: &Device, k: &Kernels) -> Result<bool, GpuError> {
        self.nonfinite(dev, k, true)
    }

    /// (max |u_x| + |u_y| + |u_z|, <E:E>, <E:Q>, <E:S:E>) as sums over the grid.
    pub(super) fn report_sums(
        &mut self,
        dev: &Device,
        k: &Kernels,
    ) -> Result<(f64, f64, f64, f64), GpuError> {
        let (cfg, blocks) = config(self.n_len);
        let n = self.n_len as i64;
        let mut b = dev.stream.launch_builder(&k.report_partials);
        b.arg(&self.ug)
            .arg(&self.e)
            .arg(&self.q)
            .arg(&self.se)
            .arg(&n)
            .arg(&mut self.partial);
        // SAFETY: report_partials(const double* ug, const double* e, const double* q,
        // const double* se, long long N, double* partial): ug 3 N, e, q and se 6 N doubles,
        // partial at least 4 blocks; thread p < N reads index c N + p only.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        let r = self.reduce(dev, blocks, 4, &[0])?;
        Ok((r[0], r[1], r[2], r[3]))
    }

    /// sum over the spectrum of |u|^2 (Parseval).
    pub(super) fn u_norm(&mut self, dev: &Device, k: &Kernels) -> Result<f64, GpuError> {
        let (cfg, blocks) = config(self.s_len);
        let n = self.n as i32;
        let mut b = dev.stream.launch_builder(&k.norm_partials);
        b.arg(&self.u_work).arg(&n).arg(&mut self.partial);
        // SAFETY: norm_partials(const double2* u, int n, double* partial): u_work holds 3 S
        // values, partial at least one per block; thread s < S reads index c S + s.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(self.reduce(dev, blocks, 1, &[])?[0])
    }

    /// The IMEX update into `q_new`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn imex(
        &mut self,
        dev: &Device,
        k: &Kernels,
        a: [f64; 3],
        bcoef: [f64; 2],
        dt: f64,
        diffusion: f64,
        two: bool,
    ) -> Result<(), GpuError> {
        let (cfg, _) = config(self.s_len);
        let (n, two) = (self.n as i32, two as i32);
        let mut b = dev.stream.launch_builder(&k.imex_update);
        b.arg(&self.q_hat)
            .arg(&self.nl)
            .arg(&self.q_prev)
            .arg(&self.nl_prev)
            .arg(&mut self.q_new)
            .arg(&n)
            .arg(&self.k2)
            .arg(&a[0])
            .arg(&a[1])
            .arg(&a[2])
            .arg(&bcoef[0])
            .arg(&bcoef[1])
            .arg(&dt)
            .arg(&diffusion)
            .arg(&two);
        // SAFETY: imex_update(const double2* q, const double2* nl, const double2* q_prev,
        // const double2* nl_prev, double2* out, int n, const double* k2, double a0, double a1,
        // double a2, double b0, double b1, double dt, double diffusion, int two): the five
        // spectra hold 6 S values each, k2 n doubles; thread s < S touches index c S + s.
        unsafe { b.launch(cfg) }.map_err(driver)?;
        Ok(())
    }

    /// The step is accepted: Q^{n-1} <- Q^n <- Q^{n+1}, N^{n-1} <- N^n, and the converged
    /// velocity becomes the next warm start.
    pub(super) fn commit_step(&mut self) {
        std::mem::swap(&mut self.u_hat, &mut self.u_work);
        std::mem::swap(&mut self.q_prev, &mut self.q_hat);
        std::mem::swap(&mut self.q_hat, &mut self.q_new);
        std::mem::swap(&mut self.nl_prev, &mut self.nl);
        self.has_prev = true;
    }
}

/// Which grid field an inverse transform writes.
#[derive(Clone, Copy)]
enum Field {
    Q,
    E,
    Ug,
    G,
    Dq,
}

/// Which spectra a kernel works on.
#[derive(Clone, Copy)]
enum Spectra {
    Spec,
    Nonlinear,
}
