//! The device side of the GPU mean-field step: the buffers, the transforms and every kernel
//! launch, on a [`motile_gpu::Device`] (CUDA, or the host emulation of the same kernels). The
//! only module of the crate that allows `unsafe`: the arguments' number, order and types are
//! the declarations' of `signatures.rs` (checked against `kernels.cu`), but the indices a kernel
//! touches are not checked by anything, so each launch states why they lie inside the buffers
//! it is given.
#![allow(unsafe_code)]

use crate::gpu::error::GpuError;
use crate::gpu::signatures::{
    ChangePartials, ClosureField, Contract, ContractGradient, DerivativeSpectra, ExplicitTerms,
    ImexUpdate, NormPartials, ReportPartials, ScaleDealias, Stokes, StrainSpectra, WarmStart,
};
use crate::gpu::work::Layout;
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
/// component (2 S doubles), grid fields `N = n^3` doubles (sizes from [`Layout`], which
/// [`crate::gpu::device_bytes`] adds up). Three scratch buffers hold, one after another within
/// a step, values whose lifetimes do not overlap (each is dead before the next is written):
///
/// | phase | `six` (6 spectra) | `wide` (9 fields or 6 spectra) | `big` (21 fields) | `u_next` (3 spectra) |
/// |---|---|---|---|---|
/// | Q to the grid | Q's spectra (transformed) | | | |
/// | closure | | | S | |
/// | fixed point | E's five spectra, then the deviatoric stress's | E's five fields, then the stress's (in place) | S | the next iterate |
/// | grad u, S:E | S:E | grad u (eight fields) | S, then u at 18 N | one spectrum's derivatives; u's copy |
/// | explicit terms | S:E, then the terms (in place) | grad u | grad Q at 0, u at 18 N | one spectrum's derivatives |
/// | IMEX update | the new Q | the terms' spectra | | |
///
/// At the commit the new Q's buffer becomes `q_hat` (and the old `q_prev`'s becomes `six`),
/// and the terms' spectra are copied into `nl_prev`.
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
    nl_prev: Buffer,
    has_prev: bool,
    /// The last accepted step's velocity (the warm start); untouched by a failing step.
    u_hat: Buffer,
    /// The fixed point's current iterate, and its next one (then scratch).
    u_work: Buffer,
    u_next: Buffer,
    /// Q on the grid.
    q: Buffer,
    /// Scratch of six spectra (see the table above).
    six: Buffer,
    /// Scratch of nine grid fields or six spectra.
    wide: Buffer,
    /// The closure's 21 lab-frame components per point, then scratch.
    big: Buffer,
    /// The fixed point's change partials (downloaded every iteration).
    partial: Buffer,
    /// The step's other reductions' partials, each in its own buffer so that one download at
    /// the end of the step reads them all (no host round trip in between): the closure's, the
    /// report's, the explicit terms' non-finite count, `|u|^2`, the update's non-finite count.
    step_partials: [Buffer; 5],
}

/// What the step's reductions give, read in one download at the end of the step
/// ([`Buffers::step_sums`]).
pub(super) struct StepSums {
    pub(super) min_eigenvalue: f64,
    pub(super) max_eigenvalue: f64,
    pub(super) entropy_sum: f64,
    pub(super) u_max: f64,
    /// Grid sums of E:E, E:Q and E:S:E.
    pub(super) e_sums: (f64, f64, f64),
    pub(super) terms_nonfinite: bool,
    pub(super) u_norm_sqr: f64,
    pub(super) update_nonfinite: bool,
}

/// Where u on the grid lies in `big` (after S is dead): behind the 18 fields of grad Q.
fn ug_at(n_len: usize) -> usize {
    18 * n_len
}

impl Buffers {
    pub(super) fn new(
        dev: &Device,
        n: usize,
        coef: &[f64],
        w: &Wavenumbers,
    ) -> Result<Self, GpuError> {
        let l = Layout::of(n);
        let (s_len, n_len) = (l.s, l.n3);
        Ok(Self {
            n,
            s_len,
            n_len,
            fft: dev.fft3(n, 1, Direction::Both)?,
            k1: dev.upload(&w.k1)?,
            k2: dev.upload(&w.k2)?,
            keep: dev.upload(&w.keep)?,
            coef: dev.upload(coef)?,
            q_hat: dev.zeros(l.spectra(6))?,
            q_prev: dev.zeros(l.spectra(6))?,
            nl_prev: dev.zeros(l.spectra(6))?,
            has_prev: false,
            u_hat: dev.zeros(l.spectra(3))?,
            u_work: dev.zeros(l.spectra(3))?,
            u_next: dev.zeros(l.spectra(3))?,
            q: dev.zeros(l.fields(6))?,
            six: dev.zeros(l.spectra(6))?,
            wide: dev.zeros(l.wide())?,
            big: dev.zeros(l.fields(21))?,
            partial: dev.zeros(l.partials())?,
            step_partials: [
                dev.zeros(l.step_partials()[0])?,
                dev.zeros(l.step_partials()[1])?,
                dev.zeros(l.step_partials()[2])?,
                dev.zeros(l.step_partials()[3])?,
                dev.zeros(l.step_partials()[4])?,
            ],
        })
    }

    /// Bytes of every buffer allocated (the FFT plan apart).
    #[cfg(test)]
    fn allocated_bytes(&self) -> usize {
        let f64s = [
            &self.k1,
            &self.k2,
            &self.coef,
            &self.q_hat,
            &self.q_prev,
            &self.nl_prev,
            &self.u_hat,
            &self.u_work,
            &self.u_next,
            &self.q,
            &self.six,
            &self.wide,
            &self.big,
            &self.partial,
        ];
        let step: usize = self.step_partials.iter().map(|b| b.len()).sum();
        8 * (f64s.iter().map(|b| b.len()).sum::<usize>() + step) + 4 * self.keep.len()
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

    /// Sum of the first `blocks * stride` partials of `partial`, `stride` per block: per
    /// slot, the block values in block order (max for the slots in `max_slots`).
    fn reduce(
        dev: &Device,
        partial: &Buffer,
        blocks: usize,
        stride: usize,
        max_slots: &[usize],
    ) -> Result<Vec<f64>, GpuError> {
        let host = dev.download_range(partial, 0, blocks * stride)?;
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

    /// `count` real fields from the first `count` spectra of `src` (destroyed) into `dst`, from
    /// its double `at` on.
    fn inverse_many(
        dev: &Device,
        fft: &Fft3,
        src: &mut Buffer,
        (dst, at): (&mut Buffer, usize),
        count: usize,
        (s, n): (usize, usize),
    ) -> Result<(), GpuError> {
        for c in 0..count {
            dev.inverse(fft, src, 2 * c * s, dst, at + c * n)?;
        }
        Ok(())
    }

    /// The first `count` real fields of `src` forward transformed into the first `count`
    /// spectra of `dst`.
    fn forward_many(
        dev: &Device,
        fwd: &Fft3,
        (src, n): (&Buffer, usize),
        (dst, s): (&mut Buffer, usize),
        count: usize,
    ) -> Result<(), GpuError> {
        for c in 0..count {
            dev.forward(fwd, src, c * n, dst, 2 * c * s)?;
        }
        Ok(())
    }

    /// Q's six spectra to the grid (through a copy in `six`), and the fixed point's first
    /// iterate (stepper.rs `warm_start`): the last accepted velocity, plus the Stokes flow of
    /// Q's change since the previous state where there is one.
    pub(super) fn inverse_q(&mut self, dev: &Device) -> Result<(), GpuError> {
        let (s, n) = (self.s_len, self.n_len);
        if self.has_prev {
            // SAFETY: warm_start(const double2* q, const double2* q_prev, const double2*
            // u_hat, double2* u, int n, const double* k1, const double* k2, const int* keep):
            // q_hat and q_prev hold 6 S values, u_hat and u_work 3 S, k1, k2 and keep n;
            // thread s < S reads index c S + s of each and writes u[i S + s] for i < 3.
            unsafe {
                dev.launch(
                    s,
                    WarmStart {
                        q: &self.q_hat,
                        q_prev: &self.q_prev,
                        u_hat: &self.u_hat,
                        u: &mut self.u_work,
                        n: self.n as i32,
                        k1: &self.k1,
                        k2: &self.k2,
                        keep: &self.keep,
                    },
                )
            }?;
        } else {
            dev.copy((&self.u_hat, 0), (&mut self.u_work, 0), 6 * s)?;
        }
        dev.copy((&self.q_hat, 0), (&mut self.six, 0), 12 * s)?;
        Self::inverse_many(dev, &self.fft, &mut self.six, (&mut self.q, 0), 6, (s, n))
    }

    /// The closure field into `big` (its partials: the smallest and largest eigenvalue, the
    /// entropy sum, read by [`Self::step_sums`]).
    pub(super) fn closure(
        &mut self,
        dev: &Device,
        deg: usize,
        with_entropy: bool,
    ) -> Result<(), GpuError> {
        // SAFETY: closure_field(const double* q, double* s21, const double* coef, int deg,
        // int with_entropy, long long N, double* partial): q holds 6 N doubles, big 21 N, coef
        // the 4 (deg + 1)^2 table coefficients uploaded for this degree, partial at least
        // 3 blocks; each thread reads point p < N and writes s21[21 p..21 p + 21] and its
        // block's three partials.
        unsafe {
            dev.launch(
                self.n_len,
                ClosureField {
                    q: &self.q,
                    s21: &mut self.big,
                    coef: &self.coef,
                    deg: deg as i32,
                    with_entropy: i32::from(with_entropy),
                    N: self.n_len as i64,
                    partial: &mut self.step_partials[0],
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The step's reductions, in one download (the first waits for the step's kernels, the
    /// others find nothing queued), each folded in block order as before.
    pub(super) fn step_sums(&self, dev: &Device) -> Result<StepSums, GpuError> {
        let p = &self.step_partials;
        let (n, s) = (blocks(self.n_len), blocks(self.s_len));
        let closure = Self::reduce(dev, &p[0], n, 3, &[0, 1])?;
        let report = Self::reduce(dev, &p[1], n, 4, &[0])?;
        let terms = Self::reduce(dev, &p[2], blocks(6 * self.s_len), 1, &[])?;
        let norm = Self::reduce(dev, &p[3], s, 1, &[])?;
        let update = Self::reduce(dev, &p[4], s, 1, &[])?;
        Ok(StepSums {
            min_eigenvalue: -closure[0],
            max_eigenvalue: closure[1],
            entropy_sum: closure[2],
            u_max: report[0],
            e_sums: (report[1], report[2], report[3]),
            terms_nonfinite: terms[0] > 0.0,
            u_norm_sqr: norm[0],
            update_nonfinite: update[0] > 0.0,
        })
    }

    /// E of the current u on the grid: its first five components (E is trace-free), 5 strain
    /// spectra in `six`, 5 inverse transforms into `wide`.
    pub(super) fn strain_to_grid(&mut self, dev: &Device) -> Result<(), GpuError> {
        // SAFETY: strain_spectra(const double2* u, double2* out, int n, const double* k1):
        // u_work holds 3 S values, six 6 S, k1 n; thread s < S reads u[i S + s] and writes
        // out[c S + s] for c < 5.
        unsafe {
            dev.launch(
                self.s_len,
                StrainSpectra {
                    u: &self.u_work,
                    out: &mut self.six,
                    n: self.n as i32,
                    k1: &self.k1,
                },
            )
        }?;
        let (s, n) = (self.s_len, self.n_len);
        Self::inverse_many(
            dev,
            &self.fft,
            &mut self.six,
            (&mut self.wide, 0),
            5,
            (s, n),
        )
    }

    /// The active stress -Q + zeta S:E over the grid E in `wide`: its deviatoric part's first
    /// five components forward transformed into `six` (unscaled: [`Self::stokes`] scales and
    /// dealiases them as it reads them, and completes the trace-free tensor).
    pub(super) fn stress(&mut self, dev: &Device, zeta: f64) -> Result<(), GpuError> {
        self.contract(dev, zeta)?;
        let (s, n) = (self.s_len, self.n_len);
        Self::forward_many(dev, &self.fft, (&self.wide, n), (&mut self.six, s), 5)
    }

    /// The stress `-Q + zeta S:E` over the grid E in `wide` (five components), its deviatoric
    /// part's first five components in place.
    fn contract(&mut self, dev: &Device, zeta: f64) -> Result<(), GpuError> {
        // SAFETY: contract(const double* s21, double* e, const double* q, double zeta,
        // long long N): big holds 21 N doubles, q 6 N, wide max(9 N, 12 S) >= 6 N; thread
        // p < N reads s21[21 p..21 p + 21] and q[c N + p] for c < 6, and reads and writes
        // index c N + p of wide for c < 5.
        unsafe {
            dev.launch(
                self.n_len,
                Contract {
                    s21: &self.big,
                    e: &mut self.wide,
                    q: &self.q,
                    zeta,
                    N: self.n_len as i64,
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// Scale by 1/n^3 and dealias the six spectra at the start of `wide` (the explicit
    /// terms'; the stress's are scaled and dealiased by [`Self::stokes`] as it reads them).
    fn scale_dealias(&mut self, dev: &Device) -> Result<(), GpuError> {
        let total = 6 * self.s_len;
        let target = &mut self.wide;
        // SAFETY: scale_dealias(double2* c, long long count, int n, double scale,
        // const int* keep, int dealias, double* partial): wide holds at least `count` = 6 S
        // complex values (max(9 N, 12 S) doubles), keep n ints, partial at least one per
        // block; thread t < count touches c[t] only, each block writes its partial.
        unsafe {
            dev.launch(
                total,
                ScaleDealias {
                    c: target,
                    count: total as i64,
                    n: self.n as i32,
                    scale: 1.0 / self.n_len as f64,
                    keep: &self.keep,
                    dealias: 1,
                    partial: &mut self.step_partials[2],
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The Stokes velocity of the stress spectra (raw forward transforms, scaled and
    /// dealiased as they are read) into `u_next`.
    pub(super) fn stokes(&mut self, dev: &Device) -> Result<(), GpuError> {
        // SAFETY: stokes(const double2* sigma, double2* u, int n, const double* k1,
        // const double* k2, double scale, const int* keep): six holds 6 S values, u_next 3 S,
        // k1, k2 and keep n; thread s < S reads sigma[c S + s] and writes u[i S + s].
        unsafe {
            dev.launch(
                self.s_len,
                Stokes {
                    sigma: &self.six,
                    u: &mut self.u_next,
                    n: self.n as i32,
                    k1: &self.k1,
                    k2: &self.k2,
                    scale: 1.0 / self.n_len as f64,
                    keep: &self.keep,
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The fixed point's relative change between `u_next` and `u_work` (solver.rs rel_change).
    pub(super) fn change(&mut self, dev: &Device) -> Result<f64, GpuError> {
        // SAFETY: change_partials(const double2* a, const double2* b, int n, double* partial):
        // both hold 3 S values, partial at least 2 per block; thread s < S reads index c S + s.
        unsafe {
            dev.launch(
                self.s_len,
                ChangePartials {
                    a: &self.u_next,
                    b: &self.u_work,
                    n: self.n as i32,
                    partial: &mut self.partial,
                },
            )
        }?;
        let r = Self::reduce(dev, &self.partial, blocks(self.s_len), 2, &[])?;
        Ok((r[0] / r[1].max(FLOW_FLOOR * FLOW_FLOOR)).sqrt())
    }

    /// The new iterate becomes the current one.
    pub(super) fn accept_u(&mut self) {
        std::mem::swap(&mut self.u_work, &mut self.u_next);
    }

    /// grad u on the grid (`wide`), S:E with E from it (`six`; S is dead after), u on the
    /// grid (`big` at 18 N): the explicit terms' and the report's inputs.
    /// [`Self::report_sums`] must read them before [`Self::explicit_terms`] writes grad Q
    /// over `big`.
    pub(super) fn gradients(&mut self, dev: &Device) -> Result<(), GpuError> {
        let (s, n) = (self.s_len, self.n_len);
        // Eight components: d_z u_z = -(d_x u_x + d_y u_y) (div u = 0) where it is read.
        for i in 0..3 {
            self.derivatives(dev, Spectrum::U, i)?;
            let dst = (&mut self.wide, 3 * i * n);
            let count = if i == 2 { 2 } else { 3 };
            Self::inverse_many(dev, &self.fft, &mut self.u_next, dst, count, (s, n))?;
        }
        // SAFETY: contract_gradient(const double* s21, const double* g, double* se,
        // long long N): big holds 21 N doubles, wide at least 9 N, six 12 S >= 6 N; thread
        // p < N reads s21[21 p..21 p + 21] and g[m N + p] for m < 8, writes se[c N + p].
        unsafe {
            dev.launch(
                n,
                ContractGradient {
                    s21: &self.big,
                    g: &self.wide,
                    se: &mut self.six,
                    N: n as i64,
                },
            )
        }?;
        dev.copy((&self.u_work, 0), (&mut self.u_next, 0), 6 * s)?;
        let dst = (&mut self.big, ug_at(n));
        Self::inverse_many(dev, &self.fft, &mut self.u_next, dst, 3, (s, n))
    }

    /// The three derivative spectra of component `first` of u (`u_work`) or Q (`q_hat`) into
    /// `u_next`.
    fn derivatives(&mut self, dev: &Device, of: Spectrum, first: usize) -> Result<(), GpuError> {
        let input = match of {
            Spectrum::U => &self.u_work,
            Spectrum::Q => &self.q_hat,
        };
        // SAFETY: derivative_spectra(const double2* c, int first, double2* out, int comps,
        // int n, const double* k1): the input holds 3 S (u_work, first < 3) or 6 S (q_hat,
        // first < 6) values, u_next 3 S, k1 n; thread s < S reads c[first S + s] and writes
        // out[dir S + s] for dir < 3 (one component).
        unsafe {
            dev.launch(
                self.s_len,
                DerivativeSpectra {
                    c: input,
                    first: first as i32,
                    out: &mut self.u_next,
                    comps: 1,
                    n: self.n as i32,
                    k1: &self.k1,
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The explicit terms' spectra into `wide` (grad Q to the grid over E in `big`, one Q
    /// component at a time; the products over S:E in `six`; forward, dealiased).
    pub(super) fn explicit_terms(&mut self, dev: &Device) -> Result<(), GpuError> {
        let (s, n) = (self.s_len, self.n_len);
        for m in 0..6 {
            self.derivatives(dev, Spectrum::Q, m)?;
            let dst = (&mut self.big, 3 * m * n);
            Self::inverse_many(dev, &self.fft, &mut self.u_next, dst, 3, (s, n))?;
        }
        // SAFETY: explicit_terms(const double* ug, long long ug_at, const double* g,
        // const double* q, const double* dq, double* se, long long N): big holds 21 N doubles
        // (dq its first 18 N, u the 3 N from ug_at = 18 N), wide at least 9 N, q 6 N, six
        // 12 S >= 6 N; thread p < N reads index m N + p of each (ug from ug_at) and writes
        // se[c N + p] for c < 6.
        unsafe {
            dev.launch(
                self.n_len,
                ExplicitTerms {
                    ug: &self.big,
                    ug_at: ug_at(n) as i64,
                    g: &self.wide,
                    q: &self.q,
                    dq: &self.big,
                    se: &mut self.six,
                    N: self.n_len as i64,
                },
            )
        }?;
        Self::forward_many(dev, &self.fft, (&self.six, n), (&mut self.wide, s), 6)?;
        self.scale_dealias(dev)
    }

    /// The partials of (max |u_x| + |u_y| + |u_z|, <E:E>, <E:Q>, <E:S:E>) as sums over the
    /// grid (read by [`Self::step_sums`]); after [`Self::gradients`], before
    /// [`Self::explicit_terms`].
    pub(super) fn report_sums(&mut self, dev: &Device) -> Result<(), GpuError> {
        // SAFETY: report_partials(const double* ug, long long ug_at, const double* g,
        // const double* q, const double* se, long long N, double* partial): big holds 21 N
        // doubles (u the 3 N from ug_at = 18 N), wide (grad u) at least 9 N, q 6 N, six
        // 12 S >= 6 N, partial at least 4 per block; thread p < N reads index c N + p only
        // (ug from ug_at).
        unsafe {
            dev.launch(
                self.n_len,
                ReportPartials {
                    ug: &self.big,
                    ug_at: ug_at(self.n_len) as i64,
                    g: &self.wide,
                    q: &self.q,
                    se: &self.six,
                    N: self.n_len as i64,
                    partial: &mut self.step_partials[1],
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The partials of the sum over the spectrum of |u|^2 (Parseval; read by
    /// [`Self::step_sums`]).
    pub(super) fn u_norm(&mut self, dev: &Device) -> Result<(), GpuError> {
        // SAFETY: norm_partials(const double2* u, int n, double* partial): u_work holds 3 S
        // values, partial at least one per block; thread s < S reads index c S + s.
        unsafe {
            dev.launch(
                self.s_len,
                NormPartials {
                    u: &self.u_work,
                    n: self.n as i32,
                    partial: &mut self.step_partials[3],
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The IMEX update into `six`.
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
        // double a2, double b0, double b1, double dt, double diffusion, int two,
        // double* partial): q_hat,
        // q_prev, nl_prev and six hold 6 S values each, wide (the explicit terms) at least
        // 6 S, k2 n doubles, partial (the non-finite counts) at least one per block; thread
        // s < S touches index c S + s, each block writes its partial.
        unsafe {
            dev.launch(
                self.s_len,
                ImexUpdate {
                    q: &self.q_hat,
                    nl: &self.wide,
                    q_prev: &self.q_prev,
                    nl_prev: &self.nl_prev,
                    out: &mut self.six,
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
                    partial: &mut self.step_partials[4],
                },
            )
        }
        .map_err(GpuError::from)
    }

    /// The step is accepted: Q^{n-1} <- Q^n <- Q^{n+1} (the buffers rotate: the new Q's in
    /// `six` becomes `q_hat`, the old `q_prev`'s becomes `six`), N^{n-1} <- N^n (copied from
    /// `wide`), and the converged velocity becomes the next warm start.
    pub(super) fn commit_step(&mut self, dev: &Device) -> Result<(), GpuError> {
        dev.copy((&self.wide, 0), (&mut self.nl_prev, 0), 12 * self.s_len)?;
        std::mem::swap(&mut self.u_hat, &mut self.u_work);
        std::mem::swap(&mut self.q_prev, &mut self.q_hat);
        std::mem::swap(&mut self.q_hat, &mut self.six);
        self.has_prev = true;
        Ok(())
    }
}

/// Whose derivatives: u's (`u_work`) or Q's (`q_hat`).
#[derive(Clone, Copy)]
enum Spectrum {
    U,
    Q,
}

#[cfg(test)]
mod tests {
    use super::{Buffers, Wavenumbers};
    use crate::gpu::signatures::KERNELS;
    use crate::gpu::work::device_bytes;
    use crate::solver::grid::SpectralGrid;
    use motile_gpu::{Backend, Device};

    /// The buffers allocated on the host emulation take the bytes `device_bytes` counts, at a
    /// few small grids.
    #[test]
    fn allocation_is_the_counted_bytes() {
        let opened = Device::open(Backend::HostEmulation, &KERNELS);
        let Some(dev) = motile_gpu::open_or_skip(opened, Backend::HostEmulation) else {
            return;
        };
        let deg = 5;
        let coef = vec![0.0; 4 * (deg + 1) * (deg + 1)];
        for n in [4, 6, 8, 12] {
            let w = Wavenumbers::of(&SpectralGrid::new(n));
            let b = Buffers::new(&dev, n, &coef, &w).unwrap();
            assert_eq!(b.allocated_bytes(), device_bytes(n, deg), "n = {n}");
        }
    }

    /// The step's buffers at 256^3: 33 half spectra, 27 grid fields and a nine-field scratch
    /// (9.31 GB; 57 spectra and 75 fields, 17.79 GB, before they were shared).
    #[test]
    fn bytes_at_256() {
        let (n, deg) = (256, 20);
        let (s, n3) = (n * n * (n / 2 + 1), n * n * n);
        let bytes = device_bytes(n, deg);
        let fields = 16 * 33 * s + 8 * (27 + 9) * n3;
        // Beside them the tables and the reductions' partials (6 MB).
        assert!(bytes >= fields && bytes - fields < 1 << 24, "{bytes}");
        assert!(bytes < 9_310_000_000, "{bytes}");
        eprintln!("device_bytes(256) = {bytes}");
    }
}
