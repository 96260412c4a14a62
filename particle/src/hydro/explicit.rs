//! Slender-body theory with explicit force densities (`hydrodynamics = "sbt-explicit"`,
//! docs/MODEL.md §2a): every rod carries the force density of an isolated swimmer,
//! `f(s) = (U/(2 eta)) sign(s) p` (force- and torque-free), on the half-rod Gauss rule of the
//! slender-body level; the flow of all the other rods (and of every periodic image) at each
//! rod's nodes is one periodic RPY sum of these densities; the rod moves with the rigid-body
//! projection (P2)-(P3) of that flow. It is slender-body theory without the GMRES coupling of
//! the densities: each rod's flow is that of a rod of finite length, smooth over its length
//! (unlike a point stresslet, whose near field turns neighbours far too fast), and the cost is
//! one sum per step. What it leaves out is the change of each rod's density by the flow of the
//! others (of relative order `u/U`), and the flows of contact forces: contacts act through the
//! local mobility, as at the dipole level.

use crate::ewald::periodic::RpyGeometry;
use crate::ewald::shared::{RankShare, SharedEwald};
use crate::hydro::mobility::{
    ForceDensity, HydroReport, LocalDrag, Mobility, MobilityError, MobilityState, ResidentMobility,
    RodVelocities, SharedMobility,
};
use crate::hydro::slender::{
    SlenderParams, default_rpy_radius, flow_velocities, half_rod_rule, node_positions,
};
use crate::hydro::sum::FlowSum;
use crate::model::geometry::Vec3;
use crate::model::rods::RodSet;
use crate::model::units::{ROD_LENGTH, SWIM_SPEED, eta};
use crate::parallel::part::Part;
use rayon::prelude::*;
use std::time::Instant;

/// The explicit slender-body mobility; owns the periodic sum and the quadrature.
#[derive(Debug)]
pub struct ExplicitSlender {
    pub(crate) diameter: f64,
    /// RPY radius of the nodes.
    radius: f64,
    pub(crate) sum: Box<dyn FlowSum>,
    /// The sum shared among ranks, when this mobility runs on one rank's part of a box.
    pub(crate) shared: Option<SharedEwald>,
    pub(crate) s: Vec<f64>,
    pub(crate) w: Vec<f64>,
    local: LocalDrag,
    pub(crate) report: HydroReport,
    density: Vec<Vec3>,
}

impl ExplicitSlender {
    /// The explicit level for rods of `params.diameter`, with `params.quadrature_points` nodes
    /// per rod and RPY radius `params.rpy_radius` (the slender-body level's settings; GMRES's
    /// are unused), on the given periodic sum.
    pub fn new(params: SlenderParams, sum: Box<dyn FlowSum>) -> Self {
        let (s, w) = half_rod_rule(params.quadrature_points, ROD_LENGTH);
        Self {
            diameter: params.diameter,
            radius: params.rpy_radius,
            sum,
            shared: None,
            s,
            w,
            local: LocalDrag::new(params.diameter),
            report: HydroReport::default(),
            density: Vec::new(),
        }
    }

    /// The default settings for rods of diameter `b` (4 nodes, the default RPY radius).
    pub fn for_diameter(diameter: f64, sum: Box<dyn FlowSum>) -> Self {
        let params = SlenderParams {
            rpy_radius: default_rpy_radius(diameter),
            ..SlenderParams::for_diameter(diameter)
        };
        Self::new(params, sum)
    }

    /// The same mobility able to run on one rank's part of a box shared by several, its sum
    /// then [`SharedEwald`] at tolerance `tol` ([`SharedMobility::predicted_velocities_shared`]).
    pub fn shared(mut self, tol: f64) -> Result<Self, crate::ewald::periodic::SumError> {
        self.shared = Some(SharedEwald::new(tol)?);
        Ok(self)
    }

    /// The isolated swimmer's density at every node of the rods with axes `p`.
    fn densities(&self, p: &[Vec3]) -> Vec<Vec3> {
        let c = SWIM_SPEED / (2.0 * eta(self.diameter));
        let m = self.s.len();
        (0..p.len() * m)
            .into_par_iter()
            .map(|k| {
                let (n, j) = (k / m, k % m);
                p[n].map(|v| c * self.s[j].signum() * v)
            })
            .collect()
    }

    /// Velocities of the first `owned` rods from the flow `u` at their nodes: swimming plus
    /// the rigid-body projection of the flow.
    fn apply_flow(&self, p: &[Vec3], u: &[Vec3], out: &mut RodVelocities) {
        let owned = u.len() / self.s.len();
        let flow = flow_velocities(&p[..owned], u, (&self.s, &self.w));
        out.v[..owned]
            .par_iter_mut()
            .zip(out.w[..owned].par_iter_mut())
            .zip(flow.par_iter().zip(&p[..owned]))
            .for_each(|((v, w), ((dv, dw), pn))| {
                *v = [0, 1, 2].map(|d| SWIM_SPEED * pn[d] + dv[d]);
                *w = *dw;
            });
    }

    pub(crate) fn geometry(&self, box_length: f64) -> RpyGeometry {
        RpyGeometry {
            box_length,
            radius: self.radius,
            group: self.s.len(),
        }
    }

    /// The weighted forces `f(s_j) w_j` of the densities.
    fn weighted(&self, density: &[Vec3]) -> Vec<Vec3> {
        let m = self.s.len();
        density
            .par_iter()
            .enumerate()
            .map(|(k, f)| f.map(|v| v * self.w[k % m]))
            .collect()
    }
}

impl MobilityState for ExplicitSlender {
    fn sum_state(&self) -> Vec<u32> {
        crate::hydro::sum::adaptive_state(self.sum.as_ref(), self.shared.as_ref())
    }

    fn set_sum_state(&mut self, state: &[u32]) {
        crate::hydro::sum::set_adaptive_state(self.sum.as_mut(), self.shared.as_mut(), state);
    }
}

impl SharedMobility for ExplicitSlender {
    fn shared_reach(&self, total: usize, box_length: f64) -> f64 {
        // Node pairs within the cutoff; nodes lie within half a rod of their centres.
        self.shared.as_ref().map_or(0.0, |s| {
            s.preferred_rpy_reach(total * self.s.len(), box_length) + ROD_LENGTH
        })
    }

    fn predicted_velocities_shared(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
        part: Part<'_>,
    ) -> Result<(), MobilityError> {
        let m = self.s.len();
        let density = self.densities(p);
        let points = node_positions(&rods.x, p, &self.s);
        let weighted = self.weighted(&density);
        let geometry = self.geometry(rods.box_length);
        let t = Instant::now();
        let shared = self
            .shared
            .as_mut()
            .ok_or(MobilityError::NotShared("sbt-explicit"))?;
        // Copies reach `part.reach` beyond the slab from their centres; nodes lie within half
        // a rod of theirs.
        let counts = RankShare {
            owned: part.halo.owned * m,
            total: part.total * m,
            reach: part.reach - ROD_LENGTH,
        };
        let u = shared.rpy(part.comm, counts, &geometry, &points, &weighted)?;
        self.report = HydroReport {
            seconds_sums: t.elapsed().as_secs_f64(),
            ..HydroReport::default()
        };
        self.report.add_sum(shared.last_report());
        self.apply_flow(p, &u, out);
        self.density = density;
        Ok(())
    }
}

impl Mobility for ExplicitSlender {
    fn name(&self) -> &'static str {
        "sbt-explicit"
    }

    fn diameter(&self) -> f64 {
        self.diameter
    }

    fn on_ranks(&mut self) -> Option<&mut dyn SharedMobility> {
        if self.shared.is_some() {
            Some(self)
        } else {
            None
        }
    }

    fn resident(&mut self) -> Option<&mut dyn ResidentMobility> {
        Some(self)
    }

    fn free_velocities(
        &mut self,
        rods: &RodSet,
        p: &[Vec3],
        out: &mut RodVelocities,
    ) -> Result<(), MobilityError> {
        let density = self.densities(p);
        let points = node_positions(&rods.x, p, &self.s);
        let t = Instant::now();
        let u = self.sum.rpy(
            &self.geometry(rods.box_length),
            &points,
            &self.weighted(&density),
        )?;
        self.report = HydroReport {
            seconds_sums: t.elapsed().as_secs_f64(),
            ..HydroReport::default()
        };
        self.report.add_sum(self.sum.last_report());
        self.apply_flow(p, &u, out);
        self.density = density;
        Ok(())
    }

    fn density_for(&mut self, p: &[Vec3]) {
        self.density = self.densities(p);
    }

    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3) {
        self.local.local(p, f, t)
    }

    fn report(&self) -> HydroReport {
        self.report.clone()
    }

    fn force_density(&self) -> Option<ForceDensity<'_>> {
        Some(ForceDensity {
            s: &self.s,
            w: &self.w,
            f: &self.density,
        })
    }
}
