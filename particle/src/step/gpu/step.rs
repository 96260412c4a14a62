//! The rooms joined into a step of the local-drag (`none`) level on the device (`step.cu`):
//! see [`super`].
#![allow(unsafe_code)]

use super::device::{GpuStep, int};
use super::signatures::{AddVelocities, PairOverlap, SwimVelocities};
use super::solver::DeviceContactError;
use super::solver::DeviceContactProblem;
use super::update::DeviceRods;
use crate::hydro::mobility::LocalDrag;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED};
use crate::step::contact::{ContactParams, ContactReport};
use motile_gpu::{Buffer, GpuError};

/// What one device step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceStepReport {
    /// The contact solver's report.
    pub contact: ContactReport,
    /// Neighbour pairs within the reach.
    pub pairs: usize,
    /// Largest true overlap of the constrained pairs after the move (rod lengths; 0 if none).
    pub max_overlap: f64,
    /// Its pair.
    pub worst: (u32, u32),
}

/// A step's report with its velocities and contact forces left on the device.
pub(super) struct StepOutput {
    pub(super) report: DeviceStepReport,
    /// Velocities and angular velocities (triples).
    pub(super) v: Buffer,
    pub(super) w: Buffer,
    /// Each rod's contact force and torque (6 values), if there were constraints.
    pub(super) ft: Option<Buffer>,
}

impl GpuStep {
    /// One step of swimming rods with contacts and no hydrodynamics (the `none` level) on the
    /// device: neighbour pairs, constraints, the swimming velocities, the contact problem
    /// (from zero: no warm start), the velocities with the contact forces through the local
    /// drag, the move, and the true overlaps after it. What the CPU's step does beyond this
    /// (warm starts, the projection of overlaps above half the tolerance, the step's
    /// statistics) is not on the device yet; the overlap is reported, not corrected.
    pub fn step_local_drag(
        &self,
        rods: &mut DeviceRods,
        dt: f64,
        params: &ContactParams,
    ) -> Result<DeviceStepReport, DeviceContactError> {
        Ok(self.step_output(rods, dt, params)?.report)
    }

    /// [`Self::step_local_drag`] with the velocities and contact forces left on the device.
    pub(super) fn step_output(
        &self,
        rods: &mut DeviceRods,
        dt: f64,
        params: &ContactParams,
    ) -> Result<StepOutput, DeviceContactError> {
        let n = rods.len;
        let ni = int(n, "rods")?;
        let reach = ROD_LENGTH + rods.diameter + params.margin;
        let pairs = self.build(&rods.x, n, rods.box_length, reach)?;
        let cons = self.constraints(rods, &pairs, params.margin)?;
        let dev = &self.dev;
        let mut v = dev.zeros::<f64>(3 * n)?;
        let mut w = dev.zeros::<f64>(3 * n)?;
        if rods.q.len() < 4 * n {
            return Err(GpuError::Input(format!("quaternions shorter than {n} rods")).into());
        }
        // SAFETY: thread r < n reads q[4 r..4 r + 4] (checked) and writes v, w at 3 r..3 r + 3
        // (3 n allocated).
        unsafe {
            dev.launch(
                n,
                SwimVelocities {
                    q: &rods.q,
                    v: &mut v,
                    w: &mut w,
                    n: ni,
                    u: SWIM_SPEED,
                },
            )?;
        }
        let problem = DeviceContactProblem {
            rods,
            cons: &cons,
            free_v: &v,
            free_w: &w,
            drag: LocalDrag::new(rods.diameter).coefficients(),
            dt,
        };
        let mut report = DeviceStepReport {
            pairs: pairs.len,
            ..DeviceStepReport::default()
        };
        let mut ft = None;
        let contact = match self.solve_on_device(problem, params, &[])? {
            Some(mut solved) => {
                report.contact = self.report(&solved)?.1;
                // The contact velocities of the multipliers (into the problem's vel).
                let lam = std::mem::replace(&mut solved.lam, dev.zeros::<f64>(1)?);
                let mut unused = dev.zeros::<f64>(cons.len)?;
                self.apply(&mut solved.prob, &lam, None, &mut unused)?;
                Some((solved.prob.vel, solved.prob.ft))
            }
            None => None,
        };
        if let Some((vel, f)) = contact {
            // SAFETY: thread r < n reads vel[6 r..6 r + 6] (6 n) and updates v, w at
            // 3 r..3 r + 3 (3 n).
            unsafe {
                dev.launch(
                    n,
                    AddVelocities {
                        vel: &vel,
                        v: &mut v,
                        w: &mut w,
                        n: ni,
                    },
                )?;
            }
            ft = Some(f);
        }
        self.update(rods, &v, &w, dt)?;
        if cons.len > 0 {
            let mut out = dev.zeros::<f64>(cons.len)?;
            // SAFETY: thread k < m reads ci[k], cj[k] (m), rods below n, their centres (3 n)
            // and quaternions (4 n), and writes out[k] (m).
            unsafe {
                dev.launch(
                    cons.len,
                    PairOverlap {
                        x: &rods.x,
                        q: &rods.q,
                        ci: &cons.i,
                        cj: &cons.j,
                        out: &mut out,
                        m: int(cons.len, "constraints")?,
                        l: rods.box_length,
                        b: rods.diameter,
                    },
                )?;
            }
            let overlaps = dev.download(&out)?;
            // The largest, the first of equals (as the CPU's, which also breaks ties by pair).
            let (k, o) = overlaps
                .iter()
                .enumerate()
                .fold((0, 0.0), |a, (k, &o)| if o > a.1 { (k, o) } else { a });
            report.max_overlap = o;
            if o > 0.0 {
                let (i, j) = (
                    dev.download_range(&cons.i, k, 1)?[0],
                    dev.download_range(&cons.j, k, 1)?[0],
                );
                report.worst = (i as u32, j as u32);
            }
        }
        Ok(StepOutput { report, v, w, ft })
    }
}
