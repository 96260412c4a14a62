//! `motile stability onset`: where the particle model starts to behave like the continuum
//! (docs/MODEL.md §5). For each volume fraction `nu` and each value of `L nu`, a particle run
//! from the same seeded perturbation of the continuum's initial field (box-scale modes,
//! `|m| = 1`), its box-scale velocity fitted for a growth rate; the chart shows `gamma / nu`
//! against `L nu` (growth rates scale with `nu`, the onset box with `1/nu`), beside the
//! continuum's rate (M3) in the same units, which has no onset in `L`.

use crate::io::rundir::TimeSeries;
use crate::io::write_atomic;
use crate::report::curves::{MIN_GROWTH_FACTOR, MIN_R_SQUARED};
use crate::report::plot::{Chart, Series, line_chart};
use crate::run::particle::{self, ParticleRunConfig, PerturbationConfig};
use anyhow::Context;
use motile_analysis::stats::{GrowthFit, growth_phase};
use motile_particle::model::level::Hydrodynamics;
use motile_particle::model::units::{
    DEFAULT_DIAMETER, continuum_growth_rate, meanfield_time_unit, zeta,
};
use std::fmt::Write as _;
use std::path::Path;

/// Settings of an onset scan.
#[derive(Clone, Debug, PartialEq)]
pub struct OnsetOptions {
    /// Volume fractions.
    pub fractions: Vec<f64>,
    /// Values of `L nu` (the box side of each run is `L nu / nu`, rounded to a tenth).
    pub box_nu: Vec<f64>,
    /// The hydrodynamic level (a flow is needed: Dipole or Sbt).
    pub hydrodynamics: Hydrodynamics,
    /// Time step (1/beta).
    pub dt: f64,
    /// End time times `nu` (each run ends at `t_end_nu / nu`, the same number of continuum
    /// time units).
    pub t_end_nu: f64,
    /// Amplitude of the seeded perturbation (largest component of `Q'`).
    pub amplitude: f64,
    /// Fast-sum tolerance.
    pub sum_tolerance: f64,
}

impl Default for OnsetOptions {
    fn default() -> Self {
        Self {
            fractions: vec![3.75, 5.0],
            box_nu: vec![30.0, 45.0, 60.0],
            hydrodynamics: Hydrodynamics::Sbt,
            dt: 0.04,
            t_end_nu: 40.0,
            amplitude: 0.025,
            sum_tolerance: 1e-2,
        }
    }
}

/// One run of the scan.
#[derive(Clone, Debug, PartialEq)]
pub struct OnsetPoint {
    /// Volume fraction.
    pub nu: f64,
    /// Box side (l).
    pub box_length: f64,
    /// Rods.
    pub rods: usize,
    /// The fit of the box-scale velocity norm (rate in 1/beta).
    pub fit: Option<GrowthFit>,
    /// Whether the fit is a growth phase (grew by 3 with R^2 >= 0.9).
    pub grew: bool,
    /// Wall seconds.
    pub seconds: f64,
}

/// The continuum's growth rate (M3, `D = 0`) in particle units at volume fraction `nu` for
/// rods of diameter `b`: `(1/5)/(1 + zeta/15) nu/(8 eta mu)`, `zeta = nu/(24 eta mu)`.
pub fn continuum_rate(nu: f64, diameter: f64) -> f64 {
    continuum_growth_rate(zeta(nu, diameter)) / meanfield_time_unit(nu, diameter)
}

/// The growth rate of a box-scale norm series: its growth phase if it has one (the criterion of
/// `motile compare`), else the fit over the whole series (a decay or a flat line).
pub fn box_scale_fit(t: &[f64], u: &[f64]) -> (Option<GrowthFit>, bool) {
    match growth_phase(t, u, MIN_GROWTH_FACTOR, MIN_R_SQUARED) {
        Some((g, grew)) => (Some(g), grew),
        None => (None, false),
    }
}

/// Run the scan into `out` (one run directory per point, then `onset.{png,svg,csv,md}`).
pub fn onset(
    opts: &OnsetOptions,
    out: &Path,
    mut event: impl FnMut(&str),
) -> anyhow::Result<Vec<OnsetPoint>> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut points = Vec::new();
    for &nu in &opts.fractions {
        for &lnu in &opts.box_nu {
            let l = (10.0 * lnu / nu).round() / 10.0;
            let t_end = opts.t_end_nu / nu;
            let mut cfg = ParticleRunConfig {
                box_length: l,
                volume_fraction: nu,
                dt: opts.dt,
                t_end,
                hydrodynamics: opts.hydrodynamics,
                initial: "perturbation".into(),
                perturbation: PerturbationConfig {
                    amplitude: opts.amplitude,
                    mode_min: 1,
                    mode_max: 1,
                    ..PerturbationConfig::default()
                },
                diagnostic_interval: (t_end / 40.0 / opts.dt).round().max(1.0) * opts.dt,
                snapshot_interval: t_end,
                checkpoint_interval: t_end,
                vtk: false,
                ..ParticleRunConfig::default()
            };
            cfg.hydro.sum_tolerance = opts.sum_tolerance;
            let dir = out.join(format!("nu{nu}_L{l}"));
            let seconds_file = dir.join("onset_seconds.txt");
            let ts_path = dir.join("timeseries.csv");
            // A finished run with the same settings is reused (a scan can be extended or
            // re-charted without running its cells again); anything else is run afresh.
            let finished = crate::io::rundir::read_run_config::<ParticleRunConfig>(
                &dir,
                ParticleRunConfig::validate,
            )
            // Both resolved: defaults that follow other keys (the RPY radius) filled in.
            .is_ok_and(|c| c.resolved() == cfg.resolved())
                && TimeSeries::read(&ts_path).is_ok_and(|ts| {
                    ts.column("t [1/beta]")
                        .and_then(|t| t.last().copied())
                        .is_some_and(|t| t > t_end - cfg.diagnostic_interval)
                });
            let (rods, seconds) = if finished {
                let seconds = std::fs::read_to_string(&seconds_file)
                    .ok()
                    .and_then(|s| s.trim().parse().ok())
                    .unwrap_or(f64::NAN);
                ((nu * l * l * l).round() as usize, seconds)
            } else {
                crate::io::remove_old_run(&dir)?;
                let t = std::time::Instant::now();
                let summary = particle::run_particle(&cfg, &dir, false)
                    .with_context(|| format!("onset run nu = {nu}, L/l = {l}"))?;
                let seconds = t.elapsed().as_secs_f64();
                write_atomic(&seconds_file, format!("{seconds}\n").as_bytes())?;
                (summary.rods.len(), seconds)
            };
            let ts = TimeSeries::read(&ts_path)?;
            let time = ts.column("t [1/beta]").context("time column")?;
            let u = ts
                .column("velocity_norm_box [beta L]")
                .context("box-scale velocity column")?;
            let (fit, grew) = box_scale_fit(&time, &u);
            event(&format!(
                "nu = {nu}, L/l = {l} ({rods} rods, {seconds:.0} s{}): {}",
                if finished { ", done already" } else { "" },
                fit.as_ref().map_or("no fit".into(), |g| format!(
                    "rate {:.4} +- {:.4} per 1/beta over [{:.2}, {:.2}], R^2 {:.2}, grew x{:.2}{}",
                    g.rate,
                    g.std_error,
                    g.t0,
                    g.t1,
                    g.r_squared,
                    g.growth_factor,
                    if grew { " (growth phase)" } else { "" }
                ))
            ));
            points.push(OnsetPoint {
                nu,
                box_length: l,
                rods,
                fit,
                grew,
                seconds,
            });
        }
    }
    write_onset(&points, opts, out)?;
    Ok(points)
}

fn write_onset(points: &[OnsetPoint], opts: &OnsetOptions, out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from(
        "nu,L/l,L nu,rods,rate [1/beta],rate_std_error,rate/nu,continuum_rate/nu,r_squared,growth_factor,growth_phase,t0,t1,seconds\n",
    );
    let mut md = format!(
        "# Onset of the instability ({} model)\n\nEach run starts from the same seeded perturbation of the isotropic state (box-scale modes |m| = 1, amplitude {}), the rods' orientations drawn from it (docs/MODEL.md §5); the growth rate is a least-squares fit of the logarithm of the box-scale velocity norm, and its peak local rate (charted), over its growth phase (from the start to where the local rate falls below 40% of its largest value, grown at least 3 times with R^2 >= 0.9) or, without one, over the whole run. Continuum: (M3) with D = 0, in particle units.\n\n| nu | L/l | L nu | rods | rate (1/beta) | peak rate / nu | continuum / nu | growth phase | R^2 | grew by | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        opts.hydrodynamics, opts.amplitude
    );
    for p in points {
        let c = continuum_rate(p.nu, DEFAULT_DIAMETER) / p.nu;
        let (rate, err, r2, gf, t0, t1) = p.fit.as_ref().map_or(
            (f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN),
            |g| {
                (
                    g.rate,
                    g.std_error,
                    g.r_squared,
                    g.growth_factor,
                    g.t0,
                    g.t1,
                )
            },
        );
        writeln!(
            csv,
            "{},{},{},{},{rate:e},{err:e},{:e},{c:e},{r2},{gf},{},{t0},{t1},{:.1}",
            p.nu,
            p.box_length,
            p.box_length * p.nu,
            p.rods,
            rate / p.nu,
            p.grew,
            p.seconds
        )
        .expect("string");
        writeln!(
            md,
            "| {} | {} | {:.1} | {} | {rate:.4} +- {err:.4} | {:.4} | {c:.4} | {} | {r2:.2} | {gf:.2} | {:.0} |",
            p.nu,
            p.box_length,
            p.box_length * p.nu,
            p.rods,
            p.fit.as_ref().map_or(f64::NAN, |g| g.peak_rate) / p.nu,
            if p.grew { "yes" } else { "no" },
            p.seconds
        )
        .expect("string");
    }
    write_atomic(&out.join("onset.csv"), csv.as_bytes())?;
    write_atomic(&out.join("onset.md"), md.as_bytes())?;
    let mut series: Vec<Series> = Vec::new();
    let (x_lo, x_hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        let x = p.box_length * p.nu;
        (a.min(x), b.max(x))
    });
    for &nu in &opts.fractions {
        series.push(Series {
            label: format!("particles, nu = {nu} ({})", opts.hydrodynamics),
            points: points
                .iter()
                .filter(|p| p.nu == nu)
                .filter_map(|p| {
                    p.fit
                        .as_ref()
                        .map(|g| (p.box_length * nu, g.peak_rate / nu))
                })
                .collect(),
        });
    }
    for &nu in &opts.fractions {
        let c = continuum_rate(nu, DEFAULT_DIAMETER) / nu;
        series.push(Series {
            label: format!("continuum (M3, D = 0), nu = {nu}"),
            points: vec![(x_lo, c), (x_hi, c)],
        });
    }
    line_chart(
        &out.join("onset"),
        &Chart {
            title: "Growth rate of the box-scale flow over nu, against L nu (docs/MODEL.md section 5)",
            x_label: "L nu [l]",
            y_label: "peak growth rate / nu [beta]",
            series,
        },
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continuum_rate_is_the_linear_theory_in_particle_units() {
        // nu = 0.625: zeta = 0.1421, gamma = 0.2/(1 + zeta/15) = 0.19812, times nu/(8 eta).
        let r = continuum_rate(0.625, DEFAULT_DIAMETER);
        assert!((r - 0.19812 * 0.625 / (8.0 * 0.183234)).abs() < 1e-4, "{r}");
    }

    #[test]
    fn a_growth_phase_needs_growth_and_a_good_fit() {
        let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.5).collect();
        // Grows at 0.3, then saturates at 50 x the start.
        let u: Vec<f64> = t.iter().map(|t| (0.3f64 * t).exp().min(50.0)).collect();
        let (g, grew) = box_scale_fit(&t, &u);
        let g = g.unwrap();
        // Its peak local rate is the rate; the fit over the phase reaches just past the bend.
        assert!(
            grew && (g.peak_rate - 0.3).abs() < 1e-9 && (g.rate - 0.3).abs() < 0.01 * 0.3,
            "{g:?}"
        );
        // A flat noisy series is no growth phase.
        let flat: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, _)| 1.0 + 0.05 * ((k * 7919) % 13) as f64 / 13.0)
            .collect();
        let (g, grew) = box_scale_fit(&t, &flat);
        assert!(!grew && g.unwrap().rate.abs() < 0.02);
    }
}
