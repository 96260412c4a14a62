//! A run's comparison read back from its compact products: a run directory without snapshots
//! whose `compare/` holds what `motile compare` wrote of it (`velocity_correlation.csv`,
//! `trajectories.csv`, `correlation_lengths.csv`, `order_correlations.csv`), as
//! `scripts/series_harvest.sh` files the members of a series run on another machine into the
//! gallery. `motile compare` then draws such a run beside run directories with snapshots; the
//! files are read through `products.rs`.

use crate::report::curves::{
    CorrCurve, CorrelationLength, OrderCorrelation, RunAnalysis, TrajectoryCurve,
};
use crate::report::opened_run::OpenedRun;
use crate::report::products::{check_curve, check_within, number, records_of};
use anyhow::bail;

/// The comparison's analysis of the run labelled `label`, from its compact products (no
/// velocity slice: that needs a snapshot).
pub(crate) fn read_analysis(run: &OpenedRun, label: &str) -> anyhow::Result<RunAnalysis> {
    let (path, rows) = records_of(run, "velocity_correlation.csv", label, 0)?;
    if rows.is_empty() {
        bail!(
            "{}: no Corr[u] of the run `{label}` (a run without snapshots is drawn from its compare/ products)",
            path.display()
        );
    }
    let corr_label = rows[0][0].clone();
    // The label says "..., N snapshot(s) from t = ...".
    let window_count = corr_label
        .split(", ")
        .find_map(|part| part.split_once(" snapshot(s)").map(|(n, _)| n))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or(0);
    let column = |k: usize| {
        rows.iter()
            .map(|r| number(r, k, &path))
            .collect::<anyhow::Result<Vec<f64>>>()
    };
    let (r, value) = (column(1)?, column(2)?);
    check_curve(&path, "r/L", &r, &[("Corr[u]", &value)])?;
    let corr_u = Some(CorrCurve {
        label: corr_label,
        r,
        value,
    });
    Ok(RunAnalysis {
        corr_u,
        slice: None,
        traj: read_trajectory(run, label)?,
        order: read_orders(run, label)?,
        window_count,
        particle: run.particle().map(|(_, units)| *units),
        lengths: read_lengths(run, label)?,
        zero_fields: Vec::new(),
    })
}

/// The rods' MSD and orientation autocorrelation, `None` for a mean-field run.
fn read_trajectory(run: &OpenedRun, label: &str) -> anyhow::Result<Option<TrajectoryCurve>> {
    let (path, rows) = records_of(run, "trajectories.csv", label, 0)?;
    let rows: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == label).collect();
    if rows.is_empty() {
        return Ok(None);
    }
    let column = |k: usize| {
        rows.iter()
            .map(|r| number(r, k, &path))
            .collect::<anyhow::Result<Vec<f64>>>()
    };
    let (t, msd, orientation) = (column(1)?, column(2)?, column(3)?);
    check_curve(
        &path,
        "t",
        &t,
        &[
            ("the MSD", &msd),
            ("the orientation correlation", &orientation),
        ],
    )?;
    check_within(&path, "the MSD", &msd, 0.0, f64::INFINITY)?;
    check_within(
        &path,
        "the orientation correlation",
        &orientation,
        -1.0 - 1e-9,
        1.0 + 1e-9,
    )?;
    Ok(Some(TrajectoryCurve {
        label: label.to_string(),
        t,
        msd,
        orientation,
    }))
}

/// The order-parameter correlations (`order_correlations.csv`; runs compared before that file
/// existed have none).
fn read_orders(run: &OpenedRun, label: &str) -> anyhow::Result<Vec<OrderCorrelation>> {
    let (path, rows) = records_of(run, "order_correlations.csv", label, 0)?;
    let mut orders: Vec<OrderCorrelation> = Vec::new();
    for r in rows.iter().filter(|r| r[0] == label) {
        let field = r.get(1).cloned().unwrap_or_default();
        let point = (number(r, 2, &path)?, number(r, 3, &path)?);
        match orders.iter_mut().find(|o| o.field == field) {
            Some(o) => o.points.push(point),
            None => orders.push(OrderCorrelation {
                field,
                points: vec![point],
            }),
        }
    }
    for o in &orders {
        let (r, v): (Vec<f64>, Vec<f64>) = o.points.iter().copied().unzip();
        check_curve(
            &path,
            &format!("r/L of Corr[{}]", o.field),
            &r,
            &[("Corr", &v)],
        )?;
    }
    Ok(orders)
}

/// The correlation lengths (`correlation_lengths.csv`: run, label, field, r/L, r/l).
fn read_lengths(run: &OpenedRun, label: &str) -> anyhow::Result<Vec<CorrelationLength>> {
    let (path, rows) = records_of(run, "correlation_lengths.csv", label, 1)?;
    rows.iter()
        .filter(|r| r[1] == label)
        .map(|r| {
            let length = number(r, 3, &path)?;
            // NaN: the correlation has no zero.
            if !(length.is_nan() || length.is_finite() && length > 0.0) {
                bail!(
                    "{}: correlation length {length} (a positive r/L, or NaN for none) in `{}`",
                    path.display(),
                    r.join(",")
                );
            }
            Ok(CorrelationLength {
                field: r.get(2).cloned().unwrap_or_default(),
                length,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .and_then(|lengths| {
            let fields: Vec<&str> = lengths.iter().map(|l| l.field.as_str()).collect();
            match fields
                .iter()
                .enumerate()
                .find(|(i, f)| fields[..*i].contains(f))
            {
                Some((_, f)) => bail!("{}: two correlation lengths of `{f}`", path.display()),
                None => Ok(lengths),
            }
        })
}
