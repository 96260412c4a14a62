//! What a particle run writes of each step, apart from the run loop: the time series' columns
//! and rows, the flow's norms and lowest modes from a force density, and snapshots (HDF5 and
//! VTK). A leaf: the adapter (`mod.rs`) and the resident step (`device.rs`) use it.

use super::config::ParticleRunConfig;
use crate::io::rundir::RunDir;
use crate::io::snapshot::{Kinematics, ParticleSnapshot, PointForces};
use crate::io::vtk::{write_pvd, write_rods_vtp};
use motile_analysis::correlation::{CorrelationOptions, velocity_modes, velocity_spectrum};
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::{ROD_LENGTH, SWIM_SPEED, VISCOSITY};
use motile_particle::step::report::StepReport;
use motile_particle::step::stepper::Stepper;

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

/// A row of `timeseries.csv` ([`COLUMNS`]) from a step's report, the wall-clock rate and the
/// flow's norms (all and box-scale modes).
pub(super) fn series_row(t: f64, rate: f64, report: &StepReport, norms: (f64, f64)) -> Vec<f64> {
    let c = &report.contact;
    vec![
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
        norms.0, // NORM_COLUMN
        report.max_speed,
        report.max_rotation_rate,
        report.correction_active as f64,
        report.projections as f64,
        report.hydro.sum_error_ratio,
        report.hydro.sum_level as f64,
        norms.1, // BOX_NORM_COLUMN
    ]
}

/// The wavevectors of `modes.csv`: the three lowest box modes.
const LOWEST_MODES: [[i64; 3]; 3] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

/// Columns of `modes.csv`: time, then per lowest mode the real and imaginary parts of the
/// flow's three components (A1, units of `beta l`).
pub fn mode_columns() -> Vec<String> {
    let mut c = vec!["t [1/beta]".to_string()];
    for m in ["100", "010", "001"] {
        for d in ["x", "y", "z"] {
            for part in ["re", "im"] {
                c.push(format!("u_{m}_{d}_{part} [beta l]"));
            }
        }
    }
    c
}

/// The NUFFT tolerance of the flow's norms in the time series: the norms stay within it of the
/// direct sums on force-free pairs (analysis/tests/correlation.rs), the transform at the L75
/// member's size takes 1.8x less time than at 1e-6 (BENCHMARKS.md, NUFFT), and the statistics
/// drawn from the norm carry standard errors of a few percent. `motile analyze` recomputes it
/// from snapshots at 1e-6.
pub(super) const NORM_TOLERANCE: f64 = 1e-4;

/// What a diagnostic step records of the flow of the state `at`: its norms (all analysis modes
/// and the box-scale ones, units of `beta L`) and, where asked, the row of `modes.csv` at `t`.
pub(super) struct FlowDiagnostics {
    /// `(||u||_2, box-scale ||u||_2)`; zero for models without flow.
    pub(super) norms: (f64, f64),
    /// The lowest modes' row, where asked.
    pub(super) modes: Option<Vec<f64>>,
}

/// The flow's diagnostics of the state `at` from its force density, the point forces computed
/// once for the norms and the lowest modes (docs/MODEL.md §5, §6: the velocity spectrum on
/// `floor(L/2)` modes per dimension, doublet neglected).
pub(super) fn flow_diagnostics(
    stepper: &Stepper,
    at: &RodSet,
    t: f64,
    modes: bool,
) -> anyhow::Result<FlowDiagnostics> {
    match point_forces_of(stepper, at) {
        Some(pf) => diagnostics_of(&pf, at.box_length, t, modes),
        None => Ok(FlowDiagnostics {
            norms: (0.0, 0.0),
            modes: modes.then(|| {
                let mut row = vec![t];
                row.extend([0.0; 18]);
                row
            }),
        }),
    }
}

/// The point forces of the state `at` (its force density at the quadrature points); `None`
/// for models without flow.
pub(super) fn point_forces_of(stepper: &Stepper, at: &RodSet) -> Option<PointForces> {
    let fd = stepper.mobility().force_density()?;
    let (points, forces) = fd.point_forces(at, &at.orientations());
    Some(PointForces { points, forces })
}

/// The flow's norms (and, where asked, the lowest modes' row at `t`) of point forces in a box
/// of side `l`: a function of its inputs alone, so that it can run beside the next steps.
pub(super) fn diagnostics_of(
    pf: &PointForces,
    l: f64,
    t: f64,
    modes: bool,
) -> anyhow::Result<FlowDiagnostics> {
    let norms = velocity_norms(&pf.points, &pf.forces, l)?;
    let modes = modes.then(|| {
        let mut row = vec![t];
        for u in velocity_modes(&pf.points, &pf.forces, l, VISCOSITY, &LOWEST_MODES) {
            for c in u {
                row.extend([c.re, c.im]);
            }
        }
        row
    });
    Ok(FlowDiagnostics { norms, modes })
}

/// Put the flow's norms into a time-series row made by [`series_row`].
pub(super) fn set_norms(row: &mut [f64], norms: (f64, f64)) {
    row[NORM_COLUMN] = norms.0;
    row[BOX_NORM_COLUMN] = norms.1;
}

/// Where [`series_row`] puts `velocity_norm` and `velocity_norm_box`.
const NORM_COLUMN: usize = 11;
const BOX_NORM_COLUMN: usize = 18;

/// The flow's volume-averaged L2 norm from the velocity spectrum of the point forces, over
/// the analysis modes and over the box-scale modes alone (every `|m_i| <= 1`: wavelengths of
/// one box and more, where the instability begins), both in units of `beta L`.
fn velocity_norms(points: &[[f64; 3]], forces: &[[f64; 3]], l: f64) -> anyhow::Result<(f64, f64)> {
    let modes = CorrelationOptions::default().modes_for(l);
    let spectrum = velocity_spectrum(points, forces, l, VISCOSITY, modes, NORM_TOLERANCE)?;
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

pub(super) fn write_snapshot(
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
            rods.diameter / 2.0,
            &speed,
        )?;
        pvd.retain(|(_, f)| *f != name);
        pvd.push((t, name));
        write_pvd(&run.path().join("rods.pvd"), pvd)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_norms_go_into_their_columns() {
        assert!(COLUMNS[NORM_COLUMN].starts_with("velocity_norm ["));
        assert!(COLUMNS[BOX_NORM_COLUMN].starts_with("velocity_norm_box ["));
        let mut row = vec![0.0; COLUMNS.len()];
        set_norms(&mut row, (1.0, 2.0));
        assert_eq!((row[NORM_COLUMN], row[BOX_NORM_COLUMN]), (1.0, 2.0));
    }
}
