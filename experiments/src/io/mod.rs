//! Files: run directories ([`rundir`]), verified checkpoints ([`checkpoint`]), HDF5 snapshots
//! ([`snapshot`]), VTK for ParaView ([`vtk`]), the formats' version ([`mod@format`]), and atomic
//! output (here): every file is written
//! to a temporary sibling, flushed to disk, and renamed over the target, so a killed run leaves
//! either the old file or the new one, never a truncated one.

pub mod checkpoint;
pub mod format;
pub mod rundir;
pub mod snapshot;
pub mod vtk;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Errors of run-directory input and output. Each names the file.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// A filesystem operation failed.
    #[error("{path}: {source}")]
    Fs {
        /// The file or directory.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// An HDF5 file could not be read or written.
    #[error("{path}: HDF5: {message}")]
    Hdf5 {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Not a readable motile snapshot at all: cut short (a copy or a run killed outside
    /// motile's atomic writes) or another file.
    #[error("file truncated or not a motile snapshot: {path} ({detail})")]
    NotSnapshot {
        /// The file.
        path: PathBuf,
        /// What the HDF5 reader said.
        detail: String,
    },
    /// A file's content is not what motile expects.
    #[error("{path}: {message}")]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

pub(crate) fn fs_err(path: &Path) -> impl FnOnce(std::io::Error) -> IoError + '_ {
    move |source| IoError::Fs {
        path: path.to_path_buf(),
        source,
    }
}

/// Bytes [`write_atomic`] may still write before it fails as a full disk would
/// (`u64::MAX`: no limit); set by [`fail_writes_after`].
static WRITE_BUDGET: AtomicU64 = AtomicU64::new(u64::MAX);

/// The error for a file whose content is not what motile writes: the file, and `what` in it.
pub(crate) fn damaged(path: &Path, what: String) -> anyhow::Error {
    anyhow::anyhow!(
        "{}: damaged or not written by motile: {what}",
        path.display()
    )
}

/// Fault injection for the fault tests: from now on, [`write_atomic`] in this process fails
/// as a full disk would (`StorageFull`, after writing part of the file) once `bytes` more
/// bytes have been written; `None` lifts the limit. Process-wide: a test that sets it runs
/// alone in its test binary.
pub fn fail_writes_after(bytes: Option<u64>) {
    WRITE_BUDGET.store(bytes.unwrap_or(u64::MAX), Ordering::SeqCst);
}

/// Write `bytes` to the open temporary `f`, within the injected budget.
fn write_within_budget(f: &mut fs::File, bytes: &[u8]) -> std::io::Result<()> {
    let budget = WRITE_BUDGET.load(Ordering::SeqCst);
    if budget == u64::MAX {
        return f.write_all(bytes);
    }
    let allowed = budget.min(bytes.len() as u64);
    WRITE_BUDGET.store(budget - allowed, Ordering::SeqCst);
    f.write_all(&bytes[..allowed as usize])?;
    if allowed < bytes.len() as u64 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::StorageFull,
            "No space left on device (injected)",
        ));
    }
    Ok(())
}

/// Write `bytes` to `path` atomically (temporary file in the same directory, fsync, rename,
/// fsync of the directory). A write that fails (a full disk) removes its temporary and
/// leaves the file at `path` as it was; the error names `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    fs::create_dir_all(dir).map_err(fs_err(dir))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let written = fs::File::create(&tmp).and_then(|mut f| {
        write_within_budget(&mut f, bytes)?;
        f.sync_all()
    });
    if let Err(source) = written {
        let _ = fs::remove_file(&tmp);
        return Err(IoError::Fs {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                source.kind(),
                format!("not written ({source}); the file under this name, if any, is unchanged"),
            ),
        });
    }
    fs::rename(&tmp, path).map_err(fs_err(path))?;
    // Make the rename itself durable; not all filesystems allow opening a directory.
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Remove an earlier run at `dir` (a sweep's cell run again), so the next run starts clean.
pub fn remove_old_run(dir: &Path) -> Result<(), IoError> {
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(fs_err(dir))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_content_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/a.txt");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"second");
        let names: Vec<_> = fs::read_dir(p.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "leftover files: {names:?}");
    }
}
