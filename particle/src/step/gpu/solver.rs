//! The contact solver (BBPGD, [`crate::step::contact::ContactSolver`]) with its products and
//! reductions on the device (`contacts.cu`): see [`super`].
//!
//! Each iteration runs the same arithmetic in the same order as the CPU's: the per-rod lists of
//! constraints in constraint order (an atomic scatter, then each list sorted), the forces and
//! local drag per rod, the rates per constraint, and the reductions in the CPU's fixed chunks
//! ([`CHUNK`] constraints per thread, the chunks' partials folded in order on the host). So
//! the multipliers are the CPU's bit for bit wherever the device's arithmetic is IEEE (the
//! emulation; CUDA with `fmad` off, as the device opens it). The host decides each step from
//! four numbers (the residual and the Barzilai-Borwein products): one small download per
//! iteration, the round trip this room still has.
#![allow(unsafe_code)]

use super::contacts::DeviceConstraints;
use super::device::{GpuStep, int};
use super::signatures::{
    SolverApgdStats, SolverAxes, SolverConstraints, SolverDots, SolverExtrapolate, SolverGp,
    SolverIndexCount, SolverIndexOrder, SolverIndexScatter, SolverProject, SolverQ, SolverRods,
    SolverScale, SolverStats,
};
use super::update::DeviceRods;
use crate::step::contact::{
    ContactError, ContactParams, ContactReport, LIPSCHITZ_MARGIN, Momentum, POWER_ITERATIONS,
    Stall, next_step,
};
use motile_gpu::{Buffer, GpuError};

// The fold kernels (solver_stats, solver_apgd_stats, solver_dots, step_stats) stage
// FOLD_THREADS = 256 elements per round in shared memory, one per thread of a block: every
// launch has that many.
const _: () = assert!(motile_gpu::THREADS == 256);

/// The CPU's reduction chunk, so the device's partial sums are the CPU's.
use motile_analysis::reduce::CHUNK;

/// A failure of the device solver: the device's, or the solver's own (as on the CPU).
#[derive(Debug, thiserror::Error)]
pub enum DeviceContactError {
    /// The device failed.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The solver did not converge or produced a non-finite value.
    #[error(transparent)]
    Contact(#[from] ContactError),
    /// The mobility's final velocities failed (a level whose contact forces act through its
    /// hydrodynamics: `sbt`).
    #[error(transparent)]
    Hydrodynamics(#[from] crate::hydro::mobility::MobilityError),
}

/// One contact problem on the device (the twin of [`crate::step::contact::ContactProblem`]):
/// the rods, their constraints, the velocities without contacts (triples), the local drag
/// `(trans, rot)` ([`crate::hydro::mobility::LocalDrag::coefficients`]) and the time step.
#[derive(Clone, Copy, Debug)]
pub struct DeviceContactProblem<'a> {
    /// The rods.
    pub rods: &'a DeviceRods,
    /// Their constraints.
    pub cons: &'a DeviceConstraints,
    /// Velocities without contacts.
    pub free_v: &'a Buffer,
    /// Angular velocities without contacts.
    pub free_w: &'a Buffer,
    /// The local drag's coefficients.
    pub drag: (f64, f64),
    /// The time step.
    pub dt: f64,
}

/// Where a solve starts: multipliers from the host (empty: zero) or on the device (at least
/// one per constraint, none negative).
#[derive(Clone, Copy, Debug)]
pub(super) enum Start<'a> {
    /// From the host, in constraint order.
    Host(&'a [f64]),
    /// On the device, in constraint order.
    Device(&'a Buffer),
}

/// The problem's buffers on the device.
pub(super) struct Problem<'a> {
    cons: &'a DeviceConstraints,
    p: Buffer,
    start: Buffer<i32>,
    entries: Buffer<i32>,
    pub(super) vel: Buffer,
    /// Each rod's contact force and torque (6 values) of the last product.
    pub(super) ft: Buffer,
    n: usize,
    drag: (f64, f64),
    dt: f64,
}

/// Multipliers and their gradient on the device.
struct Multipliers {
    lam: Buffer,
    g: Buffer,
}

/// A solved problem: its buffers, the multipliers and the last gradient on the device.
pub(super) struct Solved<'a> {
    pub(super) prob: Problem<'a>,
    pub(super) lam: Buffer,
    g: Buffer,
    iterations: usize,
    residual: f64,
    /// Of the iterations, APGD's.
    accelerated: usize,
}

/// What the iterations of a solve reached: the multipliers with their gradient, the
/// iterations (of them APGD's) and the residual.
struct Iterated {
    multipliers: Multipliers,
    iterations: usize,
    accelerated: usize,
    residual: f64,
}

impl Solved<'_> {
    /// The multipliers, and each rod's contact velocities and forces under them (6 values
    /// per rod each). The solve's last product was of the final multipliers (the start's,
    /// where no iteration ran; zero from a cold start), so `vel` and `ft` are theirs already.
    pub(super) fn into_forces(self) -> (Buffer, Buffer, Buffer) {
        (self.lam, self.prob.vel, self.prob.ft)
    }
}

impl GpuStep {
    /// Solve `problem` from `initial` (empty: zero), as
    /// [`crate::step::contact::ContactSolver::solve`] does: the multipliers and the report.
    pub fn solve_contacts(
        &self,
        problem: DeviceContactProblem<'_>,
        params: &ContactParams,
        initial: &[f64],
    ) -> Result<(Vec<f64>, ContactReport), DeviceContactError> {
        match self.solve_on_device(problem, params, Start::Host(initial))? {
            None => Ok((Vec::new(), ContactReport::default())),
            Some(s) => self.report(&s),
        }
    }

    /// The multipliers (downloaded) and the report of a solved problem.
    pub(super) fn report(
        &self,
        s: &Solved<'_>,
    ) -> Result<(Vec<f64>, ContactReport), DeviceContactError> {
        let (lam, g) = (self.dev.download(&s.lam)?, self.dev.download(&s.g)?);
        let active = lam.iter().filter(|&&l| l > 0.0).count();
        let predicted_overlap = g
            .iter()
            .map(|&x| -x)
            .fold(f64::NEG_INFINITY, f64::max)
            .max(0.0);
        Ok((
            lam,
            ContactReport {
                constraints: s.prob.cons.len,
                active,
                iterations: s.iterations,
                accelerated: s.accelerated,
                residual: s.residual,
                predicted_overlap,
            },
        ))
    }

    /// [`Self::solve_contacts`] leaving its results on the device (`None`: no constraints).
    pub(super) fn solve_on_device<'a>(
        &self,
        problem: DeviceContactProblem<'a>,
        params: &ContactParams,
        initial: Start<'_>,
    ) -> Result<Option<Solved<'a>>, DeviceContactError> {
        if problem.cons.len == 0 {
            return Ok(None);
        }
        check_problem(&problem, initial)?;
        let mut prob = self.problem(&problem)?;
        let q = self.rate_offsets(&problem)?;
        let start = self.start(&mut prob, &q, initial)?;
        let Iterated {
            multipliers: Multipliers { lam, g },
            iterations,
            accelerated,
            residual,
        } = self.iterate(&mut prob, &q, start, params)?;
        Ok(Some(Solved {
            prob,
            lam,
            g,
            iterations,
            residual,
            accelerated,
        }))
    }

    /// The problem's buffers: the per-rod lists of constraints in constraint order (an atomic
    /// scatter, then each list sorted) and the rods' axes.
    fn problem<'a>(
        &self,
        problem: &DeviceContactProblem<'a>,
    ) -> Result<Problem<'a>, DeviceContactError> {
        let DeviceContactProblem {
            rods,
            cons,
            drag,
            dt,
            ..
        } = *problem;
        let (m, n) = (cons.len, rods.len);
        let (mi, ni) = (int(m, "constraints")?, int(n, "rods")?);
        let dev = &self.dev;
        let mut counts = dev.zeros::<i32>(n)?;
        let mut start = dev.zeros::<i32>(n + 1)?;
        let mut fill = dev.zeros::<i32>(n)?;
        let mut entries = dev.zeros::<i32>(2 * m)?;
        let mut p = dev.zeros::<f64>(3 * n)?;
        // SAFETY: thread k < m reads ci[k], cj[k] (m), rod indices below n, and adds to
        // counts there (n).
        unsafe {
            dev.launch(
                m,
                SolverIndexCount {
                    ci: &cons.i,
                    cj: &cons.j,
                    counts: &mut counts,
                    m: mi,
                },
            )?;
        }
        self.scan(&counts, &mut start, n)?;
        // SAFETY: thread k < m writes entries at start[r] + rank for its two rods r, the ranks
        // 0..counts[r] (atomics on fill, n): below start[r + 1] <= 2 m.
        unsafe {
            dev.launch(
                m,
                SolverIndexScatter {
                    ci: &cons.i,
                    cj: &cons.j,
                    start: &start,
                    fill: &mut fill,
                    entries: &mut entries,
                    m: mi,
                },
            )?;
        }
        // SAFETY: thread r < n sorts entries[start[r]..start[r + 1]] (inside 0..2 m).
        unsafe {
            dev.launch(
                n,
                SolverIndexOrder {
                    start: &start,
                    entries: &mut entries,
                    n: ni,
                },
            )?;
            // Thread r < n reads q[4 r..4 r + 4] and writes p[3 r..3 r + 3] (checked sizes).
            dev.launch(
                n,
                SolverAxes {
                    q: &rods.q,
                    p: &mut p,
                    n: ni,
                },
            )?;
        }
        Ok(Problem {
            cons,
            p,
            start,
            entries,
            vel: dev.zeros::<f64>(6 * n)?,
            ft: dev.zeros::<f64>(6 * n)?,
            n,
            drag,
            dt,
        })
    }

    /// Each constraint's rate of approach under the velocities without contacts, times `dt`
    /// (the gradient's shift, the CPU's `q`).
    fn rate_offsets(&self, problem: &DeviceContactProblem<'_>) -> Result<Buffer, GpuError> {
        let cons = problem.cons;
        let m = cons.len;
        let mut q = self.dev.zeros::<f64>(m)?;
        // SAFETY: thread k < m reads row k (10 m), ci[k], cj[k] < n and the free velocities'
        // triples of both (3 n), and writes q[k] (m).
        unsafe {
            self.dev.launch(
                m,
                SolverQ {
                    rows: &cons.rows,
                    ci: &cons.i,
                    cj: &cons.j,
                    v: problem.free_v,
                    w: problem.free_w,
                    q: &mut q,
                    m: int(m, "constraints")?,
                    dt: problem.dt,
                },
            )?;
        }
        Ok(q)
    }

    /// The multipliers a solve starts from and their gradient. From the host: warm where any
    /// multiplier is positive (the CPU's rule). From the device: always (from all zeros the
    /// warm start's gradient is `q` itself).
    fn start(
        &self,
        prob: &mut Problem<'_>,
        q: &Buffer,
        initial: Start<'_>,
    ) -> Result<Multipliers, GpuError> {
        let (dev, m) = (&self.dev, prob.cons.len);
        let warm = match initial {
            Start::Host(h) if h.iter().any(|&l| l > 0.0) => {
                Some(dev.upload(&h.iter().map(|l| l.max(0.0)).collect::<Vec<f64>>())?)
            }
            Start::Host(_) => None,
            Start::Device(b) => {
                let mut lam = dev.zeros::<f64>(m)?;
                dev.copy((b, 0), (&mut lam, 0), m)?;
                Some(lam)
            }
        };
        let mut g = dev.zeros::<f64>(m)?;
        match warm {
            Some(lam) => {
                self.apply(prob, &lam, Some(q), &mut g)?;
                Ok(Multipliers { lam, g })
            }
            None => {
                dev.copy((q, 0), (&mut g, 0), m)?;
                let lam = dev.zeros::<f64>(m)?;
                Ok(Multipliers { lam, g })
            }
        }
    }

    /// The Barzilai-Borwein projected gradient iterations from `start` until the residual
    /// meets the tolerance, handing over to APGD where they stall (the CPU's rule).
    fn iterate(
        &self,
        prob: &mut Problem<'_>,
        q: &Buffer,
        start: Multipliers,
        params: &ContactParams,
    ) -> Result<Iterated, DeviceContactError> {
        let Multipliers { mut lam, mut g } = start;
        let (dev, m) = (&self.dev, prob.cons.len);
        let mi = int(m, "constraints")?;
        let mut partial = dev.zeros::<f64>(4 * m.div_ceil(CHUNK))?;
        let mut res = self.stats(&lam, &lam, &g, &g, &mut partial, m)?[0];
        let mut iterations = 0;
        let done = |lam, g, iterations, residual| Iterated {
            multipliers: Multipliers { lam, g },
            iterations,
            accelerated: 0,
            residual,
        };
        if res <= params.tolerance {
            return Ok(done(lam, g, iterations, res));
        }
        let mut alpha = self.first_step(prob, &lam, &g, &mut partial)?;
        let mut stall = Stall::new(res, params);
        let mut lam_new = dev.zeros::<f64>(m)?;
        let mut g_new = dev.zeros::<f64>(m)?;
        loop {
            iterations += 1;
            // SAFETY: thread k < m reads lam[k], g[k] and writes lam_new[k] (m each).
            unsafe {
                dev.launch(
                    m,
                    SolverProject {
                        lam: &lam,
                        g: &g,
                        lam_new: &mut lam_new,
                        m: mi,
                        alpha,
                    },
                )?;
            }
            self.apply(prob, &lam_new, Some(q), &mut g_new)?;
            let [r, ss, sy, yy] = self.stats(&lam, &lam_new, &g, &g_new, &mut partial, m)?;
            res = r;
            if !res.is_finite() {
                return Err(ContactError::NonFinite(iterations).into());
            }
            std::mem::swap(&mut lam, &mut lam_new);
            std::mem::swap(&mut g, &mut g_new);
            match next_step(alpha, iterations, res, [ss, sy, yy], params)? {
                Some(a) => alpha = a,
                None => return Ok(done(lam, g, iterations, res)),
            }
            if stall.stalled(iterations, res) {
                return self.accelerate(prob, q, Multipliers { lam, g }, params, iterations);
            }
        }
    }

    /// APGD from `start` where BBPGD stalled after `done` iterations (the CPU's `accelerate`).
    fn accelerate(
        &self,
        prob: &mut Problem<'_>,
        q: &Buffer,
        start: Multipliers,
        params: &ContactParams,
        done: usize,
    ) -> Result<Iterated, DeviceContactError> {
        let (dev, m) = (&self.dev, prob.cons.len);
        let mi = int(m, "constraints")?;
        let nchunks = m.div_ceil(CHUNK);
        let mut partial = dev.zeros::<f64>(4 * nchunks)?;
        let step = 1.0 / (LIPSCHITZ_MARGIN * self.largest_eigenvalue(prob, &mut partial)?);
        let Multipliers {
            lam: mut x,
            g: mut gx,
        } = start;
        let (mut y, mut gy) = (dev.zeros::<f64>(m)?, dev.zeros::<f64>(m)?);
        dev.copy((&x, 0), (&mut y, 0), m)?;
        dev.copy((&gx, 0), (&mut gy, 0), m)?;
        let (mut xn, mut gn) = (dev.zeros::<f64>(m)?, dev.zeros::<f64>(m)?);
        let mut momentum = Momentum::new();
        let mut iterations = done;
        loop {
            iterations += 1;
            // SAFETY: thread k < m reads y[k], gy[k] and writes xn[k] (m each).
            unsafe {
                dev.launch(
                    m,
                    SolverProject {
                        lam: &y,
                        g: &gy,
                        lam_new: &mut xn,
                        m: mi,
                        alpha: step,
                    },
                )?;
            }
            self.apply(prob, &xn, Some(q), &mut gn)?;
            // SAFETY: block c < ceil(m / CHUNK) (FOLD_THREADS threads) reads the four vectors
            // at c CHUNK..min((c + 1) CHUNK, m) (m each) and writes partial[2 c..2 c + 2]
            // (4 ceil(m / CHUNK) allocated).
            unsafe {
                dev.launch(
                    nchunks * motile_gpu::THREADS as usize,
                    SolverApgdStats {
                        x: &x,
                        x_new: &xn,
                        y: &y,
                        g_new: &gn,
                        partial: &mut partial,
                        m: mi,
                        chunk: CHUNK as i32,
                    },
                )?;
            }
            let part = dev.download_range(&partial, 0, 2 * nchunks)?;
            let [residual, uphill] = part
                .chunks(2)
                .fold([0.0f64; 2], |acc, a| [acc[0].max(a[0]), acc[1] + a[1]]);
            if !residual.is_finite() {
                return Err(ContactError::NonFinite(iterations).into());
            }
            if residual <= params.tolerance {
                return Ok(Iterated {
                    multipliers: Multipliers { lam: xn, g: gn },
                    iterations,
                    accelerated: iterations - done,
                    residual,
                });
            }
            if iterations >= params.max_iterations {
                return Err(ContactError::NoConvergence {
                    iterations,
                    residual,
                    tolerance: params.tolerance,
                }
                .into());
            }
            let beta = momentum.beta(uphill);
            // SAFETY: thread k < m reads xn, x, gn, gx at k and writes y[k], gy[k] (m each).
            unsafe {
                dev.launch(
                    m,
                    SolverExtrapolate {
                        x_new: &xn,
                        x: &x,
                        g_new: &gn,
                        g: &gx,
                        y: &mut y,
                        gy: &mut gy,
                        m: mi,
                        beta,
                    },
                )?;
            }
            std::mem::swap(&mut x, &mut xn);
            std::mem::swap(&mut gx, &mut gn);
        }
    }

    /// The largest eigenvalue of `A` by power iteration from the uniform vector (the CPU's
    /// `largest_eigenvalue`).
    fn largest_eigenvalue(
        &self,
        prob: &mut Problem<'_>,
        partial: &mut Buffer,
    ) -> Result<f64, GpuError> {
        let (dev, m) = (&self.dev, prob.cons.len);
        let (mi, nchunks) = (int(m, "constraints")?, m.div_ceil(CHUNK));
        let mut v = dev.upload(&vec![1.0 / (m as f64).sqrt(); m])?;
        let mut av = dev.zeros::<f64>(m)?;
        let mut estimate = 0.0;
        for _ in 0..POWER_ITERATIONS {
            self.apply(prob, &v, None, &mut av)?;
            // SAFETY: block c < ceil(m / CHUNK) reads a = b = av at c CHUNK..min((c + 1)
            // CHUNK, m) and writes partial[2 c..2 c + 2] (4 ceil(m / CHUNK) allocated).
            unsafe {
                dev.launch(
                    nchunks * motile_gpu::THREADS as usize,
                    SolverDots {
                        a: &av,
                        b: &av,
                        partial,
                        m: mi,
                        chunk: CHUNK as i32,
                    },
                )?;
            }
            let part = dev.download_range(partial, 0, 2 * nchunks)?;
            estimate = part.iter().step_by(2).sum::<f64>().sqrt();
            if !(estimate > 0.0 && estimate.is_finite()) {
                return Ok(1.0);
            }
            // SAFETY: thread k < m reads av[k] and writes v[k] (m each).
            unsafe {
                dev.launch(
                    m,
                    SolverScale {
                        a: &av,
                        out: &mut v,
                        m: mi,
                        d: estimate,
                    },
                )?;
            }
        }
        Ok(estimate)
    }

    /// The first step length, Cauchy's: `gp.gp / gp.A gp` for the projected gradient `gp` of
    /// `(lam, g)` (1 where the denominator is not positive), the products summed in the CPU's
    /// chunks.
    fn first_step(
        &self,
        prob: &mut Problem<'_>,
        lam: &Buffer,
        g: &Buffer,
        partial: &mut Buffer,
    ) -> Result<f64, GpuError> {
        let (dev, m) = (&self.dev, prob.cons.len);
        let (mi, nchunks) = (int(m, "constraints")?, m.div_ceil(CHUNK));
        let mut gp = dev.zeros::<f64>(m)?;
        let mut ag = dev.zeros::<f64>(m)?;
        // SAFETY: thread k < m reads lam[k], g[k] and writes gp[k] (m each).
        unsafe {
            dev.launch(
                m,
                SolverGp {
                    lam,
                    g,
                    gp: &mut gp,
                    m: mi,
                },
            )?;
        }
        self.apply(prob, &gp, None, &mut ag)?;
        // SAFETY: block c < ceil(m / CHUNK) (its THREADS = FOLD_THREADS threads load its
        // elements in turn, its first thread folds them) reads a, b at c
        // CHUNK..min((c + 1) CHUNK, m) and writes partial[2 c..2 c + 2] (4 ceil(m / CHUNK)
        // allocated).
        unsafe {
            dev.launch(
                nchunks * motile_gpu::THREADS as usize,
                SolverDots {
                    a: &gp,
                    b: &ag,
                    partial,
                    m: mi,
                    chunk: CHUNK as i32,
                },
            )?;
        }
        let part = dev.download_range(partial, 0, 2 * nchunks)?;
        let gg: f64 = part.iter().step_by(2).sum();
        let gag: f64 = part.iter().skip(1).step_by(2).sum();
        Ok(if gag > 0.0 { gg / gag } else { 1.0 })
    }

    /// `out = dt D^T M D lam + shift` on the device (the CPU's `apply`).
    pub(super) fn apply(
        &self,
        prob: &mut Problem<'_>,
        lam: &Buffer,
        shift: Option<&Buffer>,
        out: &mut Buffer,
    ) -> Result<(), GpuError> {
        let (m, n) = (prob.cons.len, prob.n);
        let (mi, ni) = (int(m, "constraints")?, int(n, "rods")?);
        // SAFETY: thread r < n reads p (3 n), its entries start[r]..start[r + 1] (< 2 m), each
        // naming a constraint a < m: rows (10 m) and lam[a] (m); writes vel and ft at
        // 6 r..6 r + 6 (6 n each).
        unsafe {
            self.dev.launch(
                n,
                SolverRods {
                    p: &prob.p,
                    start: &prob.start,
                    entries: &prob.entries,
                    rows: &prob.cons.rows,
                    lam,
                    vel: &mut prob.vel,
                    ft: &mut prob.ft,
                    n: ni,
                    trans: prob.drag.0,
                    rot: prob.drag.1,
                },
            )?;
        }
        // The shift (or, unused, lam itself when there is none: has_shift = 0).
        let (shift, has) = shift.map_or((lam, 0), |s| (s, 1));
        // SAFETY: thread k < m reads row k, ci[k], cj[k] < n, vel of both (6 n) and shift[k]
        // when has_shift (m), and writes out[k] (m).
        unsafe {
            self.dev.launch(
                m,
                SolverConstraints {
                    rows: &prob.cons.rows,
                    ci: &prob.cons.i,
                    cj: &prob.cons.j,
                    vel: &prob.vel,
                    shift,
                    out,
                    m: mi,
                    dt: prob.dt,
                    has_shift: has,
                },
            )?;
        }
        Ok(())
    }

    /// `fused_stats`: `[max |min(lam_new, g_new)|, |s|^2, s.y, |y|^2]` from the device's
    /// partials per chunk, folded in order here.
    fn stats(
        &self,
        lam: &Buffer,
        lam_new: &Buffer,
        g: &Buffer,
        g_new: &Buffer,
        partial: &mut Buffer,
        m: usize,
    ) -> Result<[f64; 4], GpuError> {
        let nchunks = m.div_ceil(CHUNK);
        // SAFETY: block c < ceil(m / CHUNK) (its THREADS = FOLD_THREADS threads load its
        // elements in turn, its first thread folds them) reads the four vectors at c
        // CHUNK..min((c + 1) CHUNK, m) (m each) and writes partial[4 c..4 c + 4] (4 ceil(m /
        // CHUNK)).
        unsafe {
            self.dev.launch(
                nchunks * motile_gpu::THREADS as usize,
                SolverStats {
                    lam,
                    lam_new,
                    g,
                    g_new,
                    partial,
                    m: int(m, "constraints")?,
                    chunk: CHUNK as i32,
                },
            )?;
        }
        let part = self.dev.download_range(partial, 0, 4 * nchunks)?;
        Ok(part.chunks(4).fold([0.0; 4], |acc, a| {
            [
                acc[0].max(a[0]),
                acc[1] + a[1],
                acc[2] + a[2],
                acc[3] + a[3],
            ]
        }))
    }
}

/// The shapes of `problem` and its start checked: a start of the right length, the velocities
/// and rods as long as the rods' count, the counts within the kernels' `int` range.
fn check_problem(
    problem: &DeviceContactProblem<'_>,
    initial: Start<'_>,
) -> Result<(), DeviceContactError> {
    let (m, n) = (problem.cons.len, problem.rods.len);
    let len = match initial {
        Start::Host(h) => h.len(),
        Start::Device(b) => b.len(),
    };
    assert!(
        len == 0 || len >= m,
        "initial guess has the wrong length: {len} for {m} constraints"
    );
    if problem.free_v.len() < 3 * n || problem.free_w.len() < 3 * n || problem.rods.q.len() < 4 * n
    {
        return Err(
            GpuError::Input(format!("free velocities or rods shorter than {n} rods")).into(),
        );
    }
    int(m, "constraints")?;
    int(n, "rods")?;
    int(10 * m, "10 x constraints")?;
    int(6 * n, "6 x rods")?;
    Ok(())
}
