//! The concentrated runs' pair structure (compare's `pair_correlations.csv` and
//! `pair_correlation_{c,n,Q}` figures): each run's time-averaged pair correlations of `c`, `n`
//! and `Q` ([`pair_correlations`]: without each rod's correlation with itself) against `r` in
//! rod lengths, at the same resolution (l/4 up to L/l = 32) in every box, so that the curves of
//! different boxes fall on one another where the rods, not the box, set the structure.

use crate::io::write_atomic;
use crate::report::plot::{Chart, Series, line_chart};
use crate::report::statistics::StatisticsWindow;
use motile_analysis::correlation::RadialCorrelation;
use std::fmt::Write as _;
use std::path::Path;

/// One run whose pair structure is drawn: its label, window and time-averaged pair
/// correlations ([`crate::report::statistics::pair_correlations`]).
pub(crate) struct PairRun {
    /// Legend label (the run's name).
    pub label: String,
    /// The window the correlations are averaged over.
    pub window: StatisticsWindow,
    /// `(field, curve)` for c, n and Q against r in l.
    pub curves: Vec<(&'static str, RadialCorrelation)>,
}

/// Write `pair_correlations.csv` (run, field, r in l, value) and one figure per field into
/// `out`; nothing where no run has snapshots in its window.
pub(crate) fn write_pair_correlations(runs: &[PairRun], out: &Path) -> anyhow::Result<()> {
    let curves: Vec<(&PairRun, &Vec<(&str, RadialCorrelation)>)> = runs
        .iter()
        .filter(|r| !r.curves.is_empty())
        .map(|r| (r, &r.curves))
        .collect();
    if curves.is_empty() {
        return Ok(());
    }
    let mut csv = String::from("run,field,r [l],pair correlation [1]\n");
    for (run, fields) in &curves {
        for (name, c) in fields.iter() {
            for (r, v) in c.r.iter().zip(&c.value) {
                writeln!(csv, "\"{}\",{name},{r:e},{v:e}", run.label).expect("string");
            }
        }
    }
    write_atomic(&out.join("pair_correlations.csv"), csv.as_bytes())?;
    for (field, what, y_label) in [
        ("c", "concentration: g(r) - 1", "g(r) - 1 [1]"),
        (
            "n",
            "polarity: pairs weighted by p_i.p_j",
            "pair Corr[n] [1]",
        ),
        (
            "Q",
            "nematic order: pairs weighted by Q_i:Q_j",
            "pair Corr[Q] [1]",
        ),
    ] {
        let series = curves
            .iter()
            .filter_map(|(run, fields)| {
                let (_, c) = fields.iter().find(|(n, _)| *n == field)?;
                // The radii run to L/2 (in l): the resolution is L / modes.
                let box_length = 2.0 * c.r.last().copied().unwrap_or(0.0);
                Some(Series {
                    label: format!(
                        "{} (t = {}-{}/beta, resolution {:.2} l)",
                        run.label,
                        run.window.t0,
                        run.window.t1,
                        box_length / c.modes as f64
                    ),
                    points: c.r.iter().copied().zip(c.value.iter().copied()).collect(),
                })
            })
            .collect();
        let title = format!("Pair correlation of the {what}");
        line_chart(
            &out.join(format!("pair_correlation_{field}")),
            &Chart {
                title: &title,
                x_label: "r/l [1]",
                y_label,
                series,
            },
        )?;
    }
    Ok(())
}
