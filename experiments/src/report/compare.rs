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
use crate::report::plot::{Chart, Panel, Series, heatmaps, line_chart, semilog_chart};
use anyhow::{Context, bail};
use motile_analysis::stats::window_average;
use motile_particle::model::linear_theory::onset_box;
use motile_particle::model::units::{DEFAULT_DIAMETER, SWIM_SPEED};
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
/// `orientation.{png,svg}` and `trajectories.csv`, the series summary `series.{csv,md}` and
/// `saturated_norm.{png,svg}` into `out`. Time averages are over each run's saturated state
/// ([`saturated_from`]; the table and the legends say which).
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

/// Where a run's saturated state starts (mean-field units): the later of the end of its growth
/// phase and half the run (without a growth phase, half the run). Time averages (the norm, the
/// correlations) are taken from there to the end.
pub fn saturated_from(c: &NormCurve) -> f64 {
    let half = 0.5 * c.t.last().copied().unwrap_or(0.0);
    match growth_fit(c) {
        Some((g, true)) => g.t1.max(half),
        _ => half,
    }
}

/// A run's time in its own unit from mean-field units.
fn own_time(c: &NormCurve, t_mf: f64) -> f64 {
    c.particle.as_ref().map_or(t_mf, |p| t_mf * p.time_unit)
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
        let t0 = saturated_from(c);
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
    // The norm on a log axis, each run's linear theory drawn as a slope from its first
    // sample: the box theory's Re sigma for particles (docs/MODEL.md §5b), M3 for the mean
    // field.
    let u_max = curves
        .iter()
        .flat_map(|c| c.u.iter().copied())
        .fold(0.0, f64::max);
    // Particle runs also get the box theory with the rotational diffusion measured in them.
    let slopes: Vec<(usize, &NormCurve, f64, String)> = curves
        .iter()
        .enumerate()
        .flat_map(|(i, c)| {
            let mut v = Vec::new();
            match &c.particle {
                Some(p) => {
                    if let Some(s) = p.box_theory {
                        v.push((i, c, s.re, format!("L/l = {} box theory", p.box_length)));
                    }
                    if let (Some(s), Some(d)) = (p.box_theory_dr, p.rotational_diffusion) {
                        v.push((
                            i,
                            c,
                            s.re,
                            format!(
                                "L/l = {} box theory, measured d_r = {d:.1e}/beta",
                                p.box_length
                            ),
                        ));
                    }
                }
                None => v.push((i, c, c.theory_rate, "M3".to_string())),
            }
            v
        })
        .collect();
    let theory: Vec<(Series, usize)> = slopes
        .into_iter()
        .filter_map(|(i, c, rate, what)| {
            let (&t0, &u0) = (c.t.first()?, c.u.first()?);
            if rate <= 0.0 || u0 <= 0.0 {
                return None;
            }
            let t_hit = t0 + (2.0 * u_max / u0).ln() / rate;
            let t1 = t_hit.min(c.t.last().copied().unwrap_or(t0));
            Some((
                Series {
                    label: format!("linear theory ({what}): rate {rate:.3}"),
                    points: (0..=20)
                        .map(|k| {
                            let t = t0 + (t1 - t0) * k as f64 / 20.0;
                            (t, u0 * (rate * (t - t0)).exp())
                        })
                        .collect(),
                },
                i,
            ))
        })
        .collect();
    semilog_chart(
        &out.join("velocity_norm"),
        &Chart {
            title: "Velocity norm (particles: box-scale modes), mean-field units",
            x_label: "t [mu/|sigma_a|]",
            y_label: "||u||_2 [L |sigma_a|/mu]",
            series: curves
                .iter()
                .map(|c| Series {
                    label: match &c.particle {
                        Some(p) => format!("{} (N = {}, from its noise)", c.label, p.rods),
                        None => c.label.clone(),
                    },
                    points: c.t.iter().copied().zip(c.u.iter().copied()).collect(),
                })
                .collect(),
        },
        &theory,
    )?;
    // Each run's snapshots analysed once: Corr[u] and order-parameter correlations over its second
    // half (in its own time unit), the last snapshot's velocity slice, trajectories.
    let mut correlations = Vec::new();
    let mut trajectories = Vec::new();
    let mut order: Vec<(String, Vec<Series>)> = Vec::new();
    let mut panels = Vec::new();
    // Velocity slices of every run at one time: the latest all of them reached (each run's
    // snapshot nearest it).
    let common = curves
        .iter()
        .filter_map(|c| c.t.last().copied())
        .fold(f64::INFINITY, f64::min);
    let analyses = runs
        .iter()
        .zip(&curves)
        .map(|(run, c)| {
            let slice_at = common.is_finite().then(|| own_time(c, common));
            analyse(run, &c.label, own_time(c, saturated_from(c)), slice_at)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    // Concentrated suspensions (every run a particle run with nu > 1) keep their structure at
    // the rod scale: their order-parameter correlations are read against r/l (docs/MODEL.md §7).
    let concentrated = analyses
        .iter()
        .all(|a| a.particle.is_some_and(|(_, nu)| nu > 1.0));
    let mut lcsv = String::from("run,label,field,correlation_length [L],correlation_length [l]\n");
    let mut lmd = String::from(
        "\n| run | correlation lengths (first zero of the Corr averaged over the saturated state): r/L (r/l for particle runs) |\n|---|---|\n",
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
    let corr_zero: Vec<f64> = analyses
        .iter()
        .map(|a| {
            a.lengths
                .iter()
                .find(|(n, _)| n == "u")
                .map_or(f64::NAN, |x| x.1)
        })
        .collect();
    write_series(&curves, &corr_zero, out)?;
    md.push_str(&lmd);
    md.push_str("\nTime averages are over each run's saturated state: from the later of the end of its growth phase and half the run, to its end (samples correlated over a few diagnostic intervals: the standard error comes from batch means over up to 10 contiguous blocks). Particle runs start at their sampling noise, about 1/sqrt(N) in each box mode, while the continuum starts from a seeded perturbation, so the particle curves start apart.\n");
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
        for (name, points) in a.order {
            // c and n (particle runs only) decay within a rod length: against r/l up to 5 l.
            // Q against r/L, or r/l where every run is concentrated.
            let rod_scale = name == "c" || name == "n";
            let to_l = match (concentrated || rod_scale, a.particle) {
                (true, Some((l, _))) => l,
                _ => 1.0,
            };
            let points: Vec<(f64, f64)> = points
                .into_iter()
                .map(|(r, v)| (r * to_l, v))
                .filter(|(r, _)| !rod_scale || *r <= 5.0)
                .collect();
            match order.iter_mut().find(|(n, _)| *n == name) {
                Some((_, series)) => series.push(Series {
                    label: format!("{} ({} snapshots)", c.label, a.window_count),
                    points,
                }),
                None => order.push((
                    name,
                    vec![Series {
                        label: format!("{} ({} snapshots)", c.label, a.window_count),
                        points,
                    }],
                )),
            }
        }
    }
    // Velocity magnitude on z = 0 of every run at one time (each run's snapshot nearest the
    // latest time all runs reached), side by side, one colour scale.
    if !panels.is_empty() {
        heatmaps(
            &out.join("velocity_slice"),
            "|u| on the plane z = 0 at the latest time all runs reached, mean-field units",
            "|u| [L |sigma_a|/mu]",
            &panels,
        )?;
    }
    // Order-parameter correlations, one chart per field, shapes compared (normalised at 0).
    for (name, series) in &order {
        let in_l = concentrated || name == "c" || name == "n";
        line_chart(
            &out.join(format!("correlation_{name}")),
            &Chart {
                title: &format!("Corr[{name}](r) / Corr[{name}](0), saturated state of each run"),
                x_label: if in_l { "r / l" } else { "r / L" },
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
                        .chain((pick == 0).then(|| {
                            // Free swimming: ballistic at the swimming speed.
                            let t_max = trajectories
                                .iter()
                                .flat_map(|tr| tr.t.iter().copied())
                                .fold(0.0, f64::max);
                            Series {
                                label: "(U t)^2, ballistic at the swimming speed".into(),
                                points: (0..=40)
                                    .map(|k| {
                                        let t = t_max * k as f64 / 40.0;
                                        (t, (SWIM_SPEED * t).powi(2))
                                    })
                                    .collect(),
                            }
                        }))
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

/// The series summary (`series.csv`, `series.md`): one row per run with its model, size, level,
/// growth rate with its window, R^2 and growth factor, the saturated norm with its standard
/// error, and the first zero of the time-averaged Corr[u] (units of L); and, with
/// particle runs, the saturated norm against L/l beside the continuum's, with the onset of the
/// box's linear theory marked (`saturated_norm.{png,svg}`).
fn write_series(curves: &[NormCurve], corr_zero: &[f64], out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from(
        "model,L/l,rods,level,growth_phase,growth_rate [mf],growth_t0 [mf],growth_t1 [mf],r_squared,growth_factor,theory_rate [mf],rotational_diffusion [beta],theory_rate_d_r [mf],saturated_from [mf],mean_u_l2 [mf],std_error,samples,batches,corr_u_first_zero [L]\n",
    );
    let mut md = String::from(
        "# Series summary\n\nOne row per run, mean-field units. Growth: the least-squares rate of ln ||u||_2 over the growth phase (docs/MODEL.md §6), with its window, R^2 and growth factor; theory: the box's linear theory (Re sigma of the lowest mode, docs/MODEL.md §5b) for particles, without diffusion and with the rotational diffusion d_r (1/beta) measured in the run from <p(t).p(0)> over its first half; M3 for the continuum. Saturated norm: the time average from the later of the growth phase's end and half the run, to its end; standard error from batch means over up to 10 contiguous blocks (samples within a block are correlated; blocks are taken as independent).\n\n| run | L/l | rods | level | growth rate (window, R^2, grown by) | theory | saturated ||u||_2 | samples | first zero of Corr[u] (L) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut points = Vec::new();
    let mut continuum = Vec::new();
    for (c, &zero) in curves.iter().zip(corr_zero) {
        let g = growth_fit(c);
        let t1 = c.t.last().copied().unwrap_or(0.0);
        let s0 = saturated_from(c);
        let w = window_average(&c.t, &c.u, s0, t1);
        let (model, l, rods, level, theory) = match &c.particle {
            Some(p) => (
                "particle",
                p.box_length,
                p.rods.to_string(),
                p.level.clone(),
                p.box_theory.map_or(f64::NAN, |s| s.re),
            ),
            None => (
                "meanfield",
                f64::NAN,
                "-".to_string(),
                "continuum".to_string(),
                c.theory_rate,
            ),
        };
        let (d_r, theory_dr) = c.particle.as_ref().map_or((f64::NAN, f64::NAN), |p| {
            (
                p.rotational_diffusion.unwrap_or(f64::NAN),
                p.box_theory_dr.map_or(f64::NAN, |s| s.re),
            )
        });
        let (grew, rate, g0, g1, r2, gf) = match &g {
            Some((g, p)) => (*p, g.rate, g.t0, g.t1, g.r_squared, g.growth_factor),
            None => (false, f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN),
        };
        writeln!(
            csv,
            "{model},{l},{rods},{level},{grew},{rate:e},{g0:e},{g1:e},{r2},{gf},{theory:e},{d_r:e},{theory_dr:e},{s0:e},{:e},{:e},{},{},{zero:e}",
            w.mean, w.std_error, w.samples, w.batches
        )?;
        writeln!(
            md,
            "| {} | {} | {rods} | {level} | {} | {} | {:.4e} +- {:.1e} (from t = {s0:.1}) | {} | {} |",
            c.label,
            if l.is_nan() {
                "-".into()
            } else {
                format!("{l}")
            },
            if grew {
                format!("{rate:.4} ({g0:.1}-{g1:.1}, R^2 {r2:.3}, x{gf:.0})")
            } else {
                format!("no growth phase (R^2 {r2:.2}, x{gf:.1})")
            },
            match (theory.is_nan(), d_r.is_nan()) {
                (true, _) => "damped".to_string(),
                (false, true) => format!("{theory:.4}"),
                (false, false) => format!(
                    "{theory:.4}; with d_r = {d_r:.1e}: {}",
                    if theory_dr.is_nan() {
                        "damped".to_string()
                    } else {
                        format!("{theory_dr:.4}")
                    }
                ),
            },
            w.mean,
            w.std_error,
            w.samples,
            if zero.is_nan() {
                "no zero".into()
            } else {
                format!("{zero:.3}")
            }
        )?;
        match &c.particle {
            Some(p) => points.push((p.box_length, w.mean, p.nu, p.rotational_diffusion)),
            None => continuum.push((c.label.clone(), w.mean)),
        }
    }
    write_atomic(&out.join("series.csv"), csv.as_bytes())?;
    write_atomic(&out.join("series.md"), md.as_bytes())?;
    if points.is_empty() {
        return Ok(());
    }
    let (x_lo, x_hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.0), b.max(p.0))
    });
    let nu = points[0].2;
    let onset = onset_box(nu, DEFAULT_DIAMETER, 0.0, (2.0, 1000.0));
    // The onset with the rotational diffusion measured in the runs (their mean).
    let measured: Vec<f64> = points.iter().filter_map(|p| p.3).collect();
    let onset_dr = (!measured.is_empty()).then(|| {
        let d_r = measured.iter().sum::<f64>() / measured.len() as f64;
        onset_box(nu, DEFAULT_DIAMETER, d_r, (2.0, 1000.0)).map(|o| (d_r, o))
    });
    let onset_dr = onset_dr.flatten();
    let x_lo = onset.map_or(x_lo, |o| o.min(x_lo)) * 0.9;
    let x_hi = onset_dr.map_or(x_hi, |(_, o)| o.max(x_hi)) * 1.1;
    let y_hi = points
        .iter()
        .map(|p| p.1)
        .chain(continuum.iter().map(|c| c.1))
        .fold(0.0, f64::max)
        * 1.2;
    let mut series = vec![Series {
        label: format!("particles, nu = {nu:.3}"),
        points: points.iter().map(|p| (p.0, p.1)).collect(),
    }];
    for (label, mean) in &continuum {
        series.push(Series {
            label: label.clone(),
            points: vec![(x_lo, *mean), (x_hi, *mean)],
        });
    }
    if let Some(o) = onset {
        series.push(Series {
            label: format!("onset of the lowest box mode (linear theory): L/l = {o:.1}"),
            points: vec![(o, 0.0), (o, y_hi)],
        });
    }
    if let Some((d_r, o)) = onset_dr {
        series.push(Series {
            label: format!("onset with the measured d_r = {d_r:.1e}/beta: L/l = {o:.1}"),
            points: vec![(o, 0.0), (o, y_hi)],
        });
    }
    line_chart(
        &out.join("saturated_norm"),
        &Chart {
            title: "Saturated velocity norm against the box (time average), mean-field units",
            x_label: "L / l",
            y_label: "time-averaged ||u||_2 [L |sigma_a|/mu]",
            series,
        },
    )?;
    Ok(())
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
