//! What a run will cost, from a step time measured before it starts: the run's config is run
//! twice for a few steps (at a proxy size when the run is large: at most [`PROXY_RODS`] rods or
//! a [`PROXY_GRID`]^3 grid), the difference of the two wall times over the difference of their
//! step counts is the time of one step (setup and output cancel), scaled to the run's size as
//! `N log N` (the fast sums, the FFTs and the contact solver's cell lists all scale so) and
//! multiplied by the run's step count.

use crate::campaign::run_config::RunConfig;
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::memory::HostMemoryNeed;
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::Context;
use motile_particle::model::level::Hydrodynamics;
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
    /// Seconds per step on a GPU and how they were estimated ([`gpu_estimate`]).
    pub gpu: Option<(f64, &'static str)>,
    /// Bytes of host memory the run needs on the CPU ([`HostMemoryNeed`], what a run checks
    /// against the machine before it allocates).
    pub memory_bytes: f64,
    /// Bytes of GPU memory the run needs on a GPU ([`gpu_estimate`]).
    pub gpu_memory_bytes: Option<f64>,
}

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
            let memory = self.gpu_memory_bytes.map_or(String::new(), |b| {
                format!(", {:.2} GB of GPU memory", b / 1e9)
            });
            format!(
                "; on a GPU about {} s/step = {}{memory} ({how})",
                significant(g),
                human_duration(g * self.steps as f64)
            )
        });
        format!(
            "{} s/step at {} {}{scaled} x {}{} steps = {} on {} CPU threads, {:.2} GB of memory{gpu}",
            significant(self.step_seconds),
            self.size,
            self.unit,
            if self.steps_at_least { ">= " } else { "" },
            self.steps,
            human_duration(self.seconds()),
            rayon::current_num_threads(),
            self.memory_bytes / 1e9
        )
    }
}

/// `x` to three significant figures, without an exponent ("0.659", "0.000214", "12.3").
fn significant(x: f64) -> String {
    if !(x > 0.0 && x.is_finite()) {
        return format!("{x:.3}");
    }
    let digits = |x: f64| (2 - x.log10().floor() as i32).max(0) as usize;
    let d = digits(x);
    // Rounding may carry into the next decade (0.9996 -> 1.000): count from the rounded value.
    let rounded: f64 = format!("{x:.d$}").parse().unwrap_or(x);
    let d = digits(rounded).min(d);
    format!("{rounded:.d$}")
}

/// Seconds as "0.25 s", "4.2 s", "42 s", "12.5 min", "3.2 h" or "4.1 days".
pub fn human_duration(s: f64) -> String {
    if s < 1.0 {
        format!("{s:.2} s")
    } else if s < 10.0 {
        format!("{s:.1} s")
    } else if s < 120.0 {
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

/// A run's estimated cost on a GPU, from measured rates (nothing is timed here): its steps
/// with their outputs, then its analysis and comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuEstimate {
    /// Seconds per step, outputs included.
    pub step_seconds: f64,
    /// Of which the diagnostics' share (seconds per step).
    pub output_seconds: f64,
    /// Steps of the run (a lower bound for mean-field runs).
    pub steps: u64,
    /// Whether `steps` is a lower bound (the CFL condition may shorten a mean-field step).
    pub steps_at_least: bool,
    /// Seconds of the analysis and comparison after the steps.
    pub analysis_seconds: f64,
    /// Bytes of GPU memory at the step's peak (measured per rod or grid point, with the
    /// context).
    pub memory_bytes: f64,
    /// Where the step's time comes from.
    pub how: &'static str,
}

impl GpuEstimate {
    /// Estimated wall seconds of the steps.
    pub fn step_total(&self) -> f64 {
        self.step_seconds * self.steps as f64
    }

    /// Estimated wall seconds of the whole run, analysis included.
    pub fn seconds(&self) -> f64 {
        self.step_total() + self.analysis_seconds
    }

    /// One line: the step, the steps, the analysis and the total.
    pub fn describe(&self) -> String {
        let total = self.seconds();
        let human = if total >= 120.0 {
            format!(" = {}", human_duration(total))
        } else {
            String::new()
        };
        format!(
            "on a GPU about {:.4} s/step ({:.4} of it diagnostics) x {}{} steps = {:.0} s, then {:.0} s of analysis: {total:.0} s in all{human}, {:.2} GB of GPU memory ({})",
            self.step_seconds,
            self.output_seconds,
            if self.steps_at_least { ">= " } else { "" },
            self.steps,
            self.step_total(),
            self.analysis_seconds,
            self.memory_bytes / 1e9,
            self.how
        )
    }
}

/// A resident particle step's measured rate on one H100 (BENCHMARKS.md, "GPU": `gpu_bench`,
/// the step alone): `(rods, seconds per step)` of each level's anchor.
fn resident_anchor(level: Hydrodynamics) -> (usize, f64) {
    match level {
        Hydrodynamics::Sbt => (78_125, 1.0 / 16.6),
        Hydrodynamics::SbtExplicit => (625_000, 1.0 / 20.4),
        Hydrodynamics::Dipole => (625_000, 1.0 / 29.7),
        Hydrodynamics::None => (625_000, 0.012),
    }
}

/// Seconds of one diagnostic per force point (the flow's norms, the lowest modes, on the host's
/// 16 threads, the rods downloaded for them), snapshots included: the `paper-dilute` L75
/// member's whole run on an H200 (263 672 rods, 1 054 688 points, a diagnostic every 10 steps,
/// the norms' transform then at 1e-6) took 74.9 ms per step against the `sbt-explicit`
/// anchor's 19.3 ms at that size. An upper bound since the norms' transform runs at 1e-4 and
/// beside the next steps.
const DIAGNOSTIC_SECONDS_PER_POINT: f64 = 5.27e-7;

/// Seconds of the analysis and comparison per rod and snapshot: the L75 member's 133 s for 31
/// snapshots of 263 672 rods with their force points on the node's 16 threads (1.63e-5), times
/// 0.41 for the order parameters' shared NUFFT plan and their real components two to a
/// transform, which took the analysis and comparison of an L75-sized run (13 snapshots, 2 cores)
/// from 109.3 s to 44.9 s (BENCHMARKS.md, A1).
const ANALYSIS_SECONDS_PER_ROD_SNAPSHOT: f64 = 6.7e-6;

/// Seconds of a mean-field run's analysis and comparison per grid point and snapshot (the
/// `paper-dilute` mf128 member on the H200 node: 40 s for 9 snapshots of 128^3).
const MEANFIELD_ANALYSIS_SECONDS_PER_POINT_SNAPSHOT: f64 = 2.1e-6;

/// `cfg`'s cost on a GPU from measured rates: a particle run's step from its level's resident
/// step (`resident_anchor`) and its diagnostics from the L75 member's whole run
/// (`DIAGNOSTIC_SECONDS_PER_POINT`); a mean-field run from the mf128 member's whole run on
/// an H200 (3 760 steps in 53.4 s, 14.2 ms per step at 128^3); each scaled as `N log N` (the
/// diagnostics as the points), then the analysis by its snapshots.
pub fn gpu_estimate(cfg: &RunConfig) -> GpuEstimate {
    match cfg {
        RunConfig::Particle(c) => {
            let rods = c.rod_count();
            let (anchor_rods, anchor_seconds) = resident_anchor(c.hydrodynamics);
            let step = anchor_seconds * nlogn_ratio(rods, anchor_rods);
            let points = (rods * c.hydro.quadrature_points) as f64;
            let per_step = (c.dt / c.diagnostic_interval).min(1.0);
            let output_seconds = if c.hydrodynamics.has_flow() {
                DIAGNOSTIC_SECONDS_PER_POINT * points * per_step
            } else {
                0.0
            };
            let snapshots = (c.t_end / c.snapshot_interval).floor() + 1.0;
            GpuEstimate {
                step_seconds: step + output_seconds,
                output_seconds,
                steps: (c.t_end / c.dt - 1e-9).ceil() as u64,
                steps_at_least: false,
                analysis_seconds: ANALYSIS_SECONDS_PER_ROD_SNAPSHOT * rods as f64 * snapshots,
                memory_bytes: c.gpu_memory().bytes(),
                how: "the resident step's measured rate on an H100 and the diagnostics' on an H200, scaled as N log N; BENCHMARKS.md",
            }
        }
        RunConfig::MeanField(c) => {
            let points = c.grid.pow(3);
            let snapshots = (c.t_end / c.snapshot_interval).floor() + 1.0;
            GpuEstimate {
                step_seconds: 0.0142 * nlogn_ratio(points, 128usize.pow(3)),
                output_seconds: 0.0,
                steps: meanfield_steps(c),
                steps_at_least: true,
                analysis_seconds: MEANFIELD_ANALYSIS_SECONDS_PER_POINT_SNAPSHOT
                    * points as f64
                    * snapshots,
                memory_bytes: c.gpu_memory().bytes(),
                how: "the mf128 member's whole run on an H200, scaled as N log N; at least this many steps (the CFL condition may shorten the step)",
            }
        }
    }
}

/// A mean-field run's steps at its largest step (at most `dt_max` and a tenth of the
/// diagnostic interval): a lower bound.
fn meanfield_steps(c: &MeanFieldRunConfig) -> u64 {
    let dt = c.dt_max.min(0.1 * c.diagnostic_interval);
    (c.t_end / dt - 1e-9).ceil() as u64
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
    let gpu = gpu_estimate(cfg);
    result.map(|e| CostEstimate {
        gpu: Some((gpu.step_seconds, gpu.how)),
        gpu_memory_bytes: Some(gpu.memory_bytes),
        ..e
    })
}

/// Wall seconds and steps of `run` into a fresh `dir`.
fn timed(dir: &Path, run: impl FnOnce(&Path) -> anyhow::Result<u64>) -> anyhow::Result<(f64, u64)> {
    let _ = std::fs::remove_dir_all(dir);
    let t0 = Instant::now();
    let steps = run(dir)?;
    Ok((t0.elapsed().as_secs_f64(), steps))
}

/// The least difference of the two timing runs' wall times (s). A quarter second let a 64^3
/// mean-field step (0.22 s) be timed over 4 steps, and the first run's cold start scattered
/// the estimate by 30%; 2 s spans 10 or more steps of the costliest proxies.
const MIN_TIMED_SECONDS: f64 = 2.0;

/// Seconds per step from a 2-step run and a longer one, lengthened (6, 30, 150, 750 steps, and
/// never beyond the run's own `run_steps` where that is more than 6: a proxy run past the run's
/// end may leave what the run resolves) until the difference of their wall times is at least
/// [`MIN_TIMED_SECONDS`], so that timer noise and setup do not decide the answer.
fn step_time<F>(scratch: &Path, run_steps: u64, run: impl Fn(f64) -> F) -> anyhow::Result<f64>
where
    F: FnOnce(&Path) -> anyhow::Result<u64>,
{
    let longest = (run_steps as f64).clamp(6.0, 750.0);
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
        if b.0 - a.0 >= MIN_TIMED_SECONDS || steps >= longest {
            // Noise can still make the difference negative when steps are very cheap: then
            // the longer run's own mean, setup included, bounds the step from above.
            let d = (b.0 - a.0) / (b.1 - a.1) as f64;
            return Ok(if d > 0.0 { d } else { b.0 / b.1 as f64 });
        }
        steps = (steps * 5.0).min(longest);
    }
}

fn estimate_particle(c: &ParticleRunConfig, scratch: &Path) -> anyhow::Result<CostEstimate> {
    let size = c.rod_count();
    let mut proxy = c.clone();
    let from_file = !matches!(c.initial.as_str(), "random" | "perturbation");
    if size > PROXY_RODS && !from_file {
        let shrink = (PROXY_RODS as f64 / size as f64).cbrt();
        proxy.box_length = c.box_length * shrink;
        proxy.rods = c.rods.map(|_| PROXY_RODS);
    }
    let measured_size = proxy.rod_count();
    proxy.snapshot_interval = 1e5;
    proxy.checkpoint_interval = 1e5;
    proxy.vtk = false;
    let run = |steps: f64| {
        let mut p = proxy.clone();
        p.t_end = steps * c.dt;
        move |dir: &Path| particle::run_particle(&p, dir, false).map(|s| s.steps)
    };
    let steps = (c.t_end / c.dt - 1e-9).ceil() as u64;
    let measured = step_time(scratch, steps, run)?;
    let ratio = nlogn_ratio(size, measured_size);
    Ok(CostEstimate {
        unit: "rods",
        measured_size,
        size,
        measured_step_seconds: measured,
        step_seconds: measured * ratio,
        steps,
        steps_at_least: false,
        gpu: None,
        memory_bytes: HostMemoryNeed::particle(size).bytes(),
        gpu_memory_bytes: None,
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
    let measured = step_time(scratch, meanfield_steps(c), run)?;
    let (size, measured_size) = (c.grid.pow(3), proxy.grid.pow(3));
    Ok(CostEstimate {
        unit: "grid points",
        measured_size,
        size,
        measured_step_seconds: measured,
        step_seconds: measured * nlogn_ratio(size, measured_size),
        steps: meanfield_steps(c),
        steps_at_least: true,
        gpu: None,
        memory_bytes: HostMemoryNeed::meanfield(c.grid).bytes(),
        gpu_memory_bytes: None,
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
        assert_eq!(human_duration(0.253), "0.25 s");
        assert_eq!(human_duration(4.24), "4.2 s");
        assert_eq!(human_duration(42.0), "42 s");
        assert_eq!(human_duration(750.0), "12.5 min");
        assert_eq!(human_duration(3.0 * 3600.0), "3.0 h");
        assert_eq!(human_duration(4.0 * 86_400.0), "4.0 days");
        assert_eq!(significant(0.6594), "0.659");
        assert_eq!(significant(0.000_213_7), "0.000214");
        assert_eq!(significant(12.34), "12.3");
        assert_eq!(significant(1234.0), "1234");
        assert_eq!(significant(0.9996), "1.00");
    }
}
