//! The mean-field run's config (`config.toml`): every key with its default and allowed range,
//! validated with messages that name the field.

use crate::io::rundir::parse_run_config_with;
use crate::run::Device;
use crate::run::memory::{CUDA_CONTEXT_BYTES, GpuMemoryNeed};
use motile_meanfield::control::StepControl;
use motile_meanfield::initial::Perturbation;
use motile_meanfield::solver::params::MeanFieldParams;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Configuration of a mean-field run (units: box side 1, time mu/|sigma_a|).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MeanFieldRunConfig {
    /// Grid points per dimension (even). Default 32; allowed [8, 256].
    pub grid: usize,
    /// zeta = sigma_b / mu. Default 0.1421 (nu = 0.625); allowed [0, 10].
    pub zeta: f64,
    /// Diffusion D. Default 1e-4; allowed [0, 1].
    pub diffusion: f64,
    /// End time. Default 20.
    pub t_end: f64,
    /// Largest time step. Default 0.05; allowed (0, 1].
    pub dt_max: f64,
    /// CFL number. Default 0.5; allowed (0, 2].
    pub cfl: f64,
    /// Largest ratio of consecutive steps. Default 1.5; allowed (1, 2.4).
    pub max_step_ratio: f64,
    /// "random" (perturbations with wavenumbers |m| in [mode_min, mode_max]), "plane_wave"
    /// (Q_xy = amplitude cos(2 pi m.x) with m = `wavevector`) or "snapshot" (Q of the snapshot
    /// file `snapshot`: a mean-field snapshot, spectrally resampled if its grid differs, or a
    /// particle snapshot, its second-moment density smoothed onto the grid, docs/MODEL.md §5).
    pub initial: String,
    /// Snapshot (.h5) to start from when `initial = "snapshot"`.
    pub snapshot: String,
    /// Width (standard deviation, in box sides) of the Gaussian that smooths a particle
    /// snapshot's `Q(x) = (1/N) sum_n p_n p_n delta(x - x_n)` onto the grid (modes within the
    /// grid's dealiased band, each multiplied by `exp(-2 pi^2 |m|^2 smoothing^2)`). Default
    /// 0.02; allowed [0, 0.5]. Wider loses short-wave structure; narrower keeps more of the
    /// particles' sampling noise.
    pub smoothing: f64,
    /// Perturbation amplitude. Default 1e-2; allowed (0, 0.3].
    pub amplitude: f64,
    /// Smallest integer wavenumber of random perturbations. Default 1.
    pub mode_min: usize,
    /// Largest integer wavenumber of random perturbations. Default 4.
    pub mode_max: usize,
    /// Integer wavevector of the plane wave. Default [1, 0, 0].
    pub wavevector: [i64; 3],
    /// Seed of the random perturbations.
    pub seed: u64,
    /// Relative tolerance of the Stokes fixed point. Default 1e-8.
    pub fixed_point_tolerance: f64,
    /// Iteration cap of the fixed point. Default 50.
    pub fixed_point_max_iterations: usize,
    /// Chebyshev degree of the closure tables. Default 20, from an error budget (the
    /// closure's error on S:E is 6.7e-6 of |E|, an order below the time step's; see
    /// `motile_meanfield::closure::DEFAULT_DEGREE`); 80 reproduces the source paper's numerics.
    pub closure_degree: usize,
    /// Time between diagnostics rows. Default 0.5.
    pub diagnostic_interval: f64,
    /// Time between snapshots. Default 5.
    pub snapshot_interval: f64,
    /// Time between checkpoints. Default 5.
    pub checkpoint_interval: f64,
    /// Also checkpoint when this much wall-clock time has passed since the last one, seconds.
    /// Default 900; allowed (0, 1e7].
    pub checkpoint_wall_seconds: f64,
    /// Regular checkpoints kept (older ones are deleted). Default 3; allowed [1, 1000].
    pub checkpoints_kept: usize,
    /// Retries of a step whose update produced non-finite values, each with half the previous
    /// step size, before the run stops (a fixed point that does not converge is not retried:
    /// it is solved at the state before the step, which a smaller step does not change).
    /// Default 2; allowed [0, 20].
    pub step_retries: usize,
    /// Stop when the smallest eigenvalue of Q/tr Q falls below this (realizability lost: the
    /// flow is under-resolved). Default -0.1; allowed [-1000, 0] (-1000: never stop).
    pub realizability_limit: f64,
    /// Where the steps run: "cpu" (default) or "gpu" (an NVIDIA GPU; needs a build with
    /// `--features gpu`; `motile meanfield run --device gpu` sets it too). Results agree with
    /// the CPU's to round-off (1e-12), not bit for bit.
    pub device: Device,
}

impl Default for MeanFieldRunConfig {
    fn default() -> Self {
        // The model's and the step control's defaults come from the library (one source).
        let model = MeanFieldParams::default();
        let control = StepControl::default();
        Self {
            grid: 32,
            zeta: model.zeta,
            diffusion: model.diffusion,
            t_end: 20.0,
            dt_max: control.dt_max,
            cfl: control.cfl,
            max_step_ratio: control.max_step_ratio,
            initial: "random".into(),
            snapshot: String::new(),
            smoothing: 0.02,
            amplitude: 1e-2,
            mode_min: 1,
            mode_max: 4,
            wavevector: [1, 0, 0],
            seed: 1,
            fixed_point_tolerance: model.fixed_point_tolerance,
            fixed_point_max_iterations: model.fixed_point_max_iterations,
            closure_degree: motile_meanfield::closure::DEFAULT_DEGREE,
            diagnostic_interval: 0.5,
            snapshot_interval: 5.0,
            checkpoint_interval: 5.0,
            checkpoint_wall_seconds: 900.0,
            checkpoints_kept: 3,
            realizability_limit: -0.1,
            step_retries: 2,
            device: Device::Cpu,
        }
    }
}

impl MeanFieldRunConfig {
    /// The perturbation of a "random" or "plane_wave" start.
    pub fn perturbation(&self) -> Perturbation {
        if self.initial == "plane_wave" {
            Perturbation::PlaneWave {
                amplitude: self.amplitude,
                wavevector: self.wavevector,
            }
        } else {
            Perturbation::Random {
                amplitude: self.amplitude,
                mode_min: self.mode_min,
                mode_max: self.mode_max,
                seed: self.seed,
            }
        }
    }

    /// Make a relative `snapshot` file name relative to `base` (the folder of the config file
    /// it came from) instead of the working directory.
    pub fn resolve_paths(&mut self, base: &Path) {
        if !self.snapshot.is_empty() && Path::new(&self.snapshot).is_relative() {
            let p = base.join(&self.snapshot);
            self.snapshot = std::path::absolute(&p)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned();
        }
    }

    /// The model's parameters.
    pub fn model_params(&self) -> MeanFieldParams {
        MeanFieldParams {
            zeta: self.zeta,
            diffusion: self.diffusion,
            fixed_point_tolerance: self.fixed_point_tolerance,
            fixed_point_max_iterations: self.fixed_point_max_iterations,
            fixed_point_iterations: None,
        }
    }

    /// The GPU memory a run of this config with `device = "gpu"` needs: the context and the
    /// step's measured bytes per grid point ([`motile_meanfield::GPU_BYTES_PER_POINT`]).
    pub fn gpu_memory(&self) -> GpuMemoryNeed {
        GpuMemoryNeed {
            items: self.grid.pow(3),
            what: "grid points",
            per_item: motile_meanfield::GPU_BYTES_PER_POINT,
            context: CUDA_CONTEXT_BYTES,
        }
    }

    /// The step-size control's settings.
    pub fn step_control(&self) -> StepControl {
        StepControl {
            dt_max: self.dt_max,
            cfl: self.cfl,
            max_step_ratio: self.max_step_ratio,
        }
    }

    /// Check every field; the message names the field, the value, the allowed range and the
    /// unit (time in mu/|sigma_a|, lengths in box sides).
    pub fn validate(&self) -> Result<(), String> {
        let chk = crate::io::rundir::range;
        let time = "mu/|sigma_a|";
        if !(8..=256).contains(&self.grid) || self.grid % 2 == 1 {
            return Err(format!(
                "grid = {} must be even and in [8, 256] (points per dimension)",
                self.grid
            ));
        }
        // The model's and the step control's own checks (one source for each range).
        self.model_params().validate().map_err(|e| e.to_string())?;
        self.step_control().validate().map_err(|e| e.to_string())?;
        chk("t_end", self.t_end, 0.0, 1e6, true, time)?;
        chk("smoothing", self.smoothing, 0.0, 0.5, false, "box sides")?;
        chk(
            "amplitude",
            self.amplitude,
            0.0,
            0.3,
            true,
            "dimensionless, |Q'| of a trace-1 Q",
        )?;
        chk(
            "diagnostic_interval",
            self.diagnostic_interval,
            0.0,
            1e6,
            true,
            time,
        )?;
        chk(
            "snapshot_interval",
            self.snapshot_interval,
            0.0,
            1e6,
            true,
            time,
        )?;
        chk(
            "checkpoint_interval",
            self.checkpoint_interval,
            0.0,
            1e6,
            true,
            time,
        )?;
        chk(
            "checkpoint_wall_seconds",
            self.checkpoint_wall_seconds,
            0.0,
            1e7,
            true,
            "seconds of wall-clock time",
        )?;
        chk(
            "step_retries",
            self.step_retries as f64,
            0.0,
            20.0,
            false,
            "retries",
        )?;
        chk(
            "realizability_limit",
            self.realizability_limit,
            -1000.0,
            0.0,
            false,
            "eigenvalue of Q/tr Q",
        )?;
        if !(1..=1000).contains(&self.checkpoints_kept) {
            return Err(format!(
                "checkpoints_kept = {} is outside the allowed range [1, 1000]",
                self.checkpoints_kept
            ));
        }
        if !(10..=200).contains(&self.closure_degree) {
            return Err(format!(
                "closure_degree = {} is outside the allowed range [10, 200]",
                self.closure_degree
            ));
        }
        if self.initial == "plane_wave" {
            if self
                .wavevector
                .iter()
                .any(|m| 3 * m.unsigned_abs() as usize > self.grid)
                || self.wavevector == [0; 3]
            {
                return Err(format!(
                    "wavevector = {:?}: need a non-zero integer vector with every |m| <= grid/3 = {} (the 2/3 rule keeps |m| <= n/3)",
                    self.wavevector,
                    self.grid / 3
                ));
            }
        } else if self.initial == "random"
            && (self.mode_min < 1 || self.mode_min > self.mode_max || 3 * self.mode_max > self.grid)
        {
            return Err(format!(
                "mode_min = {}, mode_max = {}: need 1 <= mode_min <= mode_max <= grid/3 = {} (the 2/3 rule keeps |m| <= n/3)",
                self.mode_min,
                self.mode_max,
                self.grid / 3
            ));
        }
        if !["random", "plane_wave", "snapshot"].contains(&self.initial.as_str()) {
            return Err(format!(
                "initial = \"{}\": allowed \"random\", \"plane_wave\" or \"snapshot\"",
                self.initial
            ));
        }
        if self.initial == "snapshot" && self.snapshot.is_empty() {
            return Err(
                "initial = \"snapshot\" needs snapshot = \"path/to/snapshot.h5\" (a mean-field or particle snapshot)"
                    .into(),
            );
        }
        Ok(())
    }
}

/// Parse a mean-field `config.toml` (with or without the `[motile]` header).
pub fn parse_config(text: &str, path: &Path) -> anyhow::Result<MeanFieldRunConfig> {
    parse_run_config_with(text, path, modes_from_grid, MeanFieldRunConfig::validate)
}

/// The perturbation's largest wavenumber left to its default (4) is never above what the
/// grid the config gives resolves (grid/3, the 2/3 rule): `grid = 8` alone runs, with modes 1-2.
fn modes_from_grid(c: &mut MeanFieldRunConfig, given: &toml::Table) {
    if !given.contains_key("mode_max") {
        c.mode_max = c.mode_max.min(c.grid / 3).max(c.mode_min);
    }
}
