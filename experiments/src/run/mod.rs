//! The run loop, written once for every model: a [`RunModel`] says how to take one step and
//! what its state and outputs are; [`start`] and [`resume`] own everything else — the run
//! directory, the config written next to the results, the time series file, checkpoints on a
//! schedule, on wall-clock time and on signals (SIGINT/SIGTERM: checkpoint, then stop), the
//! last good state when a step fails, the progress bar, the log, and resuming from the newest
//! valid checkpoint.
//!
//! One iteration: `checkpoint_due_before_step` (a checkpoint of the state the step starts
//! from), `step` (the model writes the outputs due before and after it), then a checkpoint if
//! `checkpoint_due_after_step`, a signal or the wall clock asks for one. A failed step leaves
//! the state before it with the model, which writes it as `checkpoints/last_good.h5`; the error
//! is a [`RunFailure`] naming it. At the end `finish` writes the final outputs.
//!
//! Adapters: the particle model ([`crate::run::particle`]), the mean-field model
//! ([`crate::run::meanfield`]); a test drives a third, free swimmers with an exact answer,
//! through the same loop.

pub mod failure;
pub mod meanfield;
pub mod memory;
pub mod particle;
pub mod ranks;

/// Where a run's heavy work runs (`device`): the mean-field step, or the Fourier part of the
/// particle model's hydrodynamic sums.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The CPU, on the worker threads (`--threads`).
    #[default]
    Cpu,
    /// An NVIDIA GPU through CUDA (a build with `--features gpu`; CUDA is loaded when the run
    /// starts, and a run that asks for a GPU where there is none stops with that error, never
    /// falling back to the CPU).
    Gpu,
}

/// With `device = "gpu"`: the device `MOTILE_GPU_BACKEND` names (CUDA by default; `emulation`
/// is the host emulation of the GPU kernels, the same kernels compiled by the C++ compiler and
/// run on the CPU: slow, for testing the GPU path end to end on machines without a GPU).
#[cfg(feature = "gpu")]
pub(crate) fn gpu_backend() -> anyhow::Result<motile_gpu::Backend> {
    Ok(motile_gpu::Backend::from_env()?)
}

impl std::fmt::Display for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Device::Cpu => "cpu",
            Device::Gpu => "gpu",
        })
    }
}

use crate::io::checkpoint::{self, LAST_GOOD};
use crate::io::rundir::{RunDir, TimeSeries, read_run_config};
use crate::run::failure::{FailureKind, RunFailure};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How a step (or the outputs around it) failed.
#[derive(Debug)]
pub enum StepFailure {
    /// The step failed; the model holds the state before it ([`RunModel::write_last_good`]).
    Step {
        /// What failed.
        kind: FailureKind,
        /// The failed step (1-based).
        step: u64,
        /// The time of the state before it.
        t: f64,
        /// What failed, in words ("step 7 (t = 0.07) failed: ..."); the loop adds where the
        /// state before it is saved.
        what: String,
    },
    /// The run must stop and no state is worth saving beyond the last checkpoint (the message
    /// names it).
    Stop(RunFailure),
    /// Output could not be written.
    Io(anyhow::Error),
}

impl<E: Into<anyhow::Error>> From<E> for StepFailure {
    fn from(e: E) -> Self {
        StepFailure::Io(e.into())
    }
}

/// What the loop gives a model's step: the run directory, the time series and the progress
/// bar.
#[derive(Debug)]
pub struct RunIo<'a> {
    /// The run directory.
    pub run: &'a RunDir,
    /// The time series (rows of earlier invocations included).
    pub timeseries: TimeSeries,
    /// Progress (hidden when not on a terminal).
    pub bar: ProgressBar,
}

impl RunIo<'_> {
    /// Append a row to the time series and write the file.
    pub fn push_row(&mut self, row: Vec<f64>) -> anyhow::Result<()> {
        self.timeseries.push(row);
        self.timeseries
            .write(&self.run.path().join("timeseries.csv"))?;
        Ok(())
    }

    /// Log a line to run.log.
    pub fn log(&self, line: &str) -> anyhow::Result<()> {
        Ok(self.run.log(line)?)
    }
}

/// A model the run loop can drive: its config, state, step, outputs and checkpoint codec.
pub trait RunModel: Sized {
    /// The run's config (`config.toml`).
    type Config: Serialize + DeserializeOwned + Clone;
    /// The model's name in run directories ("particle", "meanfield").
    const MODEL: &'static str;
    /// The columns of `timeseries.csv`.
    fn columns() -> &'static [&'static str];
    /// Check a config (the message names the field, the value and the allowed range).
    fn validate(cfg: &Self::Config) -> Result<(), String>;
    /// The config's seed (recorded in the run's header).
    fn seed(cfg: &Self::Config) -> u64;
    /// Build the model at its initial state (nothing written yet).
    fn new(cfg: &Self::Config) -> anyhow::Result<Self>;
    /// The state a checkpoint holds.
    type Checkpoint;
    /// Read a checkpoint file (an error here makes resume try the next older checkpoint).
    fn read_checkpoint(cfg: &Self::Config, path: &Path) -> anyhow::Result<Self::Checkpoint>;
    /// Build the model from the checkpoint read from `path` (an error here stops the resume).
    fn from_checkpoint(
        cfg: &Self::Config,
        state: Self::Checkpoint,
        path: &Path,
    ) -> anyhow::Result<Self>;
    /// Lines for the log once the run directory exists (what the run is, how it started).
    fn notes(&mut self) -> Vec<String>;
    /// Where this invocation's wall time went, for the log when it ends or is stopped (none
    /// by default).
    fn wall_note(&self) -> Option<String> {
        None
    }
    /// Write the outputs of steps taken whose computation is still running (a resident
    /// step's diagnostics): called before every checkpoint, at the end and on a failure or a
    /// stop, so the run directory holds every row up to the state a checkpoint keeps.
    fn settle(&mut self, _io: &mut RunIo) -> anyhow::Result<()> {
        Ok(())
    }
    /// Whether a time-series row of an earlier invocation is kept on resume (rows after the
    /// checkpoint's time are written again).
    fn keeps_row(&self, row: &[f64]) -> bool;
    /// Steps taken since the run began.
    fn steps(&self) -> u64;
    /// The model's time.
    fn time(&self) -> f64;
    /// Whether the run has reached its end.
    fn finished(&self) -> bool;
    /// Progress bar: template, length and position.
    fn progress(&self) -> (&'static str, u64, u64);
    /// Regular checkpoints kept, and the wall-clock seconds between checkpoints.
    fn checkpoint_policy(&self) -> (usize, f64);
    /// Outputs of a fresh run before its first step; true if a checkpoint is due then.
    fn begin(&mut self, io: &mut RunIo) -> anyhow::Result<bool>;
    /// Whether a checkpoint of the state the next step starts from is due (the model advances
    /// its schedule).
    fn checkpoint_due_before_step(&mut self) -> bool;
    /// One step, with the outputs due before and after it.
    fn step(&mut self, io: &mut RunIo) -> Result<(), StepFailure>;
    /// Whether a checkpoint is due after the step just taken.
    fn checkpoint_due_after_step(&self) -> bool;
    /// Final outputs once the run reached its end (`took_steps`: whether this invocation
    /// stepped); true if a final checkpoint is due.
    fn finish(&mut self, io: &mut RunIo, took_steps: bool) -> Result<bool, StepFailure>;
    /// Write the model's state as a checkpoint.
    fn write_checkpoint(&self, path: &Path) -> anyhow::Result<()>;
    /// Write the state before a failed step.
    fn write_last_good(&self, path: &Path) -> anyhow::Result<()>;
}

/// What one invocation of the loop did.
#[derive(Clone, Debug)]
pub struct LoopSummary {
    /// Steps taken by this invocation.
    pub steps: u64,
    /// Wall seconds of the loop.
    pub seconds: f64,
    /// The time series, rows of earlier invocations included.
    pub timeseries: TimeSeries,
}

/// Start a new run of `cfg` in `out` (refused if `out` holds a run): the initial state is
/// built, and any file it comes from read, before anything is written.
pub fn start<M: RunModel>(
    cfg: &M::Config,
    out: &Path,
    progress: bool,
) -> anyhow::Result<(M, LoopSummary)> {
    M::validate(cfg).map_err(|e| anyhow::anyhow!("config: {e}"))?;
    let mut model = M::new(cfg)?;
    let run = RunDir::create(out, M::MODEL, M::seed(cfg), cfg)?;
    for line in model.notes() {
        run.log(&line)?;
    }
    let ts = TimeSeries::new(M::columns());
    drive(model, &run, ts, progress, None)
}

/// Continue the run in `out` from its newest valid checkpoint (or its last good state).
pub fn resume<M: RunModel>(out: &Path, progress: bool) -> anyhow::Result<(M, LoopSummary)> {
    let run = RunDir::open(out)?;
    let cfg: M::Config = read_run_config(out, M::validate)?;
    let (ckpt, state) = checkpoint::load_for_resume(&run, |p| M::read_checkpoint(&cfg, p))?;
    let mut model = M::from_checkpoint(&cfg, state, &ckpt)?;
    for line in model.notes() {
        run.log(&line)?;
    }
    let path = out.join("timeseries.csv");
    // A run killed before its first row has no time series; a damaged one is refused, not
    // silently restarted.
    let mut ts = if path.exists() {
        TimeSeries::read(&path).with_context(|| {
            format!(
                "resuming {}: move the damaged time series aside to restart it at the checkpoint",
                out.display()
            )
        })?
    } else {
        TimeSeries::new(M::columns())
    };
    if ts.columns != M::columns() {
        bail!(
            "{}: its columns ({}) are not the ones this version writes ({}); move it aside to resume (the time series then restarts at the checkpoint)",
            path.display(),
            ts.columns.join(", "),
            M::columns().join(", ")
        );
    }
    ts.rows.retain(|r| model.keeps_row(r));
    run.log(&format!(
        "resuming from {} at step {} (t = {})",
        ckpt.display(),
        model.steps(),
        model.time()
    ))?;
    drive(model, &run, ts, progress, Some(&ckpt))
}

/// What a progress observer is told after each step: `(position, length, model time)` in the
/// units of [`RunModel::progress`].
pub type ProgressHook = Box<dyn Fn(u64, u64, f64) + Send + Sync>;

static PROGRESS_HOOK: std::sync::Mutex<Option<ProgressHook>> = std::sync::Mutex::new(None);

/// Observe every run loop's progress in this process (replacing an earlier observer; `None`
/// removes it): for callers without a terminal, such as a notebook.
pub fn set_progress_hook(hook: Option<ProgressHook>) {
    *PROGRESS_HOOK
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = hook;
}

fn report_progress(position: u64, length: u64, time: f64) {
    if let Some(h) = PROGRESS_HOOK
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .as_ref()
    {
        h(position, length, time);
    }
}

/// Write a numbered checkpoint (`checkpoints/ckpt_STEP.h5`), keep the newest few, and drop
/// the state saved after an earlier failure (the new checkpoint supersedes it).
fn write_regular<M: RunModel>(model: &M, run: &RunDir) -> anyhow::Result<PathBuf> {
    let dir = run.path().join("checkpoints");
    let path = dir.join(format!("ckpt_{:09}.h5", model.steps()));
    model.write_checkpoint(&path)?;
    checkpoint::prune(&dir, model.checkpoint_policy().0);
    checkpoint::remove(&dir.join(LAST_GOOD));
    Ok(path)
}

/// An output that could not be written (a full disk) stops the run: say from where it
/// resumes. Atomic writes leave every file under its final name whole.
fn write_failed(run: &RunDir, e: anyhow::Error) -> anyhow::Error {
    let next = resume_from_newest(run, "once the disk has room");
    let _ = run.log(&format!("stopped: an output could not be written: {e:#}"));
    e.context(format!(
        "the run stopped because an output could not be written; {next}"
    ))
}

/// Where a run continues from when the state before its failure could not be kept: the
/// checkpoint resume would take (an earlier failure's intact last good state, else the newest
/// intact regular checkpoint), in words, with the command (`when`: the condition to meet first).
fn resume_from_newest(run: &RunDir, when: &str) -> String {
    let dir = run.path().join("checkpoints");
    let mut candidates = checkpoint::newest_first(&dir);
    candidates.insert(0, dir.join(LAST_GOOD));
    let newest = candidates
        .into_iter()
        .find(|p| p.is_file() && checkpoint::verify(p).is_ok());
    match newest {
        Some(p) => format!(
            "its newest intact checkpoint is {}: `motile resume {}` continues from it {when}",
            p.display(),
            run.path().display()
        ),
        None => format!("it has no checkpoint yet: start it again {when}"),
    }
}

/// The error of a step that failed: an output not written ([`write_failed`]), or the step
/// itself ([`failed`]). `resumed_from` is the checkpoint this invocation resumed from when
/// the step was its first: a regular checkpoint that cannot take one step may be a damaged
/// file (the state before a failed step, last_good.h5, is expected to fail again).
fn step_failed<M: RunModel>(
    model: &M,
    run: &RunDir,
    f: StepFailure,
    resumed_from: Option<&Path>,
) -> anyhow::Error {
    if let StepFailure::Io(e) = f {
        return write_failed(run, e);
    }
    let e = failed(model, run, f);
    match resumed_from.filter(|c| c.file_name().is_some_and(|n| n != checkpoint::LAST_GOOD)) {
        Some(ckpt) => e.context(format!(
            "the first step after resuming from {} failed (the checkpoint may be damaged or written by another version of motile)",
            ckpt.display()
        )),
        None => e,
    }
}

/// The error of a failed step: the state before it saved, the failure logged.
fn failed<M: RunModel>(model: &M, run: &RunDir, f: StepFailure) -> anyhow::Error {
    match f {
        StepFailure::Io(e) => e,
        StepFailure::Stop(r) => {
            let _ = run.log(&r.message);
            r.into()
        }
        StepFailure::Step {
            kind,
            step,
            t,
            what,
        } => {
            let saved = run.path().join("checkpoints").join(LAST_GOOD);
            if let Err(w) = model.write_last_good(&saved) {
                // A device that failed may not give the state back; the checkpoints hold it.
                let next = resume_from_newest(run, "(the steps since it are run again)");
                let message =
                    format!("{what}; the state before it could not be saved ({w:#}); {next}");
                let _ = run.log(&message);
                return RunFailure {
                    kind,
                    step,
                    t,
                    message,
                }
                .into();
            }
            let _ = run.log(&what);
            RunFailure {
                kind,
                step,
                t,
                message: format!(
                    "{what}. The state before it is saved in {}; `motile resume {}` continues from it (after editing {} if a setting caused the failure)",
                    saved.display(),
                    run.path().display(),
                    run.path().join("config.toml").display()
                ),
            }
            .into()
        }
    }
}

fn drive<M: RunModel>(
    mut model: M,
    run: &RunDir,
    timeseries: TimeSeries,
    progress: bool,
    resumed_from: Option<&Path>,
) -> anyhow::Result<(M, LoopSummary)> {
    let fresh = resumed_from.is_none();
    let (template, len, pos) = model.progress();
    let bar = if progress {
        ProgressBar::new(len)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(ProgressStyle::with_template(template)?);
    bar.set_position(pos);
    let mut io = RunIo {
        run,
        timeseries,
        bar,
    };
    if fresh && model.begin(&mut io).map_err(|e| write_failed(run, e))? {
        write_regular(&model, run).map_err(|e| write_failed(run, e))?;
    }
    let start_steps = model.steps();
    let t0 = Instant::now();
    let mut last_ckpt = Instant::now();
    let wall = model.checkpoint_policy().1;
    // Wall seconds spent writing checkpoints (said in the log's last line).
    let mut checkpoint_seconds = 0.0;
    while !model.finished() {
        if model.checkpoint_due_before_step() {
            let started = Instant::now();
            model.settle(&mut io).map_err(|e| write_failed(run, e))?;
            write_regular(&model, run).map_err(|e| write_failed(run, e))?;
            checkpoint_seconds += started.elapsed().as_secs_f64();
            last_ckpt = Instant::now();
        }
        if let Err(f) = model.step(&mut io) {
            io.bar.abandon();
            // The rows of the steps before the failure are written (or said lost).
            if let Err(e) = model.settle(&mut io) {
                run.log(&format!(
                    "the outputs of the last good steps were not written: {e:#}"
                ))?;
            }
            let first = model.steps() == start_steps;
            return Err(step_failed(&model, run, f, resumed_from.filter(|_| first)));
        }
        let stop = checkpoint::stop_requested();
        if model.checkpoint_due_after_step()
            || stop.is_some()
            || last_ckpt.elapsed().as_secs_f64() >= wall
        {
            let started = Instant::now();
            model.settle(&mut io).map_err(|e| write_failed(run, e))?;
            let path = write_regular(&model, run).map_err(|e| write_failed(run, e))?;
            checkpoint_seconds += started.elapsed().as_secs_f64();
            last_ckpt = Instant::now();
            if let Some(signal) = stop {
                io.bar.abandon();
                if let Some(note) = model.wall_note() {
                    run.log(&note)?;
                }
                let at = format!("step {} (t = {:.4})", model.steps(), model.time());
                if signal == checkpoint::STOP_BY_CALLER {
                    run.log(&format!("stopped at {at} at the caller's request"))?;
                } else {
                    run.log(&format!("stopped by signal {signal} at {at}"))?;
                }
                return Err(checkpoint::Interrupted {
                    signal,
                    at,
                    checkpoint: path,
                    run_dir: run.path().to_path_buf(),
                }
                .into());
            }
        }
        io.bar.set_position(model.progress().2);
        report_progress(model.progress().2, len, model.time());
    }
    model.settle(&mut io).map_err(|e| write_failed(run, e))?;
    match model.finish(&mut io, model.steps() > start_steps) {
        Ok(true) => {
            write_regular(&model, run).map_err(|e| write_failed(run, e))?;
        }
        Ok(false) => {}
        Err(f) => {
            io.bar.abandon();
            let first = model.steps() == start_steps;
            return Err(step_failed(&model, run, f, resumed_from.filter(|_| first)));
        }
    }
    io.bar.finish();
    if model.steps() > start_steps
        && let Some(note) = model.wall_note()
    {
        run.log(&note)?;
    }
    let seconds = t0.elapsed().as_secs_f64();
    run.log(&format!(
        "finished at step {} (t = {}) in {seconds:.1} s (checkpoints {checkpoint_seconds:.1} s)",
        model.steps(),
        model.time()
    ))?;
    let summary = LoopSummary {
        steps: model.steps() - start_steps,
        seconds,
        timeseries: io.timeseries,
    };
    Ok((model, summary))
}
