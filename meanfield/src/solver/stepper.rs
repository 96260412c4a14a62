//! The time stepper of the mean-field equations (M1)-(M2) of docs/MODEL.md §4: multistep IMEX
//! schemes as coefficient tables (SBDF1, variable-step SBDF2) over one engine, the diffusion
//! implicit and everything else explicit, with a report of each step and of the state it
//! started from.

use crate::solver::grid::SpectralGrid;
use crate::solver::params::{MeanFieldError, RhsReport, SYM};
use crate::solver::rhs::{MeanFieldRhs, RhsEval, RhsTiming, all_finite};
use num_complex::Complex64;
use rayon::prelude::*;

/// A multistep IMEX scheme as a coefficient table: for step ratio `w = dt_n / dt_{n-1}`,
/// `(a0 Q^{n+1} + a1 Q^n + a2 Q^{n-1}) / dt = b0 N^n + b1 N^{n-1} + D lap Q^{n+1}`.
#[derive(Clone, Copy, Debug)]
pub struct ImexScheme {
    /// Name.
    pub name: &'static str,
    /// Steps of history it needs (1 or 2).
    pub steps: usize,
    /// Coefficients `([a0, a1, a2], [b0, b1])` for a step ratio.
    pub coefficients: fn(f64) -> ([f64; 3], [f64; 2]),
}

/// First-order IMEX Euler (SBDF1).
pub const SBDF1: ImexScheme = ImexScheme {
    name: "SBDF1",
    steps: 1,
    coefficients: |_| ([1.0, -1.0, 0.0], [1.0, 0.0]),
};

/// Second-order variable-step SBDF2 (zero-stable for step ratios below 1 + sqrt 2).
pub const SBDF2: ImexScheme = ImexScheme {
    name: "SBDF2",
    steps: 2,
    coefficients: |w| {
        (
            [(1.0 + 2.0 * w) / (1.0 + w), -(1.0 + w), w * w / (1.0 + w)],
            [1.0 + w, -w],
        )
    },
};

/// Coefficients of the six components of a symmetric tensor field.
pub type TensorCoefficients = [Vec<Complex64>; 6];

/// The previous step's Q, explicit right-hand side and step size.
#[derive(Debug, Clone)]
pub struct History {
    /// `Q^{n-1}`.
    pub q_hat: TensorCoefficients,
    /// `N^{n-1}`.
    pub nonlinear: TensorCoefficients,
    /// `dt_{n-1}`.
    pub dt: f64,
}

/// Time stepper state: the current and previous Q and right-hand sides.
#[derive(Debug, Clone)]
pub struct MeanFieldStepper {
    /// Scheme used once enough history exists (the first step always uses SBDF1).
    pub scheme: ImexScheme,
    /// Current time.
    pub t: f64,
    /// Current Q coefficients.
    pub q_hat: [Vec<Complex64>; 6],
    prev: Option<History>,
    /// Last velocity (warm start of the fixed point).
    pub u_hat: [Vec<Complex64>; 3],
    /// Where the last step's time went: the right-hand side's phases and the update (seconds).
    pub last_timing: (RhsTiming, f64),
}

/// What a step did, and diagnostics of the state it started from (volume averages over the
/// unit cube).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeanFieldStepReport {
    /// Fixed-point report of the right-hand side.
    pub rhs: RhsReport,
    /// Smallest eigenvalue of `Q / tr Q` before the step (realizability).
    pub min_eigenvalue: f64,
    /// `||u||_2`, volume-averaged.
    pub u_l2: f64,
    /// `max_x (|u_x| + |u_y| + |u_z|)`: the CFL velocity (sum over axes).
    pub u_max: f64,
    /// `||E||_2 = sqrt(<E:E>)`.
    pub e_l2: f64,
    /// `<E:Q>`, the power the active stress injects (docs/MODEL.md §4 energy identity).
    pub e_dot_q: f64,
    /// Largest eigenvalue of `Q / tr Q`.
    pub max_eigenvalue: f64,
    /// Relative entropy `H` (volume average), docs/MODEL.md §4.
    pub entropy: f64,
    /// Energy identity residual `(<2 E:E + zeta E:S:E> - <E:Q>) / <E:Q>` (zero up to the
    /// fixed-point tolerance).
    pub energy_residual: f64,
}

impl MeanFieldStepper {
    /// Start from grid values of Q.
    pub fn new(grid: &SpectralGrid, q: &[Vec<f64>; 6], scheme: ImexScheme) -> Self {
        Self {
            scheme,
            t: 0.0,
            q_hat: std::array::from_fn(|c| grid.forward(&q[c], false)),
            prev: None,
            u_hat: std::array::from_fn(|_| vec![Complex64::default(); grid.spectral_len()]),
            last_timing: Default::default(),
        }
    }

    /// The previous step's history (what SBDF2 needs besides the current state).
    pub fn history(&self) -> Option<&History> {
        self.prev.as_ref()
    }

    /// Restore a state saved from [`Self::q_hat`], [`Self::history`], [`Self::u_hat`], [`Self::t`].
    pub fn restore(
        &mut self,
        t: f64,
        q_hat: TensorCoefficients,
        history: Option<History>,
        u_hat: [Vec<Complex64>; 3],
    ) {
        self.t = t;
        self.q_hat = q_hat;
        self.prev = history;
        self.u_hat = u_hat;
    }

    /// Advance by `dt`.
    pub fn step(
        &mut self,
        rhs: &MeanFieldRhs,
        dt: f64,
    ) -> Result<MeanFieldStepReport, MeanFieldError> {
        let guess = warm_start(rhs.grid, &self.q_hat, self.prev.as_ref(), &self.u_hat);
        let ev = rhs.eval(&self.q_hat, &guess)?;
        let update_clock = std::time::Instant::now();
        let (scheme, w) = match (&self.prev, self.scheme.steps) {
            (Some(h), 2) => (self.scheme, dt / h.dt),
            _ => (SBDF1, 1.0),
        };
        let ([a0, a1, a2], [b0, b1]) = (scheme.coefficients)(w);
        let d = rhs.params.diffusion;
        let g = rhs.grid;
        let prev = self.prev.as_ref().filter(|_| scheme.steps == 2);
        let h = g.h;
        let new: [Vec<Complex64>; 6] = std::array::from_fn(|c| {
            let mut out = vec![Complex64::default(); g.spectral_len()];
            g.for_each_row(&mut out, |k, a, v| {
                let idx = k.row * h + a;
                let mut r = -a1 * self.q_hat[c][idx] + dt * b0 * ev.nonlinear[c][idx];
                if let Some(hist) = prev {
                    r += -a2 * hist.q_hat[c][idx] + dt * b1 * hist.nonlinear[c][idx];
                }
                let kk = g.k2[a] + k.k_sq[0] + k.k_sq[1];
                *v = r / (a0 + dt * d * kk);
            });
            out
        });
        // Nothing is committed unless the new state is finite: on an error the stepper still
        // holds the last good state, for the caller to save.
        if !all_finite(&new) {
            return Err(MeanFieldError::NonFinite("Q after the step"));
        }
        let report = state_report(rhs, &ev);
        let old_q = std::mem::replace(&mut self.q_hat, new);
        self.prev = Some(History {
            q_hat: old_q,
            nonlinear: ev.nonlinear,
            dt,
        });
        self.u_hat = ev.u;
        self.t += dt;
        self.last_timing = (ev.timing, update_clock.elapsed().as_secs_f64());
        Ok(report)
    }

    /// The diagnostics of the current state, without stepping: the report a step from here
    /// would give, and the right-hand side evaluation behind it (for output at the end of a
    /// run).
    pub fn diagnostics(
        &self,
        rhs: &MeanFieldRhs,
    ) -> Result<(RhsEval, MeanFieldStepReport), MeanFieldError> {
        let guess = warm_start(rhs.grid, &self.q_hat, self.prev.as_ref(), &self.u_hat);
        let ev = rhs.eval(&self.q_hat, &guess)?;
        let report = state_report(rhs, &ev);
        Ok((ev, report))
    }
}

/// The Stokes fixed point's starting velocity for a step from `q_hat`: the last velocity
/// `u_hat` plus the Stokes flow of the active stress's change since the previous state,
/// `u_hat + Stokes(div(-(Q - Q_prev)))` (its 2/3-rule modes), or `u_hat` alone without a
/// previous state. The fixed point's first iterate then misses only the change of the
/// closure's stress `zeta S:E`, so it converges in about one iteration fewer (the paper's case
/// at 32^3 to t = 40: 3.55 iterations per step on average instead of 4.50) to the same
/// tolerance. The GPU's `warm_start` kernel computes the same values in the same order.
pub(crate) fn warm_start(
    g: &SpectralGrid,
    q_hat: &[Vec<Complex64>; 6],
    prev: Option<&History>,
    u_hat: &[Vec<Complex64>; 3],
) -> [Vec<Complex64>; 3] {
    let Some(prev) = prev else {
        return u_hat.clone();
    };
    let n = g.n;
    let mut sigma: [Vec<Complex64>; 6] =
        std::array::from_fn(|_| vec![Complex64::default(); g.spectral_len()]);
    for (c, sc) in sigma.iter_mut().enumerate() {
        g.for_each_row(sc, |k, a, v| {
            if k.keep && 3 * a <= n {
                let idx = k.row * g.h + a;
                *v = -(q_hat[c][idx] - prev.q_hat[c][idx]);
            }
        });
    }
    let mut u: [Vec<Complex64>; 3] =
        std::array::from_fn(|_| vec![Complex64::default(); g.spectral_len()]);
    g.stokes_into(&sigma, &mut u);
    for (ui, hi) in u.iter_mut().zip(u_hat) {
        ui.par_iter_mut().zip(hi).for_each(|(v, h)| *v = h + *v);
    }
    u
}

/// Norms, eigenvalue bounds, entropy and the energy identity's residual of one evaluation.
fn state_report(rhs: &MeanFieldRhs, ev: &RhsEval) -> MeanFieldStepReport {
    let g = rhs.grid;
    let npts = g.len() as f64;
    let u_l2 = ev.u.iter().map(|c| g.norm_sqr(c)).sum::<f64>().sqrt();
    let ug = &ev.u_grid;
    let u_max = ug[0]
        .par_iter()
        .zip(&ug[1])
        .zip(&ug[2])
        .map(|((a, b), c)| a.abs() + b.abs() + c.abs())
        .reduce(|| 0.0, f64::max);
    let w = |c: usize| if SYM[c].0 == SYM[c].1 { 1.0 } else { 2.0 };
    // <E:E>, <E:Q>, <E:S:E> summed in fixed chunks, then in chunk order: deterministic.
    let chunks = motile_analysis::reduce::chunk_partials(g.len(), |chunk| {
        let mut acc = [0.0; 3];
        for c in 0..6 {
            for p in chunk.clone() {
                acc[0] += w(c) * ev.e[c][p] * ev.e[c][p];
                acc[1] += w(c) * ev.e[c][p] * ev.q[c][p];
                acc[2] += w(c) * ev.e[c][p] * ev.se[c][p];
            }
        }
        acc
    });
    let (mut ee, mut eq, mut ese) = (0.0, 0.0, 0.0);
    for a in &chunks {
        ee += a[0];
        eq += a[1];
        ese += a[2];
    }
    let energy_residual = (2.0 * ee + rhs.params.zeta * ese - eq) / eq.abs().max(1e-300);
    MeanFieldStepReport {
        rhs: ev.report,
        min_eigenvalue: ev.min_eigenvalue,
        u_l2,
        u_max,
        e_l2: (ee / npts).sqrt(),
        e_dot_q: eq / npts,
        max_eigenvalue: ev.max_eigenvalue,
        entropy: ev.entropy,
        energy_residual,
    }
}
