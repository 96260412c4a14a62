//! `motile compare RUN... --out DIR` (docs/MODEL.md §5): particle and mean-field runs on one chart in
//! the mean-field unit system. So far the velocity norm against time, the table of its time
//! averages, and the time-averaged velocity autocorrelation `Corr[u](r)` against `r/L`
//! (issue 6 lists the rest: slices, order-parameter correlations, growth rates).
//!
//! Conversions (docs/MODEL.md §5): particle time `t_mf = t_p nu / (8 eta mu)`, particle velocity
//! (reported normalised by `beta L`) `u_mf = (u_p / (beta L)) 8 eta mu / nu`; mean-field runs are
//! already in those units.

use crate::analyze::{AnalyzeOptions, analyze};
use crate::io::write_atomic;
use crate::meanfield_run::MeanFieldRunConfig;
use crate::particle_run::ParticleRunConfig;
use crate::plot::{Chart, Panel, Series, heatmaps, line_chart};
use crate::rundir::{RunDir, TimeSeries, read_run_config};
use crate::snapshot::Snapshot;
use anyhow::{Context, bail};
use motile_analysis::correlation::velocity_spectrum;
use motile_analysis::stats::{GrowthFit, correlation_length, growth_phase, window_average};
use motile_particle::model::units::{DEFAULT_DIAMETER, VISCOSITY, continuum_growth_rate};
use std::fmt::Write as _;
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
}

pub use motile_particle::model::units::particle_to_meanfield;

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
            Ok(NormCurve {
                label: format!(
                    "particle L/l = {l}, nu = {nu:.3} ({}{})",
                    cfg.hydrodynamics,
                    if box_scale { ", box-scale modes" } else { "" }
                ),
                run: run.into(),
                t,
                u,
                t_end_own,
                theory_rate: continuum_growth_rate(zeta),
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
struct RunAnalysis {
    /// `Corr[u](r)` averaged over the snapshots with `t >= t_start`, mean-field units; `None`
    /// if the snapshots carry no flow.
    corr_u: Option<CorrCurve>,
    /// The velocity slice of the last snapshot (see [`velocity_slice`]).
    slice: Option<(usize, Vec<f64>, f64)>,
    traj: Option<TrajectoryCurve>,
    /// `Corr[c], Corr[n], Corr[Q]` normalised by their value at 0, against `r / L`.
    order: Vec<(String, Vec<(f64, f64)>)>,
    /// Particle runs: `(L/l, nu)`.
    particle: Option<(f64, f64)>,
    /// Correlation lengths (first zero of each time-averaged correlation), `r / L`, by field.
    lengths: Vec<(String, f64)>,
    /// Fields whose L2 norm is at most [`ZERO_FIELD_NORM`] (identically zero by construction).
    zero_fields: Vec<String>,
}

/// One run's snapshots, read once: its Corr[u], order-parameter correlations, velocity slice
/// and, for particle runs, trajectory statistics.
fn analyse(run: &Path, label: &str, t_start: f64) -> anyhow::Result<RunAnalysis> {
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
    let report = analyze(&snaps, &opts).map_err(|e| anyhow::anyhow!("{}: {e}", run.display()))?;
    let slice = match snaps.last() {
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
        particle,
        lengths,
        zero_fields,
    })
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

/// What `compare` wrote.
#[derive(Clone, Debug)]
pub struct CompareReport {
    /// The curves.
    pub curves: Vec<NormCurve>,
    /// Time-averaged velocity autocorrelations (runs whose snapshots carry a flow).
    pub correlations: Vec<CorrCurve>,
    /// Trajectory statistics of the particle runs.
    pub trajectories: Vec<TrajectoryCurve>,
    /// Markdown table of the time averages.
    pub table: String,
}

/// Compare `runs` and write `velocity_norm.{png,svg,csv}`, `summary.{csv,md}`,
/// `velocity_correlation.{png,svg,csv}` and, for particle runs, `msd.{png,svg}`,
/// `orientation.{png,svg}` and `trajectories.csv` into `out`. Time averages are over the second half of
/// each run (a stated window; the table and the legend say which).
///
/// Everything is written into a staging folder beside `out` first and moved into `out` only
/// when all of it succeeded: a comparison that fails (a damaged snapshot, an unreadable run)
/// leaves nothing under the final names.
pub fn compare(runs: &[PathBuf], out: &Path) -> anyhow::Result<CompareReport> {
    if runs.is_empty() {
        bail!("compare: give at least one run directory");
    }
    let name = out
        .file_name()
        .map_or("compare".into(), |n| n.to_string_lossy().into_owned());
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent)
        .with_context(|| format!("{}: cannot create", parent.display()))?;
    let stage = parent.join(format!(".{name}.partial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&stage);
    let result = compare_into(runs, &stage).and_then(|report| {
        std::fs::create_dir_all(out)
            .with_context(|| format!("{}: cannot create", out.display()))?;
        for entry in std::fs::read_dir(&stage)? {
            let entry = entry?;
            let target = out.join(entry.file_name());
            std::fs::rename(entry.path(), &target)
                .with_context(|| format!("{}: cannot write", target.display()))?;
        }
        Ok(report)
    });
    let _ = std::fs::remove_dir_all(&stage);
    result
}

/// [`compare`] writing straight into `out`.
fn compare_into(runs: &[PathBuf], out: &Path) -> anyhow::Result<CompareReport> {
    let curves = runs
        .iter()
        .map(|r| norm_curve(r))
        .collect::<anyhow::Result<Vec<_>>>()?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut csv = String::from("run,label,t [mu/|sigma_a|],u_l2 [L |sigma_a|/mu]\n");
    for c in &curves {
        for (t, u) in c.t.iter().zip(&c.u) {
            writeln!(csv, "{},\"{}\",{t:e},{u:e}", c.run.display(), c.label).expect("string");
        }
    }
    write_atomic(&out.join("velocity_norm.csv"), csv.as_bytes())?;
    let mut md = String::from(
        "| run | averaging window (t, mean-field units) | time-averaged velocity norm (mean-field units) | standard error | samples | growth phase (t) | growth rate over the phase (peak local rate), mean-field units | R^2, grew by | linear theory (M3) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut scsv = String::from(
        "run,label,t0,t1,mean_u_l2,std_error,samples,growth_phase,growth_t0,growth_t1,growth_rate,growth_rate_std_error,peak_rate,r_squared,growth_factor,theory_rate\n",
    );
    for c in &curves {
        let t1 = c.t.last().copied().unwrap_or(0.0);
        let t0 = 0.5 * t1;
        let w = window_average(&c.t, &c.u, t0, t1);
        let g = growth_fit(c);
        let (gw, gr, gq) = match &g {
            Some((g, true)) => (
                format!("[{:.3}, {:.3}]", g.t0, g.t1),
                format!(
                    "{:.4} +- {:.1e} (peak {:.4})",
                    g.rate, g.std_error, g.peak_rate
                ),
                format!("{:.3}, x{:.1}", g.r_squared, g.growth_factor),
            ),
            Some((g, false)) => (
                "none".into(),
                "-".into(),
                format!(
                    "no growth phase (over the run: R^2 {:.2}, x{:.2})",
                    g.r_squared, g.growth_factor
                ),
            ),
            None => ("too few samples".into(), "-".into(), "-".into()),
        };
        writeln!(
            md,
            "| {} | [{t0:.3}, {t1:.3}] | {:.4e} | {:.1e} | {} | {gw} | {gr} | {gq} | {:.4} |",
            c.label, w.mean, w.std_error, w.samples, c.theory_rate
        )
        .expect("string");
        let (phase, g0, g1, grate, gerr, peak, r2, gf) = g.map_or(
            (
                false,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
            ),
            |(g, p)| {
                (
                    p,
                    g.t0,
                    g.t1,
                    g.rate,
                    g.std_error,
                    g.peak_rate,
                    g.r_squared,
                    g.growth_factor,
                )
            },
        );
        writeln!(
            scsv,
            "{},\"{}\",{t0:e},{t1:e},{:e},{:e},{},{phase},{g0:e},{g1:e},{grate:e},{gerr:e},{peak:e},{r2:e},{gf:e},{:e}",
            c.run.display(),
            c.label,
            w.mean,
            w.std_error,
            w.samples,
            c.theory_rate
        )
        .expect("string");
    }
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    write_atomic(&out.join("summary.csv"), scsv.as_bytes())?;
    line_chart(
        &out.join("velocity_norm"),
        &Chart {
            title: "Velocity norm, mean-field units (docs/MODEL.md section 5)",
            x_label: "t [mu/|sigma_a|]",
            y_label: "||u||_2 [L |sigma_a|/mu]",
            series: curves
                .iter()
                .map(|c| Series {
                    label: c.label.clone(),
                    points: c.t.iter().copied().zip(c.u.iter().copied()).collect(),
                })
                .collect(),
        },
    )?;
    // Each run's snapshots analysed once: Corr[u] and order-parameter correlations over its second
    // half (in its own time unit), the last snapshot's velocity slice, trajectories.
    let mut correlations = Vec::new();
    let mut trajectories = Vec::new();
    let mut order: Vec<(String, Vec<Series>)> = Vec::new();
    let mut panels = Vec::new();
    let analyses = runs
        .iter()
        .zip(&curves)
        .map(|(run, c)| analyse(run, &c.label, 0.5 * c.t_end_own))
        .collect::<anyhow::Result<Vec<_>>>()?;
    // Concentrated suspensions (every run a particle run with nu > 1) keep their structure at
    // the rod scale: their order-parameter correlations are read against r/l (docs/MODEL.md §7).
    let concentrated = analyses
        .iter()
        .all(|a| a.particle.is_some_and(|(_, nu)| nu > 1.0));
    let mut lcsv = String::from("run,label,field,correlation_length [L],correlation_length [l]\n");
    let mut lmd = String::from(
        "\n| run | correlation lengths (first zero of the time-averaged Corr, second half): r/L (r/l for particle runs) |\n|---|---|\n",
    );
    for ((run, c), a) in runs.iter().zip(&curves).zip(&analyses) {
        let mut cells = Vec::new();
        for (field, z) in &a.lengths {
            let in_l = a.particle.map_or(f64::NAN, |(l, _)| z * l);
            writeln!(
                lcsv,
                "{},\"{}\",{field},{z:e},{in_l:e}",
                run.display(),
                c.label
            )
            .expect("string");
            cells.push(if z.is_nan() {
                format!("{field}: no zero")
            } else if a.particle.is_some() {
                format!("{field}: {z:.3} ({in_l:.2})")
            } else {
                format!("{field}: {z:.3}")
            });
        }
        for field in &a.zero_fields {
            cells.push(format!(
                "{field}: identically zero (||{field}||_2 <= {ZERO_FIELD_NORM:.0e}), not plotted"
            ));
        }
        writeln!(lmd, "| {} | {} |", c.label, cells.join("; ")).expect("string");
    }
    write_atomic(&out.join("correlation_lengths.csv"), lcsv.as_bytes())?;
    md.push_str(&lmd);
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    for (c, a) in curves.iter().zip(analyses) {
        correlations.extend(a.corr_u);
        if let Some((n, values, t)) = a.slice {
            panels.push(Panel {
                label: format!("{} at t = {t:.3}", c.label),
                n,
                values,
            });
        }
        trajectories.extend(a.traj);
        let to_l = match (concentrated, a.particle) {
            (true, Some((l, _))) => l,
            _ => 1.0,
        };
        for (name, points) in a.order {
            let points: Vec<(f64, f64)> = points.into_iter().map(|(r, v)| (r * to_l, v)).collect();
            match order.iter_mut().find(|(n, _)| *n == name) {
                Some((_, series)) => series.push(Series {
                    label: c.label.clone(),
                    points,
                }),
                None => order.push((
                    name,
                    vec![Series {
                        label: c.label.clone(),
                        points,
                    }],
                )),
            }
        }
    }
    // Velocity magnitude on z = 0 at each run's last snapshot, side by side, one colour scale.
    if !panels.is_empty() {
        heatmaps(
            &out.join("velocity_slice"),
            "|u| on the plane z = 0, last snapshot, mean-field units",
            "|u| [L |sigma_a|/mu]",
            &panels,
        )?;
    }
    // Order-parameter correlations, one chart per field, shapes compared (normalised at 0).
    for (name, series) in &order {
        line_chart(
            &out.join(format!("correlation_{name}")),
            &Chart {
                title: &format!("Corr[{name}](r) / Corr[{name}](0), second half of each run"),
                x_label: if concentrated { "r / l" } else { "r / L" },
                y_label: &format!("Corr[{name}](r) / Corr[{name}](0)"),
                series: series.clone(),
            },
        )?;
    }
    if !trajectories.is_empty() {
        let mut tcsv = String::from("label,t [1/beta],msd [l^2],orientation_autocorrelation [1]\n");
        for tr in &trajectories {
            for k in 0..tr.t.len() {
                writeln!(
                    tcsv,
                    "\"{}\",{:e},{:e},{:e}",
                    tr.label, tr.t[k], tr.msd[k], tr.orientation[k]
                )
                .expect("string");
            }
        }
        write_atomic(&out.join("trajectories.csv"), tcsv.as_bytes())?;
        for (stem, title, y_label, pick) in [
            (
                "msd",
                "Mean squared displacement of the rods",
                "<|x(t) - x(0)|^2> [l^2]",
                0,
            ),
            (
                "orientation",
                "Orientation autocorrelation of the rods",
                "<p(t) . p(0)> [1]",
                1,
            ),
        ] {
            line_chart(
                &out.join(stem),
                &Chart {
                    title,
                    x_label: "t [1/beta]",
                    y_label,
                    series: trajectories
                        .iter()
                        .map(|tr| Series {
                            label: tr.label.clone(),
                            points: tr
                                .t
                                .iter()
                                .copied()
                                .zip(
                                    if pick == 0 { &tr.msd } else { &tr.orientation }
                                        .iter()
                                        .copied(),
                                )
                                .collect(),
                        })
                        .collect(),
                },
            )?;
        }
    }
    let mut ccsv = String::from("label,r/L,Corr[u] [(L |sigma_a|/mu)^2]\n");
    for c in &correlations {
        for (r, v) in c.r.iter().zip(&c.value) {
            writeln!(ccsv, "\"{}\",{r:e},{v:e}", c.label).expect("string");
        }
    }
    write_atomic(&out.join("velocity_correlation.csv"), ccsv.as_bytes())?;
    line_chart(
        &out.join("velocity_correlation"),
        &Chart {
            title: "Time-averaged velocity autocorrelation, mean-field units",
            x_label: "r / L",
            y_label: "Corr[u](r) [(L |sigma_a|/mu)^2]",
            series: correlations
                .iter()
                .map(|c| Series {
                    label: c.label.clone(),
                    points: c.r.iter().copied().zip(c.value.iter().copied()).collect(),
                })
                .collect(),
        },
    )?;
    Ok(CompareReport {
        curves,
        correlations,
        trajectories,
        table: md,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_are_the_model_ones() {
        // nu = 0.625: 8 eta / nu = 2.3454...
        let s = 8.0 * 0.183_233_6 / 0.625;
        let (t, u) = particle_to_meanfield(10.0, 0.01, 0.625, DEFAULT_DIAMETER);
        assert!(
            (t - 10.0 / s).abs() < 1e-5 && (u - 0.01 * s).abs() < 1e-7,
            "{t} {u}"
        );
    }
}
