//! A finished run opened once for the report (`motile compare`, the demo's checks): its
//! directory, its validated config, its time series, the list of its snapshot files and, for a
//! particle run, the units that put it in the mean-field unit system (docs/MODEL.md §5:
//! `t_mf = t_p nu / (8 eta mu)`, `u_mf = (u_p / (beta L)) 8 eta mu / nu`). The stages of a
//! comparison take what they need from here instead of reading the run directory again.

use crate::io::IoError;
use crate::io::rundir::{RunDir, TimeSeries, read_run_config};
use crate::io::snapshot::{Snapshot, read_snapshot};
use crate::run::meanfield::MeanFieldRunConfig;
use crate::run::particle::ParticleRunConfig;
use anyhow::{Context, bail};
use motile_particle::model::units::{meanfield_time_unit, particle_to_meanfield};
use std::path::{Path, PathBuf};

/// A run directory read once: config, time series, snapshot files.
#[derive(Clone, Debug)]
pub struct OpenedRun {
    /// The run directory.
    pub dir: RunDir,
    /// The run's model and its config (with a particle run's units).
    pub model: OpenedModel,
    /// The run's own time series (`timeseries.csv`).
    pub series: TimeSeries,
    /// Where the time series was read from (error messages name it).
    pub series_path: PathBuf,
    /// The snapshot files, in order.
    pub snapshot_paths: Vec<PathBuf>,
}

/// The model of an opened run, with its validated config.
#[derive(Clone, Debug)]
pub enum OpenedModel {
    /// A particle run and its units.
    Particle {
        /// The run's config.
        config: ParticleRunConfig,
        /// Its size and unit conversion.
        units: ParticleUnits,
    },
    /// A mean-field run (already in mean-field units).
    MeanField(MeanFieldRunConfig),
}

/// A particle run's size and its conversion to mean-field units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParticleUnits {
    /// Box side `L/l`.
    pub box_length: f64,
    /// Rods (the config's, or `round(nu L^3)`).
    pub rods: usize,
    /// The volume fraction of those rods, `N / L^3`.
    pub nu: f64,
    /// Rod diameter `b`.
    pub diameter: f64,
    /// The mean-field time unit in particle time, `8 eta mu / nu`: `t_mf = t_p / time_unit`.
    pub time_unit: f64,
}

impl ParticleUnits {
    /// The units of a particle run's config.
    pub fn of(config: &ParticleRunConfig) -> Self {
        let l = config.box_length;
        let rods = config.rod_count();
        let nu = rods as f64 / (l * l * l);
        Self {
            box_length: l,
            rods,
            nu,
            diameter: config.diameter,
            time_unit: meanfield_time_unit(nu, config.diameter),
        }
    }

    /// A particle time (1/beta) and velocity (normalised by `beta L`) in mean-field units.
    pub fn to_meanfield(&self, t: f64, u: f64) -> (f64, f64) {
        particle_to_meanfield(t, u, self.nu, self.diameter)
    }
}

impl OpenedRun {
    /// Open the run directory `run`: its header and config (validated), its time series and
    /// the list of its snapshots. A run of another kind than particle or mean-field is refused.
    pub fn open(run: &Path) -> anyhow::Result<Self> {
        let dir = RunDir::open(run)?;
        let kind = dir.header()?.model;
        let series_path = run.join("timeseries.csv");
        let series = TimeSeries::read(&series_path)?;
        let model = match kind.as_str() {
            "particle" => {
                let config: ParticleRunConfig = read_run_config(run, ParticleRunConfig::validate)?;
                let units = ParticleUnits::of(&config);
                OpenedModel::Particle { config, units }
            }
            "meanfield" => {
                OpenedModel::MeanField(read_run_config(run, MeanFieldRunConfig::validate)?)
            }
            other => bail!("{}: cannot compare a run of kind `{other}`", run.display()),
        };
        // A run filed without its snapshots (its compact products) has no snapshots folder.
        let snapshot_paths = if run.join("snapshots").exists() {
            dir.snapshot_paths()?
        } else {
            Vec::new()
        };
        Ok(Self {
            dir,
            model,
            series,
            series_path,
            snapshot_paths,
        })
    }

    /// The run directory's path.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// The particle run's config and units; `None` for a mean-field run.
    pub fn particle(&self) -> Option<(&ParticleRunConfig, &ParticleUnits)> {
        match &self.model {
            OpenedModel::Particle { config, units } => Some((config, units)),
            OpenedModel::MeanField(_) => None,
        }
    }

    /// The time-series column whose name starts with `prefix`.
    pub fn column(&self, prefix: &str) -> anyhow::Result<Vec<f64>> {
        let c = self
            .series
            .columns
            .iter()
            .position(|c| c.starts_with(prefix))
            .with_context(|| format!("{}: no column `{prefix}`", self.series_path.display()))?;
        Ok(self.series.rows.iter().map(|r| r[c]).collect())
    }

    /// Whether the time series has a column whose name starts with `prefix`.
    pub fn has_column(&self, prefix: &str) -> bool {
        self.series.columns.iter().any(|c| c.starts_with(prefix))
    }

    /// Read every snapshot, in order; each must be of the run's model and box (a particle
    /// run's box side, a mean-field run's grid), or the run directory holds another run's files.
    pub fn snapshots(&self) -> Result<Vec<Snapshot>, IoError> {
        let shape = self.snapshot_shape();
        self.snapshot_paths.iter().map(|p| shape.read(p)).collect()
    }

    /// What this run's snapshots must match.
    pub fn snapshot_shape(&self) -> SnapshotShape {
        match &self.model {
            OpenedModel::Particle { config, .. } => SnapshotShape::Particle {
                box_length: config.box_length,
            },
            OpenedModel::MeanField(config) => SnapshotShape::MeanField { grid: config.grid },
        }
    }
}

/// What a run's snapshots must match: its config's box (particle) or grid (mean field).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SnapshotShape {
    /// A particle run of this box side.
    Particle {
        /// The config's `box_length`.
        box_length: f64,
    },
    /// A mean-field run of this grid.
    MeanField {
        /// The config's `grid`.
        grid: usize,
    },
}

impl SnapshotShape {
    /// The snapshot at `path`, refused by name where it is not one of this run's.
    pub fn read(self, path: &Path) -> Result<Snapshot, IoError> {
        let s = read_snapshot(path)?;
        let mismatch = match (&s, self) {
            (Snapshot::Particle(s), SnapshotShape::Particle { box_length }) => (s.box_length
                != box_length)
                .then(|| format!("box_length {} (config.toml: {box_length})", s.box_length)),
            (Snapshot::Field(s), SnapshotShape::MeanField { grid }) => {
                (s.grid != grid).then(|| format!("grid {} (config.toml: {grid})", s.grid))
            }
            _ => Some("a snapshot of the other model".into()),
        };
        match mismatch {
            Some(m) => Err(IoError::Content {
                path: path.to_path_buf(),
                message: format!("not a snapshot of this run: {m}"),
            }),
            None => Ok(s),
        }
    }
}
