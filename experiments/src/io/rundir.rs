//! Run directories: one layout for every kind of run.
//!
//! ```text
//! <run>/config.toml        the fully resolved config ([motile] version, model, seed + the model's own)
//! <run>/timeseries.csv     one row per diagnostic time; header names carry units
//! <run>/snapshots/snap_NNNNNN.h5   HDF5 snapshots (crate::io::snapshot)
//! <run>/checkpoints/       restart files (written by the models' runners)
//! <run>/run.log            what the run did, with wall-clock stamps
//! <run>/analysis/          written by `motile analyze`
//! ```
//!
//! Every file except the append-only log is written atomically ([`crate::io::write_atomic`]).

use crate::io::snapshot::{Snapshot, read_snapshot};
use crate::io::{IoError, fs_err, write_atomic};
use serde::Serialize;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// Provenance written at the top of every `config.toml`.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct RunHeader {
    /// motile version that wrote the run.
    pub version: String,
    /// Model: "particle", "meanfield" or "analysis".
    pub model: String,
    /// Random seed.
    pub seed: u64,
    /// The run directory's format version ([`mod@crate::io::format`]); absent (read as 1) in
    /// runs written before formats were versioned.
    #[serde(default = "first_format")]
    pub format_version: u64,
}

fn first_format() -> u64 {
    1
}

#[derive(Serialize)]
struct ConfigFile<'a, C: Serialize> {
    motile: &'a RunHeader,
    #[serde(flatten)]
    config: &'a C,
}

/// A run directory on disk.
#[derive(Clone, Debug)]
pub struct RunDir {
    root: PathBuf,
}

impl RunDir {
    /// Create (or reuse) the directory and write the resolved config.
    pub fn create<C: Serialize>(
        root: &Path,
        model: &str,
        seed: u64,
        config: &C,
    ) -> Result<Self, IoError> {
        fs::create_dir_all(root.join("snapshots")).map_err(fs_err(root))?;
        let header = RunHeader {
            version: env!("CARGO_PKG_VERSION").into(),
            model: model.into(),
            seed,
            format_version: crate::io::format::FORMAT_VERSION,
        };
        let text = toml::to_string_pretty(&ConfigFile {
            motile: &header,
            config,
        })
        .map_err(|e| IoError::Content {
            path: root.join("config.toml"),
            message: e.to_string(),
        })?;
        write_atomic(&root.join("config.toml"), text.as_bytes())?;
        Ok(Self {
            root: root.to_path_buf(),
        })
    }

    /// Open an existing run directory of a format version this motile reads (a header that
    /// does not parse is left to the config's reader, which names the line).
    pub fn open(root: &Path) -> Result<Self, IoError> {
        if !root.join("config.toml").is_file() {
            return Err(IoError::Content {
                path: root.to_path_buf(),
                message: "not a motile run directory (no config.toml)".into(),
            });
        }
        let dir = Self {
            root: root.to_path_buf(),
        };
        if let Ok(h) = dir.header() {
            crate::io::format::check(
                Some(h.format_version),
                &h.version,
                &root.join("config.toml"),
            )?;
        }
        Ok(dir)
    }

    /// Delete temporary files a killed writer left behind (`.NAME.PID.tmp`, never a final
    /// file name) in the run directory and its subdirectories; returns how many. Only for a
    /// run no process is writing to (resume).
    pub fn remove_stale_temporaries(&self) -> usize {
        fn walk(dir: &Path, n: &mut usize) {
            let Ok(rd) = fs::read_dir(dir) else { return };
            for e in rd.flatten() {
                let p = e.path();
                let name = e.file_name().to_string_lossy().into_owned();
                if p.is_dir() {
                    walk(&p, n);
                } else if name.starts_with('.')
                    && name.ends_with(".tmp")
                    && fs::remove_file(&p).is_ok()
                {
                    *n += 1;
                }
            }
        }
        let mut n = 0;
        walk(&self.root, &mut n);
        n
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.root
    }

    /// The provenance header of `config.toml`.
    pub fn header(&self) -> Result<RunHeader, IoError> {
        #[derive(serde::Deserialize)]
        struct Head {
            motile: RunHeader,
        }
        let p = self.root.join("config.toml");
        let text = fs::read_to_string(&p).map_err(fs_err(&p))?;
        let h: Head = toml::from_str(&text).map_err(|e| IoError::Content {
            path: p,
            message: e.to_string(),
        })?;
        Ok(h.motile)
    }

    /// Path of snapshot number `index`.
    pub fn snapshot_path(&self, index: usize) -> PathBuf {
        self.root
            .join("snapshots")
            .join(format!("snap_{index:06}.h5"))
    }

    /// Snapshot files in order.
    pub fn snapshot_paths(&self) -> Result<Vec<PathBuf>, IoError> {
        let dir = self.root.join("snapshots");
        let mut v: Vec<PathBuf> = fs::read_dir(&dir)
            .map_err(fs_err(&dir))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension().is_some_and(|e| e == "h5")
                    && p.file_name()
                        .is_some_and(|n| n.to_string_lossy().starts_with("snap_"))
            })
            .collect();
        v.sort();
        Ok(v)
    }

    /// Read every snapshot, in order.
    pub fn snapshots(&self) -> Result<Vec<Snapshot>, IoError> {
        self.snapshot_paths()?
            .iter()
            .map(|p| read_snapshot(p))
            .collect()
    }

    /// Append a line to `run.log` with a UNIX-time stamp, flushed at once.
    pub fn log(&self, line: &str) -> Result<(), IoError> {
        let p = self.root.join("run.log");
        let mut f = fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&p)
            .map_err(fs_err(&p))?;
        let t = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        writeln!(f, "[{t:.3}] {line}").map_err(fs_err(&p))?;
        f.flush().map_err(fs_err(&p))
    }
}

/// Parse a run's `config.toml` text (the `[motile]` header table, if present, is ignored) into
/// the model's config and validate it; errors name the file.
pub fn parse_run_config<C: serde::de::DeserializeOwned>(
    text: &str,
    path: &Path,
    validate: impl Fn(&C) -> Result<(), String>,
) -> anyhow::Result<C> {
    parse_run_config_with(text, path, |_: &mut C, _: &toml::Table| {}, validate)
}

/// [`parse_run_config`], with `defaults` adjusting the defaults of keys the text leaves out to
/// the values it gives (`(config, the text's table)`), before validation: a default never
/// contradicts what the user wrote.
pub fn parse_run_config_with<C: serde::de::DeserializeOwned>(
    text: &str,
    path: &Path,
    defaults: impl Fn(&mut C, &toml::Table),
    validate: impl Fn(&C) -> Result<(), String>,
) -> anyhow::Result<C> {
    let mut table: toml::Table =
        toml::from_str(text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    table.remove("motile");
    let given = table.clone();
    let mut cfg: C = serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(
        |e: serde_path_to_error::Error<toml::de::Error>| {
            let at = e.path().to_string();
            let message = with_suggestion(e.inner().message());
            // The path ends at the key the error is about (a field that failed, or an unknown
            // key).
            let line = line_of_key(text, &at).map_or(String::new(), |n| format!(" line {n}:"));
            if at == "." || message.starts_with("unknown key") {
                anyhow::anyhow!("{}:{line} {message}", path.display())
            } else {
                anyhow::anyhow!("{}:{line} `{at}`: {message}", path.display())
            }
        },
    )?;
    defaults(&mut cfg, &given);
    validate(&cfg).map_err(|e| {
        // Validation messages start with the key: `contact.margin = 0.001 is ...`.
        let key = e.split(" = ").next().unwrap_or_default();
        let line = (!key.contains(' '))
            .then(|| line_of_key(text, key))
            .flatten()
            .map_or(String::new(), |n| format!(" line {n}:"));
        anyhow::anyhow!("{}:{line} {e}", path.display())
    })?;
    Ok(cfg)
}

/// The line (1-based) of `key` (`a` or `table.a`) in a TOML text: the line that assigns it at
/// the top level or under its `[table]` header. `None` where it cannot be found (a key written
/// in another form, such as an inline table).
fn line_of_key(text: &str, key: &str) -> Option<usize> {
    let (table, name) = match key.rsplit_once('.') {
        Some((t, n)) => (t, n),
        None => ("", key),
    };
    let mut current = String::new();
    for (k, line) in text.lines().enumerate() {
        let t = line.trim();
        if let Some(h) = t.strip_prefix('[').and_then(|h| h.split(']').next()) {
            current = h.trim().to_string();
            continue;
        }
        let assigned = t.split('=').next().map(|k| k.trim().trim_matches('"'));
        if current == table && t.contains('=') && assigned == Some(name) {
            return Some(k + 1);
        }
    }
    None
}

/// Rewrite serde's "unknown field `x`, expected one of `a`, `b`" as a message that names the
/// closest valid key (edit distance), e.g. "unknown key `zetta`; did you mean `zeta`?".
fn with_suggestion(message: &str) -> String {
    let Some(rest) = message.strip_prefix("unknown field `") else {
        // A negative count: the allowed range, not the type's name.
        if let Some(v) = message
            .strip_prefix("invalid value: integer `")
            .and_then(|r| r.split_once('`'))
            .map(|(v, _)| v)
            .filter(|v| v.starts_with('-'))
        {
            return format!(
                "{v} is outside the allowed range: a whole number >= 0 (docs/config.md gives each key's range)"
            );
        }
        // Serde's Rust type names in the words of a config file.
        return message
            .replace("expected f64", "expected a number")
            .replace("expected usize", "expected a whole number")
            .replace("expected u64", "expected a whole number")
            .replace("expected u32", "expected a whole number");
    };
    let Some((key, expected)) = rest.split_once('`') else {
        return message.to_string();
    };
    let valid: Vec<&str> = expected
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|v| !v.is_empty())
        .collect();
    let best = valid
        .iter()
        .map(|v| (strsim::damerau_levenshtein(key, v), *v))
        .min();
    let list = valid.join(", ");
    match best {
        Some((d, v)) if d <= key.len().max(3) / 2 + 1 => {
            format!("unknown key `{key}`; did you mean `{v}`? (valid keys: {list})")
        }
        _ => format!("unknown key `{key}` (valid keys: {list})"),
    }
}

/// Read and parse the `config.toml` of the run directory `out`.
pub fn read_run_config<C: serde::de::DeserializeOwned>(
    out: &Path,
    validate: impl Fn(&C) -> Result<(), String>,
) -> anyhow::Result<C> {
    let path = out.join("config.toml");
    let text = fs::read_to_string(&path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    parse_run_config(&text, &path, validate)
}

/// A number for a message: plain, or in exponent form when it is small (`1e-10`, not
/// `0.0000000001`).
pub fn compact(v: f64) -> String {
    motile_analysis::params::compact(v)
}

/// Check that `v` lies in `[lo, hi]` (`(lo, hi]` if `lo_open`): the message names the field,
/// the value, the range and the unit.
pub fn range(
    name: &str,
    v: f64,
    lo: f64,
    hi: f64,
    lo_open: bool,
    unit: &str,
) -> Result<(), String> {
    motile_analysis::params::check_range(name, v, lo, hi, lo_open, unit).map_err(|e| e.to_string())
}

/// Numbered checkpoints (`ckpt_*`) in a directory, oldest first; empty if there is none.
pub fn checkpoint_paths(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    v.retain(|p| {
        p.file_name().is_some_and(|n| {
            let n = n.to_string_lossy();
            n.starts_with("ckpt_") && n.ends_with(".h5")
        })
    });
    v.sort();
    v
}

/// A table of diagnostics, one row per time, written atomically as CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeSeries {
    /// Column names, each with its unit in brackets, e.g. `t [1/beta]`.
    pub columns: Vec<String>,
    /// Rows of values.
    pub rows: Vec<Vec<f64>>,
}

impl TimeSeries {
    /// An empty table with these columns.
    pub fn new(columns: &[&str]) -> Self {
        Self {
            columns: columns.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    /// Add a row (must have one value per column).
    pub fn push(&mut self, row: Vec<f64>) {
        assert_eq!(
            row.len(),
            self.columns.len(),
            "time-series row has the wrong number of values"
        );
        self.rows.push(row);
    }

    /// A column by name.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }

    /// CSV text (full precision).
    pub fn to_csv(&self) -> String {
        let mut s = self.columns.join(",");
        s.push('\n');
        for r in &self.rows {
            let cells: Vec<String> = r.iter().map(|v| format!("{v:e}")).collect();
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        s
    }

    /// Write atomically.
    pub fn write(&self, path: &Path) -> Result<(), IoError> {
        write_atomic(path, self.to_csv().as_bytes())
    }

    /// Read a CSV written by [`Self::write`].
    pub fn read(path: &Path) -> Result<Self, IoError> {
        let text = fs::read_to_string(path).map_err(fs_err(path))?;
        let mut lines = text.lines();
        let columns: Vec<String> = lines
            .next()
            .unwrap_or("")
            .split(',')
            .map(|s| s.to_string())
            .collect();
        let timed = columns
            .first()
            .is_some_and(|c| c == "t" || c.starts_with("t ["));
        let mut rows = Vec::new();
        for (i, line) in lines.enumerate() {
            let row: Result<Vec<f64>, _> =
                line.split(',').map(|c| c.trim().parse::<f64>()).collect();
            let row = row.map_err(|e| IoError::Content {
                path: path.to_path_buf(),
                message: format!("line {}: {e}", i + 2),
            })?;
            if row.len() != columns.len() {
                return Err(IoError::Content {
                    path: path.to_path_buf(),
                    message: format!(
                        "line {} has {} values, header has {}",
                        i + 2,
                        row.len(),
                        columns.len()
                    ),
                });
            }
            // Times (a first column `t [unit]`) are finite and increase down the file: rows out
            // of order or repeated are a damaged or hand-edited file, which a comparison would
            // draw as a wrong curve.
            let (t, before) = (
                row[0],
                rows.last().map_or(f64::NEG_INFINITY, |r: &Vec<f64>| r[0]),
            );
            if timed && !(t.is_finite() && t > before) {
                return Err(IoError::Content {
                    path: path.to_path_buf(),
                    message: format!(
                        "line {}: time {t} does not follow the previous row's {before}: the times must be finite and increasing",
                        i + 2
                    ),
                });
            }
            rows.push(row);
        }
        Ok(Self { columns, rows })
    }
}
