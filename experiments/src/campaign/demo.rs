//! `motile demo`: part 1 is the demo scene (experiments/scenes/demo.toml, both models above the
//! instability; [`DemoSummary`] reads back what its comparison shows); part 2, here, a free-swimming suspension, the exact solution of the particle model with
//! hydrodynamics and contacts switched off (docs/MODEL.md §1: an isolated rod swims at U along p),
//! written as a particle run and analysed. It checks the analysis end to end against numbers
//! known exactly: the shot-noise level of a random configuration and the ballistic mean squared
//! displacement `(U t)^2`.

use crate::campaign::scene::SceneReport;
use crate::io::rundir::RunDir;
use crate::io::snapshot::{ParticleSnapshot, PointForces};
use crate::report::curves::{NormCurve, growth_fit, norm_curve_of};
use crate::report::opened_run::{OpenedModel, OpenedRun};
use anyhow::Context;
use motile_analysis::quadrature::gauss_legendre;
use motile_particle::model::init::isotropic_orientation;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Slender-body coefficient `eta = ln(2 l / b) / (4 pi mu)` with `b = l/5`, `mu = 1`.
pub const ETA: f64 = 0.183_233_998_581_6;

/// Configuration of the demo (written resolved to `config.toml`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct DemoConfig {
    /// Box side L/l. Default 16.
    pub box_length: f64,
    /// Effective volume fraction nu = N l^3 / L^3. Default 0.625 (dilute).
    pub volume_fraction: f64,
    /// Final time (1/beta). Default 4.
    pub t_end: f64,
    /// Number of snapshots, evenly spaced from 0 to t_end. Default 5.
    pub snapshots: usize,
    /// Random seed.
    pub seed: u64,
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            box_length: 16.0,
            volume_fraction: 0.625,
            t_end: 4.0,
            snapshots: 5,
            seed: 1,
        }
    }
}

impl DemoConfig {
    /// Number of rods, `round(nu (L/l)^3)`.
    pub fn rods(&self) -> usize {
        (self.volume_fraction * self.box_length.powi(3)).round() as usize
    }

    /// Check ranges.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.box_length >= 2.0 && self.box_length <= 1000.0) {
            return Err(format!(
                "box_length = {} is outside the allowed range [2, 1000] (rod lengths)",
                self.box_length
            ));
        }
        if !(self.volume_fraction > 0.0 && self.volume_fraction <= 10.0) {
            return Err(format!(
                "volume_fraction = {} is outside the allowed range (0, 10]",
                self.volume_fraction
            ));
        }
        if !(self.t_end > 0.0 && self.t_end.is_finite()) {
            return Err(format!("t_end = {} must be positive (1/beta)", self.t_end));
        }
        if !(2..=10_000).contains(&self.snapshots) {
            return Err(format!(
                "snapshots = {} is outside the allowed range [2, 10000]",
                self.snapshots
            ));
        }
        Ok(())
    }
}

/// Force-density points of a free swimmer: 2-point Gauss-Legendre on each half rod (exact for
/// the slip's jump, docs/MODEL.md §1), `f = (U / (2 eta)) sign(s) p`, weighted.
fn swimmer_forces(x: [f64; 3], p: [f64; 3], pts: &mut Vec<[f64; 3]>, f: &mut Vec<[f64; 3]>) {
    let (gx, gw) = gauss_legendre(2);
    for half in [-1.0, 1.0] {
        for (s0, w0) in gx.iter().zip(&gw) {
            let s = half * 0.25 * (1.0 + s0); // map [-1, 1] onto the half rod [0, 1/2] or [-1/2, 0]
            let w = 0.25 * w0;
            pts.push([0, 1, 2].map(|d| x[d] + s * p[d]));
            f.push(p.map(|pd| half / (2.0 * ETA) * pd * w));
        }
    }
}

/// Write the demo run to `out`.
pub fn write_demo_run(out: &Path, cfg: &DemoConfig) -> anyhow::Result<RunDir> {
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("demo config: {e}"))?;
    let run = RunDir::create(out, "particle", cfg.seed, cfg)?;
    let l = cfg.box_length;
    let n = cfg.rods();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let x0: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let p: Vec<[f64; 3]> = (0..n).map(|_| isotropic_orientation(&mut rng)).collect();
    run.log(&format!(
        "demo: {n} free swimmers, L/l = {l}, nu = {}",
        cfg.volume_fraction
    ))?;
    for k in 0..cfg.snapshots {
        let t = cfg.t_end * k as f64 / (cfg.snapshots - 1) as f64;
        let mut positions = Vec::with_capacity(n);
        let mut image_counts = Vec::with_capacity(n);
        for (x, p) in x0.iter().zip(&p) {
            let raw = [0, 1, 2].map(|d| x[d] + p[d] * t);
            let img = raw.map(|r| (r / l).floor() as i64);
            positions.push(
                [0, 1, 2]
                    .map(|d| (raw[d] - l * img[d] as f64).clamp(0.0, l * (1.0 - f64::EPSILON))),
            );
            image_counts.push(img);
        }
        let (mut pts, mut f) = (Vec::new(), Vec::new());
        for (x, p) in positions.iter().zip(&p) {
            swimmer_forces(*x, *p, &mut pts, &mut f);
        }
        let snap = ParticleSnapshot {
            time: t,
            step: k as u64,
            box_length: l,
            positions,
            orientations: p.clone(),
            image_counts,
            forces: Some(PointForces {
                points: pts,
                forces: f,
            }),
            kinematics: None,
        };
        snap.write(&run.snapshot_path(k))?;
        run.log(&format!("wrote snapshot {k} at t = {t}"))?;
    }
    Ok(run)
}

/// What the demo's comparison shows, read back from the scene's output (`out/particle`,
/// `out/meanfield`, `out/compare`): the checks `motile demo` prints and its test asserts.
#[derive(Clone, Debug)]
pub struct DemoSummary {
    /// The particle run's box-scale velocity norm in its growth phase (mean-field units), if any.
    pub particle: Option<(motile_analysis::stats::GrowthFit, bool)>,
    /// The mean-field velocity norm's growth phase.
    pub meanfield: Option<(motile_analysis::stats::GrowthFit, bool)>,
    /// The continuum's linear rate (M3) at the mean-field run's settings.
    pub theory_rate: f64,
    /// Saturated norms: each run's mean over the last fifth of its window (mean-field units).
    pub saturated: (f64, f64),
    /// Each run's last growth over the last fifth of its window (ratio of the norm at the end to
    /// the norm a fifth of the window earlier): near 1 once saturated.
    pub late_growth: (f64, f64),
    /// Each run's last time in mean-field units (particle converted by U1).
    pub t_end: (f64, f64),
    /// The mean-field run's configured end time.
    pub meanfield_t_end_config: f64,
    /// Radial points of the velocity autocorrelation in `0 < r/L <= 1/2`.
    pub radial_points: usize,
}

impl DemoSummary {
    /// Read the summary of a finished demo scene in `out`.
    pub fn read(out: &Path) -> anyhow::Result<Self> {
        let particle = OpenedRun::open(&out.join("particle"))?;
        let p = norm_curve_of(&particle)?;
        let meanfield = OpenedRun::open(&out.join("meanfield"))?;
        let m = norm_curve_of(&meanfield)?;
        Self::of_runs(out, &p, &m, &meanfield)
    }

    /// The summary of the demo scene just run into `out`: from its comparison's runs and curves
    /// where it has one (each run opened once), else read back ([`Self::read`]).
    pub fn of_scene(out: &Path, report: &SceneReport) -> anyhow::Result<Self> {
        let Some(compared) = &report.compare else {
            return Self::read(out);
        };
        let find = |name: &str| {
            let path = out.join(name);
            compared
                .runs
                .iter()
                .zip(&compared.curves)
                .find(|(run, _)| run.path() == path)
                .with_context(|| format!("{}: not in the comparison", path.display()))
        };
        let (_, p) = find("particle")?;
        let (meanfield, m) = find("meanfield")?;
        Self::of_runs(out, p, m, meanfield)
    }

    /// The summary from the particle and mean-field curves `p`, `m`, the mean-field run and the
    /// comparison's velocity correlations in `out/compare`.
    fn of_runs(
        out: &Path,
        p: &NormCurve,
        m: &NormCurve,
        meanfield: &OpenedRun,
    ) -> anyhow::Result<Self> {
        let last_fifth = |t: &[f64], u: &[f64]| {
            let t1 = t.last().copied().unwrap_or(0.0);
            let t0 = 0.8 * t1;
            let w = motile_analysis::stats::window_average(t, u, t0, t1);
            let k = t.iter().position(|x| *x >= t0).unwrap_or(0);
            (w.mean, u.last().copied().unwrap_or(f64::NAN) / u[k])
        };
        let (ps, pg) = last_fifth(&p.t, &p.u);
        let (ms, mg) = last_fifth(&m.t, &m.u);
        let OpenedModel::MeanField(cfg) = &meanfield.model else {
            anyhow::bail!("{}: not a mean-field run", meanfield.path().display());
        };
        Ok(Self {
            particle: growth_fit(p),
            meanfield: growth_fit(m),
            theory_rate: m.theory_rate,
            saturated: (ps, ms),
            late_growth: (pg, mg),
            t_end: (
                p.t.last().copied().unwrap_or(f64::NAN),
                m.t.last().copied().unwrap_or(f64::NAN),
            ),
            meanfield_t_end_config: cfg.t_end,
            radial_points: radial_points(out)?,
        })
    }

    /// The lines `motile demo` prints.
    pub fn lines(&self) -> Vec<String> {
        let growth = |name: &str, g: &Option<(motile_analysis::stats::GrowthFit, bool)>| match g {
            Some((g, true)) => format!(
                "check: {name}: growth phase t_mf = [{:.2}, {:.2}], grew x{:.1} at {:.4} +- {:.1e} (R^2 {:.3}), peak local rate {:.4}",
                g.t0, g.t1, g.growth_factor, g.rate, g.std_error, g.r_squared, g.peak_rate
            ),
            Some((g, false)) => format!(
                "check: {name}: NO growth phase (over the run x{:.2}, R^2 {:.2})",
                g.growth_factor, g.r_squared
            ),
            None => format!("check: {name}: too few samples for a fit"),
        };
        vec![
            growth("particle box-scale flow", &self.particle),
            growth("mean-field flow", &self.meanfield),
            format!(
                "check: linear theory (M3) at the mean-field settings: {:.4}",
                self.theory_rate
            ),
            format!(
                "check: saturation: norm over the last fifth {:.3e} (particle) and {:.3e} (mean field); growth over it x{:.2} and x{:.2}",
                self.saturated.0, self.saturated.1, self.late_growth.0, self.late_growth.1
            ),
            format!(
                "check: same window: the particle run ends at t_mf = {:.3}, the mean-field run at {:.3} (configured {:.3})",
                self.t_end.0, self.t_end.1, self.meanfield_t_end_config
            ),
            format!(
                "check: velocity autocorrelation sampled at {} radii in 0 < r/L <= 1/2",
                self.radial_points
            ),
        ]
    }
}

/// The fewest radii in `0 < r/L <= 1/2` over the runs of the velocity autocorrelation that the
/// comparison in `out/compare` wrote.
fn radial_points(out: &Path) -> anyhow::Result<usize> {
    let csv = std::fs::read_to_string(out.join("compare").join("velocity_correlation.csv"))?;
    // Rows `"label",r/L,value` (the label may hold commas).
    let mut per_run: std::collections::BTreeMap<&str, usize> = Default::default();
    for line in csv.lines().skip(1) {
        let mut f = line.rsplitn(3, ',');
        let (_, r, label) = (f.next(), f.next(), f.next().unwrap_or(""));
        if let Some(r) = r.and_then(|r| r.trim().parse::<f64>().ok())
            && r > 0.0
            && r <= 0.5 + 1e-12
        {
            *per_run.entry(label).or_default() += 1;
        }
    }
    Ok(per_run.values().copied().min().unwrap_or(0))
}

/// The mean-field bound `||u||_2 <= sqrt(1/(24 pi^2))` (docs/MODEL.md §4), which holds once
/// `tr Q = 1`, checked on the demo's mean-field run in `out/meanfield`.
pub fn meanfield_bound_line(out: &Path) -> anyhow::Result<String> {
    let ts = crate::io::rundir::TimeSeries::read(&out.join("meanfield").join("timeseries.csv"))?;
    let u = ts.column("u_l2 [L |sigma_a|/mu]").unwrap_or_default();
    let bound = (1.0 / (24.0 * std::f64::consts::PI.powi(2))).sqrt();
    let peak = u.iter().copied().fold(0.0, f64::max);
    Ok(format!(
        "mean-field ||u||_2 from {:.2e} to {:.3e} (peak {peak:.3e}, bound sqrt(1/(24 pi^2)) = {bound:.4}: {})",
        u.first().copied().unwrap_or(f64::NAN),
        u.last().copied().unwrap_or(f64::NAN),
        if peak <= bound { "holds" } else { "VIOLATED" },
    ))
}

/// Part 2: write the free-swimming run into `out`, analyse it, and check it against the exact
/// values (the shot-noise level of a random configuration, ballistic `MSD = (U t)^2`). Returns
/// the analysis time series and the check lines.
pub fn free_swimmers(
    out: &Path,
    cfg: &DemoConfig,
) -> anyhow::Result<(crate::io::rundir::TimeSeries, Vec<String>)> {
    use crate::report::analyze::{AnalyzeOptions, analyze_run};
    write_demo_run(out, cfg)?;
    let opts = AnalyzeOptions::default();
    let report = analyze_run(out, &opts)?;
    let n = cfg.rods() as f64;
    let k = opts
        .modes
        .unwrap_or(((cfg.box_length / 2.0).floor() as usize).max(4)) as f64;
    let shot = (k.powi(3) - 1.0) / n;
    let c0 = report.timeseries.column("c_l2 [1]").unwrap_or_default();
    let c0_mean = c0.iter().map(|v| v * v).sum::<f64>() / c0.len() as f64;
    let t = report.timeseries.column("t [1/beta]").unwrap_or_default();
    let msd = report.timeseries.column("msd [l^2]").unwrap_or_default();
    let worst = t
        .iter()
        .zip(&msd)
        .skip(1)
        .map(|(t, m)| (m / (t * t) - 1.0).abs())
        .fold(0.0, f64::max);
    let lines = vec![
        format!(
            "check: Corr[c'](0) = {c0_mean:.4e}, shot noise (K^3 - 1)/N = {shot:.4e}, relative deviation {:+.3} (expected spread ~{:.3})",
            c0_mean / shot - 1.0,
            (2.0 / k.powi(3)).sqrt()
        ),
        format!("check: MSD = (U t)^2 for free swimmers: worst relative error {worst:.1e}"),
    ];
    Ok((report.timeseries, lines))
}
