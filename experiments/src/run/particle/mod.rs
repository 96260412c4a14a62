//! The particle model's adapter of the run loop ([`crate::run`]): `motile particle run` and
//! resume. [`ParticleModel`] steps the model's [`Stepper`] and writes its outputs on a schedule
//! of whole steps: time-series rows (the step's report and the flow's norms), snapshots (HDF5 +
//! VTK). Its config is in `config.rs`, its initial states and checkpoint codec in `state.rs`:
//! checkpoints hold the exact rod state (centres, quaternions, image counters), the step and
//! the solvers' warm starts, so resuming continues the trajectory bit for bit.

pub(crate) mod config;
// Without the `gpu` feature, `device_off.rs`: no device stepper, and a run that asks for one
// is refused with how to build it.
#[cfg_attr(not(feature = "gpu"), path = "device_off.rs")]
mod device;
mod outputs;
mod ranked;
mod state;
mod wall;

pub use config::*;
pub use outputs::{COLUMNS, mode_columns};
use outputs::{
    FlowDiagnostics, diagnostics_of, flow_diagnostics, point_forces_of, series_row, set_norms,
    write_snapshot,
};
pub use ranked::follow;
pub use state::*;

use crate::io::rundir::TimeSeries;
use crate::io::snapshot::{Kinematics, PointForces};
use crate::run;
use crate::run::particle::ranked::Ranked;
use crate::run::particle::wall::WallShares;
use anyhow::bail;
use motile_particle::model::rods::RodSet;
use motile_particle::step::contact::WarmStart;
use motile_particle::step::report::StepReport;
use motile_particle::step::stepper::Stepper;
use std::path::Path;
use std::time::Instant;

/// What a run did.
#[derive(Clone, Debug)]
pub struct RunSummary {
    /// Steps taken in this invocation.
    pub steps: u64,
    /// Final step number.
    pub final_step: u64,
    /// Wall seconds.
    pub seconds: f64,
    /// Final rods.
    pub rods: RodSet,
}

/// Start a new particle run in `out`.
pub fn run_particle(
    cfg: &ParticleRunConfig,
    out: &Path,
    progress: bool,
) -> anyhow::Result<RunSummary> {
    let (model, s) = run::start::<ParticleModel>(&cfg.resolved(), out, progress)?;
    Ok(model.summary(&s))
}

/// Continue a run from its newest checkpoint.
pub fn resume_particle(out: &Path, progress: bool) -> anyhow::Result<RunSummary> {
    let (model, s) = run::resume::<ParticleModel>(out, progress)?;
    Ok(model.summary(&s))
}

/// The particle model as the run loop drives it ([`run::RunModel`]): rods, the stepper with
/// its warm starts, and the output schedule in whole steps.
pub struct ParticleModel {
    cfg: ParticleRunConfig,
    rods: RodSet,
    stepper: Stepper,
    step: u64,
    total: u64,
    /// Steps between time-series rows, snapshots and checkpoints.
    every: (u64, u64, u64),
    pvd: Vec<(f64, String)>,
    warned_accuracy: bool,
    /// The step shared among ranks (`mpirun`); `rods` and `stepper` are then rank 0's copies
    /// as of the last gather, and the stepper only lends its mobility.
    ranks: Option<Ranked>,
    /// The state before a failed step (the last good state to save), or why it is lost (a
    /// device that failed and could not give it back).
    before: Option<Result<ParticleCheckpoint, String>>,
    /// The step resident on the GPU (`device = "gpu"`, [`ParticleRunConfig::resident`]): the
    /// rods live there and `rods` is their copy as of the last download (after every step at
    /// the levels with flow, whose sum needs them).
    device: Option<device::DeviceStepper>,
    /// Whether the device step's flow is summed on the device too (the rods then stay there
    /// between outputs).
    resident_flow: bool,
    window: (Instant, u64),
    notes: Vec<String>,
    /// `modes.csv` (with `lowest_modes`): loaded at the first step of an invocation, rows
    /// after the state it starts from dropped (they are written again).
    modes: Option<TimeSeries>,
    /// Where this invocation's wall time went (logged at its end).
    spent: WallShares,
    /// The resident step's last diagnostic, its transform still running ([`Self::settle_diagnostics`]).
    pending: Option<PendingDiagnostics>,
}

impl std::fmt::Debug for ParticleModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParticleModel")
            .field("rods", &self.rods.len())
            .field("step", &self.step)
            .field("total", &self.total)
            .finish_non_exhaustive()
    }
}

impl ParticleModel {
    fn with_state(
        cfg: &ParticleRunConfig,
        rods: RodSet,
        (warm, hydro_warm, sum_state): (WarmStart, Vec<f64>, Vec<u32>),
        step: u64,
    ) -> anyhow::Result<Self> {
        let mut stepper = Stepper::new(mobility(cfg)?, cfg.contact.clone());
        stepper.set_warm_start(warm);
        stepper.mobility_mut().set_warm_state(hydro_warm);
        stepper.mobility_mut().set_sum_state(&sum_state);
        let ranks = match run::ranks::world() {
            Some(comm) => Some(Ranked::start(comm, cfg, &rods, &stepper)?),
            None => None,
        };
        let every = (
            cfg.every(cfg.diagnostic_interval),
            cfg.every(cfg.snapshot_interval),
            cfg.every(cfg.checkpoint_interval),
        );
        // The VTK index of the snapshots written before `step`.
        let pvd = (0..=step / every.1)
            .map(|k| {
                (
                    (k * every.1) as f64 * cfg.dt,
                    format!("vtk/rods_{k:06}.vtp"),
                )
            })
            .collect();
        let resident = cfg.resident();
        let resident_flow = resident
            && cfg.hydrodynamics.has_flow()
            && (stepper.mobility_mut().resident()).is_some_and(|r| r.flows_on_device());
        let device = if resident {
            Some(device::open(
                &rods,
                &cfg.contact,
                &stepper.warm_start().to_vec(),
                cfg.gpu_memory(),
            )?)
        } else {
            None
        };
        Ok(Self {
            cfg: cfg.clone(),
            rods,
            stepper,
            step,
            total: cfg.total_steps(),
            every,
            pvd,
            warned_accuracy: false,
            ranks,
            before: None,
            device,
            resident_flow,
            window: (Instant::now(), 0),
            notes: if resident && !cfg.hydrodynamics.has_flow() {
                vec![
                    "the whole step runs on the GPU (device = \"gpu\", hydrodynamics = \"none\"); the rods are downloaded for outputs and checkpoints".into(),
                ]
            } else if resident_flow {
                vec![format!(
                    "the whole step runs on the GPU (device = \"gpu\", hydrodynamics = \"{}\"), the flow's sum included; the rods are downloaded for outputs and checkpoints",
                    cfg.hydrodynamics.name()
                )]
            } else if resident {
                vec![format!(
                    "the step runs on the GPU (device = \"gpu\", hydrodynamics = \"{}\"): neighbours, contacts, the move and the overlap projection; the flow is summed on the host with its Fourier part on the GPU, the rods downloaded for it every step",
                    cfg.hydrodynamics.name()
                )]
            } else if cfg.device == run::Device::Gpu {
                vec![
                    "the Fourier part of the hydrodynamic sums runs on the GPU (device = \"gpu\"); real space, contacts and the rest of the step on the CPU".into(),
                ]
            } else {
                Vec::new()
            },
            modes: None,
            spent: WallShares::default(),
            pending: None,
        })
    }

    fn summary(mut self, s: &run::LoopSummary) -> RunSummary {
        if let Err(e) = self.sync() {
            // The loop has ended and written its outputs; the rods returned are the last ones
            // downloaded (say so rather than fail).
            eprintln!("warning: the final rods could not be downloaded from the GPU: {e:#}");
        }
        RunSummary {
            steps: s.steps,
            final_step: self.step,
            seconds: s.seconds,
            rods: self.rods,
        }
    }

    /// The state now (on several ranks: gathered to rank 0, collective).
    fn checkpoint_now(&self) -> ParticleCheckpoint {
        let t = self.step as f64 * self.cfg.dt;
        match &self.ranks {
            None => ParticleCheckpoint::of(&self.rods, &self.stepper, self.step, t),
            Some(r) => {
                let (rods, _, warm, rod_state) = r.gather();
                ParticleCheckpoint {
                    rods,
                    contact_warm_start: warm,
                    gmres_warm_start: self.stepper.mobility().warm_state_of(&rod_state),
                    sum_state: r.dist.stepper().mobility().sum_state(),
                    step: self.step,
                    time: t,
                }
            }
        }
    }

    fn checkpoint_to(&self, path: &Path) -> anyhow::Result<()> {
        if let Some(d) = &self.device {
            let mut rods = self.rods.clone();
            d.download(&mut rods)?;
            let t = self.step as f64 * self.cfg.dt;
            let mut c = ParticleCheckpoint::of(&rods, &self.stepper, self.step, t);
            c.contact_warm_start = d.warm_start()?;
            c.gmres_warm_start = self.stepper.mobility().current_warm_state()?;
            c.write(path)?;
            return Ok(());
        }
        self.checkpoint_now().write(path)?;
        Ok(())
    }

    /// On several ranks: bring the whole state to rank 0's `rods` and its mobility (the
    /// slender-body solution, for the outputs' force density; collective); returns the last
    /// step's kinematics there. One process: the stepper's.
    fn sync(&mut self) -> anyhow::Result<Kinematics> {
        if let Some(d) = &self.device {
            d.download(&mut self.rods)?;
            let (velocities, angular_velocities, contact_forces) = d.kinematics()?;
            return Ok(Kinematics {
                velocities,
                angular_velocities,
                contact_forces,
            });
        }
        if let Some(r) = &self.ranks {
            let (rods, rows, _, rod_state) = r.gather();
            self.rods = rods;
            if !rod_state.is_empty() {
                let m = self.stepper.mobility_mut();
                m.set_warm_state(m.warm_state_of(&rod_state));
            }
            return Ok(Kinematics {
                velocities: rows.iter().map(|x| [x[0], x[1], x[2]]).collect(),
                angular_velocities: rows.iter().map(|x| [x[3], x[4], x[5]]).collect(),
                contact_forces: rows.iter().map(|x| [x[6], x[7], x[8]]).collect(),
            });
        }
        Ok(Kinematics {
            velocities: self.stepper.velocities().v.clone(),
            angular_velocities: self.stepper.velocities().w.clone(),
            contact_forces: self.stepper.contact_forces().to_vec(),
        })
    }
}

impl run::RunModel for ParticleModel {
    type Config = ParticleRunConfig;
    const MODEL: &'static str = "particle";

    fn columns() -> &'static [&'static str] {
        &COLUMNS
    }

    fn validate(cfg: &ParticleRunConfig) -> Result<(), String> {
        cfg.validate()
    }

    fn seed(cfg: &ParticleRunConfig) -> u64 {
        cfg.seed
    }

    fn new(cfg: &ParticleRunConfig) -> anyhow::Result<Self> {
        check_memory(cfg)?;
        let rods = initial_rods(cfg)?;
        let mut m = Self::with_state(cfg, rods, (Vec::new(), Vec::new(), Vec::new()), 0)?;
        m.notes.push(format!(
            "particle run: {} rods, L/l = {}, dt = {}, t_end = {}",
            m.rods.len(),
            m.rods.box_length,
            cfg.dt,
            cfg.t_end
        ));
        Ok(m)
    }

    type Checkpoint = ParticleCheckpoint;

    fn read_checkpoint(cfg: &ParticleRunConfig, path: &Path) -> anyhow::Result<Self::Checkpoint> {
        let c = ParticleCheckpoint::read(path, cfg.diameter)?;
        c.check_for(cfg, path)?;
        Ok(c)
    }

    fn from_checkpoint(
        cfg: &ParticleRunConfig,
        c: ParticleCheckpoint,
        path: &Path,
    ) -> anyhow::Result<Self> {
        let (saved_step, time) = (c.step, c.time);
        // Steps count in units of the config's dt; a dt edited before resuming (the usual
        // answer to a failed step) rebases the counter so the run continues from the
        // checkpoint's time.
        let step = (time / cfg.dt).round();
        // Whole steps stay exact in f64 below 2^52; more is a damaged time, not a long run.
        let exact = step < 2f64.powi(52);
        if !exact {
            bail!(
                "{}: damaged or not written by motile: time {time} is {step:e} steps of dt = {}",
                path.display(),
                cfg.dt
            );
        }
        if (step * cfg.dt - time).abs() > 1e-9 * time.max(1.0) {
            bail!(
                "{}: the checkpoint's time t = {time} is not a whole number of steps of dt = {} (config.toml); choose a dt that divides it (for example {})",
                path.display(),
                cfg.dt,
                time / (time / cfg.dt).ceil()
            );
        }
        let step = step as u64;
        let warm = (c.contact_warm_start, c.gmres_warm_start, c.sum_state);
        let mut m = Self::with_state(cfg, c.rods, warm, step)?;
        if step != saved_step {
            m.notes.push(format!(
                "dt changed to {}: step counter rebased from {saved_step} to {step} (t = {time})",
                cfg.dt
            ));
        }
        Ok(m)
    }

    fn notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notes)
    }

    fn keeps_row(&self, row: &[f64]) -> bool {
        row[0] <= self.time() + 0.5 * self.cfg.dt
    }

    fn steps(&self) -> u64 {
        self.step
    }

    fn time(&self) -> f64 {
        self.step as f64 * self.cfg.dt
    }

    fn finished(&self) -> bool {
        self.step >= self.total
    }

    fn progress(&self) -> (&'static str, u64, u64) {
        (
            "{bar:30} {pos}/{len} steps {msg} [{elapsed} < {eta}]",
            self.total,
            self.step,
        )
    }

    fn checkpoint_policy(&self) -> (usize, f64) {
        (self.cfg.checkpoints_kept, self.cfg.checkpoint_wall_seconds)
    }

    fn begin(&mut self, _io: &mut run::RunIo) -> anyhow::Result<bool> {
        self.pvd.clear();
        self.sync()?;
        write_snapshot(&self.cfg, _io.run, &self.rods, 0, None, None, &mut self.pvd)?;
        Ok(true)
    }

    fn checkpoint_due_before_step(&mut self) -> bool {
        false
    }

    fn step(&mut self, io: &mut run::RunIo) -> Result<(), run::StepFailure> {
        let started = Instant::now();
        let stepped = self.step_and_outputs(io);
        self.spent.total += started.elapsed().as_secs_f64();
        stepped
    }

    fn checkpoint_due_after_step(&self) -> bool {
        self.step.is_multiple_of(self.every.2) || self.step == self.total
    }

    fn finish(
        &mut self,
        _io: &mut run::RunIo,
        _took_steps: bool,
    ) -> Result<bool, run::StepFailure> {
        Ok(false)
    }

    fn wall_note(&self) -> Option<String> {
        Some(self.spent.describe())
    }

    fn settle(&mut self, io: &mut run::RunIo) -> anyhow::Result<()> {
        self.settle_diagnostics(io)
    }

    fn write_checkpoint(&self, path: &Path) -> anyhow::Result<()> {
        self.checkpoint_to(path)
    }

    fn write_last_good(&self, path: &Path) -> anyhow::Result<()> {
        match &self.before {
            None => bail!("no failed step: nothing to save as the last good state"),
            Some(Err(lost)) => bail!("{lost}"),
            Some(Ok(before)) => before.write(path)?,
        }
        Ok(())
    }
}

/// A time-series row whose flow diagnostics are still being computed on a host thread (the
/// resident step: the device steps on meanwhile).
struct PendingDiagnostics {
    /// The row, its norms zero until the job ends.
    row: Vec<f64>,
    /// The flow's diagnostics; `None` for models without flow.
    job: Option<std::thread::JoinHandle<anyhow::Result<FlowDiagnostics>>>,
}

impl ParticleModel {
    /// Write the pending diagnostic's rows (time series, lowest modes), waiting for its
    /// transform: before the next diagnostic, a checkpoint, the end or a failure, so the files
    /// hold every row up to the state a checkpoint keeps.
    fn settle_diagnostics(&mut self, io: &mut run::RunIo) -> anyhow::Result<()> {
        let Some(PendingDiagnostics { mut row, job }) = self.pending.take() else {
            return Ok(());
        };
        let started = Instant::now();
        let modes = match job {
            Some(job) => {
                let d = job
                    .join()
                    .map_err(|_| anyhow::anyhow!("the flow diagnostics' thread panicked"))??;
                set_norms(&mut row, d.norms);
                d.modes
            }
            None => None,
        };
        io.push_row(row)?;
        if let Some(m) = modes {
            self.push_modes(io, m)?;
        }
        self.spent.diagnostics += started.elapsed().as_secs_f64();
        Ok(())
    }

    /// One step and the outputs due after it (the host's step, the ranks' or the device's).
    fn step_and_outputs(&mut self, io: &mut run::RunIo) -> Result<(), run::StepFailure> {
        let step = self.step + 1;
        let cfg = &self.cfg;
        // One process keeps the state before the step; ranks keep theirs and give it back on
        // a failure, and gather it before the steps whose outputs need the flow's force
        // density (the time series' velocity norms, snapshots' point forces), which is that of
        // the state before the step.
        let (diag, snap, _) = self.every;
        if self.device.is_some() {
            return self.device_step(io, step);
        }
        let before = match &self.ranks {
            None => Some(ParticleCheckpoint::of(
                &self.rods,
                &self.stepper,
                self.step,
                run::RunModel::time(self),
            )),
            Some(_)
                if cfg.hydrodynamics.has_flow()
                    && (step.is_multiple_of(diag) || step.is_multiple_of(snap)) =>
            {
                let b = self.checkpoint_now();
                self.stepper
                    .mobility_mut()
                    .density_for(&b.rods.orientations());
                Some(b)
            }
            Some(_) => None,
        };
        let stepped = match &mut self.ranks {
            None => self.stepper.step(&mut self.rods, cfg.dt),
            Some(r) => r.step(cfg.dt),
        };
        let mut synced = None;
        let report = match stepped {
            // On ranks, a mobility with per-rod state (the slender-body solution: the force
            // density of the state before the step) brings it to rank 0 for the outputs.
            Ok(r)
                if self.ranks.is_some()
                    && self.stepper.mobility().rod_state_width() > 0
                    && (step.is_multiple_of(diag) || step.is_multiple_of(snap)) =>
            {
                synced = Some(self.sync()?);
                r
            }
            Ok(r) => r,
            Err(e) => {
                self.before = Some(Ok(before.unwrap_or_else(|| self.checkpoint_now())));
                let cfg = &self.cfg;
                return Err(run::StepFailure::Step {
                    kind: (&e).into(),
                    step,
                    t: (step - 1) as f64 * cfg.dt,
                    what: format!("step {step} (t = {:.4}) failed: {e}", step as f64 * cfg.dt),
                });
            }
        };
        self.step = step;
        self.window.1 += 1;
        self.spent.add_step(&report);
        let t = step as f64 * self.cfg.dt;
        self.warn_accuracy(io, step, &report)?;
        if step.is_multiple_of(diag) {
            let rate = self.window.1 as f64 / self.window.0.elapsed().as_secs_f64().max(1e-9);
            self.window = (Instant::now(), 0);
            let c = &report.contact;
            let started = Instant::now();
            let diagnosed = match &before {
                Some(b) => Some(flow_diagnostics(
                    &self.stepper,
                    &b.rods,
                    t,
                    self.cfg.lowest_modes,
                )?),
                None => None,
            };
            let norms = diagnosed.as_ref().map_or((0.0, 0.0), |d| d.norms);
            io.push_row(series_row(t, rate, &report, norms))?;
            io.bar.set_message(format!(
                "t = {t:.3}, {rate:.1} steps/s, {} contacts, max overlap {:.1e}",
                c.active, report.max_overlap
            ));
            if let Some(row) = diagnosed.and_then(|d| d.modes) {
                self.push_modes(io, row)?;
            }
            self.spent.diagnostics += started.elapsed().as_secs_f64();
        }
        if step.is_multiple_of(snap) {
            let started = Instant::now();
            let kin = match synced {
                Some(k) => k,
                None => self.sync()?,
            };
            let forces = before.as_ref().and_then(|b| {
                self.stepper.mobility().force_density().map(|fd| {
                    let (points, forces) = fd.point_forces(&b.rods, &b.rods.orientations());
                    PointForces { points, forces }
                })
            });
            write_snapshot(
                &self.cfg,
                io.run,
                &self.rods,
                step,
                Some(kin),
                forces,
                &mut self.pvd,
            )?;
            self.spent.snapshots += started.elapsed().as_secs_f64();
        }
        Ok(())
    }
}

impl ParticleModel {
    /// Never silent: where the finest level of the fast sum could not meet the tolerance,
    /// say so once per run (log and terminal).
    fn warn_accuracy(
        &mut self,
        io: &mut run::RunIo,
        step: u64,
        report: &StepReport,
    ) -> anyhow::Result<()> {
        if self.warned_accuracy || report.hydro.sums == 0 || report.hydro.sum_tolerance_met {
            return Ok(());
        }
        self.warned_accuracy = true;
        let cfg = &self.cfg;
        let msg = format!(
            "warning: at step {step} (t = {:.4}) the fast sum's estimated error is {:.1} times hydro.sum_tolerance = {:e} even at its finest setting; results carry that error (see docs/accuracy.md; `motile check-accuracy {}` measures it). Said once per run",
            step as f64 * cfg.dt,
            report.hydro.sum_error_ratio,
            cfg.hydro.sum_tolerance,
            io.run.path().display()
        );
        io.log(&msg)?;
        io.bar.println(&msg);
        Ok(())
    }

    /// A step resident on the GPU ([`ParticleRunConfig::resident`]): the rods stay on the
    /// device; they are downloaded for snapshots and checkpoints, and the state before a
    /// failed step from the device's copy of it. At the levels with flow the flow is summed
    /// on the device where the mobility can (`dipole`, `sbt-explicit`, `sbt`: [`Self::resident_flow`]; the rods are
    /// then downloaded only before the steps whose outputs need them), else on the host from
    /// the rods before the step (their copy in `rods`, downloaded after every step); the time
    /// series' flow norms, the lowest modes and the snapshots' point forces are the CPU's, of
    /// the state before the step. Without flow the norms are zero.
    fn device_step(&mut self, io: &mut run::RunIo, step: u64) -> Result<(), run::StepFailure> {
        let dt = self.cfg.dt;
        let (diag, snap, _) = self.every;
        let flow = self.cfg.hydrodynamics.has_flow();
        let resident_flow = self.resident_flow;
        let d = self
            .device
            .as_mut()
            .expect("a device step without a device");
        if resident_flow && (step.is_multiple_of(diag) || step.is_multiple_of(snap)) {
            // The outputs below need the state before the step, which stays on the device.
            d.download(&mut self.rods)?;
            let p = self.rods.orientations();
            self.stepper.mobility_mut().density_for(&p);
        }
        let stepped = if flow {
            d.step_with_flow(dt, self.stepper.mobility_mut(), &self.rods)
        } else {
            d.step(dt)
        };
        let report = match stepped {
            Ok(r) => r,
            Err(e) => {
                self.before = state_before_failure(
                    d,
                    &e,
                    FailedStep {
                        rods: &self.rods,
                        stepper: &self.stepper,
                        step: self.step,
                        dt,
                        resident_flow,
                    },
                )?;
                return Err(run::StepFailure::Step {
                    kind: (&e).into(),
                    step,
                    t: (step - 1) as f64 * dt,
                    what: format!("step {step} (t = {:.4}) failed: {e}", step as f64 * dt),
                });
            }
        };
        self.step = step;
        self.window.1 += 1;
        let t = step as f64 * dt;
        if resident_flow && (step.is_multiple_of(diag) || step.is_multiple_of(snap)) {
            // The step's solution (sbt), kept on the device: the outputs' force density.
            if let Some(resident) = self.stepper.mobility_mut().resident() {
                resident.sync_resident()?;
            }
        }
        self.warn_accuracy(io, step, &report)?;
        // What the outputs need of the state before the step (its point forces), then the
        // state after it.
        let started = Instant::now();
        let (at_diag, at_snap) = (step.is_multiple_of(diag), step.is_multiple_of(snap));
        let point_forces = (flow && (at_diag || at_snap))
            .then(|| point_forces_of(&self.stepper, &self.rods))
            .flatten();
        let (for_diagnostics, forces) = match (at_diag, at_snap) {
            (true, true) => (point_forces.clone(), point_forces),
            (true, false) => (point_forces, None),
            (false, _) => (None, point_forces),
        };
        let box_length = self.rods.box_length;
        self.spent.diagnostics += started.elapsed().as_secs_f64();
        if flow && !resident_flow {
            let d = self
                .device
                .as_ref()
                .expect("a device step without a device");
            d.download(&mut self.rods)?;
        }
        if at_diag {
            // The previous diagnostic's rows first; this one's transform runs on a host thread
            // while the device takes the next steps.
            self.settle_diagnostics(io)?;
            let started = Instant::now();
            let rate = self.window.1 as f64 / self.window.0.elapsed().as_secs_f64().max(1e-9);
            self.window = (Instant::now(), 0);
            let c = &report.contact;
            io.bar.set_message(format!(
                "t = {t:.3}, {rate:.1} steps/s (GPU), {} contacts, max overlap {:.1e}",
                c.active, report.max_overlap
            ));
            let modes = self.cfg.lowest_modes;
            self.pending = Some(PendingDiagnostics {
                row: series_row(t, rate, &report, (0.0, 0.0)),
                job: for_diagnostics.map(|pf| {
                    std::thread::spawn(move || diagnostics_of(&pf, box_length, t, modes))
                }),
            });
            self.spent.diagnostics += started.elapsed().as_secs_f64();
        }
        if step.is_multiple_of(snap) {
            let started = Instant::now();
            let kin = self.sync()?;
            write_snapshot(
                &self.cfg,
                io.run,
                &self.rods,
                step,
                Some(kin),
                forces,
                &mut self.pvd,
            )?;
            self.spent.snapshots += started.elapsed().as_secs_f64();
        }
        Ok(())
    }

    /// Append a row to `modes.csv` (loading the file at the first row of an invocation and
    /// dropping rows after the state the invocation started from).
    fn push_modes(&mut self, io: &run::RunIo, row: Vec<f64>) -> anyhow::Result<()> {
        let path = io.run.path().join("modes.csv");
        let columns = mode_columns();
        let t0 = row[0] - self.cfg.diagnostic_interval * 0.5;
        let modes = self.modes.get_or_insert_with(|| {
            let mut ts = TimeSeries::read(&path)
                .ok()
                .filter(|ts| ts.columns == columns)
                .unwrap_or_else(|| {
                    TimeSeries::new(&columns.iter().map(String::as_str).collect::<Vec<_>>())
                });
            ts.rows.retain(|r| r[0] < t0);
            ts
        });
        modes.push(row);
        modes.write(&path)?;
        Ok(())
    }
}
