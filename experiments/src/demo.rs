//! `motile demo`, part 2: a free-swimming suspension, the exact solution of the particle model with
//! hydrodynamics and contacts switched off (docs/MODEL.md §1: an isolated rod swims at U along p),
//! written as a particle run and analysed. It checks the analysis end to end against numbers
//! known exactly: the shot-noise level of a random configuration and the ballistic mean squared
//! displacement `(U t)^2`. Until the particle and mean-field solvers land, this is the
//! README's main job.

use crate::rundir::RunDir;
use crate::snapshot::{ParticleSnapshot, PointForces};
use motile_analysis::quadrature::gauss_legendre;
use motile_particle::init::isotropic_orientation;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Slender-body coefficient `eta = ln(2 l / b) / (4 pi mu)` with `b = l/5`, `mu = 1`.
pub const ETA: f64 = 0.183_233_998_581_6;

/// Configuration of the demo (written resolved to `config.toml`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct DemoConfig {
    /// Box side L/l. Default 16.
    pub box_length: f64,
    /// Effective volume fraction nu = N l^3 / L^3. Default 0.625 (dilute).
    pub volume_fraction: f64,
    /// Final time (1/beta). Default 4.
    pub t_end: f64,
    /// Number of snapshots, evenly spaced from 0 to t_end. Default 5.
    pub snapshots: usize,
    /// Random seed.
    pub seed: u64,
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            box_length: 16.0,
            volume_fraction: 0.625,
            t_end: 4.0,
            snapshots: 5,
            seed: 1,
        }
    }
}

impl DemoConfig {
    /// Number of rods, `round(nu (L/l)^3)`.
    pub fn rods(&self) -> usize {
        (self.volume_fraction * self.box_length.powi(3)).round() as usize
    }

    /// Check ranges.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.box_length >= 2.0 && self.box_length <= 1000.0) {
            return Err(format!(
                "box_length = {} is outside the allowed range [2, 1000] (rod lengths)",
                self.box_length
            ));
        }
        if !(self.volume_fraction > 0.0 && self.volume_fraction <= 10.0) {
            return Err(format!(
                "volume_fraction = {} is outside the allowed range (0, 10]",
                self.volume_fraction
            ));
        }
        if !(self.t_end > 0.0 && self.t_end.is_finite()) {
            return Err(format!("t_end = {} must be positive (1/beta)", self.t_end));
        }
        if !(2..=10_000).contains(&self.snapshots) {
            return Err(format!(
                "snapshots = {} is outside the allowed range [2, 10000]",
                self.snapshots
            ));
        }
        Ok(())
    }
}

/// Force-density points of a free swimmer: 2-point Gauss-Legendre on each half rod (exact for
/// the slip's jump, docs/MODEL.md §1), `f = (U / (2 eta)) sign(s) p`, weighted.
fn swimmer_forces(x: [f64; 3], p: [f64; 3], pts: &mut Vec<[f64; 3]>, f: &mut Vec<[f64; 3]>) {
    let (gx, gw) = gauss_legendre(2);
    for half in [-1.0, 1.0] {
        for (s0, w0) in gx.iter().zip(&gw) {
            let s = half * 0.25 * (1.0 + s0); // map [-1, 1] onto the half rod [0, 1/2] or [-1/2, 0]
            let w = 0.25 * w0;
            pts.push([0, 1, 2].map(|d| x[d] + s * p[d]));
            f.push(p.map(|pd| half / (2.0 * ETA) * pd * w));
        }
    }
}

/// Write the demo run to `out`.
pub fn write_demo_run(out: &Path, cfg: &DemoConfig) -> anyhow::Result<RunDir> {
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("demo config: {e}"))?;
    let run = RunDir::create(out, "particle", cfg.seed, cfg)?;
    let l = cfg.box_length;
    let n = cfg.rods();
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let x0: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let p: Vec<[f64; 3]> = (0..n).map(|_| isotropic_orientation(&mut rng)).collect();
    run.log(&format!(
        "demo: {n} free swimmers, L/l = {l}, nu = {}",
        cfg.volume_fraction
    ))?;
    for k in 0..cfg.snapshots {
        let t = cfg.t_end * k as f64 / (cfg.snapshots - 1) as f64;
        let mut positions = Vec::with_capacity(n);
        let mut image_counts = Vec::with_capacity(n);
        for (x, p) in x0.iter().zip(&p) {
            let raw = [0, 1, 2].map(|d| x[d] + p[d] * t);
            let img = raw.map(|r| (r / l).floor() as i64);
            positions.push(
                [0, 1, 2]
                    .map(|d| (raw[d] - l * img[d] as f64).clamp(0.0, l * (1.0 - f64::EPSILON))),
            );
            image_counts.push(img);
        }
        let (mut pts, mut f) = (Vec::new(), Vec::new());
        for (x, p) in positions.iter().zip(&p) {
            swimmer_forces(*x, *p, &mut pts, &mut f);
        }
        let snap = ParticleSnapshot {
            time: t,
            step: k as u64,
            box_length: l,
            positions,
            orientations: p.clone(),
            image_counts,
            forces: Some(PointForces {
                points: pts,
                forces: f,
            }),
            kinematics: None,
        };
        snap.write(&run.snapshot_path(k))?;
        run.log(&format!("wrote snapshot {k} at t = {t}"))?;
    }
    Ok(run)
}
