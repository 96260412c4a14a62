//! The particle run's state and files: initial configurations (random, perturbed, or read from
//! a snapshot or a text table, checked for overlaps) and the checkpoint codec.

use super::config::ParticleRunConfig;
use crate::io::snapshot::{Snapshot, read_snapshot};
use crate::io::{IoError, checkpoint, damaged};
use crate::run;
use crate::run::memory::{self, HostMemoryNeed};
use anyhow::{Context, bail};
use hdf5_pure::{AttrValue, FileBuilder};
use motile_meanfield::initial::PerturbationField;
use motile_particle::model::geometry::quat_from_axis;
use motile_particle::model::init::{
    nonoverlapping_with, overlapping_pairs, perturbed_orientation, random_nonoverlapping,
};
use motile_particle::model::rods::RodSet;
use motile_particle::step::contact::WarmStart;
use motile_particle::step::report::StepError;
use motile_particle::step::stepper::Stepper;
use std::path::Path;

/// Load an initial configuration of rods of diameter `diameter` from a snapshot (.h5) or a
/// text table, validated: unit orientations, and no two rods overlapping by more than
/// `overlap_tolerance` (rod lengths;
/// a run's own snapshots carry overlaps up to `contact.overlap_tolerance`, and rods at exactly
/// one diameter are in contact, not overlapping).
pub fn load_configuration(
    path: &Path,
    box_length: f64,
    diameter: f64,
    overlap_tolerance: f64,
) -> anyhow::Result<RodSet> {
    let (x, p, l): (Vec<[f64; 3]>, Vec<[f64; 3]>, f64) = if path
        .extension()
        .is_some_and(|e| e == "h5")
    {
        match read_snapshot(path)? {
            Snapshot::Particle(s) if (s.box_length - box_length).abs() <= 1e-9 * box_length => {
                (s.positions, s.orientations, box_length)
            }
            Snapshot::Particle(s) => bail!(
                "{}: a snapshot of a box of side {} l, the config's box_length is {box_length}: set box_length = {} to start from it",
                path.display(),
                s.box_length,
                s.box_length
            ),
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
        diameter,
        // Orientations are accepted within 1e-8 (HDF5) or 1e-6 (text) of unit length and
        // normalised here, so that the rods' quaternions are unit to round-off.
        q: p.iter()
            .map(|p| {
                let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                quat_from_axis(p.map(|c| c / n))
            })
            .collect(),
        image: vec![[0; 3]; x.len()],
        x: wrapped,
    };
    // No two rods may overlap.
    if let Err(e) = no_overlaps(&rods, diameter, overlap_tolerance) {
        bail!("{}: {e}", path.display());
    }
    Ok(rods)
}

/// No two of `rods` (of `diameter`) overlap by more than `tolerance`, or which do, in words.
fn no_overlaps(rods: &RodSet, diameter: f64, tolerance: f64) -> Result<(), String> {
    let bad = overlapping_pairs(rods, tolerance);
    match bad.first() {
        None => Ok(()),
        Some(&(i, j, dist)) => Err(format!(
            "rods {i} and {j} overlap by {:.2e} (centreline distance {dist:.4} < diameter {diameter}), more than contact.overlap_tolerance = {tolerance}; {} such pairs in all",
            diameter - dist,
            bad.len()
        )),
    }
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
    pub(super) fn of(rods: &RodSet, stepper: &Stepper, step: u64, time: f64) -> Self {
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
    /// added since are optional), for rods of diameter `diameter` (the run's config keeps it).
    pub fn read(path: &Path, diameter: f64) -> anyhow::Result<Self> {
        read_checkpoint(path, diameter)
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
    crate::io::format::stamp(&mut b);
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

fn read_checkpoint(path: &Path, diameter: f64) -> anyhow::Result<ParticleCheckpoint> {
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
        diameter,
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
    let index = |v: i64| u32::try_from(v).unwrap_or(u32::MAX);
    let warm = pairs
        .chunks_exact(2)
        .zip(lambda)
        .map(|(p, l)| ((index(p[0]), index(p[1])), l))
        .collect();
    // Absent in checkpoints of runs without hydrodynamics written before it existed.
    let hydro = if f.has("gmres_warm_start") {
        f.f64s("gmres_warm_start")?
    } else {
        Vec::new()
    };
    // Absent in checkpoints written before the accuracy contract: the sum starts at level 0.
    let sum_state = if f.has("sum_state") {
        f.i64s("sum_state")?
            .into_iter()
            .map(|v| u32::try_from(v).map_err(|_| damaged(path, format!("sum_state value {v}"))))
            .collect::<anyhow::Result<_>>()?
    } else {
        Vec::new()
    };
    let c = ParticleCheckpoint {
        rods,
        contact_warm_start: warm,
        gmres_warm_start: hydro,
        sum_state,
        step,
        time,
    };
    c.check_values(path)?;
    Ok(c)
}

/// Largest image counter a checkpoint may hold: a rod that crossed the box 2^40 times.
const MAX_IMAGE: i64 = 1 << 40;

impl ParticleCheckpoint {
    /// What every checkpoint motile writes satisfies: a positive box, finite centres within a
    /// box length of it, unit quaternions (to 1e-10 in |q|^2), image counters below 2^40,
    /// warm-start pairs of two different rods with finite, non-negative multipliers, a finite
    /// GMRES warm start, a finite non-negative time. A file that breaks one is refused by name
    /// before the run uses it.
    fn check_values(&self, path: &Path) -> anyhow::Result<()> {
        let (rods, l) = (&self.rods, self.rods.box_length);
        if !(l.is_finite() && l > 0.0) {
            return Err(damaged(path, format!("box_length {l}")));
        }
        if !(self.time.is_finite() && self.time >= 0.0) {
            return Err(damaged(path, format!("time {}", self.time)));
        }
        if rods.is_empty() {
            return Err(damaged(path, "no rods".into()));
        }
        for i in 0..rods.len() {
            let (x, q) = (rods.x[i], rods.q[i]);
            if !x.iter().all(|v| v.is_finite() && (-l..2.0 * l).contains(v)) {
                return Err(damaged(path, format!("rod {i} at {x:?}, box [0, {l})^3")));
            }
            let norm2: f64 = q.iter().map(|v| v * v).sum();
            let unit = (norm2 - 1.0).abs() <= 1e-10;
            if !unit {
                return Err(damaged(
                    path,
                    format!("rod {i}'s quaternion {q:?} is not a unit one"),
                ));
            }
            if rods.image[i].iter().any(|v| v.abs() > MAX_IMAGE) {
                return Err(damaged(
                    path,
                    format!("rod {i}'s image counters {:?}", rods.image[i]),
                ));
            }
        }
        let n = rods.len() as u32;
        if let Some(((a, b), w)) = self
            .contact_warm_start
            .iter()
            .find(|((a, b), w)| a >= &n || b >= &n || a == b || !(w.is_finite() && *w >= 0.0))
        {
            return Err(damaged(
                path,
                format!("warm-start pair ({a}, {b}) with multiplier {w} among {n} rods"),
            ));
        }
        if let Some(v) = self.gmres_warm_start.iter().find(|v| !v.is_finite()) {
            return Err(damaged(path, format!("gmres_warm_start holds {v}")));
        }
        Ok(())
    }
}

/// The rods a run starts from: random (seeded), drawn from a perturbation, or read from
/// `initial`.
pub fn initial_rods(cfg: &ParticleRunConfig) -> anyhow::Result<RodSet> {
    if cfg.initial == "perturbation" {
        let n = cfg.rod_count();
        let field = PerturbationField::new(&cfg.perturbation.perturbation());
        let peak = field.max_norm();
        if peak >= 2.0 / 15.0 {
            bail!(
                "perturbation.amplitude = {}: |Q'| reaches {peak:.3}, the orientation distribution (1 + (15/2) Q':pp)/4 pi turns negative beyond 2/15 = 0.133; lower the amplitude",
                cfg.perturbation.amplitude
            );
        }
        let l = cfg.box_length;
        return Ok(nonoverlapping_with(
            n,
            l,
            cfg.diameter,
            cfg.seed,
            200_000,
            |x, rng| perturbed_orientation(&field.eval(x.map(|c| c / l)), rng),
        )?);
    }
    if cfg.initial == "random" {
        let n = cfg.rod_count();
        Ok(random_nonoverlapping(
            n,
            cfg.box_length,
            cfg.diameter,
            cfg.seed,
            200_000,
        )?)
    } else {
        load_configuration(
            Path::new(&cfg.initial),
            cfg.box_length,
            cfg.diameter,
            cfg.contact.overlap_tolerance,
        )
    }
}

impl ParticleCheckpoint {
    /// Whether it belongs to a run of `cfg`: the config's box, and no two rods overlapping by
    /// more than contact.overlap_tolerance (a run's own checkpoints never do).
    pub(super) fn check_for(&self, cfg: &ParticleRunConfig, path: &Path) -> anyhow::Result<()> {
        let l = self.rods.box_length;
        if (l - cfg.box_length).abs() > 1e-12 * cfg.box_length {
            bail!(
                "{}: a checkpoint of a box of side {l} l, the run's config.toml says box_length = {}",
                path.display(),
                cfg.box_length
            );
        }
        // A run's own checkpoints overlap by at most contact.overlap_tolerance.
        no_overlaps(&self.rods, cfg.diameter, cfg.contact.overlap_tolerance)
            .map_err(|e| damaged(path, e))
    }
}

/// What a run checks before it allocates or writes anything, and all `--dry-run` checks
/// beyond the config's ranges: the memory a generated start needs on this machine, and the
/// file a start from a file reads (read and validated).
pub fn preflight(cfg: &ParticleRunConfig) -> anyhow::Result<()> {
    check_memory(cfg)?;
    if !generated(cfg) {
        initial_rods(cfg).with_context(|| format!("`initial` = {:?}", cfg.initial))?;
    }
    Ok(())
}

fn generated(cfg: &ParticleRunConfig) -> bool {
    cfg.initial == "random" || cfg.initial == "perturbation"
}

/// A generated start of more rods than this machine's memory holds is refused (one process on
/// the CPU; under MPI each rank holds a share, on a GPU the device's own check applies).
pub(super) fn check_memory(cfg: &ParticleRunConfig) -> anyhow::Result<()> {
    if generated(cfg) && cfg.device == run::Device::Cpu && run::ranks::world().is_none() {
        HostMemoryNeed::particle(cfg.rod_count())
            .check(memory::available())
            .map_err(|e| anyhow::anyhow!("config: {} rods: {e}", cfg.rod_count()))?;
    }
    Ok(())
}

/// What a failed device step leaves to resume from.
pub(super) struct FailedStep<'a> {
    /// The rods on the host (the state before the step where the flow's sum failed there).
    pub rods: &'a RodSet,
    pub stepper: &'a Stepper,
    /// The last step completed.
    pub step: u64,
    pub dt: f64,
    /// Whether the flow's sum runs on the device.
    pub resident_flow: bool,
}

/// The state before a failed device step, with the multipliers of the step before it (a failed
/// step keeps them). The device keeps the state before a failed step; a step that failed before
/// reaching it (the flow's sum) leaves the rods on the host as the last good state. A device
/// that failed may not answer: then no state is kept (`Some(Err)` says why), and the run names
/// the newest checkpoint instead.
pub(super) fn state_before_failure(
    d: &mut super::device::DeviceStepper,
    e: &StepError,
    failed: FailedStep,
) -> Result<Option<Result<ParticleCheckpoint, String>>, run::StepFailure> {
    let mut rods = failed.rods.clone();
    let kept = if !matches!(e, StepError::Hydrodynamics(_)) {
        d.download_before(&mut rods)
    } else if failed.resident_flow {
        // The flow's sum failed on the device, which kept the rods unmoved.
        d.download(&mut rods)
    } else {
        Ok(())
    };
    Ok(match kept.and_then(|()| d.warm_start()) {
        Ok(warm) => {
            let t = failed.step as f64 * failed.dt;
            let mut before = ParticleCheckpoint::of(&rods, failed.stepper, failed.step, t);
            before.contact_warm_start = warm;
            before.gmres_warm_start = failed.stepper.mobility().current_warm_state()?;
            Some(Ok(before))
        }
        Err(lost) => Some(Err(format!(
            "the device did not give back the state before the step: {lost}"
        ))),
    })
}
