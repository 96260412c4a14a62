//! The readers a user reaches, each fed a damaged file, and the valid files they start from:
//! a tiny particle run (`sbt`, so its checkpoints hold every dataset) and a tiny mean-field
//! run, made once per campaign. A reader returns a [`Verdict`]: refused with a message, or
//! accepted, and then whether what it accepted is consistent (checked on the result, not on
//! the reader's own say-so).

use super::family::Family;
use crate::campaign::scene::{self, parse_scene};
use crate::io::checkpoint::write_verified;
use crate::report::opened_run::OpenedRun;
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::Context;
use std::path::{Path, PathBuf};

/// What a reader did with a damaged file.
#[derive(Debug)]
pub enum Verdict {
    /// Refused with this message.
    Refused(String),
    /// Accepted; `Err` says what is inconsistent in what it accepted.
    Accepted(Result<(), String>),
}

/// The particle seed run: 16 rods in a box of 3 rod lengths, five steps, `sbt`, checkpoints
/// and snapshots every two steps.
const PARTICLE_SEED: &str = "\
box_length = 3.0
rods = 16
dt = 0.02
t_end = 0.1
seed = 3
hydrodynamics = \"sbt\"
diagnostic_interval = 0.02
snapshot_interval = 0.04
checkpoint_interval = 0.04

[hydro]
sum_tolerance = 1e-2
quadrature_points = 4
";

/// The mean-field seed run: 8^3 modes to t = 0.4, checkpoints and snapshots every 0.2.
const MEANFIELD_SEED: &str = "\
grid = 8
t_end = 0.4
dt_max = 0.05
diagnostic_interval = 0.1
snapshot_interval = 0.2
checkpoint_interval = 0.2
";

/// The valid files every family starts from.
#[derive(Debug)]
pub struct Seeds {
    /// The particle seed run's directory.
    pub particle_run: PathBuf,
    /// The mean-field seed run's directory.
    pub meanfield_run: PathBuf,
    /// The particle seed run as the series harvest files it: config, time series and its
    /// comparison's compact products, no snapshots.
    pub compact_run: PathBuf,
}

impl Seeds {
    /// Make both seed runs under `dir`.
    pub fn make(dir: &Path) -> anyhow::Result<Self> {
        let particle_run = dir.join("seed-particle");
        let meanfield_run = dir.join("seed-meanfield");
        crate::io::remove_old_run(&particle_run)?;
        crate::io::remove_old_run(&meanfield_run)?;
        let p = particle::parse_config(PARTICLE_SEED, Path::new("seed-particle.toml"))?;
        particle::run_particle(&p, &particle_run, false)?;
        let m = meanfield::parse_config(MEANFIELD_SEED, Path::new("seed-meanfield.toml"))?;
        meanfield::run_meanfield(&m, &meanfield_run, false)?;
        let compact_run = dir.join("seed-compact");
        compact_of(&particle_run, &compact_run)?;
        Ok(Self {
            particle_run,
            meanfield_run,
            compact_run,
        })
    }

    /// The file a family's mutations start from, and the name it is read under.
    pub fn file(&self, family: Family) -> anyhow::Result<(Vec<u8>, &'static str)> {
        let read = |p: PathBuf| std::fs::read(&p).with_context(|| p.display().to_string());
        Ok(match family {
            Family::ParticleConfig => (PARTICLE_SEED.into(), "config.toml"),
            Family::MeanFieldConfig => (MEANFIELD_SEED.into(), "config.toml"),
            Family::Scene => (builtin("paper-concentrated").into(), "scene.toml"),
            Family::ParticleSnapshot => (
                read(self.particle_run.join("snapshots/snap_000001.h5"))?,
                "initial.h5",
            ),
            Family::FieldSnapshot => (
                read(self.meanfield_run.join("snapshots/snap_000001.h5"))?,
                "initial.h5",
            ),
            Family::ParticleCheckpoint => {
                (read(oldest_checkpoint(&self.particle_run)?)?, "ckpt.h5")
            }
            Family::MeanFieldCheckpoint => {
                (read(oldest_checkpoint(&self.meanfield_run)?)?, "ckpt.h5")
            }
            Family::RunDirectory => (
                read(self.particle_run.join("timeseries.csv"))?,
                "timeseries.csv",
            ),
            Family::RunConfig => (read(self.particle_run.join("config.toml"))?, "config.toml"),
            Family::RunSnapshot => (
                read(self.particle_run.join("snapshots").join(AUDITED))?,
                AUDITED,
            ),
            Family::CompactCorrelation
            | Family::CompactTrajectories
            | Family::CompactOrders
            | Family::CompactLengths => {
                let name = family.compact_file().unwrap_or_default();
                (read(self.compact_run.join("compare").join(name))?, name)
            }
            Family::SeriesTable => (
                read(self.compact_run.join("compare").join("series.csv"))?,
                "series.csv",
            ),
        })
    }
}

fn builtin(name: &str) -> &'static str {
    scene::BUILTIN
        .iter()
        .find(|(n, _)| *n == name)
        .map_or("", |(_, t)| t)
}

fn oldest_checkpoint(run: &Path) -> anyhow::Result<PathBuf> {
    crate::io::checkpoint::newest_first(&run.join("checkpoints"))
        .pop()
        .with_context(|| format!("{}: no checkpoint", run.display()))
}

fn refused(e: anyhow::Error) -> Verdict {
    Verdict::Refused(format!("{e:#}"))
}

fn check(ok: bool, why: impl FnOnce() -> String) -> Result<(), String> {
    if ok { Ok(()) } else { Err(why()) }
}

/// Feed `bytes`, written as `work/name`, to the family's reader.
pub fn read(family: Family, seeds: &Seeds, bytes: &[u8], work: &Path, name: &str) -> Verdict {
    let outcome =
        match family {
            Family::ParticleConfig => write(work, name, bytes).and_then(particle_config),
            Family::MeanFieldConfig => write(work, name, bytes).and_then(meanfield_config),
            Family::Scene => write(work, name, bytes).and_then(scene_file),
            Family::ParticleSnapshot => write(work, name, bytes).and_then(particle_initial),
            Family::FieldSnapshot => write(work, name, bytes).and_then(field_initial),
            Family::ParticleCheckpoint => checkpoint_run(&seeds.particle_run, bytes, work)
                .and_then(|dir| particle_resume(&dir)),
            Family::MeanFieldCheckpoint => checkpoint_run(&seeds.meanfield_run, bytes, work)
                .and_then(|dir| meanfield_resume(&dir)),
            Family::RunDirectory | Family::RunConfig => {
                run_copy(&seeds.particle_run, bytes, work, name).and_then(|dir| opened_run(&dir))
            }
            Family::RunSnapshot => run_copy(
                &seeds.particle_run,
                bytes,
                work,
                &format!("snapshots/{name}"),
            )
            .and_then(|dir| audited(&dir)),
            Family::CompactCorrelation
            | Family::CompactTrajectories
            | Family::CompactOrders
            | Family::CompactLengths => {
                compact_copy(&seeds.compact_run, bytes, work, name).and_then(|dir| compact(&dir))
            }
            Family::SeriesTable => write(work, name, bytes).and_then(|p| series_table(&p)),
        };
    outcome.unwrap_or_else(refused)
}

fn write(work: &Path, name: &str, bytes: &[u8]) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(work)?;
    let p = work.join(name);
    std::fs::write(&p, bytes)?;
    Ok(p)
}

/// `motile particle run CONFIG --dry-run`: parse and validate; what is accepted must write
/// out and read back as the same config.
fn particle_config(path: PathBuf) -> anyhow::Result<Verdict> {
    config_round_trip(&path, particle::parse_config)
}

/// `motile meanfield run CONFIG --dry-run`, with the same round trip.
fn meanfield_config(path: PathBuf) -> anyhow::Result<Verdict> {
    config_round_trip(&path, meanfield::parse_config)
}

fn config_round_trip<C: serde::Serialize + PartialEq + std::fmt::Debug>(
    path: &Path,
    parse: impl Fn(&str, &Path) -> anyhow::Result<C>,
) -> anyhow::Result<Verdict> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let cfg = parse(&text, path)?;
    let again = toml::to_string(&cfg)
        .map_err(anyhow::Error::from)
        .and_then(|t| parse(&t, path));
    Ok(Verdict::Accepted(check(
        again.as_ref().is_ok_and(|c| *c == cfg),
        || format!("accepted config does not read back: {again:?}"),
    )))
}

/// `motile run SCENE.toml --dry-run`: a scene accepted has named runs with valid configs.
fn scene_file(path: PathBuf) -> anyhow::Result<Verdict> {
    let text = std::fs::read_to_string(&path).with_context(|| path.display().to_string())?;
    let s = parse_scene(&text, &path.display().to_string())?;
    Ok(Verdict::Accepted(check(
        !s.runs.is_empty() && s.runs.iter().all(|(n, _)| !n.is_empty()),
        || "accepted scene without named runs".into(),
    )))
}

/// A particle run's initial state from the file: rods accepted are inside the box with unit
/// orientations.
fn particle_initial(path: PathBuf) -> anyhow::Result<Verdict> {
    let cfg = ParticleRunConfig {
        initial: path.display().to_string(),
        ..particle::parse_config(PARTICLE_SEED, Path::new("seed.toml"))?
    };
    let rods = particle::initial_rods(&cfg)?;
    let l = rods.box_length;
    let bad = (0..rods.len()).find(|&i| {
        let q = rods.q[i];
        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        !rods.x[i].iter().all(|&v| (0.0..l).contains(&v)) || (norm - 1.0).abs() > 1e-9
    });
    Ok(Verdict::Accepted(check(
        !rods.is_empty() && l.is_finite() && l > 0.0 && bad.is_none(),
        || {
            format!(
                "accepted {} rods in a box of {l}, rod {bad:?} outside it or not unit",
                rods.len()
            )
        },
    )))
}

/// A mean-field run's initial state from the file: Q accepted is finite with a positive
/// trace everywhere.
fn field_initial(path: PathBuf) -> anyhow::Result<Verdict> {
    let base = meanfield::parse_config(MEANFIELD_SEED, Path::new("seed.toml"))?;
    let cfg = MeanFieldRunConfig {
        initial: "snapshot".into(),
        snapshot: path.display().to_string(),
        ..base
    };
    let q = meanfield::initial_state(&cfg)?;
    let n3 = cfg.grid.pow(3);
    let finite = q
        .iter()
        .all(|c| c.len() == n3 && c.iter().all(|v| v.is_finite()));
    let trace = finite && (0..n3).all(|i| q[0][i] + q[3][i] + q[5][i] > 0.0);
    Ok(Verdict::Accepted(check(finite && trace, || {
        format!("accepted Q: finite and {n3} points each {finite}, positive trace {trace}")
    })))
}

/// A copy of `seed` (config, time series, snapshots) whose only checkpoint is `bytes` at the
/// seed's oldest checkpoint's name, with a matching checksum file: a checkpoint damaged
/// before it was checksummed, or written by another version.
fn checkpoint_run(seed: &Path, bytes: &[u8], work: &Path) -> anyhow::Result<PathBuf> {
    let dir = work.join("run");
    copy_run(seed, &dir, "snapshots")?;
    let name = oldest_checkpoint(seed)?;
    let ckpts = dir.join("checkpoints");
    std::fs::create_dir_all(&ckpts)?;
    write_verified(&ckpts.join(name.file_name().unwrap_or_default()), bytes)?;
    Ok(dir)
}

/// A copy of `seed` with `bytes` as its file `name`.
fn run_copy(seed: &Path, bytes: &[u8], work: &Path, name: &str) -> anyhow::Result<PathBuf> {
    let dir = work.join("run");
    copy_run(seed, &dir, "snapshots")?;
    std::fs::write(dir.join(name), bytes)?;
    Ok(dir)
}

/// Copy the files of a run directory and of its sub-folder `sub` (snapshots, compare).
fn copy_run(seed: &Path, dir: &Path, sub: &str) -> anyhow::Result<()> {
    for sub in ["", sub] {
        std::fs::create_dir_all(dir.join(sub))?;
        for e in std::fs::read_dir(seed.join(sub))? {
            let e = e?;
            if e.file_type()?.is_file() {
                std::fs::copy(e.path(), dir.join(sub).join(e.file_name()))?;
            }
        }
    }
    Ok(())
}

/// `motile resume` of a particle run: a resumed run ends at its config's last step with as
/// many rods as its config, finite and unit.
fn particle_resume(dir: &Path) -> anyhow::Result<Verdict> {
    let cfg: ParticleRunConfig =
        crate::io::rundir::read_run_config(dir, ParticleRunConfig::validate)?;
    let s = particle::resume_particle(dir, false)?;
    let last = (cfg.t_end / cfg.dt).round() as u64;
    let finite = s.rods.x.iter().flatten().all(|v| v.is_finite());
    let unit = s
        .rods
        .q
        .iter()
        .all(|q| (q.iter().map(|v| v * v).sum::<f64>().sqrt() - 1.0).abs() < 1e-9);
    Ok(Verdict::Accepted(check(
        s.final_step == last && s.rods.len() == cfg.rod_count() && finite && unit,
        || {
            format!(
                "resumed to step {} (config: {last}) with {} rods (config: {}), finite {finite}, unit {unit}",
                s.final_step,
                s.rods.len(),
                cfg.rod_count()
            )
        },
    )))
}

/// `motile resume` of a mean-field run: it ends at t_end with finite diagnostics.
fn meanfield_resume(dir: &Path) -> anyhow::Result<Verdict> {
    let cfg: MeanFieldRunConfig =
        crate::io::rundir::read_run_config(dir, MeanFieldRunConfig::validate)?;
    let s = meanfield::resume_meanfield(dir, false)?;
    let last = s.timeseries.rows.last().cloned().unwrap_or_default();
    let t = last.first().copied().unwrap_or(f64::NAN);
    Ok(Verdict::Accepted(check(
        (t - cfg.t_end).abs() < 1e-9 * cfg.t_end.max(1.0) && last.iter().all(|v| !v.is_nan()),
        || {
            format!(
                "resumed to t = {t} (t_end {}), last row {last:?}",
                cfg.t_end
            )
        },
    )))
}

/// `run` filed as the series harvest files a member into `compact`: its config, time series
/// and what `motile compare` wrote of it.
fn compact_of(run: &Path, compact: &Path) -> anyhow::Result<()> {
    crate::io::remove_old_run(compact)?;
    let products = compact.join("compare");
    crate::report::compare::compare(&[run.to_path_buf()], &products)?;
    for f in ["config.toml", "timeseries.csv"] {
        std::fs::copy(run.join(f), compact.join(f))?;
    }
    Ok(())
}

/// A copy of the compact run `seed` with `bytes` as its product `name`.
fn compact_copy(seed: &Path, bytes: &[u8], work: &Path, name: &str) -> anyhow::Result<PathBuf> {
    let dir = work.join("run");
    copy_run(seed, &dir, "compare")?;
    std::fs::write(dir.join("compare").join(name), bytes)?;
    Ok(dir)
}

/// `motile compare` of a compact run, as far as it reads the products: the norm curve (the
/// rotational diffusion from `trajectories.csv`) and the analysis. Accepted curves are finite
/// with increasing abscissae, MSDs not negative, orientation correlations within [-1, 1],
/// correlation lengths positive (or NaN: no zero).
fn compact(dir: &Path) -> anyhow::Result<Verdict> {
    let run = OpenedRun::open(dir)?;
    let curve = crate::report::curves::norm_curve_of(&run)?;
    let a = crate::report::compact::read_analysis(&run, &curve.label)?;
    let increasing = |x: &[f64]| x.windows(2).all(|w| w[1] > w[0]);
    let finite = |x: &[f64]| x.iter().all(|v| v.is_finite());
    let mut bad = Vec::new();
    if let Some(c) = &a.corr_u
        && !(c.r.len() == c.value.len() && increasing(&c.r) && finite(&c.r) && finite(&c.value))
    {
        bad.push("Corr[u]");
    }
    if let Some(t) = &a.traj {
        let same = t.t.len() == t.msd.len() && t.t.len() == t.orientation.len();
        if !(same
            && increasing(&t.t)
            && finite(&t.t)
            && t.msd.iter().all(|&m| m.is_finite() && m >= 0.0)
            && t.orientation.iter().all(|o| o.abs() <= 1.0 + 1e-9))
        {
            bad.push("trajectories");
        }
    }
    for o in &a.order {
        let (r, v): (Vec<f64>, Vec<f64>) = o.points.iter().copied().unzip();
        if !(increasing(&r) && finite(&r) && finite(&v)) {
            bad.push("order correlations");
        }
    }
    if a.lengths
        .iter()
        .any(|l| !(l.length.is_nan() || l.length > 0.0 && l.length.is_finite()))
    {
        bad.push("correlation lengths");
    }
    let diffusion = curve.particle.as_ref().and_then(|p| p.rotational_diffusion);
    if diffusion.is_some_and(|d| !d.is_finite()) {
        bad.push("rotational diffusion");
    }
    Ok(Verdict::Accepted(check(
        bad.is_empty() && a.corr_u.is_some(),
        || {
            format!(
                "accepted compact products with inconsistent {bad:?} (Corr[u] present: {})",
                a.corr_u.is_some()
            )
        },
    )))
}

/// `motile compare --table FILE`: rows accepted have positive norms, and particle rows a
/// positive box and density and a rotational diffusion not negative (or none).
fn series_table(path: &Path) -> anyhow::Result<Verdict> {
    use crate::report::series::TablePoint;
    let rows = crate::report::series::read_table(path, &[])?;
    let bad = rows.iter().find(|r| match &r.point {
        TablePoint::Particle(p) => {
            !(p.box_length > 0.0 && p.nu > 0.0 && p.mean > 0.0 && p.mean.is_finite())
                || p.rotational_diffusion
                    .is_some_and(|d| !(d >= 0.0 && d.is_finite()))
                || !p.nu.is_finite()
        }
        TablePoint::Continuum(mean) => !(mean.is_finite() && *mean > 0.0),
    });
    Ok(Verdict::Accepted(check(bad.is_none(), || {
        format!("accepted row `{}`", bad.map_or("", |r| r.line.as_str()))
    })))
}

/// The snapshot `check-accuracy --snapshot 1` audits.
const AUDITED: &str = "snap_000001.h5";

/// `motile check-accuracy RUN_DIR --snapshot 1` (16 targets): an audit accepted measures
/// finite errors of every output against the direct sum.
fn audited(dir: &Path) -> anyhow::Result<Verdict> {
    let a = crate::report::accuracy::audit(dir, Some(1), 16)?;
    let finite = a
        .rows
        .iter()
        .all(|r| r.max_relative.is_finite() && r.l2_relative.is_finite());
    Ok(Verdict::Accepted(check(
        !a.rows.is_empty() && finite && a.time.is_finite(),
        || {
            format!(
                "audit at t = {} with {} rows, errors finite: {finite}",
                a.time,
                a.rows.len()
            )
        },
    )))
}

/// `motile compare` and `analyze` opening a run: a time series accepted has finite,
/// increasing times, and every snapshot reads.
fn opened_run(dir: &Path) -> anyhow::Result<Verdict> {
    let run = OpenedRun::open(dir)?;
    let t = run.column("t")?;
    let snapshots = run.snapshots()?;
    let increasing = t.windows(2).all(|w| w[1] > w[0]) && t.iter().all(|v| v.is_finite());
    let l = run.particle().map(|(c, _)| c.box_length);
    let same_box = snapshots.iter().all(|s| match s {
        crate::io::snapshot::Snapshot::Particle(p) => Some(p.box_length) == l,
        crate::io::snapshot::Snapshot::Field(_) => false,
    });
    Ok(Verdict::Accepted(check(
        increasing && !snapshots.is_empty() && same_box,
        || {
            format!(
                "accepted times {t:?} (finite and increasing: {increasing}), snapshots of the config's box {l:?}: {same_box}"
            )
        },
    )))
}
