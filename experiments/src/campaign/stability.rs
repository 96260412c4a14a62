//! `motile stability particle|meanfield`: where methods fail. A grid of short runs, time step
//! against volume fraction (particle) or against resolution (mean-field); each cell is the
//! run's outcome, read from the structured error a failing run ends with (overlap beyond
//! tolerance, contact solver or GMRES not converging, non-finite values; realizability lost,
//! fixed point not converging), drawn as a map (PNG, SVG) with the CSV behind it.

use crate::io::rundir::TimeSeries;
use crate::io::write_atomic;
use crate::report::plot::{OutcomeMap, outcome_map};
use crate::run::failure::{FailureKind, RunFailure};
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::Context;
use std::fmt::Write as _;
use std::path::Path;

/// Outcome categories: legend name and colour.
pub const CATEGORIES: [(&str, (u8, u8, u8)); 8] = [
    ("ran to the end", (120, 200, 120)),
    ("overlap beyond tolerance", (240, 170, 60)),
    ("contact solver failed", (200, 120, 200)),
    ("GMRES failed", (120, 160, 230)),
    ("non-finite (blow-up)", (220, 80, 80)),
    ("realizability lost", (250, 220, 90)),
    ("fixed point failed", (150, 110, 90)),
    ("other error", (170, 170, 170)),
];

/// The category of a run's result, an index into [`CATEGORIES`], from the [`RunFailure`] in
/// its error chain (the variant, never the message's text); errors that are not a failed step
/// (a bad file, a full disk) are "other error".
pub fn classify(result: &anyhow::Result<()>) -> usize {
    let Err(e) = result else { return 0 };
    match RunFailure::of(e).map(|f| f.kind) {
        Some(FailureKind::Overlap) => 1,
        Some(FailureKind::ContactSolver) => 2,
        Some(FailureKind::Hydrodynamics) => 3,
        Some(FailureKind::NonFinite) => 4,
        Some(FailureKind::Realizability) => 5,
        Some(FailureKind::FixedPoint) => 6,
        Some(FailureKind::Setup | FailureKind::Device) | None => 7,
    }
}

/// One cell of a map.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// The time step (particle: dt; mean-field: dt_max).
    pub dt: f64,
    /// The other axis (volume fraction or grid).
    pub y: f64,
    /// Category index into [`CATEGORIES`].
    pub category: usize,
    /// Simulated time reached.
    pub t_reached: f64,
    /// The error message (empty when the run ended normally).
    pub message: String,
    /// Wall seconds.
    pub seconds: f64,
    /// A figure of merit for runs that ended (particle: largest overlap in l; mean-field:
    /// smallest eigenvalue of Q/tr Q).
    pub merit: f64,
}

fn column_extreme(ts: &Path, prefix: &str, max: bool) -> f64 {
    let Ok(ts) = TimeSeries::read(ts) else {
        return f64::NAN;
    };
    let Some(c) = ts.columns.iter().position(|c| c.starts_with(prefix)) else {
        return f64::NAN;
    };
    let vals = ts.rows.iter().map(|r| r[c]);
    if max {
        vals.fold(f64::NEG_INFINITY, f64::max)
    } else {
        vals.fold(f64::INFINITY, f64::min)
    }
}

/// Run one cell into a fresh `dir`: its outcome, the time it reached and its figure of merit
/// (the extreme of a time-series column: `(prefix, largest?)`).
fn run_cell(
    dir: &Path,
    label: &str,
    (dt, y, t_end): (f64, f64, f64),
    (merit_column, largest): (&str, bool),
    run: impl FnOnce(&Path) -> anyhow::Result<()>,
    event: &mut dyn FnMut(&str),
) -> anyhow::Result<Cell> {
    crate::io::remove_old_run(dir)?;
    let t0 = std::time::Instant::now();
    let result = run(dir);
    let seconds = t0.elapsed().as_secs_f64();
    let category = classify(&result);
    let t_reached = match &result {
        Ok(()) => t_end,
        Err(e) => RunFailure::of(e).map_or(f64::NAN, |f| f.t),
    };
    let message = result.err().map(|e| format!("{e:#}")).unwrap_or_default();
    event(&format!(
        "{label}: {} (t = {t_reached}, {seconds:.1} s){}",
        CATEGORIES[category].0,
        if message.is_empty() {
            String::new()
        } else {
            format!(": {message}")
        }
    ));
    Ok(Cell {
        dt,
        y,
        category,
        t_reached,
        message,
        seconds,
        merit: column_extreme(&dir.join("timeseries.csv"), merit_column, largest),
    })
}

/// Write the map's CSV, PNG and SVG as `out/<stem>.*`: `(stem, title)` name it, `(y_name,
/// merit_name)` its vertical axis and the merit of a run that ended well, `(dts, ys)` its axes.
fn write_map(
    out: &Path,
    (stem, title): (&str, &str),
    (y_name, merit_name): (&str, &str),
    (dts, ys): (&[f64], &[f64]),
    cells: &[Cell],
) -> anyhow::Result<String> {
    let mut csv = format!("dt,{y_name},outcome,t_reached,wall_seconds,{merit_name},message\n");
    for c in cells {
        writeln!(
            csv,
            "{},{},\"{}\",{},{:.2},{:e},\"{}\"",
            c.dt,
            c.y,
            CATEGORIES[c.category].0,
            c.t_reached,
            c.seconds,
            c.merit,
            c.message.replace('"', "'")
        )
        .expect("string");
    }
    write_atomic(&out.join(format!("{stem}.csv")), csv.as_bytes())?;
    let used: Vec<usize> = (0..CATEGORIES.len())
        .filter(|k| cells.iter().any(|c| c.category == *k))
        .collect();
    let map = OutcomeMap {
        title,
        x_label: "time step dt",
        y_label: y_name,
        x_ticks: dts.iter().map(|d| format!("{d}")).collect(),
        y_ticks: ys.iter().map(|y| format!("{y}")).collect(),
        categories: used
            .iter()
            .map(|&k| (CATEGORIES[k].0.to_string(), CATEGORIES[k].1))
            .collect(),
        cells: cells
            .iter()
            .map(|c| {
                let xi = dts.iter().position(|d| *d == c.dt).unwrap_or(0);
                let yi = ys.iter().position(|y| *y == c.y).unwrap_or(0);
                let k = used.iter().position(|u| *u == c.category).unwrap_or(0);
                let text = if c.category == 0 {
                    format!("{merit_name}\n{:.1e}\n{:.0} s", c.merit, c.seconds)
                } else {
                    format!("stopped at\nt = {:.1}\n{:.0} s", c.t_reached, c.seconds)
                };
                (xi, yi, k, text)
            })
            .collect(),
    };
    outcome_map(&out.join(stem), &map)?;
    let mut md = format!(
        "| dt | {y_name} | outcome | t reached | wall (s) | {merit_name} |\n|---|---|---|---|---|---|\n"
    );
    for c in cells {
        writeln!(
            md,
            "| {} | {} | {} | {} | {:.1} | {:.2e} |",
            c.dt, c.y, CATEGORIES[c.category].0, c.t_reached, c.seconds, c.merit
        )
        .expect("string");
    }
    write_atomic(&out.join(format!("{stem}.md")), md.as_bytes())?;
    Ok(md)
}

/// Particle map: every `dt` against every volume fraction, from `base` (box, hydrodynamics,
/// t_end, seed), runs in `out/runs/`, map `out/stability_particle.*`.
pub fn particle_map(
    base: &ParticleRunConfig,
    dts: &[f64],
    fractions: &[f64],
    out: &Path,
    event: &mut dyn FnMut(&str),
) -> anyhow::Result<(Vec<Cell>, String)> {
    // Every cell's config is checked before anything is written.
    let mut configs = Vec::new();
    for &nu in fractions {
        for &dt in dts {
            let mut c = base.clone();
            c.volume_fraction = nu;
            c.rods = None;
            c.dt = dt;
            // The contact margin follows the step where it must (2.5 U dt).
            c.contact.margin = c.contact.margin.max(2.5 * dt);
            c.vtk = false;
            c.snapshot_interval = c.t_end;
            c.checkpoint_interval = c.t_end;
            c.diagnostic_interval = c.diagnostic_interval.max(dt);
            c.validate()
                .map_err(|e| anyhow::anyhow!("stability map, dt = {dt}, nu = {nu}: {e}"))?;
            configs.push((nu, dt, c));
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut cells = Vec::new();
    for (nu, dt, c) in configs {
        let dir = out.join("runs").join(format!("particle_nu{nu}_dt{dt}"));
        cells.push(run_cell(
            &dir,
            &format!("nu = {nu}, dt = {dt}"),
            (dt, nu, c.t_end),
            ("max_overlap", true),
            |d| particle::run_particle(&c, d, false).map(|_| ()),
            event,
        )?);
    }
    let title = format!(
        "particle ({}), L/l = {}, to t = {} (1/beta)",
        base.hydrodynamics, base.box_length, base.t_end
    );
    let md = write_map(
        out,
        ("stability_particle", &title),
        ("volume fraction nu", "max overlap [l]"),
        (dts, fractions),
        &cells,
    )?;
    Ok((cells, md))
}

/// Mean-field map: every `dt_max` against every grid, from `base` (zeta, D, t_end, initial
/// condition; `cfl` and `step_retries` as given there), runs in `out/runs/`, map
/// `out/stability_meanfield.*`.
pub fn meanfield_map(
    base: &MeanFieldRunConfig,
    dts: &[f64],
    grids: &[usize],
    out: &Path,
    event: &mut dyn FnMut(&str),
) -> anyhow::Result<(Vec<Cell>, String)> {
    // Every cell's config is checked before anything is written.
    let mut configs = Vec::new();
    for &n in grids {
        for &dt in dts {
            let mut c = base.clone();
            c.grid = n;
            c.dt_max = dt;
            c.snapshot_interval = c.t_end;
            c.checkpoint_interval = c.t_end;
            c.validate()
                .map_err(|e| anyhow::anyhow!("stability map, dt = {dt}, grid = {n}: {e}"))?;
            configs.push((n, dt, c));
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    meanfield::closure_tables(base.closure_degree)?;
    let mut cells = Vec::new();
    for (n, dt, c) in configs {
        let dir = out.join("runs").join(format!("meanfield_{n}_dt{dt}"));
        cells.push(run_cell(
            &dir,
            &format!("grid {n}^3, dt_max = {dt}"),
            (dt, n as f64, c.t_end),
            ("min_eigenvalue", false),
            |d| meanfield::run_meanfield(&c, d, false).map(|_| ()),
            event,
        )?);
    }
    let title = format!(
        "mean field, zeta = {}, D = {}, cfl = {}, to t = {}",
        base.zeta, base.diffusion, base.cfl, base.t_end
    );
    let ys: Vec<f64> = grids.iter().map(|&n| n as f64).collect();
    let md = write_map(
        out,
        ("stability_meanfield", &title),
        ("grid points per side", "min eig Q/trQ"),
        (dts, &ys),
        &cells,
    )?;
    Ok((cells, md))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failures_are_classified_by_their_variant() {
        let kinds = [
            (FailureKind::Overlap, 1),
            (FailureKind::ContactSolver, 2),
            (FailureKind::Hydrodynamics, 3),
            (FailureKind::NonFinite, 4),
            (FailureKind::Realizability, 5),
            (FailureKind::FixedPoint, 6),
            (FailureKind::Setup, 7),
        ];
        for (kind, k) in kinds {
            let e: anyhow::Error = RunFailure {
                kind,
                step: 3,
                t: 0.5,
                // The text says nothing that could classify it.
                message: "failed".into(),
            }
            .into();
            let r: anyhow::Result<()> = Err(e.context("cell 4"));
            assert_eq!(classify(&r), k, "{kind:?}");
        }
        // Another error mentioning GMRES is still "other": the text is not read.
        assert_eq!(classify(&Err(anyhow::anyhow!("GMRES overlap by"))), 7);
        assert_eq!(classify(&Ok(())), 0);
    }
}
