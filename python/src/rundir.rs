//! Run directories: `open` and the lazy `RunDirectory` (config, CSV files, snapshots, status).

use crate::{Columns, table_to_py, value_error};
use motile_experiments::io::checkpoint;
use motile_experiments::io::rundir::{RunDir, TimeSeries, read_run_config};
use motile_experiments::io::snapshot::Snapshot;
use motile_experiments::report::opened_run::SnapshotShape;
use motile_experiments::run::meanfield::MeanFieldRunConfig;
use motile_experiments::run::particle::ParticleRunConfig;
use numpy::IntoPyArray;
use numpy::ndarray::{Array2, Array4};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// A run directory, read lazily.
#[pyclass(module = "motile._motile")]
pub(crate) struct RunDirectory {
    path: PathBuf,
    model: String,
    config: toml::Table,
    snapshots: Vec<PathBuf>,
    /// What its snapshots must match (the config's box or grid).
    shape: SnapshotShape,
}

/// Open the run directory `path`.
#[pyfunction]
pub(crate) fn open(path: PathBuf) -> PyResult<RunDirectory> {
    let dir = RunDir::open(&path).map_err(value_error)?;
    let header = dir.header().map_err(value_error)?;
    // The config as the model reads it (every key and range checked), so that a damaged file
    // is refused by name here as by `motile compare`, not handed on as a dict.
    let shape = match header.model.as_str() {
        "particle" => SnapshotShape::Particle {
            box_length: read_run_config(&path, ParticleRunConfig::validate)
                .map_err(value_error)?
                .box_length,
        },
        "meanfield" => SnapshotShape::MeanField {
            grid: read_run_config(&path, MeanFieldRunConfig::validate)
                .map_err(value_error)?
                .grid,
        },
        other => {
            return Err(value_error(format!(
                "{}: a run of kind `{other}` (\"particle\" or \"meanfield\")",
                path.join("config.toml").display()
            )));
        }
    };
    let text = std::fs::read_to_string(path.join("config.toml")).map_err(value_error)?;
    let mut config: toml::Table = toml::from_str(&text).map_err(value_error)?;
    config.remove("motile");
    let snapshots = dir.snapshot_paths().map_err(value_error)?;
    Ok(RunDirectory {
        path,
        model: header.model,
        config,
        snapshots,
        shape,
    })
}

/// A time series file as `(columns, rows)`.
fn read_columns(path: &Path) -> PyResult<TimeSeries> {
    TimeSeries::read(path).map_err(value_error)
}

#[pymethods]
impl RunDirectory {
    /// The directory.
    #[getter]
    fn path(&self) -> String {
        self.path.display().to_string()
    }

    /// "particle" or "meanfield".
    #[getter]
    fn model(&self) -> String {
        self.model.clone()
    }

    /// The resolved config (every key, defaults filled in), as `config.toml` holds it.
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        table_to_py(py, &self.config)
    }

    /// Snapshots in the directory.
    #[getter]
    fn snapshot_count(&self) -> usize {
        self.snapshots.len()
    }

    /// `(names, units, columns)` of `timeseries.csv` (or, with `file`, another CSV of the run
    /// such as `modes.csv`): each column's name and unit split from its header, and its values.
    #[pyo3(signature = (file="timeseries.csv"))]
    fn read_csv<'py>(&self, py: Python<'py>, file: &str) -> PyResult<Columns<'py>> {
        let ts = read_columns(&self.path.join(file))?;
        let mut names = Vec::new();
        let mut units = Vec::new();
        let mut cols = Vec::new();
        for (k, c) in ts.columns.iter().enumerate() {
            let (name, unit) = match c.split_once(" [") {
                Some((n, u)) => (n.to_string(), u.trim_end_matches(']').to_string()),
                None => (c.clone(), String::new()),
            };
            names.push(name);
            units.push(unit);
            let v: Vec<f64> = ts.rows.iter().map(|r| r[k]).collect();
            cols.push(v.into_pyarray(py));
        }
        Ok((names, units, cols))
    }

    /// Snapshot `k` (negative counts from the end), read now: a dict of numpy arrays.
    fn snapshot<'py>(&self, py: Python<'py>, k: isize) -> PyResult<Bound<'py, PyDict>> {
        let n = self.snapshots.len() as isize;
        let i = if k < 0 { n + k } else { k };
        if i < 0 || i >= n {
            return Err(value_error(format!(
                "snapshot {k}: the run has {n} snapshot(s)"
            )));
        }
        let snap = self
            .shape
            .read(&self.snapshots[i as usize])
            .map_err(value_error)?;
        let d = PyDict::new(py);
        let rows3 = |v: &[[f64; 3]]| -> PyResult<_> {
            Array2::from_shape_vec((v.len(), 3), v.as_flattened().to_vec())
                .map(|a| a.into_pyarray(py))
                .map_err(value_error)
        };
        match snap {
            Snapshot::Particle(p) => {
                d.set_item("kind", "particle")?;
                d.set_item("time", p.time)?;
                d.set_item("step", p.step)?;
                d.set_item("box_length", p.box_length)?;
                d.set_item("positions", rows3(&p.positions)?)?;
                d.set_item("orientations", rows3(&p.orientations)?)?;
                let images: Vec<i64> = p.image_counts.iter().flatten().copied().collect();
                d.set_item(
                    "image_counts",
                    Array2::from_shape_vec((p.image_counts.len(), 3), images)
                        .map_err(value_error)?
                        .into_pyarray(py),
                )?;
                if let Some(f) = &p.forces {
                    d.set_item("force_points", rows3(&f.points)?)?;
                    d.set_item("point_forces", rows3(&f.forces)?)?;
                }
                if let Some(k) = &p.kinematics {
                    d.set_item("velocities", rows3(&k.velocities)?)?;
                    d.set_item("angular_velocities", rows3(&k.angular_velocities)?)?;
                    d.set_item("contact_forces", rows3(&k.contact_forces)?)?;
                }
            }
            Snapshot::Field(f) => {
                d.set_item("kind", "meanfield")?;
                d.set_item("time", f.time)?;
                d.set_item("step", f.step)?;
                d.set_item("box_length", f.box_length)?;
                d.set_item("grid", f.grid)?;
                let n = f.grid;
                // Memory x fastest: numpy shape (component, z, y, x); the Python half
                // transposes to (component, x, y, z).
                let q: Vec<f64> = f.q.iter().flatten().copied().collect();
                let u: Vec<f64> = f.u.iter().flatten().copied().collect();
                d.set_item(
                    "Q",
                    Array4::from_shape_vec((6, n, n, n), q)
                        .map_err(value_error)?
                        .into_pyarray(py),
                )?;
                d.set_item(
                    "u",
                    Array4::from_shape_vec((3, n, n, n), u)
                        .map_err(value_error)?
                        .into_pyarray(py),
                )?;
            }
        }
        Ok(d)
    }

    /// The snapshots' times, each file read for it.
    fn snapshot_times(&self) -> PyResult<Vec<f64>> {
        self.snapshots
            .iter()
            .map(|p| self.shape.read(p).map(|s| s.time()).map_err(value_error))
            .collect()
    }

    /// Whether the run `finished`, is `resumable` (stopped with a checkpoint), `failed` (with
    /// the saved state before the failed step and the reason from its log), or `empty`; with
    /// the time it reached (its time series' last row, or the checkpoint it resumes from where
    /// that is later) and its configured end time.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let t_end = self
            .config
            .get("t_end")
            .and_then(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
            .unwrap_or(f64::NAN);
        let interval = self
            .config
            .get("diagnostic_interval")
            .and_then(|v| v.as_float())
            .unwrap_or(0.0);
        let last = TimeSeries::read(&self.path.join("timeseries.csv"))
            .ok()
            .and_then(|ts| ts.rows.last().map(|r| r[0]))
            .unwrap_or(f64::NAN);
        let ckpts = self.path.join("checkpoints");
        let failed = ckpts.join(checkpoint::LAST_GOOD).exists();
        let regular = checkpoint::newest_first(&ckpts);
        let has_checkpoint = !regular.is_empty();
        // The time reached: a run stopped between diagnostics is as far as the checkpoint it
        // resumes from (the state before a failed step, else the newest regular one).
        let saved = if failed {
            Some(ckpts.join(checkpoint::LAST_GOOD))
        } else {
            regular.first().cloned()
        };
        let reached = saved
            .and_then(|p| checkpoint::time_of(&p).ok())
            .map_or(last, |t| if last.is_nan() { t } else { last.max(t) });
        let reason = std::fs::read_to_string(self.path.join("run.log"))
            .ok()
            .and_then(|log| {
                log.lines()
                    .rev()
                    .find(|l| l.contains("failed") || l.contains("stopped"))
                    .map(|l| l.split_once("] ").map_or(l, |x| x.1).to_string())
            });
        let state = if failed {
            "failed"
        } else if last >= t_end - 0.5 * interval - 1e-9 {
            "finished"
        } else if has_checkpoint {
            "resumable"
        } else {
            "empty"
        };
        d.set_item("state", state)?;
        d.set_item("t", reached)?;
        d.set_item("t_end", t_end)?;
        d.set_item("reason", if state == "finished" { None } else { reason })?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "motile.RunDirectory('{}', model='{}', {} snapshot(s))",
            self.path.display(),
            self.model,
            self.snapshots.len()
        )
    }
}
