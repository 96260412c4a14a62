//! `motile compare RUN... --out DIR` (docs/MODEL.md §5): particle and mean-field runs on one chart in
//! the mean-field unit system (the curves of [`crate::report::curves`]): the velocity norm
//! against time with its growth phases, the table of its time averages, the time-averaged
//! correlation functions, trajectory statistics and velocity slices.
//!
//! Conversions (docs/MODEL.md §5): particle time `t_mf = t_p nu / (8 eta mu)`, particle velocity
//! (reported normalised by `beta L`) `u_mf = (u_p / (beta L)) 8 eta mu / nu`; mean-field runs are
//! already in those units.

use crate::io::write_atomic;
use crate::report::curves::{
    CorrCurve, NormCurve, TrajectoryCurve, ZERO_FIELD_NORM, analyse, growth_fit, norm_curve,
};
use crate::report::plot::{Chart, Panel, Series, heatmaps, line_chart};
use anyhow::{Context, bail};
use motile_analysis::stats::window_average;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `compare` wrote.
#[derive(Clone, Debug)]
pub struct CompareReport {
    /// The curves.
    pub curves: Vec<NormCurve>,
    /// Time-averaged velocity autocorrelations (runs whose snapshots carry a flow).
    pub correlations: Vec<CorrCurve>,
    /// Trajectory statistics of the particle runs.
    pub trajectories: Vec<TrajectoryCurve>,
    /// Markdown table of the time averages.
    pub table: String,
}

/// Compare `runs` and write `velocity_norm.{png,svg,csv}`, `summary.{csv,md}`,
/// `velocity_correlation.{png,svg,csv}` and, for particle runs, `msd.{png,svg}`,
/// `orientation.{png,svg}` and `trajectories.csv` into `out`. Time averages are over the second half of
/// each run (a stated window; the table and the legend say which).
///
/// Everything is written into a staging folder beside `out` first and moved into `out` only
/// when all of it succeeded: a comparison that fails (a damaged snapshot, an unreadable run)
/// leaves nothing under the final names.
pub fn compare(runs: &[PathBuf], out: &Path) -> anyhow::Result<CompareReport> {
    if runs.is_empty() {
        bail!("compare: give at least one run directory");
    }
    let name = out
        .file_name()
        .map_or("compare".into(), |n| n.to_string_lossy().into_owned());
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent)
        .with_context(|| format!("{}: cannot create", parent.display()))?;
    let stage = parent.join(format!(".{name}.partial-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&stage);
    let result = compare_into(runs, &stage).and_then(|report| {
        std::fs::create_dir_all(out)
            .with_context(|| format!("{}: cannot create", out.display()))?;
        for entry in std::fs::read_dir(&stage)? {
            let entry = entry?;
            let target = out.join(entry.file_name());
            std::fs::rename(entry.path(), &target)
                .with_context(|| format!("{}: cannot write", target.display()))?;
        }
        Ok(report)
    });
    let _ = std::fs::remove_dir_all(&stage);
    result
}

/// [`compare`] writing straight into `out`.
fn compare_into(runs: &[PathBuf], out: &Path) -> anyhow::Result<CompareReport> {
    let curves = runs
        .iter()
        .map(|r| norm_curve(r))
        .collect::<anyhow::Result<Vec<_>>>()?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut csv = String::from("run,label,t [mu/|sigma_a|],u_l2 [L |sigma_a|/mu]\n");
    for c in &curves {
        for (t, u) in c.t.iter().zip(&c.u) {
            writeln!(csv, "{},\"{}\",{t:e},{u:e}", c.run.display(), c.label).expect("string");
        }
    }
    write_atomic(&out.join("velocity_norm.csv"), csv.as_bytes())?;
    let mut md = String::from(
        "| run | averaging window (t, mean-field units) | time-averaged velocity norm (mean-field units) | standard error | samples | growth phase (t) | growth rate over the phase (peak local rate), mean-field units | R^2, grew by | linear theory (M3) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut scsv = String::from(
        "run,label,t0,t1,mean_u_l2,std_error,samples,growth_phase,growth_t0,growth_t1,growth_rate,growth_rate_std_error,peak_rate,r_squared,growth_factor,theory_rate\n",
    );
    for c in &curves {
        let t1 = c.t.last().copied().unwrap_or(0.0);
        let t0 = 0.5 * t1;
        let w = window_average(&c.t, &c.u, t0, t1);
        let g = growth_fit(c);
        let (gw, gr, gq) = match &g {
            Some((g, true)) => (
                format!("[{:.3}, {:.3}]", g.t0, g.t1),
                format!(
                    "{:.4} +- {:.1e} (peak {:.4})",
                    g.rate, g.std_error, g.peak_rate
                ),
                format!("{:.3}, x{:.1}", g.r_squared, g.growth_factor),
            ),
            Some((g, false)) => (
                "none".into(),
                "-".into(),
                format!(
                    "no growth phase (over the run: R^2 {:.2}, x{:.2})",
                    g.r_squared, g.growth_factor
                ),
            ),
            None => ("too few samples".into(), "-".into(), "-".into()),
        };
        writeln!(
            md,
            "| {} | [{t0:.3}, {t1:.3}] | {:.4e} | {:.1e} | {} | {gw} | {gr} | {gq} | {:.4} |",
            c.label, w.mean, w.std_error, w.samples, c.theory_rate
        )
        .expect("string");
        let (phase, g0, g1, grate, gerr, peak, r2, gf) = g.map_or(
            (
                false,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
                f64::NAN,
            ),
            |(g, p)| {
                (
                    p,
                    g.t0,
                    g.t1,
                    g.rate,
                    g.std_error,
                    g.peak_rate,
                    g.r_squared,
                    g.growth_factor,
                )
            },
        );
        writeln!(
            scsv,
            "{},\"{}\",{t0:e},{t1:e},{:e},{:e},{},{phase},{g0:e},{g1:e},{grate:e},{gerr:e},{peak:e},{r2:e},{gf:e},{:e}",
            c.run.display(),
            c.label,
            w.mean,
            w.std_error,
            w.samples,
            c.theory_rate
        )
        .expect("string");
    }
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    write_atomic(&out.join("summary.csv"), scsv.as_bytes())?;
    line_chart(
        &out.join("velocity_norm"),
        &Chart {
            title: "Velocity norm, mean-field units (docs/MODEL.md section 5)",
            x_label: "t [mu/|sigma_a|]",
            y_label: "||u||_2 [L |sigma_a|/mu]",
            series: curves
                .iter()
                .map(|c| Series {
                    label: c.label.clone(),
                    points: c.t.iter().copied().zip(c.u.iter().copied()).collect(),
                })
                .collect(),
        },
    )?;
    // Each run's snapshots analysed once: Corr[u] and order-parameter correlations over its second
    // half (in its own time unit), the last snapshot's velocity slice, trajectories.
    let mut correlations = Vec::new();
    let mut trajectories = Vec::new();
    let mut order: Vec<(String, Vec<Series>)> = Vec::new();
    let mut panels = Vec::new();
    let analyses = runs
        .iter()
        .zip(&curves)
        .map(|(run, c)| analyse(run, &c.label, 0.5 * c.t_end_own))
        .collect::<anyhow::Result<Vec<_>>>()?;
    // Concentrated suspensions (every run a particle run with nu > 1) keep their structure at
    // the rod scale: their order-parameter correlations are read against r/l (docs/MODEL.md §7).
    let concentrated = analyses
        .iter()
        .all(|a| a.particle.is_some_and(|(_, nu)| nu > 1.0));
    let mut lcsv = String::from("run,label,field,correlation_length [L],correlation_length [l]\n");
    let mut lmd = String::from(
        "\n| run | correlation lengths (first zero of the time-averaged Corr, second half): r/L (r/l for particle runs) |\n|---|---|\n",
    );
    for ((run, c), a) in runs.iter().zip(&curves).zip(&analyses) {
        let mut cells = Vec::new();
        for (field, z) in &a.lengths {
            let in_l = a.particle.map_or(f64::NAN, |(l, _)| z * l);
            writeln!(
                lcsv,
                "{},\"{}\",{field},{z:e},{in_l:e}",
                run.display(),
                c.label
            )
            .expect("string");
            cells.push(if z.is_nan() {
                format!("{field}: no zero")
            } else if a.particle.is_some() {
                format!("{field}: {z:.3} ({in_l:.2})")
            } else {
                format!("{field}: {z:.3}")
            });
        }
        for field in &a.zero_fields {
            cells.push(format!(
                "{field}: identically zero (||{field}||_2 <= {ZERO_FIELD_NORM:.0e}), not plotted"
            ));
        }
        writeln!(lmd, "| {} | {} |", c.label, cells.join("; ")).expect("string");
    }
    write_atomic(&out.join("correlation_lengths.csv"), lcsv.as_bytes())?;
    md.push_str(&lmd);
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    for (c, a) in curves.iter().zip(analyses) {
        correlations.extend(a.corr_u);
        if let Some((n, values, t)) = a.slice {
            panels.push(Panel {
                label: format!("{} at t = {t:.3}", c.label),
                n,
                values,
            });
        }
        trajectories.extend(a.traj);
        let to_l = match (concentrated, a.particle) {
            (true, Some((l, _))) => l,
            _ => 1.0,
        };
        for (name, points) in a.order {
            let points: Vec<(f64, f64)> = points.into_iter().map(|(r, v)| (r * to_l, v)).collect();
            match order.iter_mut().find(|(n, _)| *n == name) {
                Some((_, series)) => series.push(Series {
                    label: c.label.clone(),
                    points,
                }),
                None => order.push((
                    name,
                    vec![Series {
                        label: c.label.clone(),
                        points,
                    }],
                )),
            }
        }
    }
    // Velocity magnitude on z = 0 at each run's last snapshot, side by side, one colour scale.
    if !panels.is_empty() {
        heatmaps(
            &out.join("velocity_slice"),
            "|u| on the plane z = 0, last snapshot, mean-field units",
            "|u| [L |sigma_a|/mu]",
            &panels,
        )?;
    }
    // Order-parameter correlations, one chart per field, shapes compared (normalised at 0).
    for (name, series) in &order {
        line_chart(
            &out.join(format!("correlation_{name}")),
            &Chart {
                title: &format!("Corr[{name}](r) / Corr[{name}](0), second half of each run"),
                x_label: if concentrated { "r / l" } else { "r / L" },
                y_label: &format!("Corr[{name}](r) / Corr[{name}](0)"),
                series: series.clone(),
            },
        )?;
    }
    if !trajectories.is_empty() {
        let mut tcsv = String::from("label,t [1/beta],msd [l^2],orientation_autocorrelation [1]\n");
        for tr in &trajectories {
            for k in 0..tr.t.len() {
                writeln!(
                    tcsv,
                    "\"{}\",{:e},{:e},{:e}",
                    tr.label, tr.t[k], tr.msd[k], tr.orientation[k]
                )
                .expect("string");
            }
        }
        write_atomic(&out.join("trajectories.csv"), tcsv.as_bytes())?;
        for (stem, title, y_label, pick) in [
            (
                "msd",
                "Mean squared displacement of the rods",
                "<|x(t) - x(0)|^2> [l^2]",
                0,
            ),
            (
                "orientation",
                "Orientation autocorrelation of the rods",
                "<p(t) . p(0)> [1]",
                1,
            ),
        ] {
            line_chart(
                &out.join(stem),
                &Chart {
                    title,
                    x_label: "t [1/beta]",
                    y_label,
                    series: trajectories
                        .iter()
                        .map(|tr| Series {
                            label: tr.label.clone(),
                            points: tr
                                .t
                                .iter()
                                .copied()
                                .zip(
                                    if pick == 0 { &tr.msd } else { &tr.orientation }
                                        .iter()
                                        .copied(),
                                )
                                .collect(),
                        })
                        .collect(),
                },
            )?;
        }
    }
    let mut ccsv = String::from("label,r/L,Corr[u] [(L |sigma_a|/mu)^2]\n");
    for c in &correlations {
        for (r, v) in c.r.iter().zip(&c.value) {
            writeln!(ccsv, "\"{}\",{r:e},{v:e}", c.label).expect("string");
        }
    }
    write_atomic(&out.join("velocity_correlation.csv"), ccsv.as_bytes())?;
    line_chart(
        &out.join("velocity_correlation"),
        &Chart {
            title: "Time-averaged velocity autocorrelation, mean-field units",
            x_label: "r / L",
            y_label: "Corr[u](r) [(L |sigma_a|/mu)^2]",
            series: correlations
                .iter()
                .map(|c| Series {
                    label: c.label.clone(),
                    points: c.r.iter().copied().zip(c.value.iter().copied()).collect(),
                })
                .collect(),
        },
    )?;
    Ok(CompareReport {
        curves,
        correlations,
        trajectories,
        table: md,
    })
}

#[cfg(test)]
mod tests {
    use motile_particle::model::units::{DEFAULT_DIAMETER, particle_to_meanfield};

    #[test]
    fn conversions_are_the_model_ones() {
        // nu = 0.625: 8 eta / nu = 2.3454...
        let s = 8.0 * 0.183_233_6 / 0.625;
        let (t, u) = particle_to_meanfield(10.0, 0.01, 0.625, DEFAULT_DIAMETER);
        assert!(
            (t - 10.0 / s).abs() < 1e-5 && (u - 0.01 * s).abs() < 1e-7,
            "{t} {u}"
        );
    }
}
