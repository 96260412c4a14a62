//! The series summary of `motile compare` (`series.csv`, `series.md`): one row per run with its
//! model, size, level, growth rate with its window, R^2 and growth factor, the saturated norm
//! with its standard error, and the first zero of the time-averaged Corr[u] (units of L); and,
//! with particle runs, the saturated norm against L/l beside the continuum's, with the onset of
//! the box's linear theory marked (`saturated_norm.{png,svg}`, docs/MODEL.md §5b).

use crate::io::write_atomic;
use crate::report::curves::{NormCurve, NormStatistics};
use crate::report::plot::{Series, log_chart};
use motile_particle::model::linear_theory::onset_box;
use motile_particle::model::units::DEFAULT_DIAMETER;
use std::path::Path;

const CSV_HEADER: &str = "run,model,L/l,rods,level,growth_phase,growth_rate [mf],growth_t0 [mf],growth_t1 [mf],r_squared,growth_factor,theory_rate [mf],rotational_diffusion [beta],theory_rate_d_r [mf],saturated_from [mf],mean_u_l2 [mf],std_error,samples,batches,corr_u_first_zero [L]\n";

const MD_HEADER: &str = "# Series summary\n\nOne row per run, mean-field units. Growth: the least-squares rate of ln ||u||_2 over the growth phase (docs/MODEL.md §6), with its window, R^2 and growth factor; theory: the box's linear theory (Re sigma of the lowest mode, docs/MODEL.md §5b) for particles, without diffusion and with the rotational diffusion d_r (1/beta) measured in the run from <p(t).p(0)> over its first half; M3 for the continuum. Saturated norm: the time average from the later of the growth phase's end and half the run, to its end; standard error from batch means over up to 10 contiguous blocks (samples within a block are correlated; blocks are taken as independent).\n\n| run | L/l | rods | level | growth rate (window, R^2, grown by) | theory | saturated ||u||_2 | samples | first zero of Corr[u] (L) |\n|---|---|---|---|---|---|---|---|---|\n";

/// What a row says about the run's model and its theory.
struct RunColumns {
    /// The run directory's name (a scene's member name).
    run: String,
    model: &'static str,
    /// `L/l`; NaN for the continuum.
    box_length: f64,
    rods: String,
    level: String,
    /// The linear theory's rate (mean-field units); NaN where damped.
    theory: f64,
    /// The rotational diffusion measured in a particle run (1/beta); NaN where not.
    rotational_diffusion: f64,
    /// The box theory's rate with it; NaN where not measured or damped.
    theory_with_diffusion: f64,
}

impl RunColumns {
    fn of(c: &NormCurve) -> Self {
        let run = c.run.file_name().map_or_else(
            || c.run.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        match &c.particle {
            Some(p) => Self {
                run,
                model: "particle",
                box_length: p.box_length,
                rods: p.rods.to_string(),
                level: p.level.clone(),
                theory: p.box_theory.map_or(f64::NAN, |s| s.re),
                rotational_diffusion: p.rotational_diffusion.unwrap_or(f64::NAN),
                theory_with_diffusion: p.box_theory_dr.map_or(f64::NAN, |s| s.re),
            },
            None => Self {
                run,
                model: "meanfield",
                box_length: f64::NAN,
                rods: "-".to_string(),
                level: "continuum".to_string(),
                theory: c.theory_rate,
                rotational_diffusion: f64::NAN,
                theory_with_diffusion: f64::NAN,
            },
        }
    }
}

/// A particle run's saturated norm against its box.
pub(crate) struct SaturatedPoint {
    pub(crate) box_length: f64,
    pub(crate) mean: f64,
    pub(crate) nu: f64,
    pub(crate) rotational_diffusion: Option<f64>,
}

/// The series summary (`series.csv`, `series.md`) of the runs' `curves` with their
/// `statistics` and the first zeros of their Corr[u] (`corr_u_zeros`), and, with particle runs,
/// `saturated_norm.{png,svg}`.
pub(crate) fn write_series(
    curves: &[NormCurve],
    statistics: &[NormStatistics],
    corr_u_zeros: &[f64],
    table: Option<&Path>,
    out: &Path,
) -> anyhow::Result<()> {
    let mut csv = String::from(CSV_HEADER);
    let mut md = String::from(MD_HEADER);
    let mut points = Vec::new();
    let mut continuum = Vec::new();
    let names: Vec<String> = curves.iter().map(|c| RunColumns::of(c).run).collect();
    for ((c, s), &zero) in curves.iter().zip(statistics).zip(corr_u_zeros) {
        let columns = RunColumns::of(c);
        csv.push_str(&csv_row(&columns, s, zero));
        md.push_str(&md_row(c, &columns, s, zero));
        match &c.particle {
            Some(p) => points.push(SaturatedPoint {
                box_length: p.box_length,
                mean: s.average.mean,
                nu: p.nu,
                rotational_diffusion: p.rotational_diffusion,
            }),
            None => continuum.push((c.label.clone(), s.average.mean)),
        }
    }
    if let Some(path) = table {
        for row in read_table(path, &names)? {
            csv.push_str(&row.line);
            csv.push('\n');
            match row.point {
                TablePoint::Particle(p) => points.push(p),
                TablePoint::Continuum(mean) => {
                    continuum.push((format!("continuum, run {} (table)", row.run), mean))
                }
            }
        }
    }
    write_atomic(&out.join("series.csv"), csv.as_bytes())?;
    write_atomic(&out.join("series.md"), md.as_bytes())?;
    if points.is_empty() {
        return Ok(());
    }
    points.sort_by(|a, b| a.box_length.total_cmp(&b.box_length));
    write_saturated_norm(&points, &continuum, out)
}

fn csv_row(columns: &RunColumns, s: &NormStatistics, zero: f64) -> String {
    let (g, grew) = s.fit_or_nan();
    let RunColumns {
        run,
        model,
        box_length: l,
        rods,
        level,
        theory,
        rotational_diffusion: d_r,
        theory_with_diffusion: theory_dr,
    } = columns;
    let w = &s.average;
    format!(
        "{run},{model},{l},{rods},{level},{grew},{:e},{:e},{:e},{},{},{theory:e},{d_r:e},{theory_dr:e},{:e},{:e},{:e},{},{},{zero:e}\n",
        g.rate,
        g.t0,
        g.t1,
        g.r_squared,
        g.growth_factor,
        s.saturated_from,
        w.mean,
        w.std_error,
        w.samples,
        w.batches
    )
}

fn md_row(c: &NormCurve, columns: &RunColumns, s: &NormStatistics, zero: f64) -> String {
    let (g, grew) = s.fit_or_nan();
    let (rate, g0, g1, r2, gf) = (g.rate, g.t0, g.t1, g.r_squared, g.growth_factor);
    let (theory, d_r, theory_dr) = (
        columns.theory,
        columns.rotational_diffusion,
        columns.theory_with_diffusion,
    );
    let l = columns.box_length;
    let theory_cell = match (theory.is_nan(), d_r.is_nan()) {
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
    };
    format!(
        "| {} | {} | {} | {} | {} | {theory_cell} | {:.4e} +- {:.1e} (from t = {:.1}) | {} | {} |\n",
        c.label,
        if l.is_nan() {
            "-".into()
        } else {
            format!("{l}")
        },
        columns.rods,
        columns.level,
        if grew {
            format!("{rate:.4} ({g0:.1}-{g1:.1}, R^2 {r2:.3}, x{gf:.0})")
        } else {
            format!("no growth phase (R^2 {r2:.2}, x{gf:.1})")
        },
        s.average.mean,
        s.average.std_error,
        s.saturated_from,
        s.average.samples,
        if zero.is_nan() {
            "no zero".into()
        } else {
            format!("{zero:.3}")
        }
    )
}

/// A row of an earlier series table (`--table`): its text and what the saturated-norm chart
/// draws of it.
pub(crate) struct TableRow {
    pub(crate) run: String,
    pub(crate) line: String,
    pub(crate) point: TablePoint,
}

/// What a table row adds to the saturated-norm chart.
pub(crate) enum TablePoint {
    Particle(SaturatedPoint),
    Continuum(f64),
}

/// The rows of the series table at `path` (a `series.csv` written by `motile compare`, such as
/// the gallery's) whose runs are not among `compared`.
/// Each row has the header's fields, a run named once, and the values the chart draws in
/// range (a positive box and saturated norm, a whole number of rods, a rotational diffusion
/// not negative or NaN); else an error naming the file and row.
pub(crate) fn read_table(path: &Path, compared: &[String]) -> anyhow::Result<Vec<TableRow>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    let mut lines = text.lines();
    if lines.next() != Some(CSV_HEADER.trim_end()) {
        anyhow::bail!(
            "{}: not a series table (its header is not `{}`)",
            path.display(),
            CSV_HEADER.trim_end()
        );
    }
    let mut rows = Vec::new();
    let mut seen: Vec<String> = Vec::new();
    let fields = CSV_HEADER.trim_end().split(',').count();
    for (k, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').collect();
        let bad = |what: String| anyhow::anyhow!("{}: row {}: {what}", path.display(), k + 2);
        if f.len() != fields {
            return Err(bad(format!("{} fields, the header has {fields}", f.len())));
        }
        if seen.contains(&f[0].to_string()) {
            return Err(bad(format!("run `{}` a second time", f[0])));
        }
        seen.push(f[0].to_string());
        let num = |i: usize| -> anyhow::Result<f64> {
            f.get(i).and_then(|v| v.parse::<f64>().ok()).ok_or_else(|| {
                anyhow::anyhow!(
                    "{}: row {}: field {} is not a number",
                    path.display(),
                    k + 2,
                    i + 1
                )
            })
        };
        let run = f[0].to_string();
        if compared.contains(&run) {
            continue;
        }
        let mean = num(15)?;
        if !(mean.is_finite() && mean > 0.0) {
            return Err(bad(format!("mean_u_l2 {mean} (positive)")));
        }
        let point = if f.get(1) == Some(&"particle") {
            let (l, rods) = (num(2)?, num(3)?);
            let d_r = num(12)?;
            let nu = rods / (l * l * l);
            if !(l.is_finite() && rods >= 1.0 && rods.fract() == 0.0 && nu.is_finite() && nu > 0.0)
            {
                return Err(bad(format!(
                    "L/l {l:e}, rods {rods:e} (a box and whole rods of a finite, positive density)"
                )));
            }
            if !(d_r.is_nan() || d_r.is_finite() && d_r >= 0.0) {
                return Err(bad(format!(
                    "rotational_diffusion {d_r} (not negative, or NaN)"
                )));
            }
            TablePoint::Particle(SaturatedPoint {
                box_length: l,
                mean,
                nu,
                rotational_diffusion: (!d_r.is_nan()).then_some(d_r),
            })
        } else if f.get(1) == Some(&"meanfield") {
            TablePoint::Continuum(mean)
        } else {
            return Err(bad(format!("model `{}` (particle or meanfield)", f[1])));
        };
        rows.push(TableRow {
            run,
            line: line.to_string(),
            point,
        });
    }
    Ok(rows)
}

/// `saturated_norm.{png,svg}`: the particle runs' saturated norms against `L/l`, the
/// continuum's as flat lines, and the box theory's onset without and with the rotational
/// diffusion measured in the runs (their mean).
fn write_saturated_norm(
    points: &[SaturatedPoint],
    continuum: &[(String, f64)],
    out: &Path,
) -> anyhow::Result<()> {
    let (x_lo, x_hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.box_length), b.max(p.box_length))
    });
    let nu = points[0].nu;
    let onset = onset_box(nu, DEFAULT_DIAMETER, 0.0, (2.0, 1000.0));
    let measured: Vec<f64> = points
        .iter()
        .filter_map(|p| p.rotational_diffusion)
        .collect();
    let onset_dr = (!measured.is_empty())
        .then(|| {
            let d_r = measured.iter().sum::<f64>() / measured.len() as f64;
            onset_box(nu, DEFAULT_DIAMETER, d_r, (2.0, 1000.0)).map(|o| (d_r, o))
        })
        .flatten();
    let x_lo = onset.map_or(x_lo, |o| o.min(x_lo)) * 0.9;
    let x_hi = onset_dr.map_or(x_hi, |(_, o)| o.max(x_hi)) * 1.1;
    // Log axes: the particles' norms sit an order of magnitude below the continuum's.
    let means = points
        .iter()
        .map(|p| p.mean)
        .chain(continuum.iter().map(|c| c.1));
    let y_hi = means.clone().fold(0.0, f64::max) * 1.5;
    let y_lo = means.fold(f64::INFINITY, f64::min) / 1.5;
    let mut series = vec![Series {
        label: format!("particles, nu = {nu:.3}"),
        points: points.iter().map(|p| (p.box_length, p.mean)).collect(),
    }];
    for (label, mean) in continuum {
        series.push(Series {
            label: label.clone(),
            points: vec![(x_lo, *mean), (x_hi, *mean)],
        });
    }
    let onset_line = |label: String, o: f64| Series {
        label,
        points: vec![(o, y_lo), (o, y_hi)],
    };
    if let Some(o) = onset {
        series.push(onset_line(
            format!("onset of the lowest box mode (linear theory): L/l = {o:.1}"),
            o,
        ));
    }
    if let Some((d_r, o)) = onset_dr {
        series.push(onset_line(
            format!("onset with the measured d_r = {d_r:.1e}/beta: L/l = {o:.1}"),
            o,
        ));
    }
    let labels: Vec<(f64, f64, String)> = points
        .iter()
        .map(|p| (p.box_length, p.mean, format!("{:.2e}", p.mean)))
        .collect();
    log_chart(
        &out.join("saturated_norm"),
        "Saturated velocity norm against the box (time average), mean-field units",
        "L / l",
        "time-averaged ||u||_2 [L |sigma_a|/mu]",
        &series,
        &labels,
    )?;
    Ok(())
}
