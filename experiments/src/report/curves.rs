//! What `motile compare` reads from each run (docs/MODEL.md §5), in the mean-field unit system:
//! the velocity norm against time and its growth phase, the time-averaged correlation functions,
//! trajectory statistics and velocity slices. Particle time `t_mf = t_p nu / (8 eta mu)`,
//! particle velocity (reported normalised by `beta L`) `u_mf = (u_p / (beta L)) 8 eta mu / nu`;
//! mean-field runs are already in those units.

use crate::io::snapshot::Snapshot;
use crate::report::analyze::{AnalysisReport, AnalyzeOptions, analyze};
use crate::report::opened_run::{OpenedModel, OpenedRun, ParticleUnits};
use crate::run::meanfield::MeanFieldRunConfig;
use crate::run::particle::ParticleRunConfig;
use anyhow::bail;
use motile_analysis::correlation::velocity_spectrum;
use motile_analysis::stats::{
    GrowthFit, WindowAverage, correlation_length, growth_phase, window_average,
};
use motile_particle::model::linear_theory::{growth_rate, lowest_mode};
use motile_particle::model::units::{
    DEFAULT_DIAMETER, VISCOSITY, continuum_growth_rate, meanfield_time_unit, particle_to_meanfield,
    zeta,
};
use std::path::{Path, PathBuf};

/// One run's velocity norm in mean-field units.
#[derive(Clone, Debug, PartialEq)]
pub struct NormCurve {
    /// Legend label (model, size, level).
    pub label: String,
    /// The run directory.
    pub run: PathBuf,
    /// Times, `mu/|sigma_a|`.
    pub t: Vec<f64>,
    /// `||u||_2`, `L |sigma_a| / mu`.
    pub u: Vec<f64>,
    /// The run's last time in its own unit (1/beta or mu/|sigma_a|).
    pub t_end_own: f64,
    /// The continuum's linear growth rate for this run, mean-field units (docs/MODEL.md (M3)):
    /// `(1/5)/(1 + zeta/15) - D k^2` with the run's `zeta` and, for a mean-field run, its `D`
    /// and smallest perturbed wavenumber; particles have no `D`.
    pub theory_rate: f64,
    /// Particle runs: what the series summary needs.
    pub particle: Option<ParticleInfo>,
}

/// A particle run's size and level, and its box theory.
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleInfo {
    /// Box side `L/l`.
    pub box_length: f64,
    /// Rods.
    pub rods: usize,
    /// Volume fraction.
    pub nu: f64,
    /// The hydrodynamic level.
    pub level: String,
    /// The lowest box mode's rate in the box's linear theory without diffusion
    /// (docs/MODEL.md §5b), mean-field units; `None` where the mode is damped.
    pub box_theory: Option<num_complex::Complex64>,
    /// The run's own time unit in mean-field units' terms: `t_mf = t_p / unit`.
    pub time_unit: f64,
    /// The effective rotational diffusion measured in the run (1/beta), from its snapshots
    /// over the first half ([`rotational_diffusion`]); `None` with fewer than three.
    pub rotational_diffusion: Option<f64>,
    /// The box theory's rate with that rotational diffusion, mean-field units; `None` where
    /// not measured or damped.
    pub box_theory_dr: Option<num_complex::Complex64>,
}

/// Read one run's velocity norm, converted to mean-field units.
pub fn norm_curve(run: &Path) -> anyhow::Result<NormCurve> {
    norm_curve_of(&OpenedRun::open(run)?)
}

/// An opened run's velocity norm, converted to mean-field units, with its linear theory.
pub fn norm_curve_of(run: &OpenedRun) -> anyhow::Result<NormCurve> {
    match &run.model {
        OpenedModel::Particle { config, units } => particle_curve(run, config, units),
        OpenedModel::MeanField(config) => meanfield_curve(run, config),
    }
}

/// A particle run's box-scale velocity norm in mean-field units, its box theory without and
/// with the rotational diffusion measured in it.
fn particle_curve(
    run: &OpenedRun,
    config: &ParticleRunConfig,
    units: &ParticleUnits,
) -> anyhow::Result<NormCurve> {
    if !config.hydrodynamics.has_flow() {
        bail!(
            "{}: a particle run without hydrodynamics has no flow to compare (hydrodynamics = \"none\")",
            run.path().display()
        );
    }
    let t = run.column("t [")?;
    // The box-scale modes (every |m_i| <= 1) where the instability begins and where the
    // continuum's grid and the rods' sampling noise do not differ; runs written before that
    // column existed fall back to all analysis modes.
    let u = if run.has_column("velocity_norm_box") {
        run.column("velocity_norm_box")?
    } else {
        run.column("velocity_norm")?
    };
    let t_end_own = t.last().copied().unwrap_or(0.0);
    let (t, u) = t
        .iter()
        .zip(&u)
        .map(|(t, u)| units.to_meanfield(*t, *u))
        .unzip();
    // Near-field encounters and contacts turn rods as a rotational diffusion would: measured
    // from <p(t).p(0)> over the first half of the run (before a saturated flow adds its own
    // turning), and the theory with it.
    let label = format!(
        "particle L/l = {}, nu = {:.3} ({})",
        units.box_length, units.nu, config.hydrodynamics
    );
    let rotational_diffusion = if crate::report::products::is_compact(run) {
        let samples = crate::report::products::orientation_samples(run, &label)?;
        diffusive_rate(&log_samples(&samples, 0.5 * t_end_own), 0.5 * t_end_own)
    } else {
        rotational_diffusion_of(&run.snapshot_paths, 0.5 * t_end_own)?
    };
    Ok(NormCurve {
        label,
        run: run.path().into(),
        t,
        u,
        t_end_own,
        theory_rate: continuum_growth_rate(zeta(units.nu, units.diameter)),
        particle: Some(ParticleInfo {
            box_length: units.box_length,
            rods: units.rods,
            nu: units.nu,
            level: config.hydrodynamics.to_string(),
            box_theory: box_theory(units, 0.0),
            time_unit: units.time_unit,
            rotational_diffusion,
            box_theory_dr: rotational_diffusion.and_then(|d| box_theory(units, d)),
        }),
    })
}

/// The lowest box mode's rate in the box's linear theory with rotational diffusion `d_r`
/// (docs/MODEL.md §5b), mean-field units; `None` where it is damped.
fn box_theory(units: &ParticleUnits, d_r: f64) -> Option<num_complex::Complex64> {
    growth_rate(units.nu, units.diameter, lowest_mode(units.box_length), d_r)
        .map(|g| g.sigma * units.time_unit)
}

/// A mean-field run's velocity norm and its continuum theory (M3) at its smallest perturbed
/// wavenumber.
fn meanfield_curve(run: &OpenedRun, config: &MeanFieldRunConfig) -> anyhow::Result<NormCurve> {
    let t = run.column("t [")?;
    let m = if config.initial == "plane_wave" {
        config
            .wavevector
            .iter()
            .map(|v| (v * v) as f64)
            .sum::<f64>()
            .sqrt()
    } else {
        config.mode_min as f64
    };
    let k = 2.0 * std::f64::consts::PI * m;
    Ok(NormCurve {
        label: format!(
            "mean field {}^3, zeta = {}, D = {}",
            config.grid, config.zeta, config.diffusion
        ),
        run: run.path().into(),
        t_end_own: t.last().copied().unwrap_or(0.0),
        t,
        u: run.column("u_l2")?,
        theory_rate: continuum_growth_rate(config.zeta) - config.diffusion * k * k,
        particle: None,
    })
}

/// Mean squared displacement and orientation autocorrelation of a particle run against time
/// (particle units: the rods' own clock is the natural one for trajectories).
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectoryCurve {
    /// Legend label.
    pub label: String,
    /// Snapshot times, 1/beta.
    pub t: Vec<f64>,
    /// `<|x(t) - x(0)|^2>`, l^2.
    pub msd: Vec<f64>,
    /// `<p(t) . p(0)>`.
    pub orientation: Vec<f64>,
}

/// A run's time-averaged velocity autocorrelation in mean-field units.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrCurve {
    /// Legend label, with the averaging window.
    pub label: String,
    /// `r / L`.
    pub r: Vec<f64>,
    /// `Corr[u](r)`, `(L |sigma_a| / mu)^2`.
    pub value: Vec<f64>,
}

/// The velocity magnitude on the plane z = 0 of one snapshot, mean-field units.
#[derive(Clone, Debug, PartialEq)]
pub struct VelocitySlice {
    /// Points per side.
    pub n: usize,
    /// `|u|` at `values[y n + x]`.
    pub values: Vec<f64>,
    /// The snapshot's time, mean-field units.
    pub time: f64,
}

/// An order parameter's time-averaged correlation normalised by its value at 0.
pub(crate) struct OrderCorrelation {
    /// The field: `c`, `n` or `Q`.
    pub(crate) field: String,
    /// `(r / L, Corr(r) / Corr(0))`.
    pub(crate) points: Vec<(f64, f64)>,
}

/// A field's correlation length: the first zero of its time-averaged correlation.
pub(crate) struct CorrelationLength {
    /// The field.
    pub(crate) field: String,
    /// `r / L`; NaN without a zero.
    pub(crate) length: f64,
}

/// What the in-memory analysis of one run gives the comparison.
pub(crate) struct RunAnalysis {
    /// `Corr[u](r)` averaged over the snapshots with `t >= t_start`, mean-field units; `None`
    /// if the snapshots carry no flow.
    pub(crate) corr_u: Option<CorrCurve>,
    /// The velocity slice of the chosen snapshot (see [`velocity_slice`]).
    pub(crate) slice: Option<VelocitySlice>,
    pub(crate) traj: Option<TrajectoryCurve>,
    /// `Corr[c], Corr[n], Corr[Q]` normalised by their value at 0, against `r / L`.
    pub(crate) order: Vec<OrderCorrelation>,
    /// Snapshots in the averaging window.
    pub(crate) window_count: usize,
    /// Particle runs: their size and units.
    pub(crate) particle: Option<ParticleUnits>,
    /// Correlation lengths (first zero of each time-averaged correlation), `r / L`, by field.
    pub(crate) lengths: Vec<CorrelationLength>,
    /// Fields whose L2 norm is at most [`ZERO_FIELD_NORM`] (identically zero by construction).
    pub(crate) zero_fields: Vec<String>,
}

/// What to analyse of one run: its label, where its averaging window starts and the time of
/// its velocity slice, both in the run's own unit.
pub(crate) struct AnalysisWindow<'a> {
    /// Legend label.
    pub(crate) label: &'a str,
    /// Start of the averaging window.
    pub(crate) t_start: f64,
    /// The time whose nearest snapshot gives the slice (the last snapshot without one).
    pub(crate) slice_at: Option<f64>,
}

/// One run's snapshots, read once: its Corr[u] and order-parameter correlations averaged over
/// the snapshots from `window.t_start`, the velocity slice of the snapshot nearest
/// `window.slice_at`, and, for particle runs, trajectory statistics.
pub(crate) fn analyse(run: &OpenedRun, window: &AnalysisWindow) -> anyhow::Result<RunAnalysis> {
    let snaps = run.snapshots()?;
    let report = averaged_correlations(run, &snaps, window.t_start)?;
    let slice = nearest_slice(run, &snaps, window.slice_at)?;
    let traj = (report.kind == "particle").then(|| trajectory_curve(&report, window.label));
    let units = run.particle().map(|(_, units)| *units);
    // Particle runs: r in rod lengths and velocities in beta L, to mean-field units.
    let (r_scale, v_scale) = units.map_or((1.0, 1.0), |u| {
        (1.0 / u.box_length, u.time_unit * u.time_unit)
    });
    // Fields identically zero by construction (the mean-field c = tr Q - 1 while tr Q = 1) have
    // no correlation to normalise: left out of the charts and named in the table instead.
    let zero_fields: Vec<String> = report
        .mean
        .iter()
        .filter(|(_, c)| c.at_zero().abs().sqrt() <= ZERO_FIELD_NORM)
        .map(|(n, _)| n.clone())
        .collect();
    let unit = if units.is_some() {
        "1/beta"
    } else {
        "mu/|sigma_a|"
    };
    let corr_u = report
        .mean
        .iter()
        .find(|(n, _)| n == "u")
        .map(|(_, c)| CorrCurve {
            label: format!(
                "{}, {} snapshot(s) from t = {:.3} [{unit}]",
                window.label, report.window_count, window.t_start
            ),
            r: c.r.iter().map(|r| r * r_scale).collect(),
            value: c.value.iter().map(|v| v * v_scale).collect(),
        });
    Ok(RunAnalysis {
        corr_u,
        slice,
        traj,
        order: order_correlations(&report, &zero_fields, r_scale),
        window_count: report.window_count,
        particle: units,
        lengths: correlation_lengths(&report, &zero_fields, r_scale),
        zero_fields,
    })
}

/// The time-averaged correlations of a run's snapshots from `t_start`. Concentrated particle
/// runs keep their structure at the rod scale: resolved to r ~ l/2 (2 L/l modes, at most 64)
/// instead of the default L/(2l). In dilute particle runs c and n decay within a rod length,
/// so their correlations come from 2 L/l modes (at most 128), the flow's and Q's from the
/// default modes.
fn averaged_correlations(
    run: &OpenedRun,
    snaps: &[Snapshot],
    t_start: f64,
) -> anyhow::Result<AnalysisReport> {
    let config = run.particle().map(|(config, _)| config);
    let rod_modes =
        |c: &ParticleRunConfig, most: usize| ((2.0 * c.box_length).ceil() as usize).clamp(4, most);
    let opts = AnalyzeOptions {
        t_start,
        modes: config
            .filter(|c| c.volume_fraction > 1.0)
            .map(|c| rod_modes(c, 64)),
        ..AnalyzeOptions::default()
    };
    let mut report =
        analyze(snaps, &opts).map_err(|e| anyhow::anyhow!("{}: {e}", run.path().display()))?;
    if let Some(c) = config.filter(|c| c.volume_fraction <= 1.0) {
        for (name, corr) in rod_scale_correlations(snaps, t_start, rod_modes(c, 128))? {
            if let Some(slot) = report.mean.iter_mut().find(|(n, _)| *n == name) {
                slot.1 = corr;
            }
        }
    }
    Ok(report)
}

/// The velocity slice of the snapshot nearest `slice_at` (runs of both models end at nearly,
/// not exactly, the same time in the common unit), or of the last snapshot.
fn nearest_slice(
    run: &OpenedRun,
    snaps: &[Snapshot],
    slice_at: Option<f64>,
) -> anyhow::Result<Option<VelocitySlice>> {
    let chosen = match slice_at {
        Some(t) => snaps
            .iter()
            .min_by(|a, b| (a.time() - t).abs().total_cmp(&(b.time() - t).abs())),
        None => snaps.last(),
    };
    let diameter = run
        .particle()
        .map_or(DEFAULT_DIAMETER, |(config, _)| config.diameter);
    match chosen {
        Some(snap) => velocity_slice(snap, diameter)
            .map_err(|e| anyhow::anyhow!("{}: {e}", run.path().display())),
        None => Ok(None),
    }
}

/// A particle run's mean squared displacement and orientation autocorrelation per snapshot.
fn trajectory_curve(report: &AnalysisReport, label: &str) -> TrajectoryCurve {
    TrajectoryCurve {
        label: label.into(),
        t: report.snapshots.iter().map(|s| s.time).collect(),
        msd: report
            .snapshots
            .iter()
            .map(|s| s.msd.unwrap_or(f64::NAN))
            .collect(),
        orientation: report
            .snapshots
            .iter()
            .map(|s| s.orientation.unwrap_or(f64::NAN))
            .collect(),
    }
}

/// Each non-zero field's correlation length, `r` scaled by `r_scale`.
fn correlation_lengths(
    report: &AnalysisReport,
    zero_fields: &[String],
    r_scale: f64,
) -> Vec<CorrelationLength> {
    report
        .mean
        .iter()
        .filter(|(n, _)| !zero_fields.contains(n))
        .map(|(n, c)| CorrelationLength {
            field: n.clone(),
            length: correlation_length(&c.r, &c.value).map_or(f64::NAN, |z| z * r_scale),
        })
        .collect()
}

/// The order parameters' correlations (every field but `u`, positive at 0 and not zero),
/// normalised at 0, `r` scaled by `r_scale`.
fn order_correlations(
    report: &AnalysisReport,
    zero_fields: &[String],
    r_scale: f64,
) -> Vec<OrderCorrelation> {
    report
        .mean
        .iter()
        .filter(|(n, c)| n != "u" && c.at_zero() > 0.0 && !zero_fields.contains(n))
        .map(|(n, c)| {
            let c0 = c.at_zero();
            OrderCorrelation {
                field: n.clone(),
                points: c
                    .r
                    .iter()
                    .zip(&c.value)
                    .map(|(r, v)| (r * r_scale, v / c0))
                    .collect(),
            }
        })
        .collect()
}

/// `Corr[c]` and `Corr[n]` of the particle snapshots from `t_start`, averaged, on `modes`
/// Fourier modes per axis (one plan, both spread in one pass per snapshot).
fn rod_scale_correlations(
    snaps: &[Snapshot],
    t_start: f64,
    modes: usize,
) -> anyhow::Result<Vec<(String, motile_analysis::correlation::RadialCorrelation)>> {
    use crate::report::statistics::{snapshot_curves, summed};
    use motile_analysis::correlation::OrderParameter;
    let window: Vec<_> = snaps
        .iter()
        .filter_map(|s| match s {
            Snapshot::Particle(p) if p.time >= t_start - 1e-9 => Some(p),
            _ => None,
        })
        .collect();
    let curves = snapshot_curves(
        &window,
        &[OrderParameter::Concentration, OrderParameter::Polarity],
        modes,
        &|spec, _, _| spec.correlation(None),
    )?;
    Ok(["c", "n"]
        .into_iter()
        .enumerate()
        .filter_map(|(k, name)| {
            let mut acc = summed(curves.iter().map(|c| &c[k]))?;
            acc.value.iter_mut().for_each(|v| *v /= window.len() as f64);
            Some((name.to_string(), acc))
        })
        .collect())
}

/// The velocity magnitude on the plane z = 0 of a snapshot, in mean-field units. Particle runs:
/// the velocity field of the snapshot's force density on `min(2 L/l, 64)` modes per side
/// (docs/MODEL.md §6, doublet neglected); mean-field runs: the snapshot's grid. `None` if the
/// snapshot has no flow. `diameter`: the particle run's rod diameter, which sets the time unit
/// of the conversion.
pub fn velocity_slice(
    snap: &Snapshot,
    diameter: f64,
) -> Result<Option<VelocitySlice>, motile_analysis::nufft::NufftError> {
    let (n, grid, time): (usize, [Vec<f64>; 3], f64) = match snap {
        Snapshot::Particle(p) => {
            let Some(f) = &p.forces else {
                return Ok(None);
            };
            let l = p.box_length;
            let nu = p.positions.len() as f64 / (l * l * l);
            let modes = ((2.0 * l) as usize).clamp(8, 64) & !1;
            let spec = velocity_spectrum(&f.points, &f.forces, l, VISCOSITY, modes, 1e-6)?;
            // u / (beta L) to mean-field units.
            let s = meanfield_time_unit(nu, diameter) / l;
            let g = [0, 1, 2].map(|c| spec.to_grid(c).into_iter().map(|v| v * s).collect());
            (modes, g, particle_to_meanfield(p.time, 0.0, nu, diameter).0)
        }
        Snapshot::Field(f) => (f.grid, f.u.clone(), f.time),
    };
    let values = (0..n * n)
        .map(|k| (0..3).map(|c| grid[c][k].powi(2)).sum::<f64>().sqrt())
        .collect();
    Ok(Some(VelocitySlice { n, values, time }))
}

/// A field whose time-averaged `||Phi||_2` is at most this is identically zero (round-off), not
/// physics: the mean-field `c = tr Q - 1` with `tr Q = 1` conserved.
pub const ZERO_FIELD_NORM: f64 = 1e-10;

/// Smallest growth and fit quality that make a growth phase (docs/MODEL.md §6).
pub const MIN_GROWTH_FACTOR: f64 = 3.0;
/// See [`MIN_GROWTH_FACTOR`].
pub const MIN_R_SQUARED: f64 = 0.9;

/// The growth rate of `||u||_2` in a run's growth phase ([`growth_phase`]: from its first
/// sample to where the local growth rate falls below 40% of its largest value, before nonlinear
/// saturation, or to the end if it never does). The flag says whether that is a growth phase: the norm grew by at least [`MIN_GROWTH_FACTOR`]
/// with `R^2` at least [`MIN_R_SQUARED`]. Without one (a particle run at its noise level, a
/// decay) the fit is over the whole run and only its growth factor and `R^2` are reported, not
/// its rate. `None` with fewer than 3 samples.
pub fn growth_fit(c: &NormCurve) -> Option<(GrowthFit, bool)> {
    growth_phase(&c.t, &c.u, MIN_GROWTH_FACTOR, MIN_R_SQUARED)
}

/// Where a run's saturated state starts (mean-field units): the later of the end of its growth
/// phase and half the run (without a growth phase, half the run). Time averages (the norm, the
/// correlations) are taken from there to the end.
pub fn saturated_from(c: &NormCurve) -> f64 {
    let half = 0.5 * c.t.last().copied().unwrap_or(0.0);
    match growth_fit(c) {
        Some((g, true)) => g.t1.max(half),
        _ => half,
    }
}

/// What the comparison's tables report of one run's norm: its growth fit and its time average
/// over the saturated state.
#[derive(Clone, Debug)]
pub struct NormStatistics {
    /// [`growth_fit`].
    pub growth: Option<(GrowthFit, bool)>,
    /// Start of the saturated state ([`saturated_from`]), mean-field units.
    pub saturated_from: f64,
    /// The run's last time, mean-field units.
    pub t_end: f64,
    /// The norm's time average from `saturated_from` to `t_end`.
    pub average: WindowAverage,
}

impl NormStatistics {
    /// The statistics of one curve.
    pub fn of(c: &NormCurve) -> Self {
        let t_end = c.t.last().copied().unwrap_or(0.0);
        let saturated_from = saturated_from(c);
        Self {
            growth: growth_fit(c),
            saturated_from,
            t_end,
            average: window_average(&c.t, &c.u, saturated_from, t_end),
        }
    }

    /// The growth fit and whether it is a growth phase; without a fit (too few samples), NaN
    /// in every field and no growth phase, as the tables write it.
    pub fn fit_or_nan(&self) -> (GrowthFit, bool) {
        self.growth.unwrap_or((nan_growth_fit(), false))
    }
}

/// A growth fit that is not there, as the tables write it: NaN in every field, no samples.
pub fn nan_growth_fit() -> GrowthFit {
    GrowthFit {
        rate: f64::NAN,
        std_error: f64::NAN,
        samples: 0,
        t0: f64::NAN,
        t1: f64::NAN,
        r_squared: f64::NAN,
        growth_factor: f64::NAN,
        peak_rate: f64::NAN,
    }
}

/// The effective rotational diffusion of the rods of the run in `dir`, from their orientation
/// autocorrelation `C(t) = <p(t).p(0)>` over the snapshots up to `t1`: where the rods turn
/// diffusively, `ln C = -2 d_r t` (after a short ballistic start). The least-squares slopes of
/// `ln C` over the window's two halves must agree within 25%, else the turning is not a
/// diffusion (it is driven: in concentrated suspensions, or by a growing flow) and there is
/// no `d_r` (`None`, also with fewer than three snapshots in a half); `d_r` is the second
/// half's slope over `-2`.
pub fn rotational_diffusion(dir: &Path, t1: f64) -> anyhow::Result<Option<f64>> {
    let paths = crate::io::rundir::RunDir::open(dir)?.snapshot_paths()?;
    rotational_diffusion_of(&paths, t1)
}

/// [`rotational_diffusion`] of the rods in the snapshot files `paths` (in order).
fn rotational_diffusion_of(paths: &[PathBuf], t1: f64) -> anyhow::Result<Option<f64>> {
    let mut first: Option<Vec<[f64; 3]>> = None;
    let mut samples = Vec::new();
    for p in paths {
        let Snapshot::Particle(s) = crate::io::snapshot::read_snapshot(p)? else {
            continue;
        };
        if s.time > t1 + 1e-9 {
            break;
        }
        let p0 = first.get_or_insert_with(|| s.orientations.clone());
        let c = motile_analysis::stats::orientation_autocorrelation(p0, &s.orientations);
        samples.push((s.time, c));
    }
    Ok(diffusive_rate(&log_samples(&samples, t1), t1))
}

/// `(t, ln C)` of the positive samples `(t, C)` with `t <= t1`.
fn log_samples(samples: &[(f64, f64)], t1: f64) -> Vec<(f64, f64)> {
    samples
        .iter()
        .filter(|(t, c)| *t <= t1 + 1e-9 && *c > 0.0)
        .map(|(t, c)| (*t, c.ln()))
        .collect()
}

/// The `d_r` of `(t, ln C)` samples over `[0, t1]` as [`rotational_diffusion`] defines it.
fn diffusive_rate(points: &[(f64, f64)], t1: f64) -> Option<f64> {
    let slope = |lo: f64, hi: f64| {
        let s: Vec<&(f64, f64)> = points
            .iter()
            .filter(|(t, _)| *t >= lo - 1e-9 && *t <= hi + 1e-9)
            .collect();
        if s.len() < 3 {
            return None;
        }
        let n = s.len() as f64;
        let (mt, my) = s
            .iter()
            .fold((0.0, 0.0), |(a, b), (t, y)| (a + t / n, b + y / n));
        let (num, den) = s.iter().fold((0.0, 0.0), |(a, b), (t, y)| {
            (a + (t - mt) * (y - my), b + (t - mt) * (t - mt))
        });
        (den > 0.0).then(|| num / den)
    };
    let (a, b) = (slope(0.0, 0.5 * t1)?, slope(0.5 * t1, t1)?);
    if b >= 0.0 || (a - b).abs() > 0.25 * a.abs().max(b.abs()) {
        return None;
    }
    Some(-b / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Diffusive decorrelation (after a ballistic start) gives its d_r; an accelerating one,
    /// as a growing flow turns rods, gives none.
    #[test]
    fn rotational_diffusion_only_where_the_turning_is_diffusive() {
        let d = 6.5e-3;
        let diffusive: Vec<(f64, f64)> = (0..=30)
            .map(|k| {
                let t = 5.0 * k as f64;
                (t, -2.0 * d * t + 0.02 * (1.0 - (-t / 5.0f64).exp()))
            })
            .collect();
        let got = diffusive_rate(&diffusive, 150.0).unwrap();
        assert!((got - d).abs() < 1e-3 * d, "{got}");
        let driven: Vec<(f64, f64)> = (0..=20)
            .map(|k| {
                let t = 0.25 * k as f64;
                (t, -0.01 * t * t)
            })
            .collect();
        assert_eq!(diffusive_rate(&driven, 5.0), None);
        assert_eq!(diffusive_rate(&diffusive[..3], 10.0), None);
    }
}
