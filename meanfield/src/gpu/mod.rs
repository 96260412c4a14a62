//! The mean-field step on an NVIDIA GPU (feature `gpu`): the same equations and algorithm as
//! [`crate::solver`] (docs/MODEL.md §4, M1-M2), every field resident on the device. Transforms
//! by cuFFT (double precision, real-to-complex, the CPU's half-spectrum layout), the closure,
//! contractions, Stokes solve, products and the IMEX update by kernels compiled at run time by
//! NVRTC (`kernels.cu`, each the twin of a CPU loop), reductions in fixed blocks (deterministic
//! from run to run). Only reports cross the bus during a step: a handful of doubles per
//! reduction.
//!
//! The device is a [`motile_gpu::Device`] opened with a [`motile_gpu::Backend`]: CUDA, loaded at
//! run time (cudarc's dynamic loading: a build needs no CUDA toolkit, and on a machine without a
//! driver [`GpuMeanField::open`] returns `motile_gpu::GpuError::NoDevice` instead of
//! panicking), or the host emulation (the same kernels compiled by the C++ compiler and run on
//! the CPU, transforms in cuFFT's layout), which lets the kernels and the code around them be
//! tested on machines without a GPU. Kernels are declared in `signatures.rs`; their launches
//! are the only unsafe code of the crate, in `launch.rs`.
//!
//! Parity with the CPU step (three steps within 1e-12 relative, the fixed point's iteration
//! count pinned) is tested in `meanfield/tests/gpu.rs`: on the host emulation wherever a C++
//! compiler runs, and on CUDA where a GPU is present (it says it was skipped elsewhere, and
//! fails instead with `MOTILE_REQUIRE_GPU=1`).

mod error;
mod launch;
mod signatures;
mod work;

pub use error::GpuError;
pub use work::{PhaseWork, device_bytes, work_model};

use crate::closure::BinghamClosure;
use crate::gpu::signatures::KERNELS;
use crate::solver::params::{MeanFieldError, MeanFieldParams, RhsReport};
use crate::solver::rhs::MeanFieldRhs;
use crate::solver::stepper::{History, ImexScheme, MeanFieldStepReport, MeanFieldStepper, SBDF1};
use motile_gpu::{Backend, Device};
use num_complex::Complex64;

/// The mean-field state and its stepper on the device.
pub struct GpuMeanField {
    dev: Device,
    n: usize,
    params: MeanFieldParams,
    scheme: ImexScheme,
    deg: usize,
    /// Current time.
    pub t: f64,
    prev_dt: Option<f64>,
    bufs: launch::Buffers,
}

impl std::fmt::Debug for GpuMeanField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuMeanField")
            .field("device", &self.dev.describe())
            .field("n", &self.n)
            .field("t", &self.t)
            .field("closure_degree", &self.deg)
            .finish_non_exhaustive()
    }
}

impl GpuMeanField {
    /// Upload the CPU stepper's state (its time, Q, history, warm-start velocity and scheme)
    /// to the device `backend` names and prepare the step of `rhs` (grid, closure tables,
    /// parameters) there: kernels, FFT plans, tables, wavenumbers, buffers. The first step is
    /// SBDF1 without a history, as on the CPU.
    pub fn open(
        backend: Backend,
        rhs: &MeanFieldRhs<'_>,
        stepper: &MeanFieldStepper,
    ) -> Result<Self, GpuError> {
        let dev = Device::open(backend, &KERNELS)?;
        let (grid, closure, params): (_, &BinghamClosure, &MeanFieldParams) =
            (rhs.grid, rhs.closure, rhs.params);
        let (scheme, t, q_hat, history, u_hat): (ImexScheme, _, _, Option<&History>, _) = (
            stepper.scheme,
            stepper.t,
            &stepper.q_hat,
            stepper.history(),
            &stepper.u_hat,
        );
        let n = grid.n;
        let coef: Vec<f64> = closure.coefficients().iter().flatten().copied().collect();
        let wavenumbers = launch::Wavenumbers::of(grid);
        let mut bufs = launch::Buffers::new(&dev, n, &coef, &wavenumbers)?;
        bufs.upload_state(&dev, q_hat, history, u_hat)?;
        Ok(Self {
            dev,
            n,
            params: params.clone(),
            scheme,
            deg: closure.degree(),
            t,
            prev_dt: history.map(|h| h.dt),
            bufs,
        })
    }

    /// What the device is.
    pub fn describe(&self) -> String {
        self.dev.describe()
    }

    /// What the device has been asked to do so far: launches, transforms, transfers.
    pub fn counters(&self) -> motile_gpu::Counters {
        self.dev.counters()
    }

    /// The state, downloaded: `(t, Q coefficients, history, u coefficients)`, as
    /// [`crate::solver::stepper::MeanFieldStepper::restore`] takes it (checkpoints, snapshots).
    pub fn state(&self) -> Result<StateDownload, GpuError> {
        let (q_hat, hist, u_hat) = self.bufs.download_state(&self.dev)?;
        let history = match (self.prev_dt, hist) {
            (Some(dt), Some((q, nl))) => Some(History {
                q_hat: q,
                nonlinear: nl,
                dt,
            }),
            _ => None,
        };
        Ok((self.t, q_hat, history, u_hat))
    }

    /// Advance by `dt` as [`crate::solver::stepper::MeanFieldStepper::step`] does (SBDF1 for the first
    /// step, then variable-step SBDF2), with the entropy only if asked. Nothing is committed
    /// when the step fails: the fixed point iterates in a work buffer, and the state, the
    /// history and the warm-start velocity change only once the new Q is known to be finite.
    pub fn step(&mut self, dt: f64, with_entropy: bool) -> Result<MeanFieldStepReport, GpuError> {
        let (n, dev) = (self.n, &self.dev);
        let b = &mut self.bufs;
        let npts = (n * n * n) as f64;
        // Q to the grid.
        b.inverse_q(dev)?;
        // The closure field (its reductions, like the report's, are read at the end of the
        // step in one download).
        b.closure(dev, self.deg, with_entropy)?;
        // The Stokes fixed point from the previous u.
        let mut report = RhsReport::default();
        let zeta = self.params.zeta;
        loop {
            report.iterations += 1;
            b.strain_to_grid(dev)?;
            b.stress(dev, zeta)?;
            b.stokes(dev)?;
            report.residual = b.change(dev)?;
            b.accept_u();
            if self.params.fixed_point_done(&report)? {
                break;
            }
        }
        // u, grad u, E, S:E and the report's sums over them (before the explicit terms write
        // grad Q over E), the explicit terms.
        b.gradients(dev)?;
        b.report_sums(dev)?;
        b.explicit_terms(dev)?;
        b.u_norm(dev)?;
        // The IMEX update into the spare buffer; committed only if the terms and it are
        // finite.
        // As MeanFieldStepper::step: the scheme once it has its history, SBDF1 before.
        let (scheme, w) = match self.prev_dt {
            Some(prev) if self.scheme.steps == 2 => (self.scheme, dt / prev),
            _ => (SBDF1, 1.0),
        };
        let (a, bcoef) = (scheme.coefficients)(w);
        b.imex(
            dev,
            a,
            bcoef,
            dt,
            self.params.diffusion,
            self.prev_dt.is_some() && scheme.steps == 2,
        )?;
        let sums = b.step_sums(dev)?;
        if sums.terms_nonfinite {
            return Err(MeanFieldError::NonFinite("the right-hand side").into());
        }
        if sums.update_nonfinite {
            return Err(MeanFieldError::NonFinite("Q after the step").into());
        }
        b.commit_step(dev)?;
        let (ee, eq, ese) = sums.e_sums;
        self.prev_dt = Some(dt);
        self.t += dt;
        Ok(MeanFieldStepReport {
            rhs: report,
            min_eigenvalue: sums.min_eigenvalue,
            u_l2: sums.u_norm_sqr.sqrt(),
            u_max: sums.u_max,
            e_l2: (ee / npts).sqrt(),
            e_dot_q: eq / npts,
            max_eigenvalue: sums.max_eigenvalue,
            entropy: if with_entropy {
                sums.entropy_sum / npts
            } else {
                f64::NAN
            },
            energy_residual: (2.0 * ee + zeta * ese - eq) / eq.abs().max(1e-300),
        })
    }
}

/// A downloaded state: `(t, Q coefficients, history, u coefficients)`.
pub type StateDownload = (
    f64,
    [Vec<Complex64>; 6],
    Option<History>,
    [Vec<Complex64>; 3],
);
