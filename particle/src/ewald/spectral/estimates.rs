//! The error model of the spectral Ewald sums (docs/accuracy.md): per-target estimates of each
//! output's error from the real-space pass, reduced in fixed chunks, and the report of an
//! accepted attempt.

use crate::ewald::params::{EwaldParams, SumOutput, error_model_constants};
use crate::ewald::periodic::{ErrorEstimate, StressletField, SumReport};
use crate::model::geometry::dot;
use crate::model::units::VISCOSITY;

/// Relative error of an output allowed for in the estimate beside the near-field model (see
/// [`estimate`]): the Fourier part's error from far sources, measured at 0.02-0.1 of the
/// internal tolerance relative to their flow.
const FAR_FIELD_SHARE: f64 = 0.25;

/// The scales of one output's error estimate: the model's near-field scale
/// `scale = tol_i Phi / mu` and the internal tolerance `tol_i` (see [`estimate`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ErrorScale {
    /// The near-field scale `tol_i Phi / mu`.
    pub(crate) scale: f64,
    /// The internal tolerance `tol_i`.
    pub(crate) internal: f64,
}

/// Where the refinement stood when an attempt was accepted: its internal tolerance, the
/// refinement level and the attempts it took.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Accepted {
    /// The internal tolerance of the accepted attempt.
    pub(crate) internal: f64,
    /// The refinement level.
    pub(crate) level: u32,
    /// Attempts, the accepted one included.
    pub(crate) attempts: u32,
}

/// A stresslet attempt's outputs and the weights of its error model, per target.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StressletOutputs<'a> {
    /// The velocities and gradients.
    pub(crate) field: &'a StressletField,
    /// The weighted strengths of the real-space pass.
    pub(crate) e2: &'a [f64],
    /// The stresslets' strengths.
    pub(crate) sigma: &'a [f64],
}

/// What a stresslet attempt's estimates are measured against: its parameters, its internal
/// tolerance and the sum's tolerance.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AttemptTolerance<'a> {
    /// The attempt's parameters.
    pub(crate) params: &'a EwaldParams,
    /// The internal tolerance the attempt ran at.
    pub(crate) internal: f64,
    /// The sum's tolerance.
    pub(crate) tol: f64,
}

/// The error model's estimate for one output of an attempt (see the module doc): per target
/// `est_t^2 = (C scale)^2 e2_t + (FAR_FIELD_SHARE tol_i)^2 |q_t|^2`, the model near the target
/// (`scale = tol_i Phi / mu`, `C` the output's calibrated constant for each metric) plus a
/// small relative error of the output itself, which covers the far sources the model leaves
/// out (two stresslets further apart than the real-space cutoff: the model alone gave zero,
/// the error was 0.02 tol); against the outputs' squared norms `out2`, as max-relative and
/// relative-L2 ratios (the floor `floor` in place of outputs below it). Sums in fixed chunks,
/// so the result does not depend on the thread count.
pub(crate) fn estimate(
    output: SumOutput,
    scales: ErrorScale,
    e2: impl Fn(usize) -> f64 + Sync,
    out2: impl Fn(usize) -> f64 + Sync,
    n: usize,
    floor: f64,
) -> ErrorEstimate {
    let tot = estimate_parts(output, scales, e2, out2, n);
    estimate_from(output, tot, n, floor)
}

/// The estimate's four reductions over targets `0..n`: `[max est^2, sum est^2, max |q|^2,
/// sum |q|^2]` (sums in fixed chunks: the same bits for any thread count).
pub(crate) fn estimate_parts(
    output: SumOutput,
    scales: ErrorScale,
    e2: impl Fn(usize) -> f64 + Sync,
    out2: impl Fn(usize) -> f64 + Sync,
    n: usize,
) -> [f64; 4] {
    let [a_max, a_2, far] = estimate_weights(output, scales);
    let parts = motile_analysis::reduce::chunk_partials(n, |chunk| {
        let mut acc = [0.0f64; 4];
        for t in chunk {
            let (e, o) = (e2(t), out2(t));
            acc[0] = acc[0].max(a_max * e + far * o);
            acc[1] += a_2 * e + far * o;
            acc[2] = acc[2].max(o);
            acc[3] += o;
        }
        acc
    });
    combine_chunks(parts.iter())
}

/// The weights `[a_max, a_2, far]` of an estimate's reductions: per target the max-norm term
/// `a_max e2 + far |q|^2` and the L2 term `a_2 e2 + far |q|^2` (see [`estimate`]).
pub(crate) fn estimate_weights(output: SumOutput, scales: ErrorScale) -> [f64; 3] {
    let ErrorScale { scale, internal } = scales;
    let (c_max, c_2) = error_model_constants(output, internal);
    [
        (c_max * scale).powi(2),
        (c_2 * scale).powi(2),
        (FAR_FIELD_SHARE * internal).powi(2),
    ]
}

/// The chunks' reductions `[max, sum, max, sum]` joined in chunk order.
pub(crate) fn combine_chunks<'a>(parts: impl Iterator<Item = &'a [f64; 4]>) -> [f64; 4] {
    let mut tot = [0.0f64; 4];
    for a in parts {
        tot[0] = tot[0].max(a[0]);
        tot[1] += a[1];
        tot[2] = tot[2].max(a[2]);
        tot[3] += a[3];
    }
    tot
}

/// The report of an accepted attempt.
pub(crate) fn report_of(
    tol: f64,
    accepted: Accepted,
    params: EwaldParams,
    estimates: Vec<ErrorEstimate>,
) -> SumReport {
    let Accepted {
        internal,
        level,
        attempts,
    } = accepted;
    let met = estimates
        .iter()
        .all(|e| e.max_relative <= tol && e.l2_relative <= tol);
    SumReport {
        tolerance: tol,
        internal_tolerance: internal,
        level,
        attempts,
        params,
        estimates,
        met,
    }
}

/// The estimates of a stresslet attempt (velocity, gradient) and the worst estimate/bound
/// ratio, from its outputs (field, weighted strengths, sigma) over `n` targets in all; `reduce`
/// turns the local reductions into the whole box's (the identity for one process).
pub(crate) fn stresslet_estimates(
    outputs_of: StressletOutputs<'_>,
    tolerance: AttemptTolerance<'_>,
    floor: impl Fn(i32) -> f64,
    reduce: impl Fn([f64; 4]) -> [f64; 4],
    n: usize,
) -> (Vec<ErrorEstimate>, f64) {
    let StressletOutputs { field, e2, sigma } = outputs_of;
    let AttemptTolerance {
        params: prm,
        internal,
        tol,
    } = tolerance;
    let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
    let scale = |o: SumOutput| internal * o.self_scale(prm.xi) / VISCOSITY;
    let local = field.u.len();
    let u = estimate_parts(
        outputs[0],
        ErrorScale {
            scale: scale(outputs[0]),
            internal,
        },
        |t| e2[t],
        |t| dot(field.u[t], field.u[t]),
        local,
    );
    let g = estimate_parts(
        outputs[1],
        ErrorScale {
            scale: scale(outputs[1]),
            internal,
        },
        |t| e2[t] + sigma[t] * sigma[t],
        |t| field.grad[t].iter().map(|r| dot(*r, *r)).sum(),
        local,
    );
    stresslet_estimates_from([reduce(u), reduce(g)], n, floor, tol)
}

/// The estimates of a stresslet attempt (velocity, gradient) and the worst estimate/bound
/// ratio from the reductions of [`estimate_parts`] over all `n` targets.
pub(crate) fn stresslet_estimates_from(
    [u, g]: [[f64; 4]; 2],
    n: usize,
    floor: impl Fn(i32) -> f64,
    tol: f64,
) -> (Vec<ErrorEstimate>, f64) {
    let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
    let estimates = vec![
        estimate_from(outputs[0], u, n, floor(2)),
        estimate_from(outputs[1], g, n, floor(3)),
    ];
    let ratio = estimates
        .iter()
        .map(|e| e.max_relative.max(e.l2_relative))
        .fold(0.0, f64::max)
        / tol;
    (estimates, ratio)
}

/// The estimate from [`estimate_parts`] over `n` targets in all (relative to the output, with
/// `floor` where it vanishes).
pub(crate) fn estimate_from(
    output: SumOutput,
    tot: [f64; 4],
    n: usize,
    floor: f64,
) -> ErrorEstimate {
    let ratio = |est: f64, out: f64| {
        if est == 0.0 {
            0.0
        } else if out > 0.0 {
            est / out
        } else {
            f64::INFINITY
        }
    };
    ErrorEstimate {
        output,
        max_relative: ratio(tot[0].sqrt(), tot[2].sqrt().max(floor)),
        l2_relative: ratio(tot[1].sqrt(), tot[3].sqrt().max(floor * (n as f64).sqrt())),
    }
}
