//! [`SlenderBody`]'s solves of (P4) on the device of its resident sum (feature `gpu`): GMRES's
//! vectors and products there ([`crate::hydro::gpu`]), the host reading back per iteration
//! only the Hessenberg column and the sum's error reductions.
//!
//! Two ways in: the CPU's stepper (the rods on the host) uploads the nodes, the right-hand side
//! and the warm start per solve and downloads the solution and the flow
//! ([`SlenderBody::solve_resident`]); the resident stepper
//! ([`crate::step::gpu::DeviceStepper`]) keeps the solution (the next warm start) and the flow
//! velocities (the next prediction) on the device from step to step, with the rods, the
//! contact forces and the velocities ([`SlenderBody::predicted_resident`],
//! [`SlenderBody::final_resident`]); the host's copies are then brought up to date only where
//! asked ([`SlenderBody::device_to_host`], for outputs, checkpoints and a return to the host's
//! steps).

use super::{SlenderBody, densities};
use crate::ewald::periodic::{RpyGeometry, SumError};
use crate::ewald::spectral::SpectralEwald;
use crate::hydro::gmres::GmresInfo;
use crate::hydro::gpu::{DeviceP4, DeviceRule, P4Sum, RodMotion, SlenderDevice, SlenderFlow};
use crate::hydro::gpu::{DeviceVelocities, ResidentMobility, RodsOnDevice};
use crate::hydro::mobility::{HydroReport, LocalDrag, MobilityError};
use crate::model::geometry::Vec3;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED, eta};
use motile_gpu::{Buffer, Counters};

/// The last solution of (P4) and the flow velocities (6 per rod) on the host.
type HostState = (Vec<f64>, Vec<f64>);

/// A step's velocities and angular velocities (on the device) and its solve's report.
type StepSolve = ((Buffer, Buffer), (GmresInfo, HydroReport, f64));

/// The kernels beside `sum`'s device, opened where not yet.
fn kernels<'a>(
    slot: &'a mut Option<(SlenderDevice, DeviceRule)>,
    shuffle: u64,
    sum: &SpectralEwald,
    s: &[f64],
    w: &[f64],
) -> Result<&'a (SlenderDevice, DeviceRule), MobilityError> {
    if slot.is_none() {
        let backend = sum.device_sum()?.backend();
        let kern = SlenderDevice::open(backend).map_err(MobilityError::from)?;
        if shuffle != 0 {
            kern.shuffle_blocks(shuffle);
        }
        let rule = kern.rule(s, w).map_err(MobilityError::from)?;
        *slot = Some((kern, rule));
    }
    Ok(slot.as_ref().expect("opened above"))
}

/// The rods' quadrature nodes and axes on the device (triples), `n` rods.
#[derive(Clone, Copy)]
struct RodNodes<'a> {
    nodes: &'a Buffer,
    axes: &'a Buffer,
    n: usize,
}

/// One solve of (P4) on the device: GMRES's report and the flow at the nodes for the solution,
/// the sums folded into `report`.
struct Solve<'a> {
    kern: &'a SlenderDevice,
    rule: &'a DeviceRule,
    sum: &'a mut SpectralEwald,
    geometry: RpyGeometry,
    eta: f64,
}

impl<'a> Solve<'a> {
    fn new(
        kern: &'a SlenderDevice,
        rule: &'a DeviceRule,
        sum: &'a mut SpectralEwald,
        geometry: RpyGeometry,
        eta: f64,
    ) -> Self {
        Self {
            kern,
            rule,
            sum,
            geometry,
            eta,
        }
    }

    /// From the warm start `x` (the last iterate left there, also on failure).
    fn run(
        self,
        rods: RodNodes<'_>,
        b: &Buffer,
        x: &mut Buffer,
        params: &crate::hydro::gmres::GmresParams,
        stage: &'static str,
    ) -> Result<(GmresInfo, Buffer, HydroReport, f64), MobilityError> {
        let op = DeviceP4 {
            sum: P4Sum::Resident(self.sum),
            geometry: self.geometry,
            nodes: rods.nodes,
            p: rods.axes,
            rule: self.rule,
            n: rods.n,
            eta: self.eta,
            l: ROD_LENGTH,
        };
        let solved = self
            .kern
            .solve(op, b, x, params)
            .map_err(|source| MobilityError::Gmres { stage, source })?;
        Ok((solved.info, solved.u, solved.accuracy, solved.seconds))
    }
}

impl Solve<'_> {
    /// [`Self::run`] from the last solution in `x` (the right-hand side where there is none,
    /// as on the host), the last iterate left there.
    fn warm(
        self,
        rods: RodNodes<'_>,
        b: &Buffer,
        x: &mut Option<Buffer>,
        params: &crate::hydro::gmres::GmresParams,
        stage: &'static str,
    ) -> Result<(GmresInfo, Buffer, HydroReport, f64), MobilityError> {
        let mut start = match x.take() {
            Some(x) => x,
            None => self.kern.copy_of(b).map_err(MobilityError::from)?,
        };
        let solved = self.run(rods, b, &mut start, params, stage);
        *x = Some(start);
        solved
    }

    /// A step's solve of `n` rods with nodes `nodes`, axes `p`, and contact forces `ft` (6 per
    /// rod) where given: the right-hand side, GMRES from the last solution in `x`, the flow
    /// velocities into `flow` and the rods' velocities, with the solve's report.
    fn step(
        self,
        rods: RodNodes<'_>,
        ft: Option<&Buffer>,
        (x, flow): (&mut Option<Buffer>, &mut Option<Buffer>),
        params: &super::SlenderParams,
        stage: &'static str,
    ) -> Result<StepSolve, MobilityError> {
        let (p, n) = (rods.axes, rods.n);
        let c = SWIM_SPEED / (2.0 * self.eta);
        let (kern, rule) = (self.kern, self.rule);
        let b = kern
            .rhs(p, ft, rule, n, c, ROD_LENGTH)
            .map_err(MobilityError::from)?;
        let (info, u, accuracy, seconds) = self.warm(rods, &b, x, &params.gmres, stage)?;
        let drag = LocalDrag::new(params.diameter).coefficients();
        let SlenderFlow {
            flow: f,
            rods: DeviceVelocities { v, w },
        } = kern
            .velocities(
                p,
                &u,
                ft,
                rule,
                n,
                RodMotion {
                    length: ROD_LENGTH,
                    swim: SWIM_SPEED,
                    drag,
                },
            )
            .map_err(MobilityError::from)?;
        *flow = Some(f);
        Ok(((v, w), (info, accuracy, seconds)))
    }
}

impl SlenderBody {
    /// On the host emulation, run the blocks of this mobility's own kernels (not its sum's:
    /// [`crate::ewald::gpu::GpuFourier::shuffle_blocks`]) in a random order from now on
    /// (`seed` nonzero; 0: in order), to expose races between blocks.
    pub fn shuffle_device_blocks(&mut self, seed: u64) {
        self.device.shuffle = seed;
        if let Some((kern, _)) = &self.device.kern {
            kern.shuffle_blocks(seed);
        }
    }

    fn geometry(&self, box_length: f64) -> RpyGeometry {
        RpyGeometry {
            box_length,
            radius: self.params.rpy_radius,
            group: self.s.len(),
        }
    }

    /// A solve's report into the step's.
    fn fold_solve(&mut self, info: &GmresInfo, accuracy: &HydroReport, seconds: f64) {
        self.fold_sums(accuracy, seconds);
        self.report.gmres_iterations = info.iterations;
        self.report.gmres_residual = info.final_residual;
    }

    /// [`Self::solve`] on one process where the sum keeps its values on a device: the nodes
    /// `points` of the rods with axes `p` in a box of side `box_length`, the right-hand side
    /// and the warm start `x` uploaded, GMRES on the device, the solution and the flow at the
    /// nodes downloaded. `None` where the sum has no device.
    pub(super) fn solve_resident(
        &mut self,
        box_length: f64,
        points: &[Vec3],
        p: &[Vec3],
        rhs: &[f64],
        x: &mut Vec<f64>,
        stage: &'static str,
    ) -> Option<Result<(GmresInfo, Vec<Vec3>), MobilityError>> {
        let geometry = self.geometry(box_length);
        let e = eta(self.params.diameter);
        let sum = self.sum.resident()?;
        let mut run = || -> Result<_, MobilityError> {
            let shuffle = self.device.shuffle;
            let (kern, rule) = kernels(&mut self.device.kern, shuffle, sum, &self.s, &self.w)?;
            let up = |v: &[f64]| kern.upload(v).map_err(MobilityError::from);
            let (nodes, axes, b) = (up(points.as_flattened())?, up(p.as_flattened())?, up(rhs)?);
            let mut xd = up(x)?;
            let solve = Solve::new(kern, rule, sum, geometry, e);
            let rods = RodNodes {
                nodes: &nodes,
                axes: &axes,
                n: p.len(),
            };
            let solved = solve.run(rods, &b, &mut xd, &self.params.gmres, stage);
            // The last iterate is the next warm start, also after a failure (as on the host).
            *x = kern.download(&xd).map_err(MobilityError::from)?;
            let (info, u, accuracy, seconds) = solved?;
            let u = kern.download(&u).map_err(MobilityError::from)?;
            let u: Vec<Vec3> = u.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            Ok((info, u, accuracy, seconds))
        };
        let result = run();
        Some(result.map(|(info, u, accuracy, seconds)| {
            self.fold_sums(&accuracy, seconds);
            (info, u)
        }))
    }

    /// [`crate::hydro::mobility::Mobility::predicted_velocities_resident`]: swimming plus the
    /// last flow velocities (kept on the device, or uploaded from the host's after a resume),
    /// or on the first step an exact free solve. `None` where the sum is shared or has no
    /// device.
    pub(super) fn predicted_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
    ) -> Option<Result<(Buffer, Buffer), MobilityError>> {
        if self.shared.is_some() {
            return None;
        }
        self.report = HydroReport::default();
        let n = rods.len;
        let m = self.s.len();
        let geometry = self.geometry(rods.box_length);
        let e = eta(self.params.diameter);
        let sum = self.sum.resident()?;
        let dev = &mut self.device;
        let mut run = || -> Result<_, MobilityError> {
            let (kern, rule) = kernels(&mut dev.kern, dev.shuffle, sum, &self.s, &self.w)?;
            let up = |v: &[f64]| kern.upload(v).map_err(MobilityError::from);
            if dev.n != n {
                (dev.x, dev.flow) = (None, None);
            }
            dev.n = n;
            // After a resume (or the host's steps), the host's state is the device's start
            // (not where the host's copies are older than what the device had).
            let host = !dev.host_behind;
            if host && dev.x.is_none() && self.warm_free.len() == 3 * m * n {
                dev.x = Some(up(&self.warm_free)?);
            }
            if host && dev.flow.is_none() && self.flow.len() == n {
                let flat: Vec<f64> = self
                    .flow
                    .iter()
                    .flat_map(|(v, w)| v.iter().chain(w))
                    .copied()
                    .collect();
                dev.flow = Some(up(&flat)?);
            }
            // The state before the step, restored if the step fails.
            let copy = |b: &Option<Buffer>| b.as_ref().map(|b| kern.copy_of(b)).transpose();
            dev.before = (
                copy(&dev.x).map_err(MobilityError::from)?,
                copy(&dev.flow).map_err(MobilityError::from)?,
            );
            let p = sum
                .device_sum()?
                .rod_axes(rods.q, n)
                .map_err(MobilityError::from)?;
            let nodes = kern
                .nodes(rods.x, &p, rule, n)
                .map_err(MobilityError::from)?;
            let out = if let Some(flow) = &dev.flow {
                let v = kern
                    .predict(&p, flow, n, SWIM_SPEED)
                    .map_err(MobilityError::from)?;
                (v, None)
            } else {
                let solve = Solve::new(kern, rule, sum, geometry, e);
                let rods = RodNodes {
                    nodes: &nodes,
                    axes: &p,
                    n,
                };
                let warm = (&mut dev.x, &mut dev.flow);
                let (v, solved) = solve.step(rods, None, warm, &self.params, "free")?;
                dev.host_behind = true;
                (v, Some(solved))
            };
            dev.step = Some((p, nodes));
            Ok(out)
        };
        let result = run();
        Some(result.map(|(v, solved)| {
            self.predicted_exactly = solved.is_some();
            if let Some((info, accuracy, seconds)) = solved {
                self.fold_solve(&info, &accuracy, seconds);
            }
            v
        }))
    }

    /// [`crate::hydro::mobility::Mobility::final_velocities_resident`]: one solve of (P4) with
    /// swimming and the contact forces `ft` together (zero forces where `None`), warm-started
    /// from the last solution, unless the prediction was already the exact free solution and
    /// there are no contact forces.
    pub(super) fn final_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
        ft: Option<&Buffer>,
    ) -> Result<Option<(Buffer, Buffer)>, MobilityError> {
        if self.predicted_exactly && ft.is_none() {
            return Ok(None);
        }
        let n = rods.len;
        let geometry = self.geometry(rods.box_length);
        let e = eta(self.params.diameter);
        let not_resident = || SumError::Device("the final solve of a sum without a device".into());
        let sum = self.sum.resident().ok_or_else(not_resident)?;
        let dev = &mut self.device;
        let (Some((kern, rule)), Some((p, nodes))) = (&dev.kern, dev.step.take()) else {
            return Err(MobilityError::Sum(SumError::Device(
                "the final solve on the device before its prediction".into(),
            )));
        };
        let zeros;
        let ft = match ft {
            Some(ft) => ft,
            None => {
                zeros = kern.zeros(6 * n).map_err(MobilityError::from)?;
                &zeros
            }
        };
        let solve = Solve::new(kern, rule, sum, geometry, e);
        let rods = RodNodes {
            nodes: &nodes,
            axes: &p,
            n,
        };
        let warm = (&mut dev.x, &mut dev.flow);
        let stage = "swimming + contact";
        let (v, (info, accuracy, seconds)) =
            solve.step(rods, Some(ft), warm, &self.params, stage)?;
        dev.host_behind = true;
        self.fold_solve(&info, &accuracy, seconds);
        Ok(Some(v))
    }

    /// The resident state on the host: the last solution and the flow velocities (none
    /// where a first step's solve failed), or `None` where the device has no solution.
    pub(super) fn resident_state(&self) -> Option<Result<HostState, MobilityError>> {
        let dev = &self.device;
        let ((kern, _), x) = (dev.kern.as_ref()?, dev.x.as_ref()?);
        let get = || -> Result<HostState, motile_gpu::GpuError> {
            let flow = match &dev.flow {
                Some(f) => kern.download(f)?,
                None => Vec::new(),
            };
            Ok((kern.download(x)?, flow))
        };
        Some(get().map_err(MobilityError::from))
    }

    /// What the sum's device and the kernels' have been asked to do so far (`None` without a
    /// sum on a device).
    pub(super) fn device_counters(&mut self) -> Option<motile_gpu::Counters> {
        let mut c = self.sum.resident()?.device_counters()?;
        if let Some((kern, _)) = &self.device.kern {
            c.add(&kern.counters());
        }
        Some(c)
    }

    /// The host's copies of the solution, the flow velocities and the force density brought
    /// up to the device's, which stays current.
    pub(super) fn sync_from_device(&mut self) -> Result<(), MobilityError> {
        if let Some(state) = self.resident_state() {
            let (x, flow) = state?;
            self.warm_free = x;
            self.flow = flow
                .chunks_exact(6)
                .map(|c| ([c[0], c[1], c[2]], [c[3], c[4], c[5]]))
                .collect();
            self.density = densities(&self.warm_free);
        }
        self.device.host_behind = false;
        Ok(())
    }

    /// [`Self::sync_from_device`], then the device's state dropped: the host's steps go on
    /// from here.
    pub(super) fn device_to_host(&mut self) -> Result<(), MobilityError> {
        self.sync_from_device()?;
        self.device.forget();
        Ok(())
    }
}

impl ResidentMobility for SlenderBody {
    fn flows_on_device(&mut self) -> bool {
        self.shared.is_none() && self.sum.resident().is_some()
    }

    fn predicted_velocities_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
    ) -> Option<Result<DeviceVelocities, MobilityError>> {
        self.predicted_resident(rods)
            .map(|done| done.map(DeviceVelocities::from))
    }

    fn finishes_on_device(&self) -> bool {
        true
    }

    fn sum_counters(&mut self) -> Option<Counters> {
        self.device_counters()
    }

    fn final_velocities_resident(
        &mut self,
        rods: RodsOnDevice<'_>,
        contact: Option<&Buffer>,
    ) -> Result<Option<DeviceVelocities>, MobilityError> {
        self.final_resident(rods, contact)
            .map(|done| done.map(DeviceVelocities::from))
    }

    fn resident_warm_state(&self) -> Option<Result<Vec<f64>, MobilityError>> {
        self.resident_state()
            .map(|r| r.map(|(x, flow)| [x, flow].concat()))
    }

    fn sync_resident(&mut self) -> Result<(), MobilityError> {
        self.sync_from_device()
    }

    fn rollback_resident(&mut self) {
        self.device.rollback();
    }
}
