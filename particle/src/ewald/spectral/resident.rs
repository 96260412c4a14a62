//! The sums with their points, values and results on the device (feature `gpu`): the same
//! parameter choice, error model and refinement as the sums of host values (`mod.rs`), each
//! attempt run by [`crate::ewald::gpu::GpuFourier`]'s resident sums, the host reading back
//! only the error model's reductions (a few numbers per 4 096 points).

use super::estimates::{
    ErrorScale, combine_chunks, estimate_from, estimate_weights, stresslet_estimates_from,
};
use super::{SpectralEwald, SumTiming, check_params};
use crate::ewald::gpu::resident::{RpyInputs, StressletInputs};
use crate::ewald::gpu::{OrientedPoints, PointForces};
use crate::ewald::kernels::{RealSpaceTable, StressletTable};
use crate::ewald::params::{
    ERROR_MODEL_RANGE, EwaldParams, PAIR_COST, STRESSLET_PAIR_COST, SumOutput,
};
use crate::ewald::periodic::{RpyGeometry, SumError, check_rpy};
use crate::model::geometry::Vec3;
use crate::model::units::VISCOSITY;
use motile_gpu::Buffer;
use std::f64::consts::PI;
use std::time::Instant;

/// The flow of a stresslet sum left on the device: velocities (triples) and gradients (9 per
/// point, `du_i/dx_m` at `3 i + m`), as [`crate::ewald::periodic::StressletField`] holds them.
#[derive(Debug)]
pub struct ResidentField {
    /// Velocities.
    pub u: Buffer,
    /// Gradients.
    pub grad: Buffer,
}

impl SpectralEwald {
    /// Before an attempt on the device with parameters `prm` in a box of side `l`: the
    /// parameters checked and recorded, a new generation (the device caches keyed by it are
    /// then this attempt's). The host grid goes where the parameters change, and the host
    /// sums' prepared points always (their generation is not this sum's: the next host sum
    /// prepares afresh, so no device cache of this sum's points is taken for its).
    fn begin_resident_attempt(&mut self, prm: EwaldParams, l: f64) -> Result<(), SumError> {
        check_params(&prm, l)?;
        if self.last != Some(prm) {
            self.grid = None;
        }
        self.prepared = None;
        self.last = Some(prm);
        self.generation += 1;
        Ok(())
    }

    /// [`crate::ewald::periodic::PeriodicStokes::stresslets`] of `n` stresslets
    /// `sigma p_n p_n` of one strength `sigma` at the `stresslets`' centres `x` with axes `p`
    /// (triples on this sum's device), the flow left there: the same parameters, estimates,
    /// refinement and report as the sum of host values. An error where this sum has no device.
    pub fn stresslets_resident(
        &mut self,
        box_length: f64,
        stresslets: OrientedPoints<'_>,
        sigma: f64,
        n: usize,
    ) -> Result<ResidentField, SumError> {
        let l = box_length;
        if !(sigma.is_finite() && l.is_finite() && l > 0.0) {
            return Err(SumError::Input(format!(
                "stresslets on the device: strength {sigma}, box {l}"
            )));
        }
        let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
        let floor = |k: i32| sigma.abs() / (8.0 * PI * VISCOSITY * l.powi(k));
        let mut attempts = 0;
        loop {
            attempts += 1;
            let internal = self.internal_tolerance();
            let prm = self.fixed.unwrap_or_else(|| {
                EwaldParams::choose_for(internal, n, l, &outputs, STRESSLET_PAIR_COST)
            });
            self.begin_resident_attempt(prm, l)?;
            let t0 = Instant::now();
            let xi = prm.xi;
            let scale = |o: SumOutput| internal * o.self_scale(xi) / VISCOSITY;
            let table = StressletTable::new(prm.cutoff, xi);
            let inputs = StressletInputs {
                table: &table,
                cutoff: prm.cutoff,
                r0: ERROR_MODEL_RANGE * prm.spacing(l),
                sigma,
                own_c: sigma * PI.sqrt() * xi * xi * xi / (2.0 * PI * PI),
                mu: VISCOSITY,
                weights: outputs.map(|o| {
                    let scales = ErrorScale {
                        scale: scale(o),
                        internal,
                    };
                    estimate_weights(o, scales)
                }),
                chunk: motile_analysis::reduce::CHUNK,
            };
            let geo = crate::ewald::gpu::backend::geometry(&prm, l);
            let generation = self.generation;
            let gpu = self.gpu.as_mut().ok_or_else(|| {
                SumError::Device("a resident sum on a sum without a device".into())
            })?;
            let res = gpu
                .stresslet_resident(generation, &geo, &inputs, stresslets, n)
                .map_err(|e| SumError::Device(e.to_string()))?;
            let joined = res.reductions.each_ref().map(|r| combine_chunks(r.iter()));
            let (estimates, ratio) = stresslet_estimates_from(joined, n, floor, self.tol);
            self.timing = SumTiming {
                fourier: t0.elapsed().as_secs_f64(),
                ..SumTiming::default()
            };
            if self.accept(ratio)? {
                self.record(internal, attempts, estimates);
                return Ok(ResidentField {
                    u: res.u,
                    grad: res.grad,
                });
            }
        }
    }
}

impl SpectralEwald {
    /// The device this sum runs on (for the kernels around a resident sum).
    pub(crate) fn device_sum(&self) -> Result<&crate::ewald::gpu::GpuFourier, SumError> {
        self.gpu
            .as_ref()
            .ok_or_else(|| SumError::Device("a resident sum on a sum without a device".into()))
    }
}

impl SpectralEwald {
    /// [`crate::ewald::periodic::PeriodicStokes::rpy`] of the `n` points of `sources` with their
    /// forces (triples, and field-major, on this sum's device) in groups of
    /// `geometry.group`, the velocities left there: the same parameters, estimate, refinement
    /// and report as the sum of host values.
    pub fn rpy_resident(
        &mut self,
        geometry: &RpyGeometry,
        sources: PointForces<'_>,
        n: usize,
    ) -> Result<Buffer, SumError> {
        let (l, a) = (geometry.box_length, geometry.radius);
        if !(l.is_finite() && l > 0.0 && a.is_finite() && a >= 0.0) || geometry.group == 0 {
            return Err(SumError::Input(format!(
                "RPY sum on the device: box {l}, radius {a}, group {}",
                geometry.group
            )));
        }
        let output = SumOutput::RpyVelocity;
        let mut attempts = 0;
        loop {
            attempts += 1;
            let internal = self.internal_tolerance();
            let prm = self
                .fixed
                .unwrap_or_else(|| EwaldParams::choose_for(internal, n, l, &[output], PAIR_COST));
            self.begin_resident_attempt(prm, l)?;
            let t0 = Instant::now();
            let scale = internal * output.self_scale(prm.xi) / VISCOSITY;
            let table = RealSpaceTable::new(prm.cutoff, prm.xi, a);
            let inputs = RpyInputs {
                table: &table,
                cutoff: prm.cutoff,
                r0: ERROR_MODEL_RANGE * prm.spacing(l),
                a,
                group: geometry.group,
                mu: VISCOSITY,
                weights: estimate_weights(output, ErrorScale { scale, internal }),
                chunk: motile_analysis::reduce::CHUNK,
            };
            let geo = crate::ewald::gpu::backend::geometry(&prm, l);
            let generation = self.generation;
            let gpu = self.gpu.as_mut().ok_or_else(|| {
                SumError::Device("a resident sum on a sum without a device".into())
            })?;
            let (u, reductions) = gpu
                .rpy_resident(generation, &geo, &inputs, sources, n)
                .map_err(|e| SumError::Device(e.to_string()))?;
            let est = estimate_from(output, combine_chunks(reductions.iter()), n, 0.0);
            let ratio = est.max_relative.max(est.l2_relative) / self.tol;
            self.timing = SumTiming {
                fourier: t0.elapsed().as_secs_f64(),
                ..SumTiming::default()
            };
            if self.accept(ratio)? {
                self.record(internal, attempts, vec![est]);
                return Ok(u);
            }
        }
    }
}

impl SpectralEwald {
    /// Values onto this sum's device (inputs of the resident sums, for callers that hold
    /// their data on the host: benchmarks, tests).
    pub fn upload(&self, values: &[f64]) -> Result<Buffer, SumError> {
        self.device_sum()?
            .upload(values)
            .map_err(|e| SumError::Device(e.to_string()))
    }

    /// A buffer of this sum's device (a resident sum's result) on the host.
    pub fn download(&self, buf: &Buffer) -> Result<Vec<f64>, SumError> {
        self.device_sum()?
            .download(buf)
            .map_err(|e| SumError::Device(e.to_string()))
    }
}

impl SpectralEwald {
    /// [`crate::ewald::periodic::PeriodicStokes::rpy`] of host values through
    /// [`Self::rpy_resident`]: the points uploaded once into `points_on_device` (the caller's
    /// cache for one set of points: the products of one GMRES solve), the forces each product,
    /// the velocities downloaded; the cell list, the corrections and the error model on the
    /// device, the same parameters, refinement and report.
    pub fn rpy_via_device(
        &mut self,
        geometry: &RpyGeometry,
        points: &[Vec3],
        points_on_device: &mut Option<Buffer>,
        forces: &[Vec3],
    ) -> Result<Vec<Vec3>, SumError> {
        check_rpy(geometry, points, forces)?;
        let nodes = match points_on_device.take() {
            Some(b) if b.len() == 3 * points.len() => b,
            _ => self.upload(points.as_flattened())?,
        };
        let force = self.upload(forces.as_flattened())?;
        let fields: Vec<f64> = (0..3)
            .flat_map(|d| forces.iter().map(move |v| v[d]))
            .collect();
        let fields = self.upload(&fields)?;
        let sources = PointForces {
            points: &nodes,
            forces: &force,
            fields: &fields,
        };
        let u = self.rpy_resident(geometry, sources, points.len());
        *points_on_device = Some(nodes);
        let u = self.download(&u?)?;
        Ok(u.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }
}

impl SpectralEwald {
    /// What this sum's device has been asked to do so far (`None` for a sum on the CPU).
    pub fn device_counters(&self) -> Option<motile_gpu::Counters> {
        self.gpu.as_ref().map(|g| g.counters())
    }
}
