//! The rooms joined into a step of the local-drag (`none`) level on the device (`step.cu`):
//! see [`super`].
#![allow(unsafe_code)]

use super::cells::DevicePairs;
use super::contacts::DeviceConstraints;
use super::device::{GpuStep, int};
use super::signatures::{
    AddRows, AddVelocities, PairOverlap, ProjectionMove, SwimVelocities, WarmGather,
};
use super::solver::DeviceContactError;
use super::solver::{DeviceContactProblem, Solved, Start};
use super::update::DeviceRods;
use crate::hydro::gpu::RodsOnDevice;
use crate::hydro::mobility::{LocalDrag, MobilityError};
use crate::model::geometry::Vec3;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED};
use crate::step::contact::{ContactParams, ContactReport};
use crate::step::stepper::PROJECTIONS;
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
    /// Rounds of the overlap projection.
    pub projections: usize,
    /// Constraints the correction after a level's final velocities made active (see
    /// [`crate::step::report::StepReport::correction_active`]).
    pub correction_active: usize,
}

/// A step's multipliers by pair, its warm start for the next: the constraints' pairs
/// `(i, j)`, sorted, and their multipliers (the first `len` values of each).
#[derive(Debug)]
pub(super) struct Warm {
    pub(super) i: Buffer<i32>,
    pub(super) j: Buffer<i32>,
    pub(super) lam: Buffer,
    pub(super) len: usize,
}

/// Where a step's free velocities (before contacts) come from.
pub(super) enum Free<'a> {
    /// Swimming alone (the `none` level), computed on the device.
    Swimming,
    /// Velocities and angular velocities per rod from the host.
    Host(&'a [Vec3], &'a [Vec3]),
    /// The same, already on the device (triples; a resident flow's).
    Device(Buffer, Buffer),
}

/// A level's final velocities from the step's contact forces (`sbt`: one solve with the
/// contact forces through its full hydrodynamics): given each rod's contact force and torque
/// (6 values; `None` where no constraint is active), the velocities and angular velocities
/// (triples) that replace the planned ones, or `None` to keep those.
pub(super) type Finish<'a> = &'a mut dyn FnMut(
    RodsOnDevice<'_>,
    Option<&Buffer>,
) -> Result<Option<(Buffer, Buffer)>, MobilityError>;

/// A step's length and contact settings.
#[derive(Clone, Copy, Debug)]
pub(super) struct Stepping<'a> {
    /// The time step.
    pub(super) dt: f64,
    /// The contact solver's settings.
    pub(super) params: &'a ContactParams,
}

/// What the projection moves besides the rods: their velocities and, where there were
/// constraints, their contact forces.
struct Moved<'a> {
    v: &'a mut Buffer,
    ft: Option<&'a mut Buffer>,
}

/// What a step's contact problem left on the device.
struct ContactStep {
    /// Its report.
    report: ContactReport,
    /// Each rod's contact force and torque (6 values), if there were constraints.
    forces: Option<Buffer>,
    /// The multipliers, if there were constraints.
    multipliers: Option<Buffer>,
}

/// Velocities and angular velocities `(v, w)` (triples) checked to hold `n` rods.
fn check_triples(what: &str, v: &Buffer, w: &Buffer, n: usize) -> Result<(), GpuError> {
    if v.len() < 3 * n || w.len() < 3 * n {
        return Err(GpuError::Input(format!(
            "{what}: {} and {} values for {n} rods",
            v.len(),
            w.len()
        )));
    }
    Ok(())
}

/// A step's report with its velocities and contact forces left on the device.
pub(super) struct StepOutput {
    pub(super) report: DeviceStepReport,
    /// Velocities and angular velocities (triples).
    pub(super) v: Buffer,
    pub(super) w: Buffer,
    /// Each rod's contact force and torque (6 values), if there were constraints.
    pub(super) ft: Option<Buffer>,
    /// The multipliers by pair (`None`: no constraints).
    pub(super) warm: Option<Warm>,
}

impl GpuStep {
    /// One step of swimming rods with contacts and no hydrodynamics (the `none` level) on the
    /// device: neighbour pairs, constraints, the swimming velocities, the contact problem
    /// (from zero: no warm start), the velocities with the contact forces through the local
    /// drag, the move, the true overlaps after it and their projection where they exceed
    /// half the tolerance (as the CPU's stepper). [`super::DeviceStepper`] adds the warm
    /// start and the step's statistics.
    pub fn step_local_drag(
        &self,
        rods: &mut DeviceRods,
        dt: f64,
        params: &ContactParams,
    ) -> Result<DeviceStepReport, DeviceContactError> {
        Ok(self
            .step_output(rods, Stepping { dt, params }, Free::Swimming, None, None)?
            .report)
    }

    /// [`Self::step_local_drag`] with the velocities and contact forces left on the device,
    /// from the free velocities `free` (velocities and angular velocities per rod, computed
    /// elsewhere: a hydrodynamic level's flow) where given, else from swimming alone; the
    /// contact problem starts from the multipliers of `warm`'s pairs where given (the
    /// stepper's warm start), else from zero. With `finish`, the level's final velocities
    /// replace the planned ones before the move, and a second contact problem from zero with
    /// them (the CPU stepper's correction) adds the impulses that restore the constraints they
    /// break.
    pub(super) fn step_output(
        &self,
        rods: &mut DeviceRods,
        stepping: Stepping<'_>,
        free: Free<'_>,
        finish: Option<Finish<'_>>,
        warm: Option<&Warm>,
    ) -> Result<StepOutput, DeviceContactError> {
        let Stepping { dt, params } = stepping;
        let reach = ROD_LENGTH + rods.diameter + params.margin;
        let pairs = self.build(&rods.x, rods.len, rods.box_length, reach)?;
        let cons = self.constraints(rods, &pairs, params.margin)?;
        let mut report = DeviceStepReport {
            pairs: pairs.len,
            ..DeviceStepReport::default()
        };
        let (mut v, mut w) = self.free_velocities(rods, free)?;
        let contact = self.contact_step(rods, &cons, &mut v, &mut w, stepping, warm)?;
        report.contact = contact.report;
        let mut ft = contact.forces;
        if let Some(finish) = finish {
            let active = report.contact.active > 0;
            let at = RodsOnDevice {
                x: &rods.x,
                q: &rods.q,
                len: rods.len,
                box_length: rods.box_length,
            };
            if let Some(done) = finish(at, ft.as_ref().filter(|_| active))? {
                (v, w) = done;
                check_triples("final velocities", &v, &w, rods.len)?;
            }
            // As the CPU's stepper: whenever there are constraints, also where the prediction
            // stood.
            report.correction_active =
                self.correct(rods, &cons, &mut v, &mut w, &mut ft, stepping)?;
        }
        self.update(rods, &v, &w, dt)?;
        (report.max_overlap, report.worst) = self.max_overlap(rods, &cons)?;
        let moved = Moved {
            v: &mut v,
            ft: ft.as_mut(),
        };
        let cells = pairs.cells_per_side;
        self.project(rods, &cons, cells, moved, stepping, &mut report)?;
        // The constraints' pairs (sorted) with their multipliers: the next step's start.
        let len = cons.len;
        let warm = contact.multipliers.map(|lam| Warm {
            i: cons.i,
            j: cons.j,
            lam,
            len,
        });
        Ok(StepOutput {
            report,
            v,
            w,
            ft,
            warm,
        })
    }

    /// The velocities and angular velocities (triples, on the device) a step plans with:
    /// `free`'s, uploaded from the host where they are there, or swimming computed here.
    fn free_velocities(
        &self,
        rods: &DeviceRods,
        free: Free<'_>,
    ) -> Result<(Buffer, Buffer), DeviceContactError> {
        let (dev, n) = (&self.dev, rods.len);
        match free {
            Free::Device(v, w) => {
                check_triples("free velocities", &v, &w, n)?;
                Ok((v, w))
            }
            Free::Host(fv, fw) => {
                if fv.len() != n || fw.len() != n {
                    return Err(GpuError::Input(format!(
                        "free velocities for {} and {} rods, not {n}",
                        fv.len(),
                        fw.len()
                    ))
                    .into());
                }
                Ok((
                    dev.upload(fv.as_flattened())?,
                    dev.upload(fw.as_flattened())?,
                ))
            }
            Free::Swimming => {
                let mut v = dev.zeros::<f64>(3 * n)?;
                let mut w = dev.zeros::<f64>(3 * n)?;
                if rods.q.len() < 4 * n {
                    return Err(
                        GpuError::Input(format!("quaternions shorter than {n} rods")).into(),
                    );
                }
                // SAFETY: thread r < n reads q[4 r..4 r + 4] (checked) and writes v, w at
                // 3 r..3 r + 3 (3 n allocated).
                unsafe {
                    dev.launch(
                        n,
                        SwimVelocities {
                            q: &rods.q,
                            v: &mut v,
                            w: &mut w,
                            n: int(n, "rods")?,
                            u: SWIM_SPEED,
                        },
                    )?;
                }
                Ok((v, w))
            }
        }
    }

    /// The step's contact problem from the planned velocities `(v, w)`, started from the
    /// multipliers of `warm`'s pairs where given: its report, its forces (6 values per rod)
    /// and multipliers where there were constraints, and the contact forces' local-drag
    /// velocities added to `(v, w)`.
    fn contact_step(
        &self,
        rods: &DeviceRods,
        cons: &DeviceConstraints,
        v: &mut Buffer,
        w: &mut Buffer,
        stepping: Stepping<'_>,
        warm: Option<&Warm>,
    ) -> Result<ContactStep, DeviceContactError> {
        let Stepping { dt, params } = stepping;
        let n = rods.len;
        let problem = DeviceContactProblem {
            rods,
            cons,
            free_v: v,
            free_w: w,
            drag: LocalDrag::new(rods.diameter).coefficients(),
            dt,
        };
        let initial = match warm {
            Some(w) if cons.len > 0 => Some(self.warm_gather(cons, w)?),
            _ => None,
        };
        let start = initial.as_ref().map_or(Start::Host(&[]), Start::Device);
        let Some(solved) = self.solve_on_device(problem, params, start)? else {
            return Ok(ContactStep {
                report: ContactReport::default(),
                forces: None,
                multipliers: None,
            });
        };
        let report = self.report(&solved)?.1;
        let (lam, vel, forces) = solved.into_forces();
        // SAFETY: thread r < n reads vel[6 r..6 r + 6] (6 n) and updates v, w at
        // 3 r..3 r + 3 (3 n).
        unsafe {
            self.dev.launch(
                n,
                AddVelocities {
                    vel: &vel,
                    v,
                    w,
                    n: int(n, "rods")?,
                },
            )?;
        }
        Ok(ContactStep {
            report,
            forces: Some(forces),
            multipliers: Some(lam),
        })
    }

    /// The projection of overlaps above half the tolerance after the move (the CPU
    /// stepper's): the constraints of the same pairs `cons` rebuilt at the new positions, a
    /// contact problem with no free motion through the local translational drag (rotation 0),
    /// the rods translated by its displacements, `v` and the contact forces `ft` updated; at
    /// most [`PROJECTIONS`] rounds, counted in `report` with the overlap left.
    fn project(
        &self,
        rods: &mut DeviceRods,
        cons: &DeviceConstraints,
        cells_per_side: usize,
        moved: Moved<'_>,
        stepping: Stepping<'_>,
        report: &mut DeviceStepReport,
    ) -> Result<(), DeviceContactError> {
        let Stepping { dt, params } = stepping;
        let Moved { v, mut ft } = moved;
        let (dev, n) = (&self.dev, rods.len);
        while report.max_overlap > 0.5 * params.overlap_tolerance
            && report.projections < PROJECTIONS
        {
            report.projections += 1;
            let zero = dev.zeros::<f64>(3 * n)?;
            let mut same = DevicePairs {
                first: dev.zeros::<i32>(cons.len)?,
                second: dev.zeros::<i32>(cons.len)?,
                len: cons.len,
                cells_per_side,
            };
            dev.copy((&cons.i, 0), (&mut same.first, 0), cons.len)?;
            dev.copy((&cons.j, 0), (&mut same.second, 0), cons.len)?;
            let again = self.constraints(rods, &same, params.margin)?;
            let problem = DeviceContactProblem {
                rods,
                cons: &again,
                free_v: &zero,
                free_w: &zero,
                drag: (LocalDrag::new(rods.diameter).coefficients().0, 0.0),
                dt,
            };
            let moved = self
                .solve_on_device(problem, params, Start::Host(&[]))?
                .map(Solved::into_forces);
            if let (Some((_, vel, pushes)), Some(ft)) = (moved, ft.as_deref_mut()) {
                // SAFETY: thread r < n moves x, image (3 n) and adds to v (3 n) and ft (6 n)
                // at its rod from vel and pushes (6 n each).
                unsafe {
                    dev.launch(
                        n,
                        ProjectionMove {
                            x: &mut rods.x,
                            image: &mut rods.image,
                            vel: &vel,
                            pft: &pushes,
                            v,
                            ft,
                            n: int(n, "rods")?,
                            dt,
                            l: rods.box_length,
                        },
                    )?;
                }
            }
            (report.max_overlap, report.worst) = self.max_overlap(rods, cons)?;
        }
        Ok(())
    }

    /// The correction after a level's final velocities `(v, w)` (the CPU stepper's): the
    /// contact problem of `cons` from zero with them as the free velocities; where it makes
    /// constraints active, their local-drag velocities added to `(v, w)` and their forces to
    /// `ft`. Returns the active constraints.
    fn correct(
        &self,
        rods: &DeviceRods,
        cons: &DeviceConstraints,
        v: &mut Buffer,
        w: &mut Buffer,
        ft: &mut Option<Buffer>,
        stepping: Stepping<'_>,
    ) -> Result<usize, DeviceContactError> {
        let Stepping { dt, params } = stepping;
        let n = rods.len;
        let problem = DeviceContactProblem {
            rods,
            cons,
            free_v: v,
            free_w: w,
            drag: LocalDrag::new(rods.diameter).coefficients(),
            dt,
        };
        let Some(solved) = self.solve_on_device(problem, params, Start::Host(&[]))? else {
            return Ok(0);
        };
        let active = self.report(&solved)?.1.active;
        if active == 0 {
            return Ok(0);
        }
        let (_, vel, f) = solved.into_forces();
        let dev = &self.dev;
        let ni = int(n, "rods")?;
        // SAFETY: thread r < n reads vel[6 r..6 r + 6] (6 n) and updates v, w at 3 r..3 r + 3
        // (3 n, checked by the caller).
        unsafe {
            dev.launch(
                n,
                AddVelocities {
                    vel: &vel,
                    v,
                    w,
                    n: ni,
                },
            )?;
        }
        match ft {
            Some(ft) => {
                // SAFETY: thread k < 6 n reads f[k] and updates ft[k] (6 n each).
                unsafe {
                    dev.launch(
                        6 * n,
                        AddRows {
                            src: &f,
                            dst: ft,
                            len: int(6 * n, "6 x rods")?,
                        },
                    )?;
                }
            }
            None => *ft = Some(f),
        }
        Ok(active)
    }

    /// The starting multiplier of each of `cons` from `warm`'s of the same pair (0 where
    /// none).
    fn warm_gather(&self, cons: &DeviceConstraints, warm: &Warm) -> Result<Buffer, GpuError> {
        let mut out = self.dev.zeros::<f64>(cons.len)?;
        if warm.i.len() < warm.len || warm.j.len() < warm.len || warm.lam.len() < warm.len {
            return Err(GpuError::Input(format!(
                "warm start: buffers shorter than {}",
                warm.len
            )));
        }
        // SAFETY: thread k < m reads ci[k], cj[k] (m) and searches oi, oj, olam in
        // 0..mo (checked above), and writes out[k] (m).
        unsafe {
            self.dev.launch(
                cons.len,
                WarmGather {
                    ci: &cons.i,
                    cj: &cons.j,
                    oi: &warm.i,
                    oj: &warm.j,
                    olam: &warm.lam,
                    out: &mut out,
                    m: int(cons.len, "constraints")?,
                    mo: int(warm.len, "warm-start pairs")?,
                },
            )?;
        }
        Ok(out)
    }

    /// The largest true overlap of the constrained pairs at the rods' present state (0 if
    /// none) and its pair, the first of equals (as the CPU's, which also breaks ties by pair).
    fn max_overlap(
        &self,
        rods: &DeviceRods,
        cons: &DeviceConstraints,
    ) -> Result<(f64, (u32, u32)), GpuError> {
        if cons.len == 0 {
            return Ok((0.0, (0, 0)));
        }
        let dev = &self.dev;
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
        let (k, o) = overlaps
            .iter()
            .enumerate()
            .fold((0, 0.0), |a, (k, &o)| if o > a.1 { (k, o) } else { a });
        if o > 0.0 {
            let (i, j) = (
                dev.download_range(&cons.i, k, 1)?[0],
                dev.download_range(&cons.j, k, 1)?[0],
            );
            return Ok((o, (i as u32, j as u32)));
        }
        Ok((o, (0, 0)))
    }
}
