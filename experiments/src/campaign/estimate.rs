//! What a run will cost, from a step time measured before it starts: the run's config is run
//! twice for a few steps (at a proxy size when the run is large: at most [`PROXY_RODS`] rods or
//! a [`PROXY_GRID`]^3 grid), the difference of the two wall times over the difference of their
//! step counts is the time of one step (setup and output cancel), scaled to the run's size as
//! `N log N` (the fast sums, the FFTs and the contact solver's cell lists all scale so) and
//! multiplied by the run's step count.

use crate::campaign::run_config::RunConfig;
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::Context;
use std::path::Path;
use std::time::Instant;

/// Largest particle count timed directly; larger runs are timed on a smaller box at the same
/// volume fraction.
pub const PROXY_RODS: usize = 10_000;
/// Largest mean-field grid timed directly.
pub const PROXY_GRID: usize = 64;

/// A run's estimated cost.
#[derive(Clone, Debug, PartialEq)]
pub struct CostEstimate {
    /// What `size` counts: "rods" or "grid points".
    pub unit: &'static str,
    /// Size the step was timed at (rods or grid points).
    pub measured_size: usize,
    /// The run's size (rods or grid points).
    pub size: usize,
    /// Measured seconds per step at `measured_size`.
    pub measured_step_seconds: f64,
    /// Seconds per step scaled to `size` (`N log N`).
    pub step_seconds: f64,
    /// Steps of the run (a lower bound for mean-field runs, whose step the CFL condition may
    /// shorten below `dt_max`).
    pub steps: u64,
    /// Whether `steps` is a lower bound.
    pub steps_at_least: bool,
    /// Seconds per step on a GPU and how they were estimated: particle runs with a flow, the
    /// hydrodynamic sums at the throughput an H200 measured ([`GPU_POINTS_PER_SECOND`]) and the
    /// rest of the step as timed here (the measured step less its mobility, scaled as
    /// `N log N`); mean-field runs, the H200's measured 256^3 step scaled as `N log N`.
    pub gpu: Option<(f64, &'static str)>,
}

/// Points per second of the RPY sum an H200 reached on a 1e7-point product at tolerance 1e-4
/// (BENCHMARKS.md, "GPU: a lent H200"): what a GPU estimate assumes for the sums.
pub const GPU_POINTS_PER_SECOND: f64 = 3.91e6;

impl CostEstimate {
    /// Estimated wall seconds of the whole run.
    pub fn seconds(&self) -> f64 {
        self.step_seconds * self.steps as f64
    }

    /// One line: the measurement, the scaling and the total.
    pub fn describe(&self) -> String {
        let scaled = if self.size == self.measured_size {
            String::new()
        } else {
            format!(
                " (timed at {} {}: {:.3} s, scaled as N log N)",
                self.measured_size, self.unit, self.measured_step_seconds
            )
        };
        let gpu = self.gpu.map_or(String::new(), |(g, how)| {
            format!(
                "; on a GPU about {g:.3} s/step = {} ({how})",
                human_duration(g * self.steps as f64)
            )
        });
        format!(
            "{:.3} s/step at {} {}{scaled} x {}{} steps = {} on {} CPU threads{gpu}",
            self.step_seconds,
            self.size,
            self.unit,
            if self.steps_at_least { ">= " } else { "" },
            self.steps,
            human_duration(self.seconds()),
            rayon::current_num_threads()
        )
    }
}

/// Seconds as "42 s", "12.5 min", "3.2 h" or "4.1 days".
pub fn human_duration(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.1} min", s / 60.0)
    } else if s < 172_800.0 {
        format!("{:.1} h", s / 3600.0)
    } else {
        format!("{:.1} days", s / 86_400.0)
    }
}

/// `N log N` ratio of `size` to `measured`.
fn nlogn_ratio(size: usize, measured: usize) -> f64 {
    let (n, m) = (size as f64, measured as f64);
    n * n.ln() / (m * m.ln())
}

/// Measure and estimate `cfg`'s cost, timing its steps in scratch directories under `scratch`
/// (removed afterwards).
pub fn estimate(cfg: &RunConfig, scratch: &Path) -> anyhow::Result<CostEstimate> {
    std::fs::create_dir_all(scratch)
        .with_context(|| format!("{}: cannot create", scratch.display()))?;
    let result = match cfg {
        RunConfig::Particle(c) => estimate_particle(c, scratch),
        RunConfig::MeanField(c) => estimate_meanfield(c, scratch),
    };
    let _ = std::fs::remove_dir_all(scratch);
    result
}

/// Wall seconds and steps of `run` into a fresh `dir`.
fn timed(dir: &Path, run: impl FnOnce(&Path) -> anyhow::Result<u64>) -> anyhow::Result<(f64, u64)> {
    let _ = std::fs::remove_dir_all(dir);
    let t0 = Instant::now();
    let steps = run(dir)?;
    Ok((t0.elapsed().as_secs_f64(), steps))
}

/// Seconds per step from a 2-step run and a longer one, lengthened (6, 30, 150, 750 steps)
/// until the difference of their wall times is at least a quarter second, so that timer noise
/// and setup do not decide the answer.
fn step_time<F>(scratch: &Path, run: impl Fn(f64) -> F) -> anyhow::Result<f64>
where
    F: FnOnce(&Path) -> anyhow::Result<u64>,
{
    let a = timed(&scratch.join("a"), run(2.0))?;
    let mut steps = 6.0;
    loop {
        let b = timed(&scratch.join("b"), run(steps))?;
        anyhow::ensure!(
            b.1 > a.1,
            "cost estimate: the longer timing run took no more steps ({} against {})",
            b.1,
            a.1
        );
        if b.0 - a.0 >= 0.25 || steps >= 750.0 {
            // Noise can still make the difference negative when steps are very cheap: then
            // the longer run's own mean, setup included, bounds the step from above.
            let d = (b.0 - a.0) / (b.1 - a.1) as f64;
            return Ok(if d > 0.0 { d } else { b.0 / b.1 as f64 });
        }
        steps *= 5.0;
    }
}

fn estimate_particle(c: &ParticleRunConfig, scratch: &Path) -> anyhow::Result<CostEstimate> {
    let size = c
        .rods
        .unwrap_or((c.volume_fraction * c.box_length.powi(3)).round() as usize);
    let mut proxy = c.clone();
    let from_file = !matches!(c.initial.as_str(), "random" | "perturbation");
    if size > PROXY_RODS && !from_file {
        let shrink = (PROXY_RODS as f64 / size as f64).cbrt();
        proxy.box_length = c.box_length * shrink;
        proxy.rods = c.rods.map(|_| PROXY_RODS);
    }
    let measured_size = proxy
        .rods
        .unwrap_or((proxy.volume_fraction * proxy.box_length.powi(3)).round() as usize);
    proxy.snapshot_interval = 1e5;
    proxy.checkpoint_interval = 1e5;
    proxy.vtk = false;
    let run = |steps: f64| {
        let mut p = proxy.clone();
        p.t_end = steps * c.dt;
        move |dir: &Path| particle::run_particle(&p, dir, false).map(|s| s.steps)
    };
    let measured = step_time(scratch, run)?;
    let ratio = nlogn_ratio(size, measured_size);
    // The mobility alone at the proxy size (after one call that builds its plans): what a GPU
    // would take over.
    let gpu_step_seconds = if c.hydrodynamics.has_flow() {
        let rods = particle::initial_rods(&proxy)?;
        let p = rods.orientations();
        let mut mobility = particle::config::mobility(&proxy)?;
        let mut out = motile_particle::hydro::mobility::RodVelocities::zeros(rods.len());
        mobility.free_velocities(&rods, &p, &mut out)?;
        let t = Instant::now();
        mobility.free_velocities(&rods, &p, &mut out)?;
        let hydro = t.elapsed().as_secs_f64();
        let points = size * c.hydro.quadrature_points;
        let sums_per_step = if c.hydrodynamics == motile_particle::model::level::Hydrodynamics::Sbt
        {
            // GMRES: about ten products per step on the dilute runs (BENCHMARKS.md).
            10.0
        } else {
            1.0
        };
        Some((
            (measured - hydro).max(0.0) * ratio
                + sums_per_step * points as f64 / GPU_POINTS_PER_SECOND,
            "the sums at the 3.9e6 points/s an H200 measured, BENCHMARKS.md; the rest of the step on these CPU threads",
        ))
    } else {
        None
    };
    Ok(CostEstimate {
        unit: "rods",
        measured_size,
        size,
        measured_step_seconds: measured,
        step_seconds: measured * ratio,
        steps: (c.t_end / c.dt - 1e-9).ceil() as u64,
        steps_at_least: false,
        gpu: gpu_step_seconds,
    })
}

fn estimate_meanfield(c: &MeanFieldRunConfig, scratch: &Path) -> anyhow::Result<CostEstimate> {
    let mut proxy = c.clone();
    proxy.grid = c.grid.min(PROXY_GRID);
    // The run's step is at most dt_max and a tenth of the diagnostic interval.
    let dt = c.dt_max.min(0.1 * c.diagnostic_interval);
    proxy.snapshot_interval = 1e5;
    proxy.checkpoint_interval = 1e5;
    let run = |steps: f64| {
        let mut p = proxy.clone();
        p.t_end = steps * dt;
        move |dir: &Path| meanfield::run_meanfield(&p, dir, false).map(|s| s.steps)
    };
    let measured = step_time(scratch, run)?;
    let (size, measured_size) = (c.grid.pow(3), proxy.grid.pow(3));
    Ok(CostEstimate {
        unit: "grid points",
        measured_size,
        size,
        measured_step_seconds: measured,
        step_seconds: measured * nlogn_ratio(size, measured_size),
        steps: (c.t_end / dt - 1e-9).ceil() as u64,
        steps_at_least: true,
        // The H200 measured 0.0992 s per step at 256^3 (BENCHMARKS.md).
        gpu: Some((
            0.0992 * nlogn_ratio(size, 256usize.pow(3)),
            "the H200's measured 0.0992 s/step at 256^3, scaled as N log N; BENCHMARKS.md",
        )),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nlogn_scaling_and_durations() {
        assert!((nlogn_ratio(1000, 1000) - 1.0).abs() < 1e-15);
        let r = nlogn_ratio(1_000_000, 1000);
        assert!((r - 2000.0).abs() < 1e-9, "{r}");
        assert_eq!(human_duration(42.0), "42 s");
        assert_eq!(human_duration(750.0), "12.5 min");
        assert_eq!(human_duration(3.0 * 3600.0), "3.0 h");
        assert_eq!(human_duration(4.0 * 86_400.0), "4.0 days");
    }
}
