//! The mean-field model's adapter of the run loop ([`crate::run`]): `motile meanfield run` and
//! resume. [`MeanFieldModel`] steps the mean-field stepper (docs/MODEL.md §4) with the library's
//! step-size control and writes its outputs on a schedule in time: time-series rows before a
//! step, snapshots of Q and its velocity, a final row and snapshot at t_end. Its config is in
//! `config.rs`; its initial fields, closure-table cache, clock and checkpoint codec in
//! `state.rs`.

mod config;
// Without the `gpu` feature, `device_off.rs`: no GPU stepper, and a run that asks for one is
// refused with how to build it.
#[cfg_attr(not(feature = "gpu"), path = "device_off.rs")]
mod device;
mod state;
mod step_error;

pub use config::*;
pub use state::*;

use crate::io::checkpoint;
use crate::io::rundir::{RunDir, TimeSeries};
use crate::io::snapshot::FieldSnapshot;
use crate::run;
use crate::run::Device;
use crate::run::memory::HostMemoryNeed;
use anyhow::{Context, bail};
use motile_meanfield::closure::BinghamClosure;
use motile_meanfield::control::StepControl;
use motile_meanfield::solver::closure_field::Realizability;
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::{MeanFieldError, MeanFieldParams, SYM};
use motile_meanfield::solver::rhs::{MeanFieldRhs, RhsEval};
use motile_meanfield::solver::stepper::{
    MeanFieldStepReport, MeanFieldStepper, SBDF2, TensorCoefficients,
};
use std::path::Path;
use std::time::Instant;
use step_error::EngineError;

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

/// Run the mean-field model into `out`.
pub fn run_meanfield(
    cfg: &MeanFieldRunConfig,
    out: &Path,
    progress: bool,
) -> anyhow::Result<MeanFieldSummary> {
    let (model, s) = run::start::<MeanFieldModel>(cfg, out, progress)?;
    model.summary(s)
}

/// What a run checks before it allocates or writes anything, and all `--dry-run` checks
/// beyond the config's ranges: the memory its grid needs on this machine (on the CPU), and
/// the snapshot it starts from (read and validated).
pub fn preflight(cfg: &MeanFieldRunConfig) -> anyhow::Result<()> {
    check_memory(cfg)?;
    if cfg.initial == "snapshot" {
        initial_state(cfg).with_context(|| format!("`snapshot` = {:?}", cfg.snapshot))?;
    }
    Ok(())
}

/// The host memory of a run on the CPU, the GPU memory of a run on the GPU (refused before
/// anything is allocated, with the figures).
fn check_memory(cfg: &MeanFieldRunConfig) -> anyhow::Result<()> {
    let checked = match cfg.device {
        Device::Cpu => HostMemoryNeed::meanfield(cfg.grid).check(crate::run::memory::available()),
        Device::Gpu => device::check_memory(cfg.gpu_memory()),
    };
    checked.map_err(|e| anyhow::anyhow!("config: grid = {}: {e}", cfg.grid))
}

/// Continue a mean-field run from its newest checkpoint.
pub fn resume_meanfield(out: &Path, progress: bool) -> anyhow::Result<MeanFieldSummary> {
    let (model, s) = run::resume::<MeanFieldModel>(out, progress)?;
    model.summary(s)
}

/// Where the steps run: the CPU stepper, which always holds the configuration's time, and, with
/// `device = "gpu"`, the GPU stepper that holds the state itself (downloaded into the CPU
/// stepper's form for snapshots, diagnostics and checkpoints).
struct Engine {
    cpu: MeanFieldStepper,
    gpu: Option<device::GpuEngine>,
}

impl Engine {
    /// The CPU stepper, or (`device = "gpu"`) the GPU stepper started from its state.
    fn new(
        cfg: &MeanFieldRunConfig,
        cpu: MeanFieldStepper,
        grid: &SpectralGrid,
        closure: &BinghamClosure,
        params: &MeanFieldParams,
    ) -> anyhow::Result<Self> {
        let gpu = if cfg.device == Device::Gpu {
            let rhs = MeanFieldRhs {
                grid,
                closure,
                params,
                with_entropy: false,
            };
            Some(device::GpuEngine::open(&rhs, &cpu)?)
        } else {
            None
        };
        Ok(Self { cpu, gpu })
    }

    fn t(&self) -> f64 {
        self.cpu.t
    }

    /// One step; nothing is committed when it fails.
    fn step(&mut self, rhs: &MeanFieldRhs, dt: f64) -> Result<MeanFieldStepReport, EngineError> {
        if let Some(g) = self.gpu.as_mut() {
            let (report, t) = g.step(dt, rhs.with_entropy)?;
            self.cpu.t = t;
            return Ok(report);
        }
        self.cpu.step(rhs, dt).map_err(EngineError::Model)
    }

    /// The state in the CPU stepper's form (downloaded from the device with `device = "gpu"`).
    fn synced(&self) -> anyhow::Result<std::borrow::Cow<'_, MeanFieldStepper>> {
        if let Some(g) = &self.gpu {
            return Ok(std::borrow::Cow::Owned(g.synced(&self.cpu)?));
        }
        Ok(std::borrow::Cow::Borrowed(&self.cpu))
    }
}

/// The mean-field model as the run loop drives it ([`run::RunModel`]): the stepper, the
/// closure tables, and the clock (step-size control and output schedule in time).
pub struct MeanFieldModel {
    cfg: MeanFieldRunConfig,
    grid: SpectralGrid,
    stepper: Engine,
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
            .field("t", &self.stepper.t())
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
        let params = cfg.model_params();
        let stepper = Engine::new(cfg, stepper, &grid, &closure, &params)?;
        if let Some(g) = &stepper.gpu {
            notes.push(format!(
                "steps run on the GPU (device = \"gpu\"): {}",
                g.describe()
            ));
        }
        Ok(Self {
            cfg: cfg.clone(),
            grid,
            stepper,
            closure,
            params,
            control: cfg.step_control(),
            clock,
            notes,
        })
    }

    fn summary(self, s: run::LoopSummary) -> anyhow::Result<MeanFieldSummary> {
        let q_hat = self.stepper.synced()?.into_owned().q_hat;
        Ok(MeanFieldSummary {
            steps: s.steps,
            seconds: s.seconds,
            timeseries: s.timeseries,
            q_hat,
        })
    }

    fn eps(&self) -> f64 {
        1e-9 * self.cfg.t_end
    }

    /// A failed evaluation or step from the current (good) state.
    fn failure(&self, e: &MeanFieldError, dt: f64) -> run::StepFailure {
        self.failed(e.into(), &e.to_string(), dt)
    }

    fn failed(&self, kind: crate::run::failure::FailureKind, e: &str, dt: f64) -> run::StepFailure {
        let step = self.clock.steps + 1;
        let t = self.stepper.t();
        run::StepFailure::Step {
            kind,
            step,
            t,
            what: format!("mean-field step {step} at t = {t:.4} (dt = {dt:.3e}) failed: {e}"),
        }
    }

    /// A failure to read the state back from the device.
    fn device_failure(&self, e: anyhow::Error) -> run::StepFailure {
        self.failed(
            crate::run::failure::FailureKind::Device,
            &format!("{e:#}"),
            0.0,
        )
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
        check_memory(cfg)?;
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
        let c = read_checkpoint(path, cfg.grid)?;
        // The next output times lie within an interval (and a step) of the checkpoint's time.
        let k = &c.clock;
        for (name, next, interval) in [
            ("next_diag", k.next_diag, cfg.diagnostic_interval),
            ("next_snap", k.next_snap, cfg.snapshot_interval),
            ("next_ckpt", k.next_ckpt, cfg.checkpoint_interval),
        ] {
            let reach = interval + cfg.dt_max + 1e-9 * c.t.max(1.0);
            if !(next >= c.t - reach && next <= c.t.max(cfg.t_end) + reach) {
                bail!(
                    "{}: damaged or not written by motile: clock's {name} = {next} is not within an interval ({interval}) of the checkpoint's time {}",
                    path.display(),
                    c.t
                );
            }
        }
        let grid = SpectralGrid::new(cfg.grid);
        let states = [Some(&c.q_hat), c.history.as_ref().map(|h| &h.q_hat)];
        for (name, q_hat) in ["q_hat", "prev_q_hat"].iter().zip(states) {
            let Some(q_hat) = q_hat else { continue };
            let q: [Vec<f64>; 6] = std::array::from_fn(|k| grid.inverse(&q_hat[k]));
            let r = Realizability::of(&q);
            if !(r.min_trace > 0.0 && r.min_eigenvalue >= cfg.realizability_limit) {
                bail!(
                    "{}: damaged or not written by motile: dataset '{name}' is no orientation tensor field (smallest tr Q {:.3e}, must be positive; smallest eigenvalue of Q/tr Q {:.3e}, realizability_limit {})",
                    path.display(),
                    r.min_trace,
                    r.min_eigenvalue,
                    cfg.realizability_limit
                );
            }
        }
        Ok(c)
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
        row[0] < self.stepper.t() - 1e-12 * self.cfg.t_end.max(1.0)
    }

    fn steps(&self) -> u64 {
        self.clock.steps
    }

    fn time(&self) -> f64 {
        self.stepper.t()
    }

    fn finished(&self) -> bool {
        self.stepper.t() >= self.cfg.t_end - self.eps()
    }

    fn progress(&self) -> (&'static str, u64, u64) {
        (
            "{bar:30} t {msg} [{elapsed} < {eta}]",
            1000,
            (1000.0 * self.stepper.t() / self.cfg.t_end) as u64,
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
        if self.stepper.t() >= self.clock.next_ckpt - self.eps() {
            self.clock.next_ckpt += self.cfg.checkpoint_interval;
            true
        } else {
            false
        }
    }

    fn step(&mut self, io: &mut run::RunIo) -> Result<(), run::StepFailure> {
        let cfg = &self.cfg;
        let eps = 1e-9 * cfg.t_end;
        let t = self.stepper.t();
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
            let state = self.stepper.synced().map_err(|e| self.device_failure(e))?;
            let ev = match rhs.eval(&state.q_hat, &state.u_hat) {
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
                Err(EngineError::Model(e @ MeanFieldError::NonFinite(_)))
                    if retries < cfg.step_retries =>
                {
                    retries += 1;
                    io.log(&format!(
                        "step {} at t = {t} with dt = {this_dt:e} failed ({e}); retry {retries} of {} with dt = {:e}",
                        self.clock.steps + 1,
                        cfg.step_retries,
                        0.5 * this_dt
                    ))?;
                    this_dt *= 0.5;
                }
                Err(EngineError::Model(e)) => return Err(self.failure(&e, this_dt)),
                Err(EngineError::Device(e)) => {
                    return Err(self.failed(crate::run::failure::FailureKind::Device, &e, this_dt));
                }
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
            return Err(run::StepFailure::Stop(crate::run::failure::RunFailure {
                kind: crate::run::failure::FailureKind::Realizability,
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
                self.stepper.t(),
                cfg.t_end,
                this_dt,
                report.u_l2
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
            let t = self.stepper.t();
            let diag_due = t >= self.clock.next_diag - eps;
            let snap_due = t >= self.clock.next_snap - eps;
            let rhs = MeanFieldRhs {
                grid: &self.grid,
                closure: &self.closure,
                params: &self.params,
                with_entropy: true,
            };
            let state = self.stepper.synced().map_err(|e| self.device_failure(e))?;
            let (ev, report) = match state.diagnostics(&rhs) {
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
        write_checkpoint(path, &*self.stepper.synced()?, &self.clock, self.cfg.grid)
    }

    fn write_last_good(&self, path: &Path) -> anyhow::Result<()> {
        // A failed step commits nothing: the stepper holds the state before it.
        write_checkpoint(path, &*self.stepper.synced()?, &self.clock, self.cfg.grid)
    }
}
