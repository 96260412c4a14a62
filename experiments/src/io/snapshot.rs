//! HDF5 snapshots of both models, and their validation on load.
//!
//! Layout (all lengths in rod lengths `l` for particle runs and box lengths `L` for mean-field
//! runs, times in the model's own unit; see docs/run-directory.md):
//!
//! Every snapshot carries `format_version` and `motile_version` ([`mod@crate::io::format`]).
//!
//! Particle snapshot, root attributes `kind = "particle"`, `time`, `step`, `box_length`; datasets `positions (N, 3)`, `orientations (N, 3)` (unit vectors),
//! `image_counts (N, 3)` (int64, periodic images crossed: unwrapped = position + L * count),
//! and optionally `force_points (P, 3)` with `point_forces (P, 3)`: quadrature points on the rods
//! and the weighted force densities `f(s_j) w_j` there (what the velocity spectrum needs), and
//! `velocities`, `angular_velocities`, `contact_forces` (each `(N, 3)`).
//!
//! Mean-field snapshot, root attributes `kind = "meanfield"`, `time`, `step`, `box_length`,
//! `grid`; datasets `Q (6, n, n, n)` with components `xx, xy, xz, yy, yz, zz` and
//! `u (3, n, n, n)`, indexed `[component, z, y, x]` (x fastest).

use crate::io::{IoError, format, write_atomic};
use hdf5_pure::{AttrValue, File, FileBuilder};
use std::collections::HashMap;
use std::path::Path;

/// Weighted force densities at quadrature points on the rods.
#[derive(Clone, Debug, PartialEq)]
pub struct PointForces {
    /// Quadrature points `x_n + s_j p_n`.
    pub points: Vec<[f64; 3]>,
    /// `f_n(s_j) w_j` at those points.
    pub forces: Vec<[f64; 3]>,
}

/// One particle configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleSnapshot {
    /// Simulated time (1/beta).
    pub time: f64,
    /// Step number.
    pub step: u64,
    /// Box side (l).
    pub box_length: f64,
    /// Rod centres in `[0, L)^3`.
    pub positions: Vec<[f64; 3]>,
    /// Unit orientations.
    pub orientations: Vec<[f64; 3]>,
    /// Periodic images crossed since the start.
    pub image_counts: Vec<[i64; 3]>,
    /// Quadrature points and weighted force densities there, if the model computed them.
    pub forces: Option<PointForces>,
    /// Rod kinematics and contact forces of the step that led here, if a solver wrote them.
    pub kinematics: Option<Kinematics>,
}

/// Velocities, angular velocities and contact forces of every rod.
#[derive(Clone, Debug, PartialEq)]
pub struct Kinematics {
    /// Centre velocities (beta l).
    pub velocities: Vec<[f64; 3]>,
    /// Angular velocities (beta).
    pub angular_velocities: Vec<[f64; 3]>,
    /// Net contact force on each rod.
    pub contact_forces: Vec<[f64; 3]>,
}

/// One mean-field state on an `n^3` grid (flattened x fastest).
#[derive(Clone, Debug, PartialEq)]
pub struct FieldSnapshot {
    /// Simulated time (mean-field units).
    pub time: f64,
    /// Step number.
    pub step: u64,
    /// Box side (1 in mean-field units).
    pub box_length: f64,
    /// Grid points per dimension.
    pub grid: usize,
    /// `Q` components `xx, xy, xz, yy, yz, zz`.
    pub q: [Vec<f64>; 6],
    /// Velocity components.
    pub u: [Vec<f64>; 3],
}

/// Either kind of snapshot.
#[derive(Clone, Debug, PartialEq)]
pub enum Snapshot {
    /// A particle configuration.
    Particle(ParticleSnapshot),
    /// A mean-field state.
    Field(FieldSnapshot),
}

impl Snapshot {
    /// Simulated time.
    pub fn time(&self) -> f64 {
        match self {
            Snapshot::Particle(s) => s.time,
            Snapshot::Field(s) => s.time,
        }
    }
}

fn flat3<T: Copy>(v: &[[T; 3]]) -> Vec<T> {
    v.iter().flat_map(|a| a.iter().copied()).collect()
}

impl ParticleSnapshot {
    /// Write atomically to `path`.
    pub fn write(&self, path: &Path) -> Result<(), IoError> {
        let n = self.positions.len() as u64;
        let mut b = FileBuilder::new();
        b.set_attr("kind", AttrValue::VarLenString("particle".into()));
        b.set_attr("time", AttrValue::F64(self.time));
        b.set_attr("step", AttrValue::U64(self.step));
        b.set_attr("box_length", AttrValue::F64(self.box_length));
        format::stamp(&mut b);
        b.create_dataset("positions")
            .with_f64_data(&flat3(&self.positions))
            .with_shape(&[n, 3]);
        b.create_dataset("orientations")
            .with_f64_data(&flat3(&self.orientations))
            .with_shape(&[n, 3]);
        b.create_dataset("image_counts")
            .with_i64_data(&flat3(&self.image_counts))
            .with_shape(&[n, 3]);
        if let Some(PointForces {
            points: pts,
            forces: f,
        }) = &self.forces
        {
            let m = pts.len() as u64;
            b.create_dataset("force_points")
                .with_f64_data(&flat3(pts))
                .with_shape(&[m, 3]);
            b.create_dataset("point_forces")
                .with_f64_data(&flat3(f))
                .with_shape(&[m, 3]);
        }
        if let Some(k) = &self.kinematics {
            for (name, v) in [
                ("velocities", &k.velocities),
                ("angular_velocities", &k.angular_velocities),
                ("contact_forces", &k.contact_forces),
            ] {
                b.create_dataset(name)
                    .with_f64_data(&flat3(v))
                    .with_shape(&[n, 3]);
            }
        }
        let bytes = b.finish().map_err(|e| h5err(path, e))?;
        write_atomic(path, &bytes)
    }
}

impl FieldSnapshot {
    /// Write atomically to `path`.
    pub fn write(&self, path: &Path) -> Result<(), IoError> {
        let n = self.grid as u64;
        let mut b = FileBuilder::new();
        b.set_attr("kind", AttrValue::VarLenString("meanfield".into()));
        b.set_attr("time", AttrValue::F64(self.time));
        b.set_attr("step", AttrValue::U64(self.step));
        b.set_attr("box_length", AttrValue::F64(self.box_length));
        b.set_attr("grid", AttrValue::U64(n));
        format::stamp(&mut b);
        let q: Vec<f64> = self.q.iter().flatten().copied().collect();
        let u: Vec<f64> = self.u.iter().flatten().copied().collect();
        b.create_dataset("Q")
            .with_f64_data(&q)
            .with_shape(&[6, n, n, n]);
        b.create_dataset("u")
            .with_f64_data(&u)
            .with_shape(&[3, n, n, n]);
        let bytes = b.finish().map_err(|e| h5err(path, e))?;
        write_atomic(path, &bytes)
    }
}

fn h5err(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Hdf5 {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn content(path: &Path, message: String) -> IoError {
    IoError::Content {
        path: path.to_path_buf(),
        message,
    }
}

fn attr_f64(attrs: &HashMap<String, AttrValue>, name: &str, path: &Path) -> Result<f64, IoError> {
    match attrs.get(name) {
        Some(AttrValue::F64(v)) => Ok(*v),
        Some(AttrValue::U64(v)) => Ok(*v as f64),
        Some(AttrValue::I64(v)) => Ok(*v as f64),
        Some(other) => Err(content(
            path,
            format!("attribute '{name}' has unexpected type {other:?}"),
        )),
        None => Err(content(path, format!("missing root attribute '{name}'"))),
    }
}

fn read_rows(
    file: &File,
    name: &str,
    rows: Option<usize>,
    path: &Path,
) -> Result<Vec<[f64; 3]>, IoError> {
    let ds = file
        .dataset(name)
        .map_err(|e| content(path, format!("dataset '{name}': {e}")))?;
    let shape = ds.shape().map_err(|e| h5err(path, e))?;
    if shape.len() != 2 || shape[1] != 3 || rows.is_some_and(|r| shape[0] as usize != r) {
        return Err(content(
            path,
            format!(
                "dataset '{name}' has shape {shape:?}, expected [{}, 3]",
                rows.map_or("N".into(), |r| r.to_string())
            ),
        ));
    }
    let v = ds.read_f64().map_err(|e| h5err(path, e))?;
    let out: Vec<[f64; 3]> = v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    if let Some(i) = out.iter().position(|r| !r.iter().all(|x| x.is_finite())) {
        return Err(content(
            path,
            format!("dataset '{name}': row {i} is not finite: {:?}", out[i]),
        ));
    }
    Ok(out)
}

/// What every snapshot's root attributes hold.
struct SnapshotHeader {
    time: f64,
    step: u64,
    box_length: f64,
}

/// Read and validate a snapshot of either kind.
pub fn read_snapshot(path: &Path) -> Result<Snapshot, IoError> {
    if !path.exists() {
        return Err(h5err(path, "no such file"));
    }
    let (file, attrs, kind) = open_snapshot(path)?;
    format::check_hdf5(&attrs, path)?;
    let header = read_header(&attrs, path)?;
    match kind.as_str() {
        "particle" => read_particle(&file, header, path).map(Snapshot::Particle),
        "meanfield" => read_field(&file, &attrs, header, path).map(Snapshot::Field),
        other => Err(content(
            path,
            format!("unknown snapshot kind '{other}' (expected \"particle\" or \"meanfield\")"),
        )),
    }
}

/// Open a snapshot file and read its root attributes and kind. A file that is not HDF5 at all,
/// or whose root cannot be read (cut short), is not a snapshot: say so, not which attribute is
/// missing.
fn open_snapshot(path: &Path) -> Result<(File, HashMap<String, AttrValue>, String), IoError> {
    let not_snapshot = |detail: String| IoError::NotSnapshot {
        path: path.to_path_buf(),
        detail,
    };
    let file = File::open(path).map_err(|e| not_snapshot(e.to_string()))?;
    let attrs = file
        .root()
        .attrs()
        .map_err(|e| not_snapshot(e.to_string()))?;
    let kind = match attrs.get("kind") {
        Some(
            AttrValue::String(s)
            | AttrValue::VarLenString(s)
            | AttrValue::AsciiString(s)
            | AttrValue::VarLenAsciiString(s),
        ) => s.clone(),
        _ => {
            return Err(not_snapshot(
                "no root attribute 'kind' (\"particle\" or \"meanfield\")".into(),
            ));
        }
    };
    Ok((file, attrs, kind))
}

/// The time, step and (positive) box side every snapshot carries.
fn read_header(attrs: &HashMap<String, AttrValue>, path: &Path) -> Result<SnapshotHeader, IoError> {
    let time = attr_f64(attrs, "time", path)?;
    let step = attr_f64(attrs, "step", path)?;
    if !(time.is_finite()
        && time >= 0.0
        && step >= 0.0
        && step < 2f64.powi(53)
        && step.fract() == 0.0)
    {
        return Err(content(
            path,
            format!(
                "time {time}, step {step}: a time must be finite and not negative, a step a whole number"
            ),
        ));
    }
    let step = step as u64;
    let box_length = attr_f64(attrs, "box_length", path)?;
    if !(box_length.is_finite() && box_length > 0.0) {
        return Err(content(
            path,
            format!("box_length {box_length} must be positive"),
        ));
    }
    Ok(SnapshotHeader {
        time,
        step,
        box_length,
    })
}

/// A particle snapshot's datasets: positions, unit orientations, image counts, and the force
/// densities and kinematics where the file has them.
fn read_particle(
    file: &File,
    header: SnapshotHeader,
    path: &Path,
) -> Result<ParticleSnapshot, IoError> {
    let positions = read_rows(file, "positions", None, path)?;
    let n = positions.len();
    let orientations = read_rows(file, "orientations", Some(n), path)?;
    if let Some(i) = orientations
        .iter()
        .position(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs() > 1e-8)
    {
        return Err(content(
            path,
            format!(
                "dataset 'orientations': row {i} is not a unit vector: {:?}",
                orientations[i]
            ),
        ));
    }
    let image_counts = read_image_counts(file, n, path)?;
    let forces = if file.dataset("force_points").is_ok() {
        let points = read_rows(file, "force_points", None, path)?;
        // Points on rods whose centres are in the box: within half a rod length of it.
        let l = header.box_length;
        if let Some(i) = points
            .iter()
            .position(|x| x.iter().any(|&c| !(-1.0..=l + 1.0).contains(&c)))
        {
            return Err(content(
                path,
                format!(
                    "dataset 'force_points': row {i} at {:?} lies more than a rod length outside the box [0, {l})^3",
                    points[i]
                ),
            ));
        }
        let forces = read_rows(file, "point_forces", Some(points.len()), path)?;
        Some(PointForces { points, forces })
    } else {
        None
    };
    let kinematics = if file.dataset("velocities").is_ok() {
        Some(Kinematics {
            velocities: read_rows(file, "velocities", Some(n), path)?,
            angular_velocities: read_rows(file, "angular_velocities", Some(n), path)?,
            contact_forces: read_rows(file, "contact_forces", Some(n), path)?,
        })
    } else {
        None
    };
    Ok(ParticleSnapshot {
        time: header.time,
        step: header.step,
        box_length: header.box_length,
        positions,
        orientations,
        image_counts,
        forces,
        kinematics,
    })
}

/// The `(n, 3)` periodic image counts of `n` rods.
fn read_image_counts(file: &File, n: usize, path: &Path) -> Result<Vec<[i64; 3]>, IoError> {
    let ds = file
        .dataset("image_counts")
        .map_err(|e| content(path, format!("dataset 'image_counts': {e}")))?;
    let ic = ds.read_i64().map_err(|e| h5err(path, e))?;
    if ic.len() != 3 * n {
        return Err(content(
            path,
            format!(
                "dataset 'image_counts' has {} values, expected {}",
                ic.len(),
                3 * n
            ),
        ));
    }
    Ok(ic.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// A mean-field snapshot's grid and its `Q` and `u` fields.
fn read_field(
    file: &File,
    attrs: &HashMap<String, AttrValue>,
    header: SnapshotHeader,
    path: &Path,
) -> Result<FieldSnapshot, IoError> {
    let grid = attr_f64(attrs, "grid", path)? as usize;
    let q: [Vec<f64>; 6] = read_components(file, "Q", 6, grid, path)?
        .try_into()
        .expect("six components");
    let u: [Vec<f64>; 3] = read_components(file, "u", 3, grid, path)?
        .try_into()
        .expect("three components");
    Ok(FieldSnapshot {
        time: header.time,
        step: header.step,
        box_length: header.box_length,
        grid,
        q,
        u,
    })
}

/// The dataset `name` of shape `(comps, grid, grid, grid)`, finite, one vector per component.
fn read_components(
    file: &File,
    name: &str,
    comps: usize,
    grid: usize,
    path: &Path,
) -> Result<Vec<Vec<f64>>, IoError> {
    let ds = file
        .dataset(name)
        .map_err(|e| content(path, format!("dataset '{name}': {e}")))?;
    let shape = ds.shape().map_err(|e| h5err(path, e))?;
    let g = grid as u64;
    if shape != [comps as u64, g, g, g] {
        return Err(content(
            path,
            format!(
                "dataset '{name}' has shape {shape:?}, expected [{comps}, {grid}, {grid}, {grid}]"
            ),
        ));
    }
    let v = ds.read_f64().map_err(|e| h5err(path, e))?;
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(content(
            path,
            format!("dataset '{name}': value {i} is not finite"),
        ));
    }
    Ok(v.chunks_exact(grid.pow(3)).map(|c| c.to_vec()).collect())
}
