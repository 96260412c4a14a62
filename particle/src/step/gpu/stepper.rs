//! The particle step resident on the device for the local-drag (`none`) level: the rods stay
//! on the device from step to step; the host downloads them, with the last step's velocities
//! and contact forces, only for outputs, checkpoints and on failure (the state before the
//! failed step is kept on the device). See [`super`].
#![allow(unsafe_code)]

use super::device::{GpuStep, int};
use super::signatures::StepStats;
use super::solver::DeviceContactError;
use super::step::{Free, StepOutput, Warm};
use super::update::DeviceRods;
use crate::hydro::gpu::{DeviceVelocities, RodsOnDevice};
use crate::hydro::mobility::{Mobility, RodVelocities};
use crate::model::geometry::Vec3;
use crate::model::rods::RodSet;
use crate::step::contact::{ContactParams, WarmStart};
use crate::step::report::{StepError, StepReport};
use motile_gpu::{Backend, Buffer, GpuError};

/// Per rod: velocities, angular velocities and contact forces.
pub type RodKinematics = (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>);

/// The CPU's reduction chunk, so the device's partial sums are the CPU's.
use motile_analysis::reduce::CHUNK;

/// The `none`-level stepper on a device.
#[derive(Debug)]
pub struct DeviceStepper {
    gpu: GpuStep,
    rods: DeviceRods,
    before: DeviceRods,
    contact: ContactParams,
    /// The last step's velocities, angular velocities and contact forces and torques.
    last: Option<(Buffer, Buffer, Option<Buffer>)>,
    /// The last step's multipliers by pair: the next contact problem's start.
    warm: Option<Warm>,
}

/// A device's failure as the step's.
impl From<GpuError> for StepError {
    fn from(e: GpuError) -> Self {
        StepError::Device(e.to_string())
    }
}

impl DeviceStepper {
    /// The rods `rods` uploaded to the device `backend` names, stepped with contact settings
    /// `contact`, the first contact problem starting from `warm` (the multipliers by pair
    /// of the step before, as [`crate::step::stepper::Stepper::warm_start`] and checkpoints
    /// hold them; empty: from zero).
    pub fn new(
        backend: Backend,
        rods: &RodSet,
        contact: ContactParams,
        warm: &WarmStart,
    ) -> Result<Self, GpuError> {
        let gpu = GpuStep::open(backend)?;
        let (a, b) = (gpu.upload_rods(rods)?, gpu.upload_rods(rods)?);
        let n = rods.len();
        if let Some(bad) = warm
            .iter()
            .find(|((i, j), l)| i >= j || *j as usize >= n || !(*l >= 0.0 && l.is_finite()))
        {
            return Err(GpuError::Input(format!(
                "warm start: pair {:?} with multiplier {} (pairs i < j below {n}, multipliers >= 0)",
                bad.0, bad.1
            )));
        }
        if warm.windows(2).any(|w| w[0].0 >= w[1].0) {
            return Err(GpuError::Input(
                "warm start: pairs not sorted and distinct".into(),
            ));
        }
        let warm = if warm.is_empty() {
            None
        } else {
            let dev = &gpu.dev;
            let ints = |f: fn(&(u32, u32)) -> u32| -> Result<Buffer<i32>, GpuError> {
                let v = warm
                    .iter()
                    .map(|(p, _)| int(f(p) as usize, "warm-start rod"))
                    .collect::<Result<Vec<i32>, _>>()?;
                dev.upload(&v)
            };
            Some(Warm {
                i: ints(|p| p.0)?,
                j: ints(|p| p.1)?,
                lam: dev.upload(&warm.iter().map(|w| w.1).collect::<Vec<f64>>())?,
                len: warm.len(),
            })
        };
        Ok(Self {
            gpu,
            rods: a,
            before: b,
            contact,
            last: None,
            warm,
        })
    }

    /// `(bytes in use, total bytes)` of the device's memory (all processes), or `None` on the
    /// host emulation.
    pub fn memory(&self) -> Result<Option<(usize, usize)>, GpuError> {
        self.gpu.dev.memory()
    }

    /// The last step's positive multipliers by pair, sorted: the warm start a checkpoint
    /// keeps (the CPU stepper's form).
    pub fn warm_start(&self) -> Result<WarmStart, GpuError> {
        let Some(w) = &self.warm else {
            return Ok(Vec::new());
        };
        let dev = &self.gpu.dev;
        let (i, j, lam) = (
            dev.download_range(&w.i, 0, w.len)?,
            dev.download_range(&w.j, 0, w.len)?,
            dev.download_range(&w.lam, 0, w.len)?,
        );
        Ok(i.iter()
            .zip(&j)
            .zip(&lam)
            .filter(|(_, l)| **l > 0.0)
            .map(|((&a, &b), &l)| ((a as u32, b as u32), l))
            .collect())
    }

    /// What the device is, in words.
    pub fn describe(&self) -> String {
        self.gpu.describe()
    }

    /// What the device has been asked to do so far: launches, transfers.
    pub fn counters(&self) -> motile_gpu::Counters {
        self.gpu.dev.counters()
    }

    /// On the host emulation, run blocks in a random order at every launch (`seed` nonzero):
    /// the atomics then take other orders, which the step's sorts must undo.
    pub fn shuffle_blocks(&self, seed: u64) -> bool {
        self.gpu.shuffle_blocks(seed)
    }

    /// One step of `dt`: [`GpuStep::step_local_drag`] with the CPU step's report (its sums
    /// and maxima in the CPU's fixed chunks) and failures (the state before the step kept).
    pub fn step(&mut self, dt: f64) -> Result<StepReport, StepError> {
        self.step_from(dt, None)
    }

    /// One step of `dt` from the free velocities `free` (per rod: velocity and angular
    /// velocity before contacts, e.g. a hydrodynamic level's [`crate::hydro::mobility::Mobility::free_velocities`]
    /// of the rods as [`Self::download`] gives them), its contacts through the local drag: the
    /// step of the levels whose contacts act through the local mobility (`dipole`,
    /// `sbt-explicit`), their flow computed on the host. `None`: swimming alone ([`Self::step`]).
    pub fn step_from(
        &mut self,
        dt: f64,
        free: Option<(&[Vec3], &[Vec3])>,
    ) -> Result<StepReport, StepError> {
        self.step_with(
            dt,
            match free {
                Some((v, w)) => Free::Host(v, w),
                None => Free::Swimming,
            },
        )
    }

    /// One step of `dt` from the free velocities `free`.
    fn step_with(&mut self, dt: f64, free: Free<'_>) -> Result<StepReport, StepError> {
        self.step_finished(dt, free, None)
    }

    /// One step of `dt` from the free velocities `free`, with a level's final velocities from
    /// the contact forces where `finish` gives them ([`GpuStep::step_output`]).
    fn step_finished(
        &mut self,
        dt: f64,
        free: Free<'_>,
        finish: Option<super::step::Finish<'_>>,
    ) -> Result<StepReport, StepError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(StepError::InvalidTimeStep(dt));
        }
        let dev = &self.gpu.dev;
        let n = self.rods.len;
        for (src, dst) in [
            (&self.rods.x, &mut self.before.x),
            (&self.rods.q, &mut self.before.q),
        ] {
            dev.copy((src, 0), (dst, 0), src.len())
                .map_err(StepError::from)?;
        }
        dev.copy((&self.rods.image, 0), (&mut self.before.image, 0), 3 * n)
            .map_err(StepError::from)?;
        let StepOutput {
            report,
            v,
            w,
            ft,
            warm,
        } = self
            .gpu
            .step_output(
                &mut self.rods,
                super::step::Stepping {
                    dt,
                    params: &self.contact,
                },
                free,
                finish,
                self.warm.as_ref(),
            )
            .map_err(|e| match e {
                DeviceContactError::Contact(c) => StepError::Contact(c),
                DeviceContactError::Gpu(g) => StepError::from(g),
                DeviceContactError::Hydrodynamics(h) => StepError::Hydrodynamics(h),
            })?;
        let nchunks = n.div_ceil(CHUNK);
        let mut partial = dev
            .zeros::<f64>(10 * nchunks.max(1))
            .map_err(StepError::from)?;
        // SAFETY: block c < ceil(n / CHUNK) (its 256 threads compute its rods' terms in turn,
        // its first thread folds them) reads v, w (3 n), q (4 n) and, with has_ft, ft (6 n) at
        // its chunk's rods, and writes partial[10 c..10 c + 10] (10 ceil(n / CHUNK)).
        unsafe {
            dev.launch(
                nchunks * motile_gpu::THREADS as usize,
                StepStats {
                    v: &v,
                    w: &w,
                    q: &self.rods.q,
                    ft: ft.as_ref().unwrap_or(&v),
                    partial: &mut partial,
                    n: int(n, "rods").map_err(StepError::from)?,
                    chunk: CHUNK as i32,
                    has_ft: i32::from(ft.is_some()),
                },
            )
            .map_err(StepError::from)?;
        }
        let part = dev.download(&partial).map_err(StepError::from)?;
        let part: Vec<&[f64]> = part.chunks(10).take(nchunks).collect();
        if let Some(bad) = part.iter().map(|c| c[6]).find(|&b| b >= 0.0) {
            return Err(StepError::NonFinite(bad as usize));
        }
        if report.max_overlap > self.contact.overlap_tolerance {
            return Err(StepError::Overlap {
                i: report.worst.0,
                j: report.worst.1,
                overlap: report.max_overlap,
                tolerance: self.contact.overlap_tolerance,
            });
        }
        let sum = |k: usize| part.iter().map(|c| c[k]).sum::<f64>();
        let max = |k: usize| part.iter().map(|c| c[k]).fold(0.0, f64::max);
        let total = n.max(1) as f64;
        let mp = [sum(1) / total, sum(2) / total, sum(3) / total];
        let step = StepReport {
            contact: report.contact,
            max_overlap: report.max_overlap,
            projections: report.projections,
            correction_active: report.correction_active,
            mean_speed: sum(0) / total,
            max_speed: max(4),
            max_rotation_rate: max(5),
            polar_order: (mp[0] * mp[0] + mp[1] * mp[1] + mp[2] * mp[2]).sqrt(),
            net_contact_force: [sum(7), sum(8), sum(9)],
            ..StepReport::default()
        };
        self.last = Some((v, w, ft));
        self.warm = warm;
        Ok(step)
    }

    /// One step of `dt` at a level whose flow is summed on the host and whose contacts act
    /// through the local drag (`dipole`, `sbt-explicit`): the free velocities of `at` (the
    /// rods now, as [`Self::download`] gives them) from `mobility`, then
    /// [`Self::step_from`] them; the report carries the mobility's. A failure of the flow's
    /// sum ([`StepError::Hydrodynamics`]) leaves the device untouched.
    pub fn step_with_flow(
        &mut self,
        dt: f64,
        mobility: &mut dyn Mobility,
        at: &RodSet,
    ) -> Result<StepReport, StepError> {
        let (flows, finishes) = mobility.resident().map_or((false, false), |r| {
            (r.flows_on_device(), r.finishes_on_device())
        });
        if flows {
            return self.step_with_resident_flow(dt, mobility);
        }
        if finishes {
            // Its contact forces act through its full hydrodynamics: not a local-drag step.
            return Err(StepError::Device(format!(
                "the {} mobility steps on the device only with its sum there",
                mobility.name()
            )));
        }
        let mut free = RodVelocities::zeros(at.len());
        mobility.free_velocities(at, &at.orientations(), &mut free)?;
        let mut report = self.step_from(dt, Some((&free.v, &free.w)))?;
        report.hydro = mobility.report();
        Ok(report)
    }

    /// One step of `dt` at a level whose flow is summed on this device
    /// ([`Mobility::flows_on_device`]): the velocities the contact solver plans with from
    /// `mobility` ([`Mobility::predicted_velocities_resident`]), then the step from them, the
    /// rods never leaving the device; at a level whose contact forces act through its
    /// hydrodynamics ([`Mobility::finishes_on_device`]: `sbt`) the step's velocities are the
    /// mobility's from the contact forces, then corrected as the CPU's stepper does. The report
    /// carries the mobility's. A failure of the flow's sum or solve
    /// ([`StepError::Hydrodynamics`]) leaves the rods untouched (the state before the step).
    pub fn step_with_resident_flow(
        &mut self,
        dt: f64,
        mobility: &mut dyn Mobility,
    ) -> Result<StepReport, StepError> {
        let rods = RodsOnDevice {
            x: &self.rods.x,
            q: &self.rods.q,
            len: self.rods.len,
            box_length: self.rods.box_length,
        };
        let name = mobility.name();
        let no_flow =
            || StepError::Device(format!("the {name} mobility has no flow on the device"));
        let resident = mobility.resident().ok_or_else(no_flow)?;
        let DeviceVelocities { v, w } = resident
            .predicted_velocities_resident(rods)
            .ok_or_else(no_flow)??;
        let finishes = resident.finishes_on_device();
        let mut finish = |at: RodsOnDevice<'_>, contact: Option<&Buffer>| {
            let done = resident.final_velocities_resident(at, contact)?;
            Ok(done.map(|DeviceVelocities { v, w }| (v, w)))
        };
        let hook: Option<super::step::Finish<'_>> = if finishes { Some(&mut finish) } else { None };
        let done = self.step_finished(dt, Free::Device(v, w), hook);
        if done.is_err() {
            // The rods stay as before the step; so does what the mobility keeps.
            resident.rollback_resident();
        }
        let mut report = done?;
        report.hydro = mobility.report();
        Ok(report)
    }

    /// The rods now into `rods` (the same rods).
    pub fn download(&self, rods: &mut RodSet) -> Result<(), GpuError> {
        self.gpu.download_rods(&self.rods, rods)
    }

    /// The rods before the last step into `rods` (after a failed step: the last good state).
    pub fn download_before(&self, rods: &mut RodSet) -> Result<(), GpuError> {
        self.gpu.download_rods(&self.before, rods)
    }

    /// The last step's velocities, angular velocities and contact forces (zeros before the
    /// first step).
    pub fn kinematics(&self) -> Result<RodKinematics, GpuError> {
        let n = self.rods.len;
        let Some((v, w, ft)) = &self.last else {
            return Ok((vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![[0.0; 3]; n]));
        };
        let triples = |b: &[f64], stride: usize| -> Vec<Vec3> {
            (0..n)
                .map(|r| [b[stride * r], b[stride * r + 1], b[stride * r + 2]])
                .collect()
        };
        let dev = &self.gpu.dev;
        let f = match ft {
            Some(ft) => triples(&dev.download(ft)?, 6),
            None => vec![[0.0; 3]; n],
        };
        Ok((
            triples(&dev.download(v)?, 3),
            triples(&dev.download(w)?, 3),
            f,
        ))
    }
}
