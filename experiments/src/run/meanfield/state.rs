//! The mean-field run's state and files: the initial field (a perturbation, a mean-field
//! snapshot, or a particle snapshot smoothed onto the grid), the closure-table cache, the
//! driver's clock and the checkpoint codec.

use super::config::MeanFieldRunConfig;
use crate::io::snapshot::{Snapshot, read_snapshot};
use crate::io::{checkpoint, write_atomic};
use anyhow::bail;
use hdf5_pure::{AttrValue, FileBuilder};
use motile_meanfield::closure::BinghamClosure;
use motile_meanfield::initial::PerturbationField;
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::stepper::{History, MeanFieldStepper};
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// Where closure tables are cached: `$MOTILE_CACHE_DIR`, else `~/.cache/motile`.
pub fn cache_dir() -> PathBuf {
    std::env::var_os("MOTILE_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/motile")))
        .unwrap_or_else(|| PathBuf::from(".motile-cache"))
}

/// Closure tables of a degree: loaded from the cache, or built and cached.
pub fn closure_tables(degree: usize) -> anyhow::Result<BinghamClosure> {
    let path = cache_dir().join(format!("bingham_degree{degree}.bin"));
    if let Ok(bytes) = std::fs::read(&path)
        && let Some(c) = BinghamClosure::from_bytes(&bytes, degree)
    {
        return Ok(c);
    }
    let c = BinghamClosure::new(degree)
        .map_err(|e| anyhow::anyhow!("building the closure tables: {e}"))?;
    // A cache that cannot be written is not an error: the tables are rebuilt next time.
    let _ = write_atomic(&path, &c.to_bytes());
    Ok(c)
}

/// Q of a snapshot on a grid of `n^3` points: a mean-field snapshot spectrally resampled if its
/// grid differs, or a particle snapshot smoothed (see [`particle_state`]); validated: finite,
/// positive trace (concentration) everywhere.
pub fn snapshot_state(path: &Path, n: usize, smoothing: f64) -> anyhow::Result<[Vec<f64>; 6]> {
    let snap = match read_snapshot(path)? {
        Snapshot::Field(s) => s,
        Snapshot::Particle(p) => return particle_state(&p, n, smoothing, path),
    };
    let m = snap.grid;
    if let Some(i) = (0..m * m * m).find(|&i| snap.q[0][i] + snap.q[3][i] + snap.q[5][i] <= 0.0) {
        bail!(
            "{}: dataset 'Q': the trace (concentration) at point {i} is {}, must be positive",
            path.display(),
            snap.q[0][i] + snap.q[3][i] + snap.q[5][i]
        );
    }
    if m == n {
        return Ok(snap.q);
    }
    if m % 2 == 1 || m < 4 {
        bail!(
            "{}: grid {m} cannot be resampled (need an even grid of at least 4)",
            path.display()
        );
    }
    let (from, to) = (SpectralGrid::new(m), SpectralGrid::new(n));
    Ok(std::array::from_fn(|c| {
        to.inverse(&to.resample(&from.forward(&snap.q[c], false), &from))
    }))
}

/// The second-moment field of a particle snapshot on the `n^3` grid, smoothed by a Gaussian of
/// `smoothing` box sides ([`motile_meanfield::initial::from_particles`]); errors name the file.
pub fn particle_state(
    snap: &crate::io::snapshot::ParticleSnapshot,
    n: usize,
    smoothing: f64,
    path: &Path,
) -> anyhow::Result<[Vec<f64>; 6]> {
    motile_meanfield::initial::from_particles(
        &snap.positions,
        &snap.orientations,
        snap.box_length,
        n,
        smoothing,
    )
    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Initial Q on the grid.
pub fn initial_state(cfg: &MeanFieldRunConfig) -> anyhow::Result<[Vec<f64>; 6]> {
    if cfg.initial == "snapshot" {
        return snapshot_state(Path::new(&cfg.snapshot), cfg.grid, cfg.smoothing);
    }
    Ok(PerturbationField::new(&cfg.perturbation()).on_grid(cfg.grid))
}

/// The driver's clocks: step-size control and the output schedule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Clock {
    pub(super) dt: f64,
    pub(super) prev_dt: f64,
    pub(super) next_diag: f64,
    pub(super) next_snap: f64,
    pub(super) next_ckpt: f64,
    pub(super) snap_index: u64,
    pub(super) steps: u64,
}

const CLOCK_FIELDS: [&str; 7] = [
    "dt",
    "prev_dt",
    "next_diag",
    "next_snap",
    "next_ckpt",
    "snap_index",
    "steps",
];

impl Clock {
    fn to_vec(self) -> Vec<f64> {
        vec![
            self.dt,
            self.prev_dt,
            self.next_diag,
            self.next_snap,
            self.next_ckpt,
            self.snap_index as f64,
            self.steps as f64,
        ]
    }

    fn from_slice(v: &[f64]) -> Self {
        Self {
            dt: v[0],
            prev_dt: v[1],
            next_diag: v[2],
            next_snap: v[3],
            next_ckpt: v[4],
            snap_index: v[5] as u64,
            steps: v[6] as u64,
        }
    }
}

fn complex_flat(v: &[Vec<Complex64>]) -> Vec<f64> {
    v.iter()
        .flat_map(|c| c.iter().flat_map(|z| [z.re, z.im]))
        .collect()
}

fn complex_unflat<const K: usize>(v: &[f64], n3: usize) -> [Vec<Complex64>; K] {
    std::array::from_fn(|c| {
        v[2 * c * n3..2 * (c + 1) * n3]
            .chunks_exact(2)
            .map(|p| Complex64::new(p[0], p[1]))
            .collect()
    })
}

pub(super) fn write_checkpoint(
    path: &Path,
    stepper: &MeanFieldStepper,
    clock: &Clock,
    n: usize,
) -> anyhow::Result<()> {
    // Half spectrum of real fields: (n/2 + 1) n^2 coefficients per component.
    let n3 = ((n / 2 + 1) * n * n) as u64;
    let mut b = FileBuilder::new();
    b.set_attr(
        "kind",
        AttrValue::VarLenString("meanfield_checkpoint".into()),
    );
    b.set_attr("time", AttrValue::F64(stepper.t));
    crate::io::format::stamp(&mut b);
    b.set_attr("grid", AttrValue::U64(n as u64));
    b.set_attr(
        "spectral_layout",
        AttrValue::VarLenString("half spectrum [i2][i1][i0 <= n/2], (re, im)".into()),
    );
    b.set_attr(
        "clock_fields",
        AttrValue::VarLenString(CLOCK_FIELDS.join(",")),
    );
    b.create_dataset("clock")
        .with_f64_data(&clock.to_vec())
        .with_shape(&[CLOCK_FIELDS.len() as u64]);
    b.create_dataset("q_hat")
        .with_f64_data(&complex_flat(&stepper.q_hat))
        .with_shape(&[6, n3, 2]);
    b.create_dataset("u_hat")
        .with_f64_data(&complex_flat(&stepper.u_hat))
        .with_shape(&[3, n3, 2]);
    if let Some(h) = stepper.history() {
        b.create_dataset("prev_q_hat")
            .with_f64_data(&complex_flat(&h.q_hat))
            .with_shape(&[6, n3, 2]);
        b.create_dataset("prev_nonlinear")
            .with_f64_data(&complex_flat(&h.nonlinear))
            .with_shape(&[6, n3, 2]);
        b.create_dataset("prev_dt")
            .with_f64_data(&[h.dt])
            .with_shape(&[1]);
    }
    let bytes = b
        .finish()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    checkpoint::write_verified(path, &bytes)?;
    Ok(())
}

/// What a mean-field checkpoint holds: the stepper's state (time, Q and u coefficients, the
/// SBDF2 history) and the driver's clock.
#[derive(Clone, Debug)]
pub struct MeanFieldCheckpoint {
    /// Time.
    pub t: f64,
    /// Q's coefficients.
    pub q_hat: [Vec<Complex64>; 6],
    /// The previous step (SBDF2), absent before the first step.
    pub history: Option<History>,
    /// The velocity's coefficients (the fixed point's warm start).
    pub u_hat: [Vec<Complex64>; 3],
    pub(super) clock: Clock,
}

pub(super) fn read_checkpoint(path: &Path, n: usize) -> anyhow::Result<MeanFieldCheckpoint> {
    let f = checkpoint::H5Reader::open(path)?;
    let t = f.attr_f64("time")?;
    let n3 = (n / 2 + 1) * n * n;
    let q = f.f64s("q_hat")?;
    let u = f.f64s("u_hat")?;
    if q.len() != 12 * n3 || u.len() != 6 * n3 {
        bail!(
            "{}: checkpoint is for another grid size (expected {n}^3)",
            path.display()
        );
    }
    let damaged = |what: String| crate::io::damaged(path, what);
    let finite = |name: &str, v: &[f64], len: usize| {
        if v.len() != len {
            return Err(damaged(format!(
                "dataset '{name}' holds {} values, not {len}",
                v.len()
            )));
        }
        match v.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(damaged(format!("dataset '{name}' value {i} is {}", v[i]))),
            None => Ok(()),
        }
    };
    finite("q_hat", &q, 12 * n3)?;
    finite("u_hat", &u, 6 * n3)?;
    let history = if f.has("prev_dt") {
        let (prev_q, prev_nl) = (f.f64s("prev_q_hat")?, f.f64s("prev_nonlinear")?);
        finite("prev_q_hat", &prev_q, 12 * n3)?;
        finite("prev_nonlinear", &prev_nl, 12 * n3)?;
        let dt = f.f64s("prev_dt")?;
        if !(dt.len() == 1 && dt[0].is_finite() && dt[0] > 0.0) {
            return Err(damaged(format!("prev_dt {dt:?}")));
        }
        Some(History {
            q_hat: complex_unflat::<6>(&prev_q, n3),
            nonlinear: complex_unflat::<6>(&prev_nl, n3),
            dt: dt[0],
        })
    } else {
        None
    };
    let clock = f.f64s("clock")?;
    finite("clock", &clock, CLOCK_FIELDS.len())?;
    let whole = |v: f64| v >= 0.0 && v.fract() == 0.0 && v < 2f64.powi(53);
    let sane = t.is_finite()
        && t >= 0.0
        && clock[0] > 0.0
        && clock[1] >= 0.0
        && whole(clock[5])
        && whole(clock[6]);
    if !sane {
        return Err(damaged(format!(
            "time {t}, clock {} = {clock:?} (steps must be positive, counters whole)",
            CLOCK_FIELDS.join(", ")
        )));
    }
    Ok(MeanFieldCheckpoint {
        t,
        q_hat: complex_unflat::<6>(&q, n3),
        history,
        u_hat: complex_unflat::<3>(&u, n3),
        clock: Clock::from_slice(&clock),
    })
}
