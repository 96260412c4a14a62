//! The figures of `motile compare` drawn from its runs' snapshot analyses (docs/MODEL.md §5-§7):
//! velocity slices side by side, the order-parameter correlations (one chart per field), the
//! rods' mean squared displacement and orientation autocorrelation, and the time-averaged
//! velocity autocorrelation, each with its CSV where it has one.

use crate::io::write_atomic;
use crate::report::curves::{CorrCurve, NormCurve, OrderCorrelation, RunAnalysis, TrajectoryCurve};
use crate::report::plot::{Chart, Panel, Series, heatmaps, line_chart, log_chart};
use motile_particle::model::units::SWIM_SPEED;
use std::fmt::Write as _;
use std::path::Path;

/// One order parameter's correlation chart: a series per run.
pub(crate) struct OrderChart {
    /// The field: `c`, `n` or `Q`.
    field: String,
    /// One series per run that has the field.
    series: Vec<Series>,
}

/// What the comparison draws from its runs' analyses.
pub(crate) struct CompareFigures {
    /// Time-averaged Corr[u] of the runs with a flow.
    pub(crate) correlations: Vec<CorrCurve>,
    /// Trajectory statistics of the particle runs.
    pub(crate) trajectories: Vec<TrajectoryCurve>,
    /// Velocity slices of the runs with a flow.
    panels: Vec<Panel>,
    /// Order-parameter correlations by field.
    order: Vec<OrderChart>,
    /// Every run a particle run with nu > 1: their structure stays at the rod scale and their
    /// order-parameter correlations are read against r/l (docs/MODEL.md §7).
    concentrated: bool,
}

impl CompareFigures {
    /// Gather the figures' data from each run's analysis (in the runs' order).
    pub(crate) fn collect(curves: &[NormCurve], analyses: Vec<RunAnalysis>) -> Self {
        let concentrated = analyses
            .iter()
            .all(|a| a.particle.is_some_and(|p| p.nu > 1.0));
        let mut figures = Self {
            correlations: Vec::new(),
            trajectories: Vec::new(),
            panels: Vec::new(),
            order: Vec::new(),
            concentrated,
        };
        for (c, a) in curves.iter().zip(analyses) {
            figures.correlations.extend(a.corr_u);
            if let Some(slice) = a.slice {
                figures.panels.push(Panel {
                    label: format!("{} at t = {:.3}", c.label, slice.time),
                    n: slice.n,
                    values: slice.values,
                });
            }
            figures.trajectories.extend(a.traj);
            let label = format!("{} ({} snapshots)", c.label, a.window_count);
            let box_length = a.particle.map(|p| p.box_length);
            for correlation in a.order {
                figures.add_order(correlation, box_length, &label);
            }
        }
        figures
    }

    /// Add one run's order-parameter correlation to its field's chart. c and n (particle runs
    /// only) decay within a rod length: against r/l up to 5 l. Q against r/L, or r/l where every
    /// run is concentrated. `box_length`: the particle run's `L/l`.
    fn add_order(&mut self, correlation: OrderCorrelation, box_length: Option<f64>, label: &str) {
        let OrderCorrelation { field, points } = correlation;
        let rod_scale = field == "c" || field == "n";
        let to_l = match (self.concentrated || rod_scale, box_length) {
            (true, Some(l)) => l,
            _ => 1.0,
        };
        let series = Series {
            label: label.to_string(),
            points: points
                .into_iter()
                .map(|(r, v)| (r * to_l, v))
                .filter(|(r, _)| !rod_scale || *r <= 5.0)
                .collect(),
        };
        match self.order.iter_mut().find(|chart| chart.field == field) {
            Some(chart) => chart.series.push(series),
            None => self.order.push(OrderChart {
                field,
                series: vec![series],
            }),
        }
    }

    /// Write the figures into `out`.
    pub(crate) fn write(&self, out: &Path) -> anyhow::Result<()> {
        // Velocity magnitude on z = 0 of every run at one time (each run's snapshot nearest the
        // latest time all runs reached), side by side, one colour scale.
        if !self.panels.is_empty() {
            heatmaps(
                &out.join("velocity_slice"),
                "|u| on z = 0, mean-field units, at the time in each caption",
                "|u| [L |sigma_a|/mu]",
                &self.panels,
            )?;
        }
        self.write_order_charts(out)?;
        if !self.trajectories.is_empty() {
            write_trajectories(&self.trajectories, out)?;
        }
        write_velocity_correlation(&self.correlations, out)
    }

    /// Order-parameter correlations, one chart per field, shapes compared (normalised at 0).
    fn write_order_charts(&self, out: &Path) -> anyhow::Result<()> {
        for OrderChart { field, series } in &self.order {
            let in_l = self.concentrated || field == "c" || field == "n";
            line_chart(
                &out.join(format!("correlation_{field}")),
                &Chart {
                    title: &format!(
                        "Corr[{field}](r) / Corr[{field}](0), saturated state of each run"
                    ),
                    x_label: if in_l { "r / l" } else { "r / L" },
                    y_label: &format!("Corr[{field}](r) / Corr[{field}](0)"),
                    series: series.clone(),
                },
            )?;
        }
        Ok(())
    }
}

/// `trajectories.csv`, `msd.{png,svg}` (with the ballistic `(U t)^2` of free swimming) and
/// `orientation.{png,svg}`.
fn write_trajectories(trajectories: &[TrajectoryCurve], out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from("label,t [1/beta],msd [l^2],orientation_autocorrelation [1]\n");
    for tr in trajectories {
        for k in 0..tr.t.len() {
            writeln!(
                csv,
                "\"{}\",{:e},{:e},{:e}",
                tr.label, tr.t[k], tr.msd[k], tr.orientation[k]
            )
            .expect("string");
        }
    }
    write_atomic(&out.join("trajectories.csv"), csv.as_bytes())?;
    let against_time = |values: fn(&TrajectoryCurve) -> &Vec<f64>| -> Vec<Series> {
        trajectories
            .iter()
            .map(|tr| Series {
                label: tr.label.clone(),
                points: tr
                    .t
                    .iter()
                    .copied()
                    .zip(values(tr).iter().copied())
                    .collect(),
            })
            .collect()
    };
    // Log-log: ballistic swimming is a slope of 2, diffusion one of 1, and the rods of a
    // concentrated box sit decades below the ballistic line.
    let mut msd = against_time(|tr| &tr.msd);
    msd.push(ballistic(trajectories));
    for s in &mut msd {
        s.points.retain(|&(t, m)| t > 0.0 && m > 0.0);
    }
    log_chart(
        &out.join("msd"),
        "Mean squared displacement of the rods",
        "t [1/beta]",
        "<|x(t) - x(0)|^2> [l^2]",
        &msd,
        &[],
    )?;
    line_chart(
        &out.join("orientation"),
        &Chart {
            title: "Orientation autocorrelation of the rods",
            x_label: "t [1/beta]",
            y_label: "<p(t) . p(0)> [1]",
            series: against_time(|tr| &tr.orientation),
        },
    )?;
    Ok(())
}

/// Free swimming: ballistic at the swimming speed, `(U t)^2` from the earliest sampled time
/// after 0 to the latest, geometric in t (even on the log axis it is drawn on).
fn ballistic(trajectories: &[TrajectoryCurve]) -> Series {
    let times = || trajectories.iter().flat_map(|tr| tr.t.iter().copied());
    let t_max = times().fold(0.0, f64::max);
    let t_min = times()
        .filter(|t| *t > 0.0)
        .fold(t_max, f64::min)
        .max(t_max * 1e-4);
    Series {
        label: "(U t)^2, ballistic at the swimming speed".into(),
        points: (0..=40)
            .map(|k| {
                let t = t_min * (t_max / t_min).powf(k as f64 / 40.0);
                (t, (SWIM_SPEED * t).powi(2))
            })
            .collect(),
    }
}

/// `velocity_correlation.{csv,png,svg}`: each run's time-averaged Corr[u], mean-field units;
/// `velocity_correlation_normalised.{png,svg}`: the same divided by its value at 0.
fn write_velocity_correlation(correlations: &[CorrCurve], out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from("label,r/L,Corr[u] [(L |sigma_a|/mu)^2]\n");
    for c in correlations {
        for (r, v) in c.r.iter().zip(&c.value) {
            writeln!(csv, "\"{}\",{r:e},{v:e}", c.label).expect("string");
        }
    }
    write_atomic(&out.join("velocity_correlation.csv"), csv.as_bytes())?;
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
    // The shapes side by side: a particle run's flow is far weaker than the continuum's.
    line_chart(
        &out.join("velocity_correlation_normalised"),
        &Chart {
            title: "Time-averaged velocity autocorrelation, normalised at r = 0",
            x_label: "r / L",
            y_label: "Corr[u](r) / Corr[u](0)",
            series: correlations
                .iter()
                .filter(|c| c.value.first().is_some_and(|v| *v > 0.0))
                .map(|c| Series {
                    label: c.label.clone(),
                    points: c
                        .r
                        .iter()
                        .zip(&c.value)
                        .map(|(r, v)| (*r, v / c.value[0]))
                        .collect(),
                })
                .collect(),
        },
    )?;
    Ok(())
}
