//! `motile particle run` and resume: drives the particle model's [`Stepper`] and owns what the
//! model must not: the run directory, the output schedule, snapshots (HDF5 + VTK), the time
//! series, checkpoints and progress.
//!
//! Checkpoints (`checkpoints/ckpt_STEP.h5` with a checksum sidecar, the last few kept) hold the exact rod state (centres,
//! quaternions, image counters) and the step number; the step has no other state, so resuming
//! from one continues the trajectory bit for bit. On a failed step the state before it is saved
//! as `checkpoints/last_good.h5` and the error names it.

use crate::checkpoint;
use crate::io::IoError;
use crate::run;
use crate::rundir::{RunDir, parse_run_config, range};
use crate::snapshot::{Kinematics, ParticleSnapshot, PointForces, Snapshot, read_snapshot};
use crate::vtk::{write_pvd, write_rods_vtp};
use anyhow::{Context, bail};
use hdf5_pure::{AttrValue, FileBuilder};
use motile_analysis::correlation::{CorrelationOptions, velocity_spectrum};
use motile_meanfield::initial::PerturbationField;
use motile_particle::cells::CellList;
use motile_particle::contact::WarmStart;
use motile_particle::dipole::Dipole;
use motile_particle::geometry::{axpy, quat_from_axis, segment_distance};
use motile_particle::gmres::GmresParams;
use motile_particle::init::{nonoverlapping_with, perturbed_orientation, random_nonoverlapping};
use motile_particle::slender::{SlenderBody, SlenderParams};
use motile_particle::spectral_ewald::SpectralEwald;
use motile_particle::units::{DIAMETER, ROD_LENGTH, SWIM_SPEED, VISCOSITY};
use motile_particle::{ContactParams, Hydrodynamics, LocalDrag, Mobility, RodSet, Stepper};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

/// Configuration of a particle run (`config.toml`), every field with its default.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ParticleRunConfig {
    /// Box side L/l. Default 10; allowed [2, 1000].
    pub box_length: f64,
    /// Effective volume fraction nu = N l^3 / L^3 for a random start. Default 0.625 (dilute);
    /// allowed (0, 6] (random sequential addition stalls a little above 5).
    pub volume_fraction: f64,
    /// Number of rods N for a random start; when set it replaces `volume_fraction`
    /// (nu = N / (L/l)^3 must still lie in (0, 6]). Default: unset.
    pub rods: Option<usize>,
    /// Time step, 1/beta. Default 0.002; allowed (0, 0.05]. Larger steps leave larger
    /// overlaps (of order (dt w)^2 l) and need a larger contact.margin.
    pub dt: f64,
    /// End time, 1/beta. Default 2.
    pub t_end: f64,
    /// Random seed of the initial configuration. Default 1.
    pub seed: u64,
    /// Hydrodynamic coupling: "none" (free swimming with local drag, no flow), "dipole" (point
    /// stresslets moved by the periodic flow, docs/MODEL.md §2: one fast sum per step) or "sbt"
    /// (slender-body theory, docs/MODEL.md §1: a GMRES solve per step, several fast sums each).
    /// Default "none".
    pub hydrodynamics: Hydrodynamics,
    /// Settings of the hydrodynamic models.
    pub hydro: HydroConfig,
    /// "random" (isotropic), "perturbation" (orientations drawn from
    /// `Psi = (1 + (15/2) Q'(x) : pp) / 4 pi` with `Q'` from `[perturbation]`: the mean-field
    /// model's initial field, docs/MODEL.md §5), or a file: a particle snapshot (.h5) or a text table
    /// with one rod per line, `x y z px py pz`.
    pub initial: String,
    /// The perturbation of `initial = "perturbation"`.
    pub perturbation: PerturbationConfig,
    /// Time between time-series rows, 1/beta. Default 0.02.
    pub diagnostic_interval: f64,
    /// Time between snapshots, 1/beta. Default 0.2.
    pub snapshot_interval: f64,
    /// Time between checkpoints, 1/beta. Default 0.5.
    pub checkpoint_interval: f64,
    /// Also checkpoint when this much wall-clock time has passed since the last one, seconds.
    /// Default 900; allowed (0, 1e7].
    pub checkpoint_wall_seconds: f64,
    /// Regular checkpoints kept (older ones are deleted). Default 3; allowed [1, 1000].
    pub checkpoints_kept: usize,
    /// Write a VTK PolyData file (.vtp) with each snapshot, and a .pvd index. Default true.
    pub vtk: bool,
    /// Contact solver settings.
    pub contact: ContactParams,
}

impl Default for ParticleRunConfig {
    fn default() -> Self {
        Self {
            box_length: 10.0,
            volume_fraction: 0.625,
            rods: None,
            dt: 0.002,
            t_end: 2.0,
            seed: 1,
            hydrodynamics: Hydrodynamics::None,
            hydro: HydroConfig::default(),
            initial: "random".into(),
            perturbation: PerturbationConfig::default(),
            diagnostic_interval: 0.02,
            snapshot_interval: 0.2,
            checkpoint_interval: 0.5,
            checkpoint_wall_seconds: 900.0,
            checkpoints_kept: 3,
            vtk: true,
            contact: ContactParams::default(),
        }
    }
}

/// A perturbation of the isotropic state (`[perturbation]`), the same keys and function as a
/// mean-field run's initial field (`initial`, `amplitude`, `mode_min`, `mode_max`, `seed`,
/// `wavevector`), on the particle box scaled to the unit box.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PerturbationConfig {
    /// "random" (modes with `|m|` in `[mode_min, mode_max]`, random traceless amplitudes and
    /// phases) or "plane_wave" (`Q'_xy = amplitude cos(2 pi m . x / L)`). Default "random".
    pub kind: String,
    /// Largest component of `Q'`. Default 0.02; allowed (0, 0.1] (the distribution must stay
    /// positive: `|Q'|_F < 2/15` everywhere, checked).
    pub amplitude: f64,
    /// Smallest integer wavenumber. Default 1.
    pub mode_min: usize,
    /// Largest integer wavenumber. Default 2.
    pub mode_max: usize,
    /// Seed of the amplitudes and phases (not of the rods: that is the run's `seed`). Default 1.
    pub seed: u64,
    /// Plane wave's integer wavevector. Default [1, 0, 0].
    pub wavevector: [i64; 3],
}

impl Default for PerturbationConfig {
    fn default() -> Self {
        Self {
            kind: "random".into(),
            amplitude: 0.02,
            mode_min: 1,
            mode_max: 2,
            seed: 1,
            wavevector: [1, 0, 0],
        }
    }
}

impl PerturbationConfig {
    /// The perturbation (the mean-field library's description of it).
    pub fn perturbation(&self) -> motile_meanfield::initial::Perturbation {
        use motile_meanfield::initial::Perturbation;
        if self.kind == "plane_wave" {
            Perturbation::PlaneWave {
                amplitude: self.amplitude,
                wavevector: self.wavevector,
            }
        } else {
            Perturbation::Random {
                amplitude: self.amplitude,
                mode_min: self.mode_min,
                mode_max: self.mode_max,
                seed: self.seed,
            }
        }
    }

    fn validate(&self) -> Result<(), String> {
        if !["random", "plane_wave"].contains(&self.kind.as_str()) {
            return Err(format!(
                "perturbation.kind = \"{}\": allowed \"random\" or \"plane_wave\"",
                self.kind
            ));
        }
        range(
            "perturbation.amplitude",
            self.amplitude,
            0.0,
            0.1,
            true,
            "largest component of Q'",
        )?;
        if self.mode_min < 1 || self.mode_min > self.mode_max || self.mode_max > 16 {
            return Err(format!(
                "perturbation.mode_min = {}, mode_max = {}: need 1 <= mode_min <= mode_max <= 16",
                self.mode_min, self.mode_max
            ));
        }
        if self.kind == "plane_wave" && self.wavevector == [0, 0, 0] {
            return Err("perturbation.wavevector = [0, 0, 0]: a plane wave needs m != 0".into());
        }
        Ok(())
    }
}

/// Settings of the hydrodynamic models (`[hydro]`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct HydroConfig {
    /// Relative tolerance of the periodic RPY / stresslet sums (spectral Ewald): the largest
    /// error of each output over all rods, and its L2 norm, at most this fraction of the
    /// output's (docs/accuracy.md). Default 1e-4; allowed [1e-10, 1e-1]. Smaller costs more
    /// real-space pairs and Fourier modes; force-free (swimming) data cost more than random
    /// forces at the same tolerance, since their flows are weaker than their forces.
    pub sum_tolerance: f64,
    /// Quadrature nodes per rod for "sbt", even (Gauss-Legendre on each half rod). Default 4;
    /// allowed 2..=64. Cost grows linearly; error falls fast (see BENCHMARKS.md).
    pub quadrature_points: usize,
    /// GMRES relative residual tolerance for "sbt". Default 1e-5; allowed [1e-14, 1e-1].
    pub gmres_tolerance: f64,
    /// GMRES iteration cap; a solve that reaches it stops the run. Default 100; allowed
    /// [1, 10000].
    pub gmres_max_iterations: usize,
    /// GMRES restart length. Default 40; allowed [1, 1000].
    pub gmres_restart: usize,
    /// RPY radius a (rod lengths). Default (sqrt 3/2)(b/2) = 0.0866; allowed (0, 0.5].
    pub rpy_radius: f64,
}

impl Default for HydroConfig {
    /// The library's defaults ([`SlenderParams`], [`GmresParams`]): one source for each.
    fn default() -> Self {
        let s = SlenderParams::default();
        Self {
            sum_tolerance: 1e-4,
            quadrature_points: s.quadrature_points,
            gmres_tolerance: s.gmres.tol,
            gmres_max_iterations: s.gmres.max_iterations,
            gmres_restart: s.gmres.restart,
            rpy_radius: s.rpy_radius,
        }
    }
}

impl HydroConfig {
    fn validate(&self) -> Result<(), String> {
        range(
            "hydro.sum_tolerance",
            self.sum_tolerance,
            1e-10,
            1e-1,
            false,
            "relative",
        )?;
        range(
            "hydro.gmres_tolerance",
            self.gmres_tolerance,
            1e-14,
            1e-1,
            false,
            "relative",
        )?;
        range(
            "hydro.rpy_radius",
            self.rpy_radius,
            0.0,
            0.5,
            true,
            "rod lengths",
        )?;
        let q = self.quadrature_points;
        if !(2..=64).contains(&q) || q % 2 == 1 {
            return Err(format!(
                "hydro.quadrature_points = {q} must be even and in [2, 64] (nodes per rod)"
            ));
        }
        for (name, v, hi) in [
            (
                "hydro.gmres_max_iterations",
                self.gmres_max_iterations,
                10_000,
            ),
            ("hydro.gmres_restart", self.gmres_restart, 1000),
        ] {
            if !(1..=hi).contains(&v) {
                return Err(format!(
                    "{name} = {v} is outside the allowed range [1, {hi}] (iterations)"
                ));
            }
        }
        Ok(())
    }
}

impl ParticleRunConfig {
    /// Make a relative `initial` file name relative to `base` (the folder of the config file
    /// it came from) instead of the working directory.
    pub fn resolve_paths(&mut self, base: &Path) {
        if !["random", "perturbation"].contains(&self.initial.as_str())
            && Path::new(&self.initial).is_relative()
        {
            let p = base.join(&self.initial);
            self.initial = std::path::absolute(&p)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned();
        }
    }

    /// Check every field; the message names the field, the value, the range and the unit.
    pub fn validate(&self) -> Result<(), String> {
        range(
            "box_length",
            self.box_length,
            2.0,
            1000.0,
            false,
            "rod lengths",
        )?;
        range(
            "volume_fraction",
            self.volume_fraction,
            0.0,
            6.0,
            true,
            "N l^3 / L^3",
        )?;
        range("dt", self.dt, 0.0, 0.05, true, "1/beta")?;
        self.perturbation.validate()?;
        range("t_end", self.t_end, 0.0, 1e9, true, "1/beta")?;
        for (name, v) in [
            ("diagnostic_interval", self.diagnostic_interval),
            ("snapshot_interval", self.snapshot_interval),
            ("checkpoint_interval", self.checkpoint_interval),
        ] {
            range(name, v, self.dt, 1e9, false, "1/beta, at least dt")?;
        }
        range(
            "checkpoint_wall_seconds",
            self.checkpoint_wall_seconds,
            0.0,
            1e7,
            true,
            "seconds of wall-clock time",
        )?;
        range(
            "checkpoints_kept",
            self.checkpoints_kept as f64,
            1.0,
            1000.0,
            false,
            "files",
        )?;
        range(
            "contact.margin",
            self.contact.margin,
            0.0,
            1.0,
            true,
            "rod lengths",
        )?;
        range(
            "contact.tolerance",
            self.contact.tolerance,
            0.0,
            1e-2,
            true,
            "rod lengths",
        )?;
        range(
            "contact.max_iterations",
            self.contact.max_iterations as f64,
            1.0,
            1e7,
            false,
            "iterations",
        )?;
        range(
            "contact.overlap_tolerance",
            self.contact.overlap_tolerance,
            0.0,
            0.1,
            true,
            "rod lengths",
        )?;
        self.hydro.validate()?;
        if let Some(n) = self.rods {
            let nu = n as f64 / self.box_length.powi(3);
            if n == 0 || nu > 6.0 {
                return Err(format!(
                    "rods = {n} in a box of L/l = {} gives nu = N l^3/L^3 = {nu}, outside the allowed range (0, 6]",
                    self.box_length
                ));
            }
        }
        if self.contact.margin < 2.5 * self.dt {
            return Err(format!(
                "contact.margin = {} is smaller than the distance two rods close in one step (2 U dt = {}): raise it above {}",
                self.contact.margin,
                2.0 * self.dt,
                2.5 * self.dt
            ));
        }
        Ok(())
    }

    /// Steps between events of an interval.
    fn every(&self, interval: f64) -> u64 {
        ((interval / self.dt).round() as u64).max(1)
    }

    /// Total steps.
    pub fn total_steps(&self) -> u64 {
        (self.t_end / self.dt).round() as u64
    }
}

/// Parse a `config.toml` (with or without the `[motile]` header table).
pub fn parse_config(text: &str, path: &Path) -> anyhow::Result<ParticleRunConfig> {
    parse_run_config(text, path, ParticleRunConfig::validate)
}

/// The mobility named by `hydrodynamics` (validated).
fn mobility(cfg: &ParticleRunConfig) -> anyhow::Result<Box<dyn Mobility>> {
    let h = &cfg.hydro;
    let sum = || SpectralEwald::new(h.sum_tolerance).map(Box::new);
    Ok(match cfg.hydrodynamics {
        Hydrodynamics::Dipole => Box::new(Dipole::new(sum()?)),
        Hydrodynamics::Sbt => Box::new(SlenderBody::new(
            SlenderParams {
                quadrature_points: h.quadrature_points,
                rpy_radius: h.rpy_radius,
                gmres: GmresParams {
                    tol: h.gmres_tolerance,
                    restart: h.gmres_restart,
                    max_iterations: h.gmres_max_iterations,
                },
            },
            sum()?,
        )),
        Hydrodynamics::None => Box::new(LocalDrag::default()),
    })
}

/// Load an initial configuration from a snapshot (.h5) or a text table, validated: unit
/// orientations, and no two rods overlapping by more than `overlap_tolerance` (rod lengths;
/// a run's own snapshots carry overlaps up to `contact.overlap_tolerance`, and rods at exactly
/// one diameter are in contact, not overlapping).
pub fn load_configuration(
    path: &Path,
    box_length: f64,
    overlap_tolerance: f64,
) -> anyhow::Result<RodSet> {
    let (x, p, l): (Vec<[f64; 3]>, Vec<[f64; 3]>, f64) = if path
        .extension()
        .is_some_and(|e| e == "h5")
    {
        match read_snapshot(path)? {
            Snapshot::Particle(s) => (s.positions, s.orientations, s.box_length),
            Snapshot::Field(_) => bail!(
                "{}: a mean-field snapshot, not a particle configuration",
                path.display()
            ),
        }
    } else {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        let mut x = Vec::new();
        let mut p = Vec::new();
        for (k, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let v: Result<Vec<f64>, _> = line.split_whitespace().map(str::parse::<f64>).collect();
            let v = v.map_err(|e| anyhow::anyhow!("{}: line {}: {e}", path.display(), k + 1))?;
            if v.len() != 6 || !v.iter().all(|c| c.is_finite()) {
                bail!(
                    "{}: line {}: expected 6 finite numbers `x y z px py pz`, got {:?}",
                    path.display(),
                    k + 1,
                    line
                );
            }
            let n = (v[3] * v[3] + v[4] * v[4] + v[5] * v[5]).sqrt();
            if (n - 1.0).abs() > 1e-6 {
                bail!(
                    "{}: line {}: orientation ({}, {}, {}) is not a unit vector (|p| = {n})",
                    path.display(),
                    k + 1,
                    v[3],
                    v[4],
                    v[5]
                );
            }
            x.push([v[0], v[1], v[2]]);
            p.push([v[3], v[4], v[5]]);
        }
        (x, p, box_length)
    };
    if x.is_empty() {
        bail!("{}: no rods", path.display());
    }
    // Centres are wrapped into the box, but one far outside it means the file was written for
    // another box size.
    if let Some(i) = x
        .iter()
        .position(|c| c.iter().any(|&v| v < -l || v >= 2.0 * l))
    {
        bail!(
            "{}: rod {i} at {:?} lies more than a box length outside the box [0, {l})^3: was the file written for another box_length?",
            path.display(),
            x[i]
        );
    }
    let wrapped: Vec<[f64; 3]> = x
        .iter()
        .map(|c| {
            c.map(|v| v - l * (v / l).floor())
                .map(|v| if v >= l { 0.0 } else { v })
        })
        .collect();
    let rods = RodSet {
        box_length: l,
        q: p.iter().map(|p| quat_from_axis(*p)).collect(),
        image: vec![[0; 3]; x.len()],
        x: wrapped,
    };
    // No two rods may overlap.
    let reach = ROD_LENGTH + DIAMETER;
    let cells = CellList::build(&rods.x, l, reach);
    let po = rods.orientations();
    let bad = cells.map_pairs(&rods.x, reach, |i, j, d| {
        let (_, _, dist) = segment_distance(
            rods.x[i as usize],
            po[i as usize],
            axpy(rods.x[i as usize], 1.0, d),
            po[j as usize],
            ROD_LENGTH,
        );
        (dist < DIAMETER - overlap_tolerance).then_some((i.min(j), i.max(j), dist))
    });
    if let Some((i, j, dist)) = bad.iter().min_by_key(|b| (b.0, b.1)) {
        bail!(
            "{}: rods {i} and {j} overlap by {:.2e} (centerline distance {dist:.4} < diameter {DIAMETER}), more than contact.overlap_tolerance = {overlap_tolerance}; {} such pairs in all",
            path.display(),
            DIAMETER - dist,
            bad.len()
        );
    }
    Ok(rods)
}

/// What a particle checkpoint holds: the rods (centres, quaternions, image counters), the step
/// and time, and the solvers' warm starts, so a resumed run continues bit for bit.
#[derive(Clone, Debug)]
pub struct ParticleCheckpoint {
    /// The rods.
    pub rods: RodSet,
    /// The contact multipliers of the last step, keyed by rod pair (the next solve's warm start).
    pub contact_warm_start: WarmStart,
    /// The slender-body solve's force densities (GMRES warm start); empty for other levels.
    pub gmres_warm_start: Vec<f64>,
    /// The fast sum's refinement level and calm count (docs/accuracy.md); empty without one.
    pub sum_state: Vec<u32>,
    /// Step number.
    pub step: u64,
    /// Time, 1/beta.
    pub time: f64,
}

impl ParticleCheckpoint {
    /// The checkpoint of `stepper` holding `rods` at `step`.
    fn of(rods: &RodSet, stepper: &Stepper, step: u64, time: f64) -> Self {
        Self {
            rods: rods.clone(),
            contact_warm_start: stepper.warm_start().to_vec(),
            gmres_warm_start: stepper.mobility().warm_state(),
            sum_state: stepper.mobility().sum_state(),
            step,
            time,
        }
    }

    /// Write as HDF5 with a checksum sidecar.
    pub fn write(&self, path: &Path) -> Result<(), IoError> {
        write_checkpoint(
            path,
            &self.rods,
            &self.contact_warm_start,
            (&self.gmres_warm_start, &self.sum_state),
            self.step,
            self.time,
        )
    }

    /// Read one written by [`ParticleCheckpoint::write`] (or by earlier versions: datasets
    /// added since are optional).
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        read_checkpoint(path)
    }
}

fn write_checkpoint(
    path: &Path,
    rods: &RodSet,
    warm: &[((u32, u32), f64)],
    (hydro, sum_state): (&[f64], &[u32]),
    step: u64,
    time: f64,
) -> Result<(), IoError> {
    let n = rods.len() as u64;
    let mut b = FileBuilder::new();
    b.set_attr(
        "kind",
        AttrValue::VarLenString("particle_checkpoint".into()),
    );
    b.set_attr("step", AttrValue::U64(step));
    b.set_attr("time", AttrValue::F64(time));
    b.set_attr("box_length", AttrValue::F64(rods.box_length));
    let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
    b.create_dataset("positions")
        .with_f64_data(&flat(&rods.x))
        .with_shape(&[n, 3]);
    b.create_dataset("quaternions")
        .with_f64_data(&rods.q.iter().flatten().copied().collect::<Vec<_>>())
        .with_shape(&[n, 4]);
    b.create_dataset("image_counts")
        .with_i64_data(&rods.image.iter().flatten().copied().collect::<Vec<_>>())
        .with_shape(&[n, 3]);
    // The contact multipliers of the last step (the next solve's warm start).
    let pairs: Vec<i64> = warm
        .iter()
        .flat_map(|((a, b), _)| [*a as i64, *b as i64])
        .collect();
    let lambda: Vec<f64> = warm.iter().map(|w| w.1).collect();
    b.create_dataset("warm_pairs")
        .with_i64_data(&pairs)
        .with_shape(&[warm.len() as u64, 2]);
    b.create_dataset("warm_lambda")
        .with_f64_data(&lambda)
        .with_shape(&[warm.len() as u64]);
    // The hydrodynamic solver's warm start (slender-body force densities), possibly empty.
    b.create_dataset("gmres_warm_start")
        .with_f64_data(hydro)
        .with_shape(&[hydro.len() as u64]);
    // The fast sum's refinement level and calm count (docs/accuracy.md), possibly empty.
    let sum_state: Vec<i64> = sum_state.iter().map(|&v| v as i64).collect();
    b.create_dataset("sum_state")
        .with_i64_data(&sum_state)
        .with_shape(&[sum_state.len() as u64]);
    let bytes = b.finish().map_err(|e| IoError::Hdf5 {
        path: path.into(),
        message: e.to_string(),
    })?;
    checkpoint::write_verified(path, &bytes)
}

fn read_checkpoint(path: &Path) -> anyhow::Result<ParticleCheckpoint> {
    let f = checkpoint::H5Reader::open(path)?;
    let step = f.attr_u64("step")?;
    let time = f.attr_f64("time")?;
    let box_length = f.attr_f64("box_length")?;
    let read = |name: &str| f.f64s(name);
    let x = read("positions")?;
    let q = read("quaternions")?;
    let im = f.i64s("image_counts")?;
    let n = x.len() / 3;
    if q.len() != 4 * n || im.len() != 3 * n {
        bail!(
            "{}: datasets disagree on the number of rods",
            path.display()
        );
    }
    let rods = RodSet {
        box_length,
        x: x.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        q: q.chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
        image: im.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    };
    let pairs = f.i64s("warm_pairs")?;
    let lambda = read("warm_lambda")?;
    if pairs.len() != 2 * lambda.len() {
        bail!(
            "{}: warm_pairs and warm_lambda disagree in length",
            path.display()
        );
    }
    let warm = pairs
        .chunks_exact(2)
        .zip(lambda)
        .map(|(p, l)| ((p[0] as u32, p[1] as u32), l))
        .collect();
    // Absent in checkpoints of runs without hydrodynamics written before it existed.
    let hydro = if f.has("gmres_warm_start") {
        f.f64s("gmres_warm_start")?
    } else {
        Vec::new()
    };
    // Absent in checkpoints written before the accuracy contract: the sum starts at level 0.
    let sum_state = if f.has("sum_state") {
        f.i64s("sum_state")?.into_iter().map(|v| v as u32).collect()
    } else {
        Vec::new()
    };
    Ok(ParticleCheckpoint {
        rods,
        contact_warm_start: warm,
        gmres_warm_start: hydro,
        sum_state,
        step,
        time,
    })
}

/// Columns of a particle run's `timeseries.csv`.
pub const COLUMNS: [&str; 19] = [
    "t [1/beta]",
    "steps_per_second [1/s]",
    "constraints [1]",
    "active_contacts [1]",
    "solver_iterations [1]",
    "solver_residual [l]",
    "max_overlap [l]",
    "mean_speed [beta l]",
    "polar_order [1]",
    "gmres_iterations [1]",
    "gmres_residual [1]",
    "velocity_norm [beta L]",
    "max_speed [beta l]",
    "max_rotation_rate [beta]",
    "contact_corrections [1]",
    "projections [1]",
    "sum_error_estimate [tol]",
    "sum_level [1]",
    "velocity_norm_box [beta L]",
];

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

/// The rods a run starts from: random (seeded), drawn from a perturbation, or read from
/// `initial`.
pub fn initial_rods(cfg: &ParticleRunConfig) -> anyhow::Result<RodSet> {
    if cfg.initial == "perturbation" {
        let n = cfg
            .rods
            .unwrap_or((cfg.volume_fraction * cfg.box_length.powi(3)).round() as usize);
        let field = PerturbationField::new(&cfg.perturbation.perturbation());
        let peak = field.max_norm();
        if peak >= 2.0 / 15.0 {
            bail!(
                "perturbation.amplitude = {}: |Q'| reaches {peak:.3}, the orientation distribution (1 + (15/2) Q':pp)/4 pi turns negative beyond 2/15 = 0.133; lower the amplitude",
                cfg.perturbation.amplitude
            );
        }
        let l = cfg.box_length;
        return Ok(nonoverlapping_with(n, l, cfg.seed, 200_000, |x, rng| {
            perturbed_orientation(&field.eval(x.map(|c| c / l)), rng)
        })?);
    }
    if cfg.initial == "random" {
        let n = cfg
            .rods
            .unwrap_or((cfg.volume_fraction * cfg.box_length.powi(3)).round() as usize);
        Ok(random_nonoverlapping(n, cfg.box_length, cfg.seed, 200_000)?)
    } else {
        load_configuration(
            Path::new(&cfg.initial),
            cfg.box_length,
            cfg.contact.overlap_tolerance,
        )
    }
}

/// Start a new particle run in `out`.
pub fn run_particle(
    cfg: &ParticleRunConfig,
    out: &Path,
    progress: bool,
) -> anyhow::Result<RunSummary> {
    let (model, s) = run::start::<ParticleModel>(cfg, out, progress)?;
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
    /// The state before a failed step (the last good state to save).
    before: Option<ParticleCheckpoint>,
    window: (Instant, u64),
    notes: Vec<String>,
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
        Ok(Self {
            cfg: cfg.clone(),
            rods,
            stepper,
            step,
            total: cfg.total_steps(),
            every,
            pvd,
            warned_accuracy: false,
            before: None,
            window: (Instant::now(), 0),
            notes: Vec::new(),
        })
    }

    fn summary(self, s: &run::LoopSummary) -> RunSummary {
        RunSummary {
            steps: s.steps,
            final_step: self.step,
            seconds: s.seconds,
            rods: self.rods,
        }
    }

    fn checkpoint_to(&self, path: &Path) -> anyhow::Result<()> {
        let t = self.step as f64 * self.cfg.dt;
        ParticleCheckpoint::of(&self.rods, &self.stepper, self.step, t).write(path)?;
        Ok(())
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

    fn read_checkpoint(_cfg: &ParticleRunConfig, path: &Path) -> anyhow::Result<Self::Checkpoint> {
        ParticleCheckpoint::read(path)
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
        write_snapshot(&self.cfg, _io.run, &self.rods, 0, None, None, &mut self.pvd)?;
        Ok(true)
    }

    fn checkpoint_due_before_step(&mut self) -> bool {
        false
    }

    fn step(&mut self, io: &mut run::RunIo) -> Result<(), run::StepFailure> {
        let step = self.step + 1;
        let cfg = &self.cfg;
        let before = ParticleCheckpoint::of(&self.rods, &self.stepper, self.step, self.time());
        let report = match self.stepper.step(&mut self.rods, cfg.dt) {
            Ok(r) => r,
            Err(e) => {
                self.before = Some(before);
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
        let t = step as f64 * cfg.dt;
        if !self.warned_accuracy && report.hydro.sums > 0 && !report.hydro.sum_tolerance_met {
            // Never silent: the finest level of the fast sum could not meet the tolerance.
            self.warned_accuracy = true;
            let msg = format!(
                "warning: at step {step} (t = {t:.4}) the fast sum's estimated error is {:.1} times hydro.sum_tolerance = {:e} even at its finest setting; results carry that error (see docs/accuracy.md; `motile check-accuracy {}` measures it). Said once per run",
                report.hydro.sum_error_ratio,
                cfg.hydro.sum_tolerance,
                io.run.path().display()
            );
            io.log(&msg)?;
            io.bar.println(&msg);
        }
        let (diag, snap, _) = self.every;
        if step.is_multiple_of(diag) {
            let rate = self.window.1 as f64 / self.window.0.elapsed().as_secs_f64().max(1e-9);
            self.window = (Instant::now(), 0);
            let c = &report.contact;
            let norms = velocity_norms(&self.stepper, &before.rods)?;
            io.push_row(vec![
                t,
                rate,
                c.constraints as f64,
                c.active as f64,
                c.iterations as f64,
                c.residual,
                report.max_overlap,
                report.mean_speed,
                report.polar_order,
                report.hydro.gmres_iterations as f64,
                report.hydro.gmres_residual,
                norms.0,
                report.max_speed,
                report.max_rotation_rate,
                report.correction_active as f64,
                report.projections as f64,
                report.hydro.sum_error_ratio,
                report.hydro.sum_level as f64,
                norms.1,
            ])?;
            io.bar.set_message(format!(
                "t = {t:.3}, {rate:.1} steps/s, {} contacts, max overlap {:.1e}",
                c.active, report.max_overlap
            ));
        }
        if step.is_multiple_of(snap) {
            let kin = Kinematics {
                velocities: self.stepper.velocities().v.clone(),
                angular_velocities: self.stepper.velocities().w.clone(),
                contact_forces: self.stepper.contact_forces().to_vec(),
            };
            let forces = self.stepper.mobility().force_density().map(|fd| {
                let (points, forces) = fd.point_forces(&before.rods, &before.rods.orientations());
                PointForces { points, forces }
            });
            write_snapshot(
                cfg,
                io.run,
                &self.rods,
                step,
                Some(kin),
                forces,
                &mut self.pvd,
            )?;
        }
        Ok(())
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

    fn write_checkpoint(&self, path: &Path) -> anyhow::Result<()> {
        self.checkpoint_to(path)
    }

    fn write_last_good(&self, path: &Path) -> anyhow::Result<()> {
        self.before
            .as_ref()
            .context("no failed step: nothing to save as the last good state")?
            .write(path)?;
        Ok(())
    }
}

/// `||u||_2 / (beta L)` of the step's force density (docs/MODEL.md §5, §6: the velocity spectrum on
/// `floor(L/2)` modes per dimension, doublet neglected); 0 for models without flow.
/// The flow's volume-averaged L2 norm from the velocity spectrum of the force density, over
/// the analysis modes and over the box-scale modes alone (every `|m_i| <= 1`: wavelengths of
/// one box and more, where the instability begins), both in units of `beta L`.
fn velocity_norms(stepper: &Stepper, at: &RodSet) -> anyhow::Result<(f64, f64)> {
    let Some(fd) = stepper.mobility().force_density() else {
        return Ok((0.0, 0.0));
    };
    let (points, forces) = fd.point_forces(at, &at.orientations());
    let l = at.box_length;
    let modes = CorrelationOptions::default().modes_for(l);
    let spectrum = velocity_spectrum(&points, &forces, l, VISCOSITY, modes, 1e-6)?;
    let power = spectrum.power();
    let box_scale: f64 = power
        .iter()
        .enumerate()
        .filter(|(idx, _)| {
            [idx % modes, (idx / modes) % modes, idx / (modes * modes)]
                .iter()
                .all(|&i| motile_analysis::nufft::mode_of(i, modes).abs() <= 1)
        })
        .map(|(_, p)| p)
        .sum();
    let unit = SWIM_SPEED / ROD_LENGTH * l;
    Ok((spectrum.l2_norm() / unit, box_scale.sqrt() / unit))
}

fn write_snapshot(
    cfg: &ParticleRunConfig,
    run: &RunDir,
    rods: &RodSet,
    step: u64,
    kin: Option<Kinematics>,
    forces: Option<PointForces>,
    pvd: &mut Vec<(f64, String)>,
) -> anyhow::Result<()> {
    let k = (step / cfg.every(cfg.snapshot_interval)) as usize;
    let t = step as f64 * cfg.dt;
    let p = rods.orientations();
    let speed: Vec<f64> = match &kin {
        Some(k) => k
            .velocities
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .collect(),
        None => vec![0.0; rods.len()],
    };
    let snap = ParticleSnapshot {
        time: t,
        step,
        box_length: rods.box_length,
        positions: rods.x.clone(),
        orientations: p.clone(),
        image_counts: rods.image.clone(),
        forces,
        kinematics: kin,
    };
    snap.write(&run.snapshot_path(k))?;
    if cfg.vtk {
        let name = format!("vtk/rods_{k:06}.vtp");
        write_rods_vtp(
            &run.path().join(&name),
            &rods.x,
            &p,
            ROD_LENGTH,
            DIAMETER / 2.0,
            &speed,
        )?;
        pvd.retain(|(_, f)| *f != name);
        pvd.push((t, name));
        write_pvd(&run.path().join("rods.pvd"), pvd)?;
    }
    Ok(())
}
