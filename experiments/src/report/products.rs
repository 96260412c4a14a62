//! The CSV files of a run's compact comparison products (`compare/` under a run directory
//! without snapshots, as `scripts/series_harvest.sh` files a series member run on another
//! machine): whether a run has them, and their records by run label. A leaf: the norm curve
//! (`curves.rs`, for the rotational diffusion) and the comparison's analysis (`compact.rs`) read
//! through it.

use crate::report::opened_run::OpenedRun;
use anyhow::Context;
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
pub(crate) fn number(record: &[String], k: usize, path: &Path) -> anyhow::Result<f64> {
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
pub(crate) fn records_of(
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
    let samples: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| Ok((number(r, 1, &path)?, number(r, 3, &path)?)))
        .collect::<anyhow::Result<_>>()?;
    let (t, c): (Vec<f64>, Vec<f64>) = samples.iter().copied().unzip();
    check_curve(&path, "t", &t, &[("the orientation correlation", &c)])?;
    check_within(
        &path,
        "the orientation correlation",
        &c,
        -1.0 - 1e-9,
        1.0 + 1e-9,
    )?;
    Ok(samples)
}

/// A curve as `motile compare` writes it: `x` finite and strictly increasing, each of `ys`
/// finite and of its length; else an error naming `path` and what is wrong.
pub(crate) fn check_curve(
    path: &Path,
    x_name: &str,
    x: &[f64],
    ys: &[(&str, &[f64])],
) -> anyhow::Result<()> {
    if let Some(i) = (0..x.len()).find(|&i| !x[i].is_finite() || (i > 0 && x[i] <= x[i - 1])) {
        anyhow::bail!(
            "{}: {x_name} must be finite and increasing (written by motile compare), but value {} is {} after {}",
            path.display(),
            i + 1,
            x[i],
            if i > 0 { x[i - 1] } else { f64::NAN }
        );
    }
    for (name, y) in ys {
        if y.len() != x.len() {
            anyhow::bail!(
                "{}: {} values of {name} for {} of {x_name}",
                path.display(),
                y.len(),
                x.len()
            );
        }
        if let Some(i) = y.iter().position(|v| !v.is_finite()) {
            anyhow::bail!("{}: {name} value {} is {}", path.display(), i + 1, y[i]);
        }
    }
    Ok(())
}

/// Every value of `y` within `[lo, hi]`, else an error naming `path`.
pub(crate) fn check_within(
    path: &Path,
    name: &str,
    y: &[f64],
    lo: f64,
    hi: f64,
) -> anyhow::Result<()> {
    match y.iter().position(|v| !(lo..=hi).contains(v)) {
        Some(i) => anyhow::bail!(
            "{}: {name} value {} is {}, outside [{lo:.0}, {hi:.0}]",
            path.display(),
            i + 1,
            y[i]
        ),
        None => Ok(()),
    }
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
