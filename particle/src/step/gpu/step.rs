//! The rooms joined into a step of the local-drag (`none`) level on the device (`step.cu`):
//! see [`super`].
#![allow(unsafe_code)]

use super::signatures::{AddVelocities, PairOverlap, SwimVelocities};
use super::solver::DeviceContactError;
use super::{DeviceContactProblem, DeviceRods, GpuStep, int};
use crate::hydro::mobility::LocalDrag;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED};
use crate::step::contact::{ContactParams, ContactReport};
use motile_gpu::GpuError;

/// What one device step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeviceStepReport {
    /// The contact solver's report.
    pub contact: ContactReport,
    /// Neighbour pairs within the reach.
    pub pairs: usize,
    /// Largest true overlap of the constrained pairs after the move (rod lengths; 0 if none).
    pub max_overlap: f64,
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
        if let Some(mut solved) = self.solve_on_device(problem, params, &[])? {
            report.contact = self.report(&solved)?.1;
            // The contact velocities of the multipliers (into the problem's vel), added.
            let lam = std::mem::replace(&mut solved.lam, dev.zeros::<f64>(1)?);
            let mut unused = dev.zeros::<f64>(cons.len)?;
            self.apply(&mut solved.prob, &lam, None, &mut unused)?;
            // SAFETY: thread r < n reads vel[6 r..6 r + 6] (6 n) and updates v, w at
            // 3 r..3 r + 3 (3 n).
            unsafe {
                dev.launch(
                    n,
                    AddVelocities {
                        vel: &solved.prob.vel,
                        v: &mut v,
                        w: &mut w,
                        n: ni,
                    },
                )?;
            }
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
            report.max_overlap = dev.download(&out)?.into_iter().fold(0.0, f64::max);
        }
        Ok(report)
    }
}
