//! The device side of the GPU mean-field step: the buffers, the transforms and every kernel
//! launch, on a [`motile_gpu::Device`] (CUDA, or the host emulation of the same kernels). The
//! only module of the crate that allows `unsafe`: the arguments' number, order and types are
//! the declarations' of `signatures.rs` (checked against `kernels.cu`), but the indices a kernel
//! touches are not checked by anything, so each launch states why they lie inside the buffers
//! it is given.
#![allow(unsafe_code)]

use crate::gpu::error::GpuError;
use crate::gpu::signatures::{
    ChangePartials, ClosureField, Contract, DerivativeSpectra, ExplicitTerms, ImexUpdate,
    NonfinitePartials, NormPartials, ReportPartials, ScaleDealias, Stokes, StrainFromGradient,
    StrainSpectra,
};
use crate::solver::grid::SpectralGrid;
use crate::solver::stepper::History;
use motile_gpu::{Buffer, Device, Direction, Fft3, THREADS};
use num_complex::Complex64;

/// Flow speed below which the fixed point's change is measured absolutely (solver.rs
/// `FLOW_FLOOR`).
const FLOW_FLOOR: f64 = 1e-14;

// The block reductions of kernels.cu sum REDUCE_THREADS = 256 values per block in shared
// memory: every launch must have exactly that many threads per block.
const _: () = assert!(THREADS == 256);

/// Blocks of a launch over `elements` (one thread each, [`THREADS`] per block: the
/// reductions' tree assumes exactly that block size).
fn blocks(elements: usize) -> usize {
    elements.div_ceil(THREADS as usize).max(1)
}

/// The grid's wavenumber tables (solver.rs `SpectralGrid`), `keep` as 0/1 ints.
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
            keep: keep.iter().map(|&k| i32::from(k)).collect(),
        }
    }
}

/// Complex spectra, one after another, as interleaved (re, im) pairs.
fn flat(c: &[Vec<Complex64>]) -> Vec<f64> {
    c.iter().flatten().flat_map(|z| [z.re, z.im]).collect()
}

/// `count` spectra of `s` values each from interleaved pairs.
fn split(v: &[f64], count: usize, s: usize) -> Vec<Vec<Complex64>> {
    (0..count)
        .map(|c| {
            (0..s)
                .map(|j| Complex64::new(v[2 * (c * s + j)], v[2 * (c * s + j) + 1]))
                .collect()
        })
        .collect()
}

/// Every device buffer of the step. Spectra hold `S = n n (n/2 + 1)` complex values per
/// component (2 S doubles), grid fields `N = n^3` doubles.
pub(super) struct Buffers {
    n: usize,
    s_len: usize,
    n_len: usize,
    /// One real field to one half spectrum and back.
    fft: Fft3,
    k1: Buffer,
    k2: Buffer,
    keep: Buffer<i32>,
    coef: Buffer,
    q_hat: Buffer,
    q_prev: Buffer,
    q_new: Buffer,
    nl: Buffer,
    nl_prev: Buffer,
    has_prev: bool,
    /// The last accepted step's velocity (the warm start); untouched by a failing step.
    u_hat: Buffer,
    /// The fixed point's current iterate, and its next one.
    u_work: Buffer,
    u_new: Buffer,
    spec: Buffer,
    q: Buffer,
    e: Buffer,
    se: Buffer,
    ug: Buffer,
    g: Buffer,
    dq: Buffer,
    vals: Buffer,
    s21: Buffer,
    partial: Buffer,
}

impl Buffers {
    pub(super) fn new(
        dev: &Device,
        n: usize,
        coef: &[f64],
        w: &Wavenumbers,
    ) -> Result<Self, GpuError> {
        let (s_len, n_len) = (n * n * (n / 2 + 1), n * n * n);
        let cplx = |k: usize| dev.zeros(2 * k * s_len);
        let real = |k: usize| dev.zeros(k * n_len);
        Ok(Self {
            n,
            s_len,
            n_len,
            fft: dev.fft3(n, 1, Direction::Both)?,
            k1: dev.upload(&w.k1)?,
            k2: dev.upload(&w.k2)?,
            keep: dev.upload(&w.keep)?,
            coef: dev.upload(coef)?,
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
            partial: dev.zeros(4 * blocks(12 * s_len) + 8)?,
        })
    }

    pub(super) fn upload_state(
        &mut self,
        dev: &Device,
        q_hat: &[Vec<Complex64>; 6],
        history: Option<&History>,
        u_hat: &[Vec<Complex64>; 3],
    ) -> Result<(), GpuError> {
        dev.upload_into(&flat(q_hat), &mut self.q_hat)?;
        dev.upload_into(&flat(u_hat), &mut self.u_hat)?;
        if let Some(h) = history {
            dev.upload_into(&flat(&h.q_hat), &mut self.q_prev)?;
            dev.upload_into(&flat(&h.nonlinear), &mut self.nl_prev)?;
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
        let s = self.s_len;
        let six = |b: &Buffer| -> Result<[Vec<Complex64>; 6], GpuError> {
            let v = split(&dev.download(b)?, 6, s);
            Ok(v.try_into().expect("six spectra"))
        };
        let q = six(&self.q_hat)?;
        let u: [Vec<Complex64>; 3] = split(&dev.download(&self.u_hat)?, 3, s)
            .try_into()
            .expect("three spectra");
        let hist = if self.has_prev {
            Some((six(&self.q_prev)?, six(&self.nl_prev)?))
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
        let host = dev.download_range(&self.partial, 0, blocks * stride)?;
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
    fn inverse_many(&mut self, dev: &Device, count: usize, out: Field) -> Result<(), GpuError> {
        let (s, n) = (self.s_len, self.n_len);
        let dst = match out {
            Field::Q => &mut self.q,
            Field::E => &mut self.e,
            Field::Ug => &mut self.ug,
            Field::G => &mut self.g,
            Field::Dq => &mut self.dq,
        };
        for c in 0..count {
            dev.inverse(&self.fft, (&mut self.spec, 2 * c * s), (dst, c * n))?;
        }
        Ok(())
    }

    /// Six real fields of `src` forward transformed into the first six spectra of `dst`.
    fn forward_six(
        dev: &Device,
        fwd: &Fft3,
        (src, n): (&Buffer, usize),
        (dst, s): (&mut Buffer, usize),
    ) -> Result<(), GpuError> {
        for c in 0..6 {
            dev.forward(fwd, (src, c * n), (dst, 2 * c * s))?;
        }
        Ok(())
    }

    /// Q's six spectra to the grid, and the fixed point's iterate set to the last accepted
    /// velocity.
    pub(super) fn inverse_q(&mut self, dev: &Device) -> Result<(), GpuError> {
        let s = self.s_len;
        dev.copy((&self.u_hat, 0), (&mut self.u_work, 0), 6 * s)?;
        dev.copy((&self.q_hat, 0), (&mut self.spec, 0), 12 * s)?;
        self.inverse_many(dev, 6, Field::Q)
    }

    /// The closure field; returns (smallest eigenvalue, largest eigenvalue, entropy sum).
    pub(super) fn closure(
        &mut self,
        dev: &Device,
        deg: usize,
        with_entropy: bool,
    ) -> Result<(f64, f64, f64), GpuError> {
        // SAFETY: closure_field(const double* q, double* s21, const double* coef, int deg,
        // int with_entropy, long long N, double* partial): q holds 6 N doubles, s21 21 N, coef
        // the 4 (deg + 1)^2 table coefficients uploaded for this degree, partial at least
        // 3 blocks; each thread reads point p < N and writes s21[21 p..21 p + 21] and its
        // block's three partials.
        unsafe {
            dev.launch(
                self.n_len,
                ClosureField {
                    q: &self.q,
                    s21: &mut self.s21,
                    coef: &self.coef,
                    deg: deg as i32,
                    with_entropy: i32::from(with_entropy),
                    N: self.n_len as i64,
                    partial: &mut self.partial,
                },
            )
        }?;
        let r = self.reduce(dev, blocks(self.n_len), 3, &[0, 1])?;
        Ok((-r[0], r[1], r[2]))
    }

    /// E of the current u on the grid (6 strain spectra, 6 inverse transforms).
    pub(super) fn strain_to_grid(&mut self, dev: &Device) -> Result<(), GpuError> {
        // SAFETY: strain_spectra(const double2* u, double2* out, int n, const double* k1):
        // u_work holds 3 S values, spec 18 S >= 6 S, k1 n; thread s < S reads u[i S + s] and
        // writes out[c S + s] for c < 6.
        unsafe {
            dev.launch(
                self.s_len,
                StrainSpectra {
                    u: &self.u_work,
                    out: &mut self.spec,
                    n: self.n as i32,
                    k1: &self.k1,
                },
            )
        }?;
        self.inverse_many(dev, 6, Field::E)
    }

    /// The active stress -Q + zeta S:E, forward transformed and dealiased into the first six
    /// spectra of `spec`.
    pub(super) fn stress(&mut self, dev: &Device, zeta: f64) -> Result<(), GpuError> {
        self.contract(dev, zeta, true)?;
        let (s, n) = (self.s_len, self.n_len);
        Self::forward_six(dev, &self.fft, (&self.se, n), (&mut self.spec, s))?;
        self.scale_dealias(dev, Spectra::Spec, 6, true)
    }

    /// `S:E` (or the stress with `stress`) of the grid E into `se`.
    fn contract(&mut self, dev: &Device, zeta: f64, stress: bool) -> Result<(), GpuError> {
        // SAFETY: contract(const double* s21, const double* e, const double* q, double zeta,
        // double* out, long long N, int stress): s21 holds 21 N doubles, e, q and se 6 N each;
        // thread p < N reads and writes index c N + p for c < 6 and s21[21 p..21 p + 21].
        unsafe {
            dev.launch(
                self.n_len,
                Contract {
                    s21: &self.s21,
                    e: &self.e,
                    q: &self.q,
                    zeta,
                    out: &mut self.se,
                    N: self.n_len as i64,
                    stress: i32::from(stress),
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// Scale by 1/n^3 and dealias `count` spectra of `which`.
    fn scale_dealias(
        &mut self,
        dev: &Device,
        which: Spectra,
        count: usize,
        dealias: bool,
    ) -> Result<(), GpuError> {
        let total = count * self.s_len;
        let target = match which {
            Spectra::Spec => &mut self.spec,
            Spectra::Nonlinear => &mut self.nl,
        };
        // SAFETY: scale_dealias(double2* c, long long count, int n, double scale,
        // const int* keep, int dealias): the target holds at least `count` complex values
        // (6 S for the explicit terms, 18 S for spec), keep n ints; thread t < count
        // touches c[t] only.
        unsafe {
            dev.launch(
                total,
                ScaleDealias {
                    c: target,
                    count: total as i64,
                    n: self.n as i32,
                    scale: 1.0 / self.n_len as f64,
                    keep: &self.keep,
                    dealias: i32::from(dealias),
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The Stokes velocity of the stress spectra into `u_new`.
    pub(super) fn stokes(&mut self, dev: &Device) -> Result<(), GpuError> {
        // SAFETY: stokes(const double2* sigma, double2* u, int n, const double* k1,
        // const double* k2): spec holds 18 S >= 6 S values, u_new 3 S, k1 and k2 n; thread
        // s < S reads sigma[c S + s] and writes u[i S + s].
        unsafe {
            dev.launch(
                self.s_len,
                Stokes {
                    sigma: &self.spec,
                    u: &mut self.u_new,
                    n: self.n as i32,
                    k1: &self.k1,
                    k2: &self.k2,
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The fixed point's relative change between `u_new` and `u_work` (solver.rs rel_change).
    pub(super) fn change(&mut self, dev: &Device) -> Result<f64, GpuError> {
        // SAFETY: change_partials(const double2* a, const double2* b, int n, double* partial):
        // both hold 3 S values, partial at least 2 per block; thread s < S reads index c S + s.
        unsafe {
            dev.launch(
                self.s_len,
                ChangePartials {
                    a: &self.u_new,
                    b: &self.u_work,
                    n: self.n as i32,
                    partial: &mut self.partial,
                },
            )
        }?;
        let r = self.reduce(dev, blocks(self.s_len), 2, &[])?;
        Ok((r[0] / r[1].max(FLOW_FLOOR * FLOW_FLOOR)).sqrt())
    }

    /// The new iterate becomes the current one.
    pub(super) fn accept_u(&mut self) {
        std::mem::swap(&mut self.u_work, &mut self.u_new);
    }

    /// u and grad u on the grid, E from grad u and S:E (the explicit terms' inputs).
    pub(super) fn gradients(&mut self, dev: &Device) -> Result<(), GpuError> {
        let s = self.s_len;
        dev.copy((&self.u_work, 0), (&mut self.spec, 0), 6 * s)?;
        self.inverse_many(dev, 3, Field::Ug)?;
        self.derivatives(dev, 3)?;
        self.inverse_many(dev, 9, Field::G)?;
        // SAFETY: strain_from_gradient(const double* g, double* e, long long N): g holds 9 N,
        // e 6 N doubles; thread p < N touches index c N + p only.
        unsafe {
            dev.launch(
                self.n_len,
                StrainFromGradient {
                    g: &self.g,
                    e: &mut self.e,
                    N: self.n_len as i64,
                },
            )
        }?;
        self.contract(dev, 0.0, false)
    }

    /// Derivative spectra of `comps` inputs (u: 3 from u_work, Q: 6 from q_hat) into spec.
    fn derivatives(&mut self, dev: &Device, comps: usize) -> Result<(), GpuError> {
        let input = if comps == 3 {
            &self.u_work
        } else {
            &self.q_hat
        };
        // SAFETY: derivative_spectra(const double2* c, double2* out, int comps, int n,
        // const double* k1): the input holds comps S values (u_work 3 S, q_hat 6 S), spec 18 S
        // >= 3 comps S; thread s < S writes out[(m 3 + dir) S + s] for m < comps.
        unsafe {
            dev.launch(
                self.s_len,
                DerivativeSpectra {
                    c: input,
                    out: &mut self.spec,
                    comps: comps as i32,
                    n: self.n as i32,
                    k1: &self.k1,
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The explicit terms' spectra into `nl` (grad Q to the grid, the products, forward,
    /// dealiased).
    pub(super) fn explicit_terms(&mut self, dev: &Device) -> Result<(), GpuError> {
        self.derivatives(dev, 6)?;
        self.inverse_many(dev, 18, Field::Dq)?;
        // SAFETY: explicit_terms(const double* ug, const double* g, const double* q,
        // const double* dq, const double* se, double* out, long long N): ug 3 N, g 9 N, q 6 N,
        // dq 18 N, se 6 N, vals 6 N doubles; thread p < N touches index m N + p only.
        unsafe {
            dev.launch(
                self.n_len,
                ExplicitTerms {
                    ug: &self.ug,
                    g: &self.g,
                    q: &self.q,
                    dq: &self.dq,
                    se: &self.se,
                    out: &mut self.vals,
                    N: self.n_len as i64,
                },
            )
        }?;
        let (s, n) = (self.s_len, self.n_len);
        Self::forward_six(dev, &self.fft, (&self.vals, n), (&mut self.nl, s))?;
        self.scale_dealias(dev, Spectra::Nonlinear, 6, true)
    }

    /// Whether the explicit terms (or, with `update`, the updated Q) hold a non-finite value.
    fn nonfinite(&mut self, dev: &Device, update: bool) -> Result<bool, GpuError> {
        let count = 2 * 6 * self.s_len;
        let src = if update { &self.q_new } else { &self.nl };
        // SAFETY: nonfinite_partials(const double* v, long long count, double* partial): the
        // spectra hold 6 S complex values = 12 S doubles, read as doubles; partial holds at
        // least one value per block.
        unsafe {
            dev.launch(
                count,
                NonfinitePartials {
                    v: src,
                    count: count as i64,
                    partial: &mut self.partial,
                },
            )
        }?;
        Ok(self.reduce(dev, blocks(count), 1, &[])?[0] > 0.0)
    }

    pub(super) fn nonfinite_nonlinear(&mut self, dev: &Device) -> Result<bool, GpuError> {
        self.nonfinite(dev, false)
    }

    pub(super) fn nonfinite_update(&mut self, dev: &Device) -> Result<bool, GpuError> {
        self.nonfinite(dev, true)
    }

    /// (max |u_x| + |u_y| + |u_z|, <E:E>, <E:Q>, <E:S:E>) as sums over the grid.
    pub(super) fn report_sums(&mut self, dev: &Device) -> Result<(f64, f64, f64, f64), GpuError> {
        // SAFETY: report_partials(const double* ug, const double* e, const double* q,
        // const double* se, long long N, double* partial): ug 3 N, e, q and se 6 N doubles,
        // partial at least 4 per block; thread p < N reads index c N + p only.
        unsafe {
            dev.launch(
                self.n_len,
                ReportPartials {
                    ug: &self.ug,
                    e: &self.e,
                    q: &self.q,
                    se: &self.se,
                    N: self.n_len as i64,
                    partial: &mut self.partial,
                },
            )
        }?;
        let r = self.reduce(dev, blocks(self.n_len), 4, &[0])?;
        Ok((r[0], r[1], r[2], r[3]))
    }

    /// sum over the spectrum of |u|^2 (Parseval).
    pub(super) fn u_norm(&mut self, dev: &Device) -> Result<f64, GpuError> {
        // SAFETY: norm_partials(const double2* u, int n, double* partial): u_work holds 3 S
        // values, partial at least one per block; thread s < S reads index c S + s.
        unsafe {
            dev.launch(
                self.s_len,
                NormPartials {
                    u: &self.u_work,
                    n: self.n as i32,
                    partial: &mut self.partial,
                },
            )
        }?;
        Ok(self.reduce(dev, blocks(self.s_len), 1, &[])?[0])
    }

    /// The IMEX update into `q_new`.
    pub(super) fn imex(
        &mut self,
        dev: &Device,
        a: [f64; 3],
        bcoef: [f64; 2],
        dt: f64,
        diffusion: f64,
        two: bool,
    ) -> Result<(), GpuError> {
        // SAFETY: imex_update(const double2* q, const double2* nl, const double2* q_prev,
        // const double2* nl_prev, double2* out, int n, const double* k2, double a0, double a1,
        // double a2, double b0, double b1, double dt, double diffusion, int two): the five
        // spectra hold 6 S values each, k2 n doubles; thread s < S touches index c S + s.
        unsafe {
            dev.launch(
                self.s_len,
                ImexUpdate {
                    q: &self.q_hat,
                    nl: &self.nl,
                    q_prev: &self.q_prev,
                    nl_prev: &self.nl_prev,
                    out: &mut self.q_new,
                    n: self.n as i32,
                    k2: &self.k2,
                    a0: a[0],
                    a1: a[1],
                    a2: a[2],
                    b0: bcoef[0],
                    b1: bcoef[1],
                    dt,
                    diffusion,
                    two: i32::from(two),
                },
            )
        }
        .map_err(GpuError::from)
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
