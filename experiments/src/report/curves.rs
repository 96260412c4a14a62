//! What `motile compare` reads from each run (docs/MODEL.md §5), in the mean-field unit system:
//! the velocity norm against time and its growth phase, the time-averaged correlation functions,
//! trajectory statistics and velocity slices. Particle time `t_mf = t_p nu / (8 eta mu)`,
//! particle velocity (reported normalised by `beta L`) `u_mf = (u_p / (beta L)) 8 eta mu / nu`;
//! mean-field runs are already in those units.

use crate::io::rundir::{RunDir, TimeSeries, read_run_config};
use crate::io::snapshot::Snapshot;
use crate::report::analyze::{AnalyzeOptions, analyze};
use crate::run::meanfield::MeanFieldRunConfig;
use crate::run::particle::ParticleRunConfig;
use anyhow::{Context, bail};
use motile_analysis::correlation::velocity_spectrum;
use motile_analysis::stats::{GrowthFit, correlation_length, growth_phase};
use motile_particle::model::units::{DEFAULT_DIAMETER, VISCOSITY, continuum_growth_rate};
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

use motile_particle::model::units::particle_to_meanfield;

fn column(ts: &TimeSeries, prefix: &str, path: &Path) -> anyhow::Result<Vec<f64>> {
    let c = ts
        .columns
        .iter()
        .position(|c| c.starts_with(prefix))
        .with_context(|| format!("{}: no column `{prefix}`", path.display()))?;
    Ok(ts.rows.iter().map(|r| r[c]).collect())
}

/// Read one run's velocity norm, converted to mean-field units.
pub fn norm_curve(run: &Path) -> anyhow::Result<NormCurve> {
    let dir = RunDir::open(run)?;
    let model = dir.header()?.model;
    let ts_path = run.join("timeseries.csv");
    let ts = TimeSeries::read(&ts_path)?;
    match model.as_str() {
        "particle" => {
            let cfg: ParticleRunConfig = read_run_config(run, ParticleRunConfig::validate)?;
            if !cfg.hydrodynamics.has_flow() {
                bail!(
                    "{}: a particle run without hydrodynamics has no flow to compare (hydrodynamics = \"none\")",
                    run.display()
                );
            }
            let l = cfg.box_length;
            let n = cfg
                .rods
                .unwrap_or((cfg.volume_fraction * l * l * l).round() as usize);
            let nu = n as f64 / (l * l * l);
            let t = column(&ts, "t [", &ts_path)?;
            // The box-scale modes (every |m_i| <= 1) where the instability begins and where the
            // continuum's grid and the rods' sampling noise do not differ; runs written before
            // that column existed fall back to all analysis modes.
            let box_scale = ts
                .columns
                .iter()
                .any(|c| c.starts_with("velocity_norm_box"));
            let u = if box_scale {
                column(&ts, "velocity_norm_box", &ts_path)?
            } else {
                column(&ts, "velocity_norm", &ts_path)?
            };
            let t_end_own = t.last().copied().unwrap_or(0.0);
            let (t, u) = t
                .iter()
                .zip(&u)
                .map(|(t, u)| particle_to_meanfield(*t, *u, nu, cfg.diameter))
                .unzip();
            let zeta = motile_particle::model::units::zeta(nu, cfg.diameter);
            let time_unit = motile_particle::model::units::meanfield_time_unit(nu, cfg.diameter);
            let box_theory = motile_particle::model::linear_theory::growth_rate(
                nu,
                cfg.diameter,
                motile_particle::model::linear_theory::lowest_mode(l),
                0.0,
            )
            .map(|g| g.sigma * time_unit);
            // Near-field encounters and contacts turn rods as a rotational diffusion would:
            // measured from <p(t).p(0)> over the first half of the run (before a saturated
            // flow adds its own turning), and the theory with it.
            let rotational_diffusion = rotational_diffusion(run, 0.5 * t_end_own)?;
            let box_theory_dr = rotational_diffusion.and_then(|d| {
                motile_particle::model::linear_theory::growth_rate(
                    nu,
                    cfg.diameter,
                    motile_particle::model::linear_theory::lowest_mode(l),
                    d,
                )
                .map(|g| g.sigma * time_unit)
            });
            Ok(NormCurve {
                label: format!("particle L/l = {l}, nu = {nu:.3} ({})", cfg.hydrodynamics),
                run: run.into(),
                t,
                u,
                t_end_own,
                theory_rate: continuum_growth_rate(zeta),
                particle: Some(ParticleInfo {
                    box_length: l,
                    rods: n,
                    nu,
                    level: cfg.hydrodynamics.to_string(),
                    box_theory,
                    time_unit,
                    rotational_diffusion,
                    box_theory_dr,
                }),
            })
        }
        "meanfield" => {
            let cfg: MeanFieldRunConfig = read_run_config(run, MeanFieldRunConfig::validate)?;
            let t = column(&ts, "t [", &ts_path)?;
            let m = if cfg.initial == "plane_wave" {
                cfg.wavevector
                    .iter()
                    .map(|v| (v * v) as f64)
                    .sum::<f64>()
                    .sqrt()
            } else {
                cfg.mode_min as f64
            };
            let k = 2.0 * std::f64::consts::PI * m;
            Ok(NormCurve {
                label: format!(
                    "mean field {}^3, zeta = {}, D = {}",
                    cfg.grid, cfg.zeta, cfg.diffusion
                ),
                run: run.into(),
                t_end_own: t.last().copied().unwrap_or(0.0),
                t,
                u: column(&ts, "u_l2", &ts_path)?,
                theory_rate: continuum_growth_rate(cfg.zeta) - cfg.diffusion * k * k,
                particle: None,
            })
        }
        other => bail!("{}: cannot compare a run of kind `{other}`", run.display()),
    }
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

/// What the in-memory analysis of one run gives the comparison.
pub(crate) struct RunAnalysis {
    /// `Corr[u](r)` averaged over the snapshots with `t >= t_start`, mean-field units; `None`
    /// if the snapshots carry no flow.
    pub(crate) corr_u: Option<CorrCurve>,
    /// The velocity slice of the last snapshot (see [`velocity_slice`]).
    pub(crate) slice: Option<(usize, Vec<f64>, f64)>,
    pub(crate) traj: Option<TrajectoryCurve>,
    /// `Corr[c], Corr[n], Corr[Q]` normalised by their value at 0, against `r / L`.
    pub(crate) order: Vec<(String, Vec<(f64, f64)>)>,
    /// Snapshots in the averaging window.
    pub(crate) window_count: usize,
    /// Particle runs: `(L/l, nu)`.
    pub(crate) particle: Option<(f64, f64)>,
    /// Correlation lengths (first zero of each time-averaged correlation), `r / L`, by field.
    pub(crate) lengths: Vec<(String, f64)>,
    /// Fields whose L2 norm is at most [`ZERO_FIELD_NORM`] (identically zero by construction).
    pub(crate) zero_fields: Vec<String>,
}

/// One run's snapshots, read once: its Corr[u] and order-parameter correlations averaged over
/// the snapshots from `t_start`, the velocity slice of the snapshot nearest `slice_at` (the
/// last without one), and, for particle runs, trajectory statistics. Times in
/// the run's own unit.
pub(crate) fn analyse(
    run: &Path,
    label: &str,
    t_start: f64,
    slice_at: Option<f64>,
) -> anyhow::Result<RunAnalysis> {
    let dir = RunDir::open(run)?;
    let snaps = dir.snapshots()?;
    // Concentrated particle runs keep their structure at the rod scale: resolve r ~ l/2 there
    // (2 L/l modes, at most 64) instead of the default L/(2l).
    let pcfg: Option<ParticleRunConfig> = if dir.header()?.model == "particle" {
        Some(read_run_config(run, ParticleRunConfig::validate)?)
    } else {
        None
    };
    let modes = pcfg
        .as_ref()
        .filter(|c| c.volume_fraction > 1.0)
        .map(|c| ((2.0 * c.box_length).ceil() as usize).clamp(4, 64));
    let opts = AnalyzeOptions {
        t_start,
        modes,
        ..AnalyzeOptions::default()
    };
    let mut report =
        analyze(&snaps, &opts).map_err(|e| anyhow::anyhow!("{}: {e}", run.display()))?;
    // Dilute particle runs: c and n decay within a rod length, so their correlations come from
    // 2 L/l modes (at most 128; r ~ l/2 resolved), the flow's and Q's from the default modes.
    if let Some(c) = pcfg.as_ref().filter(|c| c.volume_fraction <= 1.0) {
        let fine = ((2.0 * c.box_length).ceil() as usize).clamp(4, 128);
        for (name, corr) in rod_scale_correlations(&snaps, t_start, fine)? {
            if let Some(slot) = report.mean.iter_mut().find(|(n, _)| *n == name) {
                slot.1 = corr;
            }
        }
    }
    let time_of = |s: &Snapshot| match s {
        Snapshot::Particle(p) => p.time,
        Snapshot::Field(f) => f.time,
    };
    // The snapshot nearest the asked time (runs of both models end at nearly, not exactly,
    // the same time in the common unit).
    let chosen = match slice_at {
        Some(t) => snaps
            .iter()
            .min_by(|a, b| (time_of(a) - t).abs().total_cmp(&(time_of(b) - t).abs())),
        None => snaps.last(),
    };
    let slice = match chosen {
        Some(last) => velocity_slice(last, pcfg.as_ref().map_or(DEFAULT_DIAMETER, |c| c.diameter))
            .map_err(|e| anyhow::anyhow!("{}: {e}", run.display()))?,
        None => None,
    };
    let traj = (report.kind == "particle").then(|| TrajectoryCurve {
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
    });
    let unit = if pcfg.is_some() {
        "1/beta"
    } else {
        "mu/|sigma_a|"
    };
    let mut particle = None;
    let (r_scale, v_scale) = if let Some(cfg) = &pcfg {
        let l = cfg.box_length;
        let n = cfg
            .rods
            .unwrap_or((cfg.volume_fraction * l * l * l).round() as usize);
        let nu = n as f64 / (l * l * l);
        particle = Some((l, nu));
        let s = motile_particle::model::units::meanfield_time_unit(nu, cfg.diameter);
        (1.0 / l, s * s)
    } else {
        (1.0, 1.0)
    };
    // Fields identically zero by construction (the mean-field c = tr Q - 1 while tr Q = 1) have
    // no correlation to normalise: left out of the charts and named in the table instead.
    let zero_fields: Vec<String> = report
        .mean
        .iter()
        .filter(|(_, c)| c.at_zero().abs().sqrt() <= ZERO_FIELD_NORM)
        .map(|(n, _)| n.clone())
        .collect();
    let lengths = report
        .mean
        .iter()
        .filter(|(n, _)| !zero_fields.contains(n))
        .map(|(n, c)| {
            (
                n.clone(),
                correlation_length(&c.r, &c.value).map_or(f64::NAN, |z| z * r_scale),
            )
        })
        .collect();
    let order = report
        .mean
        .iter()
        .filter(|(n, c)| n != "u" && c.at_zero() > 0.0 && !zero_fields.contains(n))
        .map(|(n, c)| {
            let c0 = c.at_zero();
            (
                n.clone(),
                c.r.iter()
                    .zip(&c.value)
                    .map(|(r, v)| (r * r_scale, v / c0))
                    .collect(),
            )
        })
        .collect();
    let corr_u = report
        .mean
        .iter()
        .find(|(n, _)| n == "u")
        .map(|(_, c)| CorrCurve {
            label: format!(
                "{label}, {} snapshot(s) from t = {t_start:.3} [{unit}]",
                report.window_count
            ),
            r: c.r.iter().map(|r| r * r_scale).collect(),
            value: c.value.iter().map(|v| v * v_scale).collect(),
        });
    Ok(RunAnalysis {
        corr_u,
        slice,
        traj,
        order,
        window_count: report.window_count,
        particle,
        lengths,
        zero_fields,
    })
}

/// `Corr[c]` and `Corr[n]` of the particle snapshots from `t_start`, averaged, on `modes`
/// Fourier modes per axis.
fn rod_scale_correlations(
    snaps: &[Snapshot],
    t_start: f64,
    modes: usize,
) -> anyhow::Result<Vec<(String, motile_analysis::correlation::RadialCorrelation)>> {
    use motile_analysis::correlation::{CorrelationOptions, OrderParameter, particle_coefficients};
    let opts = CorrelationOptions {
        modes: Some(modes),
        ..CorrelationOptions::default()
    };
    let mut out = Vec::new();
    for (name, which) in [
        ("c", OrderParameter::Concentration),
        ("n", OrderParameter::Polarity),
    ] {
        let mut sum: Option<motile_analysis::correlation::RadialCorrelation> = None;
        let mut count = 0usize;
        for s in snaps {
            let Snapshot::Particle(p) = s else { continue };
            if p.time < t_start - 1e-9 {
                continue;
            }
            let corr =
                particle_coefficients(&p.positions, &p.orientations, p.box_length, which, &opts)?
                    .correlation(None);
            count += 1;
            match &mut sum {
                Some(acc) => acc
                    .value
                    .iter_mut()
                    .zip(&corr.value)
                    .for_each(|(a, v)| *a += v),
                None => sum = Some(corr),
            }
        }
        if let Some(mut acc) = sum {
            acc.value.iter_mut().for_each(|v| *v /= count as f64);
            out.push((name.to_string(), acc));
        }
    }
    Ok(out)
}

/// The velocity magnitude on the plane z = 0 of a snapshot, in mean-field units:
/// `(n, values)` with `values[y n + x]`. Particle runs: the velocity field of the snapshot's
/// force density on `min(2 L/l, 64)` modes per side (docs/MODEL.md §6, doublet neglected); mean-field
/// runs: the snapshot's grid. `None` if the snapshot has no flow.
/// `diameter`: the particle run's rod diameter, which sets the time unit of the conversion.
pub fn velocity_slice(
    snap: &Snapshot,
    diameter: f64,
) -> Result<Option<(usize, Vec<f64>, f64)>, motile_analysis::nufft::NufftError> {
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
            let s = motile_particle::model::units::meanfield_time_unit(nu, diameter) / l;
            let g = [0, 1, 2].map(|c| spec.to_grid(c).into_iter().map(|v| v * s).collect());
            (modes, g, particle_to_meanfield(p.time, 0.0, nu, diameter).0)
        }
        Snapshot::Field(f) => (f.grid, f.u.clone(), f.time),
    };
    let slice = (0..n * n)
        .map(|k| (0..3).map(|c| grid[c][k].powi(2)).sum::<f64>().sqrt())
        .collect();
    Ok(Some((n, slice, time)))
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

/// The effective rotational diffusion of the rods of the run in `dir`, from their orientation
/// autocorrelation `C(t) = <p(t).p(0)>` over the snapshots up to `t1`: where the rods turn
/// diffusively, `ln C = -2 d_r t` (after a short ballistic start). The least-squares slopes of
/// `ln C` over the window's two halves must agree within 25%, else the turning is not a
/// diffusion (it is driven: in concentrated suspensions, or by a growing flow) and there is
/// no `d_r` (`None`, also with fewer than three snapshots in a half); `d_r` is the second
/// half's slope over `-2`.
pub fn rotational_diffusion(dir: &Path, t1: f64) -> anyhow::Result<Option<f64>> {
    use crate::io::snapshot::Snapshot;
    let paths = crate::io::rundir::RunDir::open(dir)?.snapshot_paths()?;
    let mut first: Option<Vec<[f64; 3]>> = None;
    let mut points = Vec::new();
    for p in paths {
        let Snapshot::Particle(s) = crate::io::snapshot::read_snapshot(&p)? else {
            continue;
        };
        if s.time > t1 + 1e-9 {
            break;
        }
        let p0 = first.get_or_insert_with(|| s.orientations.clone());
        let c = motile_analysis::stats::orientation_autocorrelation(p0, &s.orientations);
        if c > 0.0 {
            points.push((s.time, c.ln()));
        }
    }
    Ok(diffusive_rate(&points, t1))
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
