//! `motile meanfield run`: drives the mean-field stepper (docs/MODEL.md §4) and owns the run
//! directory, the time-step control, the output schedule, snapshots and the closure-table cache.
//!
//! Time step: `motile_meanfield::control::StepControl` (CFL with the sum over axes, growth
//! capped, output times reached in at most two equal steps).

use crate::checkpoint;
use crate::io::write_atomic;
use crate::run;
use crate::rundir::{RunDir, TimeSeries, parse_run_config};
use crate::snapshot::{FieldSnapshot, Snapshot, read_snapshot};
use anyhow::bail;
use hdf5_pure::{AttrValue, FileBuilder};
use motile_meanfield::closure::BinghamClosure;
use motile_meanfield::control::StepControl;
use motile_meanfield::initial::{Perturbation, PerturbationField};
use motile_meanfield::solver::{
    History, MeanFieldError, MeanFieldParams, MeanFieldRhs, MeanFieldStepReport, MeanFieldStepper,
    RhsEval, SBDF2, SYM, SpectralGrid, TensorCoefficients,
};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    /// Chebyshev degree of the closure tables. Default 80.
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
            closure_degree: 80,
            diagnostic_interval: 0.5,
            snapshot_interval: 5.0,
            checkpoint_interval: 5.0,
            checkpoint_wall_seconds: 900.0,
            checkpoints_kept: 3,
            realizability_limit: -0.1,
            step_retries: 2,
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

    /// Check every field; the message names the field, the value, the allowed range and the
    /// unit (time in mu/|sigma_a|, lengths in box sides).
    pub fn validate(&self) -> Result<(), String> {
        let chk = crate::rundir::range;
        let time = "mu/|sigma_a|";
        if !(8..=256).contains(&self.grid) || self.grid % 2 == 1 {
            return Err(format!(
                "grid = {} must be even and in [8, 256] (points per dimension)",
                self.grid
            ));
        }
        chk(
            "zeta",
            self.zeta,
            0.0,
            10.0,
            false,
            "sigma_b/mu, dimensionless",
        )?;
        chk(
            "diffusion",
            self.diffusion,
            0.0,
            1.0,
            false,
            "L^2 |sigma_a|/mu",
        )?;
        chk("t_end", self.t_end, 0.0, 1e6, true, time)?;
        chk("dt_max", self.dt_max, 0.0, 1.0, true, time)?;
        chk("cfl", self.cfl, 0.0, 2.0, true, "dimensionless")?;
        chk(
            "max_step_ratio",
            self.max_step_ratio,
            1.0,
            2.4,
            true,
            "dimensionless; SBDF2 is zero-stable below 1 + sqrt 2",
        )?;
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
            "fixed_point_tolerance",
            self.fixed_point_tolerance,
            0.0,
            1e-2,
            true,
            "relative change of u",
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
        chk(
            "fixed_point_max_iterations",
            self.fixed_point_max_iterations as f64,
            1.0,
            1e4,
            false,
            "iterations",
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
    parse_run_config(text, path, MeanFieldRunConfig::validate)
}

/// Where closure tables are cached: `$MOTILE_CACHE_DIR`, else `~/.cache/motile`.
pub fn cache_dir() -> PathBuf {
    std::env::var_os("MOTILE_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/motile")))
        .unwrap_or_else(|| PathBuf::from(".motile-cache"))
}

/// Closure tables of a degree: loaded from the cache, or built and cached.
pub fn closure_tables(degree: usize) -> anyhow::Result<BinghamClosure> {
    let path = cache_dir().join(format!("bingham_degree{degree}.bin"));
    if let Ok(bytes) = std::fs::read(&path)
        && let Some(c) = BinghamClosure::from_bytes(&bytes, degree)
    {
        return Ok(c);
    }
    let c = BinghamClosure::new(degree)
        .map_err(|e| anyhow::anyhow!("building the closure tables: {e}"))?;
    // A cache that cannot be written is not an error: the tables are rebuilt next time.
    let _ = write_atomic(&path, &c.to_bytes());
    Ok(c)
}

/// Q of a snapshot on a grid of `n^3` points: a mean-field snapshot spectrally resampled if its
/// grid differs, or a particle snapshot smoothed (see [`particle_state`]); validated: finite,
/// positive trace (concentration) everywhere.
pub fn snapshot_state(path: &Path, n: usize, smoothing: f64) -> anyhow::Result<[Vec<f64>; 6]> {
    let snap = match read_snapshot(path)? {
        Snapshot::Field(s) => s,
        Snapshot::Particle(p) => return particle_state(&p, n, smoothing, path),
    };
    let m = snap.grid;
    if let Some(i) = (0..m * m * m).find(|&i| snap.q[0][i] + snap.q[3][i] + snap.q[5][i] <= 0.0) {
        bail!(
            "{}: dataset 'Q': the trace (concentration) at point {i} is {}, must be positive",
            path.display(),
            snap.q[0][i] + snap.q[3][i] + snap.q[5][i]
        );
    }
    if m == n {
        return Ok(snap.q);
    }
    if m % 2 == 1 || m < 4 {
        bail!(
            "{}: grid {m} cannot be resampled (need an even grid of at least 4)",
            path.display()
        );
    }
    let (from, to) = (SpectralGrid::new(m), SpectralGrid::new(n));
    Ok(std::array::from_fn(|c| {
        to.inverse(&to.resample(&from.forward(&snap.q[c], false), &from))
    }))
}

/// The second-moment field of a particle snapshot on the `n^3` grid, smoothed by a Gaussian of
/// `smoothing` box sides ([`motile_meanfield::initial::from_particles`]); errors name the file.
pub fn particle_state(
    snap: &crate::snapshot::ParticleSnapshot,
    n: usize,
    smoothing: f64,
    path: &Path,
) -> anyhow::Result<[Vec<f64>; 6]> {
    motile_meanfield::initial::from_particles(
        &snap.positions,
        &snap.orientations,
        snap.box_length,
        n,
        smoothing,
    )
    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Initial Q on the grid.
pub fn initial_state(cfg: &MeanFieldRunConfig) -> anyhow::Result<[Vec<f64>; 6]> {
    if cfg.initial == "snapshot" {
        return snapshot_state(Path::new(&cfg.snapshot), cfg.grid, cfg.smoothing);
    }
    Ok(PerturbationField::new(&cfg.perturbation()).on_grid(cfg.grid))
}

/// Columns of a mean-field `timeseries.csv`.
pub const COLUMNS: [&str; 13] = [
    "t [mu/|sigma_a|]",
    "dt [mu/|sigma_a|]",
    "u_l2 [L |sigma_a|/mu]",
    "u_max [L |sigma_a|/mu]",
    "E_l2 [|sigma_a|/mu]",
    "E:Q [|sigma_a|/mu]",
    "fixed_point_iterations [1]",
    "fixed_point_residual [1]",
    "min_eigenvalue [1]",
    "max_eigenvalue [1]",
    "entropy [1]",
    "energy_identity_residual [1]",
    "steps [1]",
];

/// What a run did.
#[derive(Clone, Debug)]
pub struct MeanFieldSummary {
    /// Steps taken by this invocation.
    pub steps: u64,
    /// Wall seconds.
    pub seconds: f64,
    /// Diagnostics (all rows, including those before a resume).
    pub timeseries: TimeSeries,
    /// Final Q coefficients.
    pub q_hat: TensorCoefficients,
}

/// A row of `timeseries.csv` for the state at `t` (its diagnostics in `report`), after a step
/// of `dt`.
fn row(t: f64, dt: f64, report: &MeanFieldStepReport, steps: u64) -> Vec<f64> {
    vec![
        t,
        dt,
        report.u_l2,
        report.u_max,
        report.e_l2,
        report.e_dot_q,
        report.rhs.iterations as f64,
        report.rhs.residual,
        report.min_eigenvalue,
        report.max_eigenvalue,
        report.entropy,
        report.energy_residual,
        steps as f64,
    ]
}

/// Write the snapshot of the state at `t` (Q and the velocity of the evaluation `ev`) and
/// advance the snapshot schedule.
fn write_field_snapshot(
    run: &RunDir,
    grid: &SpectralGrid,
    clock: &mut Clock,
    cfg: &MeanFieldRunConfig,
    t: f64,
    ev: RhsEval,
) -> anyhow::Result<()> {
    let u: [Vec<f64>; 3] = std::array::from_fn(|i| grid.inverse(&ev.u[i]));
    let snap = FieldSnapshot {
        time: t,
        step: clock.steps,
        box_length: 1.0,
        grid: cfg.grid,
        q: ev.q,
        u,
    };
    snap.write(&run.snapshot_path(clock.snap_index as usize))?;
    clock.snap_index += 1;
    clock.next_snap += cfg.snapshot_interval;
    Ok(())
}

/// The driver's clocks: step-size control and the output schedule.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Clock {
    dt: f64,
    prev_dt: f64,
    next_diag: f64,
    next_snap: f64,
    next_ckpt: f64,
    snap_index: u64,
    steps: u64,
}

const CLOCK_FIELDS: [&str; 7] = [
    "dt",
    "prev_dt",
    "next_diag",
    "next_snap",
    "next_ckpt",
    "snap_index",
    "steps",
];

impl Clock {
    fn to_vec(self) -> Vec<f64> {
        vec![
            self.dt,
            self.prev_dt,
            self.next_diag,
            self.next_snap,
            self.next_ckpt,
            self.snap_index as f64,
            self.steps as f64,
        ]
    }

    fn from_slice(v: &[f64]) -> Self {
        Self {
            dt: v[0],
            prev_dt: v[1],
            next_diag: v[2],
            next_snap: v[3],
            next_ckpt: v[4],
            snap_index: v[5] as u64,
            steps: v[6] as u64,
        }
    }
}

fn complex_flat(v: &[Vec<Complex64>]) -> Vec<f64> {
    v.iter()
        .flat_map(|c| c.iter().flat_map(|z| [z.re, z.im]))
        .collect()
}

fn complex_unflat<const K: usize>(v: &[f64], n3: usize) -> [Vec<Complex64>; K] {
    std::array::from_fn(|c| {
        v[2 * c * n3..2 * (c + 1) * n3]
            .chunks_exact(2)
            .map(|p| Complex64::new(p[0], p[1]))
            .collect()
    })
}

fn write_checkpoint(
    path: &Path,
    stepper: &MeanFieldStepper,
    clock: &Clock,
    n: usize,
) -> anyhow::Result<()> {
    // Half spectrum of real fields: (n/2 + 1) n^2 coefficients per component.
    let n3 = ((n / 2 + 1) * n * n) as u64;
    let mut b = FileBuilder::new();
    b.set_attr(
        "kind",
        AttrValue::VarLenString("meanfield_checkpoint".into()),
    );
    b.set_attr("time", AttrValue::F64(stepper.t));
    b.set_attr("grid", AttrValue::U64(n as u64));
    b.set_attr(
        "spectral_layout",
        AttrValue::VarLenString("half spectrum [i2][i1][i0 <= n/2], (re, im)".into()),
    );
    b.set_attr(
        "clock_fields",
        AttrValue::VarLenString(CLOCK_FIELDS.join(",")),
    );
    b.create_dataset("clock")
        .with_f64_data(&clock.to_vec())
        .with_shape(&[CLOCK_FIELDS.len() as u64]);
    b.create_dataset("q_hat")
        .with_f64_data(&complex_flat(&stepper.q_hat))
        .with_shape(&[6, n3, 2]);
    b.create_dataset("u_hat")
        .with_f64_data(&complex_flat(&stepper.u_hat))
        .with_shape(&[3, n3, 2]);
    if let Some(h) = stepper.history() {
        b.create_dataset("prev_q_hat")
            .with_f64_data(&complex_flat(&h.q_hat))
            .with_shape(&[6, n3, 2]);
        b.create_dataset("prev_nonlinear")
            .with_f64_data(&complex_flat(&h.nonlinear))
            .with_shape(&[6, n3, 2]);
        b.create_dataset("prev_dt")
            .with_f64_data(&[h.dt])
            .with_shape(&[1]);
    }
    let bytes = b
        .finish()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    checkpoint::write_verified(path, &bytes)?;
    Ok(())
}

/// What a mean-field checkpoint holds: the stepper's state (time, Q and u coefficients, the
/// SBDF2 history) and the driver's clock.
#[derive(Clone, Debug)]
pub struct MeanFieldCheckpoint {
    /// Time.
    pub t: f64,
    /// Q's coefficients.
    pub q_hat: [Vec<Complex64>; 6],
    /// The previous step (SBDF2), absent before the first step.
    pub history: Option<History>,
    /// The velocity's coefficients (the fixed point's warm start).
    pub u_hat: [Vec<Complex64>; 3],
    clock: Clock,
}

fn read_checkpoint(path: &Path, n: usize) -> anyhow::Result<MeanFieldCheckpoint> {
    let f = checkpoint::H5Reader::open(path)?;
    let t = f.attr_f64("time")?;
    let n3 = (n / 2 + 1) * n * n;
    let q = f.f64s("q_hat")?;
    let u = f.f64s("u_hat")?;
    if q.len() != 12 * n3 || u.len() != 6 * n3 {
        bail!(
            "{}: checkpoint is for another grid size (expected {n}^3)",
            path.display()
        );
    }
    let history = if f.has("prev_dt") {
        Some(History {
            q_hat: complex_unflat::<6>(&f.f64s("prev_q_hat")?, n3),
            nonlinear: complex_unflat::<6>(&f.f64s("prev_nonlinear")?, n3),
            dt: f.f64s("prev_dt")?[0],
        })
    } else {
        None
    };
    Ok(MeanFieldCheckpoint {
        t,
        q_hat: complex_unflat::<6>(&q, n3),
        history,
        u_hat: complex_unflat::<3>(&u, n3),
        clock: Clock::from_slice(&f.f64s("clock")?),
    })
}

/// Run the mean-field model into `out`.
pub fn run_meanfield(
    cfg: &MeanFieldRunConfig,
    out: &Path,
    progress: bool,
) -> anyhow::Result<MeanFieldSummary> {
    let (model, s) = run::start::<MeanFieldModel>(cfg, out, progress)?;
    Ok(model.summary(s))
}

/// Continue a mean-field run from its newest checkpoint.
pub fn resume_meanfield(out: &Path, progress: bool) -> anyhow::Result<MeanFieldSummary> {
    let (model, s) = run::resume::<MeanFieldModel>(out, progress)?;
    Ok(model.summary(s))
}

/// The mean-field model as the run loop drives it ([`run::RunModel`]): the stepper, the
/// closure tables, and the clock (step-size control and output schedule in time).
pub struct MeanFieldModel {
    cfg: MeanFieldRunConfig,
    grid: SpectralGrid,
    stepper: MeanFieldStepper,
    closure: BinghamClosure,
    params: MeanFieldParams,
    control: StepControl,
    clock: Clock,
    notes: Vec<String>,
}

impl std::fmt::Debug for MeanFieldModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeanFieldModel")
            .field("grid", &self.cfg.grid)
            .field("t", &self.stepper.t)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl MeanFieldModel {
    fn with_state(
        cfg: &MeanFieldRunConfig,
        grid: SpectralGrid,
        stepper: MeanFieldStepper,
        clock: Clock,
        mut notes: Vec<String>,
    ) -> anyhow::Result<Self> {
        let t_tables = Instant::now();
        let closure = closure_tables(cfg.closure_degree)?;
        notes.push(format!(
            "closure tables (degree {}) ready in {:.1} s",
            cfg.closure_degree,
            t_tables.elapsed().as_secs_f64()
        ));
        let params = MeanFieldParams {
            zeta: cfg.zeta,
            diffusion: cfg.diffusion,
            fixed_point_tolerance: cfg.fixed_point_tolerance,
            fixed_point_max_iterations: cfg.fixed_point_max_iterations,
        };
        Ok(Self {
            cfg: cfg.clone(),
            grid,
            stepper,
            closure,
            params,
            control: StepControl {
                dt_max: cfg.dt_max,
                cfl: cfg.cfl,
                max_step_ratio: cfg.max_step_ratio,
            },
            clock,
            notes,
        })
    }

    fn summary(self, s: run::LoopSummary) -> MeanFieldSummary {
        MeanFieldSummary {
            steps: s.steps,
            seconds: s.seconds,
            timeseries: s.timeseries,
            q_hat: self.stepper.q_hat,
        }
    }

    fn eps(&self) -> f64 {
        1e-9 * self.cfg.t_end
    }

    /// A failed evaluation or step from the current (good) state.
    fn failure(&self, e: &MeanFieldError, dt: f64) -> run::StepFailure {
        let step = self.clock.steps + 1;
        let t = self.stepper.t;
        run::StepFailure::Step {
            kind: e.into(),
            step,
            t,
            what: format!("mean-field step {step} at t = {t:.4} (dt = {dt:.3e}) failed: {e}"),
        }
    }
}

impl run::RunModel for MeanFieldModel {
    type Config = MeanFieldRunConfig;
    type Checkpoint = MeanFieldCheckpoint;
    const MODEL: &'static str = "meanfield";

    fn columns() -> &'static [&'static str] {
        &COLUMNS
    }

    fn validate(cfg: &MeanFieldRunConfig) -> Result<(), String> {
        cfg.validate()
    }

    fn seed(cfg: &MeanFieldRunConfig) -> u64 {
        cfg.seed
    }

    fn new(cfg: &MeanFieldRunConfig) -> anyhow::Result<Self> {
        // The initial state (and any file it comes from) is checked before anything is written.
        let q0 = initial_state(cfg)?;
        let grid = SpectralGrid::new(cfg.grid);
        let stepper = MeanFieldStepper::new(&grid, &q0, SBDF2);
        let mut notes = Vec::new();
        if cfg.initial == "snapshot" {
            notes.push(format!(
                "initial state: Q of {} (a particle snapshot is smoothed with a Gaussian of {} box sides)",
                cfg.snapshot, cfg.smoothing
            ));
        }
        let dt = cfg.dt_max.min(0.1 * cfg.diagnostic_interval);
        let clock = Clock {
            dt,
            prev_dt: dt,
            next_diag: 0.0,
            next_snap: 0.0,
            next_ckpt: 0.0,
            snap_index: 0,
            steps: 0,
        };
        Self::with_state(cfg, grid, stepper, clock, notes)
    }

    fn read_checkpoint(
        cfg: &MeanFieldRunConfig,
        path: &Path,
    ) -> anyhow::Result<MeanFieldCheckpoint> {
        read_checkpoint(path, cfg.grid)
    }

    fn from_checkpoint(
        cfg: &MeanFieldRunConfig,
        c: MeanFieldCheckpoint,
        _path: &Path,
    ) -> anyhow::Result<Self> {
        let grid = SpectralGrid::new(cfg.grid);
        // Placeholder state (isotropic); the checkpoint's replaces it.
        let iso: [Vec<f64>; 6] = std::array::from_fn(|c| {
            vec![if SYM[c].0 == SYM[c].1 { 1.0 / 3.0 } else { 0.0 }; grid.len()]
        });
        let mut stepper = MeanFieldStepper::new(&grid, &iso, SBDF2);
        stepper.restore(c.t, c.q_hat, c.history, c.u_hat);
        Self::with_state(cfg, grid, stepper, c.clock, Vec::new())
    }

    fn notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notes)
    }

    fn keeps_row(&self, row: &[f64]) -> bool {
        row[0] < self.stepper.t - 1e-12 * self.cfg.t_end.max(1.0)
    }

    fn steps(&self) -> u64 {
        self.clock.steps
    }

    fn time(&self) -> f64 {
        self.stepper.t
    }

    fn finished(&self) -> bool {
        self.stepper.t >= self.cfg.t_end - self.eps()
    }

    fn progress(&self) -> (&'static str, u64, u64) {
        (
            "{bar:30} t {msg} [{elapsed} < {eta}]",
            1000,
            (1000.0 * self.stepper.t / self.cfg.t_end) as u64,
        )
    }

    fn checkpoint_policy(&self) -> (usize, f64) {
        (self.cfg.checkpoints_kept, self.cfg.checkpoint_wall_seconds)
    }

    fn begin(&mut self, _io: &mut run::RunIo) -> anyhow::Result<bool> {
        // The first checkpoint and outputs come from the schedule, before the first step.
        Ok(false)
    }

    fn checkpoint_due_before_step(&mut self) -> bool {
        if self.stepper.t >= self.clock.next_ckpt - self.eps() {
            self.clock.next_ckpt += self.cfg.checkpoint_interval;
            true
        } else {
            false
        }
    }

    fn step(&mut self, io: &mut run::RunIo) -> Result<(), run::StepFailure> {
        let cfg = &self.cfg;
        let eps = 1e-9 * cfg.t_end;
        let t = self.stepper.t;
        let at_diag = t >= self.clock.next_diag - eps;
        if at_diag {
            self.clock.next_diag += cfg.diagnostic_interval;
        }
        let mut rhs = MeanFieldRhs {
            grid: &self.grid,
            closure: &self.closure,
            params: &self.params,
            with_entropy: false,
        };
        if t >= self.clock.next_snap - eps {
            // The velocity of this Q (the stepper's is that of the previous step's state).
            let ev = match rhs.eval(&self.stepper.q_hat, &self.stepper.u_hat) {
                Ok(ev) => ev,
                Err(e) => return Err(self.failure(&e, 0.0)),
            };
            write_field_snapshot(io.run, &self.grid, &mut self.clock, cfg, t, ev)?;
        }
        // Output time ahead: spread the remaining time over at most two equal steps.
        let clock = &mut self.clock;
        let target = clock
            .next_diag
            .min(clock.next_snap)
            .min(clock.next_ckpt)
            .min(cfg.t_end);
        debug_assert!(target > t, "output clocks must be ahead of t");
        let mut this_dt = self.control.toward(t, target, clock.dt);
        rhs.with_entropy = at_diag;
        // A failed step commits nothing (the stepper holds the state before it): retry it
        // with half the step, at most `step_retries` times, then give up.
        let mut retries = 0;
        let report = loop {
            match self.stepper.step(&rhs, this_dt) {
                Ok(r) => break r,
                // Only where a smaller step is the remedy: values that blew up in the update.
                // The fixed point is solved at the state before the step, so a smaller step
                // cannot change its outcome.
                Err(e @ MeanFieldError::NonFinite(_)) if retries < cfg.step_retries => {
                    retries += 1;
                    io.log(&format!(
                        "step {} at t = {t} with dt = {this_dt:e} failed ({e}); retry {retries} of {} with dt = {:e}",
                        self.clock.steps + 1,
                        cfg.step_retries,
                        0.5 * this_dt
                    ))?;
                    this_dt *= 0.5;
                }
                Err(e) => return Err(self.failure(&e, this_dt)),
            }
        };
        let cfg = &self.cfg;
        let clock = &mut self.clock;
        clock.steps += 1;
        if report.min_eigenvalue < cfg.realizability_limit {
            let last = checkpoint::newest_first(&io.run.path().join("checkpoints"))
                .first()
                .map(|p| p.display().to_string())
                .unwrap_or_else(|| "none".into());
            return Err(run::StepFailure::Stop(crate::failure::RunFailure {
                kind: crate::failure::FailureKind::Realizability,
                step: clock.steps,
                t,
                message: format!(
                    "Q lost realizability at step {} (t = {t:.4}): the smallest eigenvalue of Q/tr Q is {:.3e}, below realizability_limit = {} (the flow is under-resolved: raise grid or diffusion). The last good checkpoint is {last}",
                    clock.steps, report.min_eigenvalue, cfg.realizability_limit
                ),
            }));
        }
        if at_diag {
            io.push_row(row(t, this_dt, &report, clock.steps))?;
            io.bar.set_message(format!(
                "{:.3} / {}, dt {:.2e}, ||u|| {:.3e}",
                self.stepper.t, cfg.t_end, this_dt, report.u_l2
            ));
        }
        // Next step from the CFL condition (sum over axes), growth capped.
        let h = 1.0 / cfg.grid as f64;
        let next = self
            .control
            .next(this_dt, clock.dt, clock.prev_dt, report.u_max, h);
        clock.prev_dt = this_dt;
        clock.dt = next;
        Ok(())
    }

    fn checkpoint_due_after_step(&self) -> bool {
        // Off-schedule checkpoints (wall clock, signal) store the state and step control as
        // they are, so resuming from one continues the same trajectory.
        false
    }

    fn finish(&mut self, io: &mut run::RunIo, took_steps: bool) -> Result<bool, run::StepFailure> {
        // The final state: outputs are written before each step, so those at t_end come here.
        // A diagnostic row and a snapshot are always written at t_end, on their schedules or
        // not (a t_end that is no multiple of the intervals still ends with its final state);
        // an off-schedule output leaves the schedule as it was, so an extended run continues
        // it. Nothing is written again when a finished run is resumed (no step taken here).
        if took_steps {
            let eps = self.eps();
            let t = self.stepper.t;
            let diag_due = t >= self.clock.next_diag - eps;
            let snap_due = t >= self.clock.next_snap - eps;
            let rhs = MeanFieldRhs {
                grid: &self.grid,
                closure: &self.closure,
                params: &self.params,
                with_entropy: true,
            };
            let (ev, report) = match self.stepper.diagnostics(&rhs) {
                Ok(r) => r,
                Err(e) => return Err(self.failure(&e, 0.0)),
            };
            if diag_due {
                self.clock.next_diag += self.cfg.diagnostic_interval;
            }
            io.push_row(row(t, self.clock.prev_dt, &report, self.clock.steps))?;
            let next_snap = self.clock.next_snap;
            write_field_snapshot(io.run, &self.grid, &mut self.clock, &self.cfg, t, ev)?;
            if !snap_due {
                self.clock.next_snap = next_snap;
            }
        }
        // Always a final checkpoint (also when a finished run is resumed: the same state).
        Ok(true)
    }

    fn write_checkpoint(&self, path: &Path) -> anyhow::Result<()> {
        write_checkpoint(path, &self.stepper, &self.clock, self.cfg.grid)
    }

    fn write_last_good(&self, path: &Path) -> anyhow::Result<()> {
        // A failed step commits nothing: the stepper holds the state before it.
        write_checkpoint(path, &self.stepper, &self.clock, self.cfg.grid)
    }
}
