//! `motile analyze`: correlation functions, norms and trajectory statistics of a run's
//! snapshots (docs/MODEL.md §6), written to `<run>/analysis/`.

use crate::io::rundir::{RunDir, TimeSeries};
use crate::io::snapshot::{FieldSnapshot, ParticleSnapshot, PointForces, Snapshot};
use crate::io::{IoError, write_atomic};
use crate::report::plot::{Chart, Series, line_chart};
use hdf5_pure::{AttrValue, FileBuilder};
use motile_analysis::correlation::{
    CorrelationOptions, OrderParameter, ParticleSpectra, RadialCorrelation, Spectrum,
    grid_coefficients, velocity_spectrum,
};
use motile_analysis::stats::{
    correlation_length, mean_squared_displacement, orientation_autocorrelation, unwrap,
};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Options of `motile analyze`, written resolved to `analysis/config.toml`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AnalyzeOptions {
    /// Fourier modes per dimension for particle snapshots. Default: floor((L/l)/2), at least 4.
    pub modes: Option<usize>,
    /// Spacing of the radii at which correlations are evaluated (units of length): each value
    /// is the exact spherical average `sum_k P(k) j0(|k| r)` of the retained modes
    /// (docs/MODEL.md (A2)). Default: L/128, 64 radii in (0, L/2].
    pub shell_width: Option<f64>,
    /// NUFFT tolerance, in [1e-12, 1e-1]. Default 1e-6.
    pub tolerance: f64,
    /// Start of the time-averaging window (model time units). Default 0: every snapshot.
    pub t_start: f64,
    /// Viscosity mu used by the velocity spectrum of particle snapshots. Default 1.
    pub viscosity: f64,
}

impl Default for AnalyzeOptions {
    fn default() -> Self {
        Self {
            modes: None,
            shell_width: None,
            tolerance: 1e-6,
            t_start: 0.0,
            viscosity: 1.0,
        }
    }
}

impl AnalyzeOptions {
    /// Check ranges; the message names the field, the value and the allowed range.
    pub fn validate(&self) -> Result<(), String> {
        if !(1e-12..=1e-1).contains(&self.tolerance) {
            return Err(format!(
                "tolerance = {:e} is outside the allowed range [1e-12, 1e-1]",
                self.tolerance
            ));
        }
        if let Some(m) = self.modes
            && !(2..=512).contains(&m)
        {
            return Err(format!(
                "modes = {m} is outside the allowed range [2, 512] (modes per dimension)"
            ));
        }
        if let Some(w) = self.shell_width
            && !(w.is_finite() && w > 0.0)
        {
            return Err(format!(
                "shell_width = {w} must be positive (units of length)"
            ));
        }
        if !(self.viscosity.is_finite() && self.viscosity > 0.0) {
            return Err(format!("viscosity = {} must be positive", self.viscosity));
        }
        if !self.t_start.is_finite() {
            return Err(format!("t_start = {} must be finite", self.t_start));
        }
        Ok(())
    }
}

/// Analysis of one snapshot.
#[derive(Clone, Debug)]
pub struct SnapshotAnalysis {
    /// Simulated time.
    pub time: f64,
    /// Field name and its radial correlation.
    pub correlations: Vec<(String, RadialCorrelation)>,
    /// Mean squared displacement since the first snapshot (particle runs).
    pub msd: Option<f64>,
    /// Orientation autocorrelation against the first snapshot (particle runs).
    pub orientation: Option<f64>,
}

/// Everything `motile analyze` computes.
#[derive(Clone, Debug)]
pub struct AnalysisReport {
    /// "particle" or "meanfield".
    pub kind: String,
    /// Per snapshot.
    pub snapshots: Vec<SnapshotAnalysis>,
    /// Time-averaged correlation of each field over snapshots with `t >= t_start`.
    pub mean: Vec<(String, RadialCorrelation)>,
    /// Number of snapshots in the averaging window.
    pub window_count: usize,
    /// Per-snapshot scalars (norms, correlation lengths, MSD).
    pub timeseries: TimeSeries,
}

/// The spectra of a particle snapshot's order parameters (on `spectra`, a plan kept from one
/// snapshot to the next) and, where it has force points, of its flow.
fn particle_fields(
    s: &ParticleSnapshot,
    opts: &AnalyzeOptions,
    spectra: &mut Option<ParticleSpectra>,
) -> Result<Vec<(String, Spectrum)>, String> {
    let copts = CorrelationOptions {
        modes: opts.modes,
        shell_width: opts.shell_width,
        tolerance: opts.tolerance,
    };
    let modes = copts.modes_for(s.box_length);
    if spectra.as_ref().is_none_or(|p| p.modes() != modes) {
        *spectra = Some(ParticleSpectra::new(modes, opts.tolerance).map_err(|e| e.to_string())?);
    }
    let plan = spectra.as_mut().expect("a plan was just made");
    let order = plan
        .of(
            &s.positions,
            &s.orientations,
            s.box_length,
            &[
                OrderParameter::Concentration,
                OrderParameter::Polarity,
                OrderParameter::Nematic,
            ],
        )
        .map_err(|e| e.to_string())?;
    let mut out: Vec<(String, Spectrum)> = ["c", "n", "Q"]
        .into_iter()
        .map(String::from)
        .zip(order)
        .collect();
    if let Some(PointForces {
        points: pts,
        forces: f,
    }) = &s.forces
    {
        let mut spec =
            velocity_spectrum(pts, f, s.box_length, opts.viscosity, modes, opts.tolerance)
                .map_err(|e| e.to_string())?;
        // Report velocities normalised by beta L (docs/MODEL.md §5), with beta = 1.
        for c in &mut spec.components {
            for v in c.iter_mut() {
                *v /= s.box_length;
            }
        }
        out.push(("u".to_string(), spec));
    }
    Ok(out)
}

fn field_fields(s: &FieldSnapshot) -> Vec<(String, Spectrum)> {
    let n = s.grid;
    let l = s.box_length;
    let trace: Vec<f64> = (0..n.pow(3))
        .map(|i| s.q[0][i] + s.q[3][i] + s.q[5][i])
        .collect();
    let dev: Vec<Vec<f64>> = (0..6)
        .map(|c| {
            if [0, 3, 5].contains(&c) {
                s.q[c]
                    .iter()
                    .zip(&trace)
                    .map(|(q, t)| q - t / 3.0)
                    .collect()
            } else {
                s.q[c].clone()
            }
        })
        .collect();
    let dref: Vec<&[f64]> = dev.iter().map(|v| v.as_slice()).collect();
    let uref: Vec<&[f64]> = s.u.iter().map(|v| v.as_slice()).collect();
    vec![
        ("c".into(), grid_coefficients(&[&trace], &[1.0], n, l, true)),
        (
            "Q".into(),
            grid_coefficients(&dref, &[1.0, 2.0, 2.0, 1.0, 2.0, 1.0], n, l, false),
        ),
        ("u".into(), grid_coefficients(&uref, &[1.0; 3], n, l, false)),
    ]
}

/// "particle" or "meanfield": the kind of a run's snapshots.
fn snapshot_kind(s: &Snapshot) -> &'static str {
    match s {
        Snapshot::Particle(_) => "particle",
        Snapshot::Field(_) => "meanfield",
    }
}

/// Analyse every snapshot of a run.
pub fn analyze(snaps: &[Snapshot], opts: &AnalyzeOptions) -> Result<AnalysisReport, String> {
    opts.validate()?;
    let first = snaps.first().ok_or("the run has no snapshots")?;
    let kind = snapshot_kind(first);
    let mut spectra = None;
    let per = snaps
        .iter()
        .map(|s| analyse_snapshot(s, first, opts, &mut spectra))
        .collect::<Result<Vec<_>, String>>()?;
    // Fields may be missing from some snapshots (the initial one of a hydrodynamic run has no
    // force density, so no velocity): the columns are those of the richest snapshot, and a
    // snapshot without a field gets NaN there.
    let names: Vec<String> = per
        .iter()
        .max_by_key(|a| a.correlations.len())
        .map(|a| a.correlations.iter().map(|(n, _)| n.clone()).collect())
        .unwrap_or_default();
    let timeseries = scalar_series(kind, &names, &per);
    let window: Vec<&SnapshotAnalysis> = per.iter().filter(|a| a.time >= opts.t_start).collect();
    if window.is_empty() {
        return Err(format!(
            "no snapshot at or after t_start = {} (last snapshot at t = {})",
            opts.t_start,
            per.last().map_or(f64::NAN, |a| a.time)
        ));
    }
    let mean = window_means(&names, &window);
    let window_count = window.len();
    Ok(AnalysisReport {
        kind: kind.into(),
        snapshots: per,
        mean,
        window_count,
        timeseries,
    })
}

/// One snapshot's correlations and, for particles, its mean squared displacement and
/// orientation autocorrelation against the `first` snapshot.
fn analyse_snapshot(
    s: &Snapshot,
    first: &Snapshot,
    opts: &AnalyzeOptions,
    spectra: &mut Option<ParticleSpectra>,
) -> Result<SnapshotAnalysis, String> {
    let (fields, msd, orientation) = match (s, first) {
        (Snapshot::Particle(p), Snapshot::Particle(p0)) => {
            if p.positions.len() != p0.positions.len() {
                return Err(format!(
                    "snapshot at t = {} has {} rods, the first has {}",
                    p.time,
                    p.positions.len(),
                    p0.positions.len()
                ));
            }
            (
                particle_fields(p, opts, spectra)?,
                Some(mean_squared_displacement(&unwrapped(p0), &unwrapped(p))),
                Some(orientation_autocorrelation(
                    &p0.orientations,
                    &p.orientations,
                )),
            )
        }
        (Snapshot::Field(f), Snapshot::Field(_)) => (field_fields(f), None, None),
        _ => return Err("the run mixes particle and mean-field snapshots".into()),
    };
    let correlations = fields
        .iter()
        .map(|(n, sp)| (n.clone(), sp.correlation(opts.shell_width)))
        .collect();
    Ok(SnapshotAnalysis {
        time: s.time(),
        correlations,
        msd,
        orientation,
    })
}

/// The rods' centres with the periodic images they crossed undone.
fn unwrapped(p: &ParticleSnapshot) -> Vec<[f64; 3]> {
    p.positions
        .iter()
        .zip(&p.image_counts)
        .map(|(x, i)| unwrap(*x, *i, p.box_length))
        .collect()
}

/// A snapshot's correlation of the field `name`, if it has that field.
fn correlation_of(a: &SnapshotAnalysis, name: &str) -> Option<RadialCorrelation> {
    a.correlations
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, c)| c.clone())
}

/// The time series of scalars: per snapshot, each field's L2 norm and correlation length, and
/// for particles the mean squared displacement and orientation autocorrelation.
fn scalar_series(kind: &str, names: &[String], per: &[SnapshotAnalysis]) -> TimeSeries {
    let particle = kind == "particle";
    let unit_t = if particle { "1/beta" } else { "mu/|sigma_a|" };
    let unit_r = if particle { "l" } else { "L" };
    let mut cols = vec![format!("t [{unit_t}]")];
    for n in names {
        let unit = match (n == "u", particle) {
            (true, true) => "beta L",
            (true, false) => "L |sigma_a|/mu",
            (false, _) => "1",
        };
        cols.push(format!("{n}_l2 [{unit}]"));
        cols.push(format!("{n}_corr_length [{unit_r}]"));
    }
    if particle {
        cols.push("msd [l^2]".into());
        cols.push("orientation_autocorrelation [1]".into());
    }
    let col_refs: Vec<&str> = cols.iter().map(|s| s.as_str()).collect();
    let mut ts = TimeSeries::new(&col_refs);
    for a in per {
        let mut row = vec![a.time];
        for n in names {
            match correlation_of(a, n) {
                Some(c) => {
                    row.push(c.at_zero().max(0.0).sqrt());
                    row.push(correlation_length(&c.r, &c.value).unwrap_or(f64::NAN));
                }
                None => row.extend([f64::NAN, f64::NAN]),
            }
        }
        if particle {
            row.push(a.msd.unwrap_or(f64::NAN));
            row.push(a.orientation.unwrap_or(f64::NAN));
        }
        ts.push(row);
    }
    ts
}

/// Each field's correlation averaged over the window's snapshots that have it.
fn window_means(
    names: &[String],
    window: &[&SnapshotAnalysis],
) -> Vec<(String, RadialCorrelation)> {
    names
        .iter()
        .filter_map(|n| {
            let have: Vec<RadialCorrelation> =
                window.iter().filter_map(|a| correlation_of(a, n)).collect();
            let base = have.first()?;
            let mut value = vec![0.0; base.value.len()];
            for c in &have {
                for (v, x) in value.iter_mut().zip(&c.value) {
                    *v += x / have.len() as f64;
                }
            }
            Some((
                n.clone(),
                RadialCorrelation {
                    r: base.r.clone(),
                    value,
                    modes: base.modes,
                },
            ))
        })
        .collect()
}

/// Write a report to `<run>/analysis/`: `config.toml`, `timeseries.csv`, `correlations.csv`,
/// `analysis.h5`, `correlations.png|svg`.
pub fn write_report(
    run: &RunDir,
    opts: &AnalyzeOptions,
    report: &AnalysisReport,
) -> Result<(), IoError> {
    let dir = run.path().join("analysis");
    let cfg = toml::to_string_pretty(opts).map_err(|e| IoError::Content {
        path: dir.join("config.toml"),
        message: e.to_string(),
    })?;
    write_atomic(&dir.join("config.toml"), cfg.as_bytes())?;
    report.timeseries.write(&dir.join("timeseries.csv"))?;
    write_atomic(
        &dir.join("correlations.csv"),
        correlations_csv(report).as_bytes(),
    )?;
    write_h5(&dir.join("analysis.h5"), opts, report)?;
    write_correlation_chart(&dir.join("correlations"), opts, report)
}

/// The time-averaged correlations as CSV, one (r, value) column pair per field.
fn correlations_csv(report: &AnalysisReport) -> String {
    let mut csv = String::new();
    let header: Vec<String> = report
        .mean
        .iter()
        .flat_map(|(n, _)| [format!("r_{n}"), format!("corr_{n}")])
        .collect();
    csv.push_str(&header.join(","));
    csv.push('\n');
    let rows = report
        .mean
        .iter()
        .map(|(_, c)| c.r.len())
        .max()
        .unwrap_or(0);
    for i in 0..rows {
        let cells: Vec<String> = report
            .mean
            .iter()
            .flat_map(|(_, c)| match (c.r.get(i), c.value.get(i)) {
                (Some(r), Some(v)) => [format!("{r:e}"), format!("{v:e}")],
                _ => [String::new(), String::new()],
            })
            .collect();
        csv.push_str(&cells.join(","));
        csv.push('\n');
    }
    csv
}

/// `analysis.h5`: per-snapshot and time-averaged correlations.
fn write_h5(h5: &Path, opts: &AnalyzeOptions, report: &AnalysisReport) -> Result<(), IoError> {
    let mut b = FileBuilder::new();
    b.set_attr("kind", AttrValue::VarLenString(report.kind.clone()));
    b.set_attr("t_start", AttrValue::F64(opts.t_start));
    b.set_attr("window_count", AttrValue::U64(report.window_count as u64));
    let times: Vec<f64> = report.snapshots.iter().map(|s| s.time).collect();
    b.create_dataset("time")
        .with_f64_data(&times)
        .with_shape(&[times.len() as u64]);
    for (n, mean) in report.mean.iter() {
        let nr = mean.r.len() as u64;
        b.create_dataset(&format!("r_{n}"))
            .with_f64_data(&mean.r)
            .with_shape(&[nr]);
        b.create_dataset(&format!("corr_mean_{n}"))
            .with_f64_data(&mean.value)
            .with_shape(&[nr]);
        // Per snapshot; NaN rows where a snapshot lacks the field (see `analyze`).
        let all: Vec<f64> = report
            .snapshots
            .iter()
            .flat_map(|s| match s.correlations.iter().find(|(m, _)| m == n) {
                Some((_, c)) if c.value.len() == mean.value.len() => c.value.clone(),
                _ => vec![f64::NAN; mean.value.len()],
            })
            .collect();
        b.create_dataset(&format!("corr_{n}"))
            .with_f64_data(&all)
            .with_shape(&[times.len() as u64, nr]);
    }
    let bytes = b.finish().map_err(|e| IoError::Hdf5 {
        path: h5.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomic(h5, &bytes)
}

/// The figure: time-averaged correlations normalised by their value at r = 0.
fn write_correlation_chart(
    stem: &Path,
    opts: &AnalyzeOptions,
    report: &AnalysisReport,
) -> Result<(), IoError> {
    let unit = if report.kind == "particle" { "l" } else { "L" };
    let series = report
        .mean
        .iter()
        .filter(|(_, c)| c.at_zero() > 0.0)
        .map(|(n, c)| Series {
            label: format!("Corr[{n}]"),
            points: c
                .r
                .iter()
                .zip(&c.value)
                .map(|(r, v)| (*r, v / c.at_zero()))
                .collect(),
        })
        .collect();
    let title = format!(
        "{} run: correlations averaged over {} snapshot(s), t >= {}",
        report.kind, report.window_count, opts.t_start
    );
    line_chart(
        stem,
        &Chart {
            title: &title,
            x_label: &format!("r [{unit}]"),
            y_label: "Corr(r) / Corr(0)",
            series,
        },
    )
}

/// Read a run, analyse it, and write the report.
pub fn analyze_run(path: &Path, opts: &AnalyzeOptions) -> anyhow::Result<AnalysisReport> {
    let run = RunDir::open(path)?;
    let snaps = run.snapshots()?;
    let report = analyze(&snaps, opts).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    write_report(&run, opts, &report)?;
    Ok(report)
}
