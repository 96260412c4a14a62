//! `motile compare RUN... --out DIR` (MODEL.md §5): particle and mean-field runs on one chart in
//! the mean-field unit system. So far the velocity norm against time and the table of its time
//! averages (issue 6 lists the rest: correlation functions, slices, growth rates).
//!
//! Conversions (MODEL.md §5): particle time `t_mf = t_p nu / (8 eta mu)`, particle velocity
//! (reported normalised by `beta L`) `u_mf = (u_p / (beta L)) 8 eta mu / nu`; mean-field runs are
//! already in those units.

use crate::io::write_atomic;
use crate::meanfield_run::MeanFieldRunConfig;
use crate::particle_run::ParticleRunConfig;
use crate::plot::{Chart, Series, line_chart};
use crate::rundir::{RunDir, TimeSeries, read_run_config};
use anyhow::{Context, bail};
use motile_analysis::stats::window_average;
use motile_particle::units::{VISCOSITY, eta};
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
}

/// Particle time and normalised velocity to mean-field units at volume fraction `nu`.
pub fn particle_to_meanfield(t_p: f64, u_p_over_beta_l: f64, nu: f64) -> (f64, f64) {
    let s = 8.0 * eta() * VISCOSITY / nu;
    (t_p / s, u_p_over_beta_l * s)
}

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
            if cfg.hydrodynamics == "none" {
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
            let u = column(&ts, "velocity_norm", &ts_path)?;
            let (t, u) = t
                .iter()
                .zip(&u)
                .map(|(t, u)| particle_to_meanfield(*t, *u, nu))
                .unzip();
            Ok(NormCurve {
                label: format!("particle L/l = {l}, nu = {nu:.3} ({})", cfg.hydrodynamics),
                run: run.into(),
                t,
                u,
            })
        }
        "meanfield" => {
            let cfg: MeanFieldRunConfig = read_run_config(run, MeanFieldRunConfig::validate)?;
            Ok(NormCurve {
                label: format!(
                    "mean field {}^3, zeta = {}, D = {}",
                    cfg.grid, cfg.zeta, cfg.diffusion
                ),
                run: run.into(),
                t: column(&ts, "t [", &ts_path)?,
                u: column(&ts, "u_l2", &ts_path)?,
            })
        }
        other => bail!("{}: cannot compare a run of kind `{other}`", run.display()),
    }
}

/// What `compare` wrote.
#[derive(Clone, Debug)]
pub struct CompareReport {
    /// The curves.
    pub curves: Vec<NormCurve>,
    /// Markdown table of the time averages.
    pub table: String,
}

/// Compare `runs` and write `velocity_norm.{png,svg,csv}` and `summary.{csv,md}` into `out`.
/// Time averages are over the second half of each run (a stated window; the table says which).
pub fn compare(runs: &[PathBuf], out: &Path) -> anyhow::Result<CompareReport> {
    if runs.is_empty() {
        bail!("compare: give at least one run directory");
    }
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
        "| run | averaging window (t, mean-field units) | time-averaged velocity norm (mean-field units) | standard error | samples |\n|---|---|---|---|---|\n",
    );
    let mut scsv = String::from("run,label,t0,t1,mean_u_l2,std_error,samples\n");
    for c in &curves {
        let t1 = c.t.last().copied().unwrap_or(0.0);
        let t0 = 0.5 * t1;
        let w = window_average(&c.t, &c.u, t0, t1);
        writeln!(
            md,
            "| {} | [{t0:.3}, {t1:.3}] | {:.4e} | {:.1e} | {} |",
            c.label, w.mean, w.std_error, w.samples
        )
        .expect("string");
        writeln!(
            scsv,
            "{},\"{}\",{t0:e},{t1:e},{:e},{:e},{}",
            c.run.display(),
            c.label,
            w.mean,
            w.std_error,
            w.samples
        )
        .expect("string");
    }
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    write_atomic(&out.join("summary.csv"), scsv.as_bytes())?;
    line_chart(
        &out.join("velocity_norm"),
        &Chart {
            title: "Velocity norm, mean-field units (MODEL.md section 5)",
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
    Ok(CompareReport { curves, table: md })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_are_the_model_ones() {
        // nu = 0.625: 8 eta / nu = 2.3454...
        let s = 8.0 * 0.183_233_6 / 0.625;
        let (t, u) = particle_to_meanfield(10.0, 0.01, 0.625);
        assert!(
            (t - 10.0 / s).abs() < 1e-5 && (u - 0.01 * s).abs() < 1e-7,
            "{t} {u}"
        );
    }
}
