//! Verified checkpoint files, their retention, and the signals that ask a run to stop.
//!
//! A checkpoint `ckpt_STEP.h5` is written atomically, then its sidecar `ckpt_STEP.h5.crc32`
//! (the file's length and CRC-32, also atomic). Resume takes the newest checkpoint whose
//! sidecar matches; one without a sidecar (killed between the two writes), truncated or with
//! a flipped bit is skipped with a warning and the previous one used. The `.h5` files stay
//! plain HDF5 for h5py.

use crate::io::rundir::checkpoint_paths;
use crate::io::{IoError, fs_err, write_atomic};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

fn sidecar(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".crc32");
    PathBuf::from(s)
}

/// Write checkpoint `bytes` to `path`, then its checksum sidecar.
pub fn write_verified(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    write_atomic(path, bytes)?;
    let line = format!("{} {:08x}\n", bytes.len(), crc32fast::hash(bytes));
    write_atomic(&sidecar(path), line.as_bytes())
}

/// Check a checkpoint against its sidecar; the error says what is wrong.
pub fn verify(path: &Path) -> Result<(), IoError> {
    let content = |message: String| IoError::Content {
        path: path.to_path_buf(),
        message,
    };
    let side = sidecar(path);
    let line = std::fs::read_to_string(&side).map_err(|_| {
        content(format!(
            "no checksum file {} (the write was interrupted)",
            side.display()
        ))
    })?;
    let mut it = line.split_whitespace();
    let (len, crc) = match (
        it.next().and_then(|v| v.parse::<usize>().ok()),
        it.next().and_then(|v| u32::from_str_radix(v, 16).ok()),
    ) {
        (Some(l), Some(c)) => (l, c),
        _ => {
            return Err(content(format!(
                "unreadable checksum file {}",
                side.display()
            )));
        }
    };
    let bytes = std::fs::read(path).map_err(fs_err(path))?;
    if bytes.len() != len {
        return Err(content(format!(
            "truncated or extended: {} bytes, the checksum file says {len}",
            bytes.len()
        )));
    }
    let got = crc32fast::hash(&bytes);
    if got != crc {
        return Err(content(format!(
            "checksum mismatch (CRC-32 {got:08x}, expected {crc:08x}): the file is damaged"
        )));
    }
    Ok(())
}

/// Keep the newest `keep` regular checkpoints of `dir` (and their sidecars).
pub fn prune(dir: &Path, keep: usize) {
    let v = checkpoint_paths(dir);
    for old in &v[..v.len().saturating_sub(keep)] {
        let _ = std::fs::remove_file(old);
        let _ = std::fs::remove_file(sidecar(old));
    }
}

/// Remove a checkpoint and its sidecar (missing files are fine).
pub fn remove(path: &Path) {
    let _ = std::fs::remove_file(path);
    let _ = std::fs::remove_file(sidecar(path));
}

/// Load the newest loadable checkpoint among `candidates` (newest first): each is verified,
/// then read by `read`; a damaged one is reported in the returned warnings and the next tried.
pub fn load_newest<T>(
    candidates: &[PathBuf],
    mut read: impl FnMut(&Path) -> anyhow::Result<T>,
) -> anyhow::Result<(PathBuf, T, Vec<String>)> {
    let mut warnings = Vec::new();
    for p in candidates {
        match verify(p)
            .map_err(anyhow::Error::from)
            .and_then(|()| read(p))
        {
            Ok(v) => return Ok((p.clone(), v, warnings)),
            Err(e) => warnings.push(format!("skipping checkpoint {}: {e:#}", p.display())),
        }
    }
    if candidates.is_empty() {
        anyhow::bail!("no checkpoint to resume from");
    }
    anyhow::bail!("no usable checkpoint: {}", warnings.join("; "))
}

/// Name (in `checkpoints/`) of the state saved right before a failed step; it exists only
/// until the next regular checkpoint, and resume prefers it.
pub const LAST_GOOD: &str = "last_good.h5";

/// What resume does first, for either model: delete temporaries of interrupted writes, then
/// load the state to continue from: `last_good.h5` if there is one (the config may have been
/// edited since, e.g. a larger iteration cap), else the newest intact regular checkpoint.
/// Skipped (damaged) checkpoints are printed as warnings and logged.
pub fn load_for_resume<T>(
    run: &crate::io::rundir::RunDir,
    read: impl FnMut(&Path) -> anyhow::Result<T>,
) -> anyhow::Result<(PathBuf, T)> {
    let stale = run.remove_stale_temporaries();
    if stale > 0 {
        run.log(&format!(
            "removed {stale} temporary files of an interrupted write"
        ))?;
    }
    let dir = run.path().join("checkpoints");
    let mut candidates = newest_first(&dir);
    if dir.join(LAST_GOOD).is_file() {
        candidates.insert(0, dir.join(LAST_GOOD));
    }
    let (path, value, warnings) = load_newest(&candidates, read)
        .map_err(|e| e.context(format!("resuming {}", run.path().display())))?;
    for w in &warnings {
        eprintln!("motile: warning: {w}");
        run.log(&format!("warning: {w}"))?;
    }
    Ok((path, value))
}

/// Regular checkpoints of a run directory's `checkpoints/`, newest first.
pub fn newest_first(dir: &Path) -> Vec<PathBuf> {
    let mut v = checkpoint_paths(dir);
    v.reverse();
    v
}

/// The simulated time a checkpoint of either model holds (its root attribute `time`).
pub fn time_of(path: &Path) -> anyhow::Result<f64> {
    H5Reader::open(path)?.attr_f64("time")
}

static SIGNAL: OnceLock<Arc<AtomicUsize>> = OnceLock::new();

/// SIGINT and SIGTERM set a flag (instead of killing the process) that running loops poll
/// through [`stop_requested`]; they then write a checkpoint and return [`Interrupted`]. A second
/// signal while the first is being handled exits at once (status 130).
pub fn install_signal_handlers() -> std::io::Result<()> {
    let which = SIGNAL.get_or_init(|| Arc::new(AtomicUsize::new(0)));
    let seen = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(sig, 130, Arc::clone(&seen))?;
        signal_hook::flag::register(sig, Arc::clone(&seen))?;
        signal_hook::flag::register_usize(sig, Arc::clone(which), sig as usize)?;
    }
    Ok(())
}

/// The "signal" of a stop the embedding program asked for (the Python module, when a progress
/// callback raised): the log says so instead of naming a signal.
pub const STOP_BY_CALLER: i32 = 1 << 16;

/// Ask running loops to stop at the next step boundary with a checkpoint, as `signal` would
/// (for callers that handle interrupts themselves, such as the Python module, instead of
/// installing the signal handlers).
pub fn request_stop(signal: i32) {
    SIGNAL
        .get_or_init(|| Arc::new(AtomicUsize::new(0)))
        .store(signal.max(1) as usize, Ordering::Relaxed);
}

/// Forget an earlier stop request (before starting another run in the same process).
pub fn clear_stop() {
    if let Some(f) = SIGNAL.get() {
        f.store(0, Ordering::Relaxed);
    }
}

/// The signal that asked the run to stop, if any.
pub fn stop_requested() -> Option<i32> {
    SIGNAL
        .get()
        .map(|f| f.load(Ordering::Relaxed))
        .filter(|&s| s != 0)
        .map(|s| s as i32)
}

/// A run stopped by a signal after writing a checkpoint.
#[derive(Debug, thiserror::Error)]
#[error(
    "stopped by signal {signal} at {at}; checkpoint written to {}. Continue with `motile resume {}`",
    checkpoint.display(),
    run_dir.display()
)]
pub struct Interrupted {
    /// The signal number.
    pub signal: i32,
    /// Where the run was ("step 120 (t = 0.24)").
    pub at: String,
    /// The checkpoint written.
    pub checkpoint: PathBuf,
    /// The run directory.
    pub run_dir: PathBuf,
}

/// An HDF5 checkpoint opened for reading; every error names the file and the item.
#[derive(Debug)]
pub struct H5Reader<'a> {
    path: &'a Path,
    file: hdf5_pure::File,
    attrs: std::collections::HashMap<String, hdf5_pure::AttrValue>,
}

impl<'a> H5Reader<'a> {
    /// Open `path` and read its root attributes.
    pub fn open(path: &'a Path) -> anyhow::Result<Self> {
        let file =
            hdf5_pure::File::open(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let attrs = file
            .root()
            .attrs()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        crate::io::format::check_hdf5(&attrs, path)?;
        Ok(Self { path, file, attrs })
    }

    fn bad_attr(&self, name: &str) -> anyhow::Error {
        anyhow::anyhow!(
            "{}: attribute '{name}' missing or of type {:?}",
            self.path.display(),
            self.attrs.get(name)
        )
    }

    /// A floating-point root attribute.
    pub fn attr_f64(&self, name: &str) -> anyhow::Result<f64> {
        match self.attrs.get(name) {
            Some(hdf5_pure::AttrValue::F64(v)) => Ok(*v),
            _ => Err(self.bad_attr(name)),
        }
    }

    /// A non-negative integer root attribute (stored as u64 or i64).
    pub fn attr_u64(&self, name: &str) -> anyhow::Result<u64> {
        match self.attrs.get(name) {
            Some(hdf5_pure::AttrValue::U64(v)) => Ok(*v),
            Some(hdf5_pure::AttrValue::I64(v)) if *v >= 0 => Ok(*v as u64),
            _ => Err(self.bad_attr(name)),
        }
    }

    /// A floating-point dataset, flattened.
    pub fn f64s(&self, name: &str) -> anyhow::Result<Vec<f64>> {
        self.file
            .dataset(name)
            .and_then(|d| d.read_f64())
            .map_err(|e| anyhow::anyhow!("{}: dataset '{name}': {e}", self.path.display()))
    }

    /// An integer dataset, flattened.
    pub fn i64s(&self, name: &str) -> anyhow::Result<Vec<i64>> {
        self.file
            .dataset(name)
            .and_then(|d| d.read_i64())
            .map_err(|e| anyhow::anyhow!("{}: dataset '{name}': {e}", self.path.display()))
    }

    /// Whether a dataset exists.
    pub fn has(&self, name: &str) -> bool {
        self.file.dataset(name).is_ok()
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        self.path
    }
}
