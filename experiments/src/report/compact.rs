//! A run's comparison read back from its compact products: a run directory without snapshots
//! whose `compare/` holds what `motile compare` wrote of it (`velocity_correlation.csv`,
//! `trajectories.csv`, `correlation_lengths.csv`, `order_correlations.csv`), as
//! `scripts/series_harvest.sh` files the members of a series run on another machine into the
//! gallery. `motile compare` then draws such a run beside run directories with snapshots.

use crate::report::curves::{
    CorrCurve, CorrelationLength, OrderCorrelation, RunAnalysis, TrajectoryCurve,
};
use crate::report::opened_run::OpenedRun;
use anyhow::{Context, bail};
use std::path::{Path, PathBuf};

/// The folder of a run's compact comparison products.
fn products(run: &OpenedRun) -> PathBuf {
    run.path().join("compare")
}

/// Whether `run` is drawn from its compact products: it has no snapshots and a `compare/`
/// with its velocity autocorrelation.
pub(crate) fn is_compact(run: &OpenedRun) -> bool {
    run.snapshot_paths.is_empty() && products(run).join("velocity_correlation.csv").is_file()
}

/// The records of a CSV file written by `motile compare` (a header, then fields separated by
/// commas; a field in double quotes may hold commas).
fn records(path: &Path) -> anyhow::Result<Vec<Vec<String>>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    Ok(text
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(split_record)
        .collect())
}

/// One CSV line's fields, quotes removed.
fn split_record(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut quoted = false;
    for ch in line.chars() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => fields.push(String::new()),
            _ => fields.last_mut().expect("one field").push(ch),
        }
    }
    fields
}

/// Field `k` of `record` as a number, the file named where it is not one.
fn number(record: &[String], k: usize, path: &Path) -> anyhow::Result<f64> {
    record
        .get(k)
        .and_then(|v| v.trim().parse().ok())
        .with_context(|| {
            format!(
                "{}: field {} of `{}` is not a number",
                path.display(),
                k + 1,
                record.join(",")
            )
        })
}

/// The records of `file` in `run`'s products whose field `column` (the label) starts with
/// `label`; none where the file is absent.
fn records_of(
    run: &OpenedRun,
    file: &str,
    label: &str,
    column: usize,
) -> anyhow::Result<(PathBuf, Vec<Vec<String>>)> {
    let path = products(run).join(file);
    if !path.is_file() {
        return Ok((path, Vec::new()));
    }
    let rows = records(&path)?
        .into_iter()
        .filter(|r| r.get(column).is_some_and(|l| l.starts_with(label)))
        .collect();
    Ok((path, rows))
}

/// `<p(t).p(0)>` of the run labelled `label`, from its `trajectories.csv`: `(t, value)`.
pub(crate) fn orientation_samples(run: &OpenedRun, label: &str) -> anyhow::Result<Vec<(f64, f64)>> {
    let (path, rows) = records_of(run, "trajectories.csv", label, 0)?;
    rows.iter()
        .map(|r| Ok((number(r, 1, &path)?, number(r, 3, &path)?)))
        .collect()
}

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
    let corr_u = Some(CorrCurve {
        label: corr_label,
        r: rows
            .iter()
            .map(|r| number(r, 1, &path))
            .collect::<anyhow::Result<_>>()?,
        value: rows
            .iter()
            .map(|r| number(r, 2, &path))
            .collect::<anyhow::Result<_>>()?,
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
    Ok(Some(TrajectoryCurve {
        label: label.to_string(),
        t: column(1)?,
        msd: column(2)?,
        orientation: column(3)?,
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
    Ok(orders)
}

/// The correlation lengths (`correlation_lengths.csv`: run, label, field, r/L, r/l).
fn read_lengths(run: &OpenedRun, label: &str) -> anyhow::Result<Vec<CorrelationLength>> {
    let (path, rows) = records_of(run, "correlation_lengths.csv", label, 1)?;
    rows.iter()
        .filter(|r| r[1] == label)
        .map(|r| {
            Ok(CorrelationLength {
                field: r.get(2).cloned().unwrap_or_default(),
                length: number(r, 3, &path)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::split_record;

    #[test]
    fn quoted_fields_keep_their_commas() {
        assert_eq!(
            split_record("\"a, b\",1e0,x"),
            vec!["a, b".to_string(), "1e0".into(), "x".into()]
        );
        assert_eq!(
            split_record("1,,2"),
            vec!["1".to_string(), "".into(), "2".into()]
        );
    }
}
