//! The version of motile's file formats: run directories (`config.toml`'s `[motile]` table),
//! HDF5 snapshots and checkpoints carry `format_version`, and every reader checks it before
//! anything else. A file without it was written before formats were versioned; its layout is
//! version 1's, so it is read as version 1. A file of a newer version is refused with the
//! version and the motile that wrote it, never misread.
//!
//! Version 1: the layouts of docs/run-directory.md. A change to a layout that an older reader
//! would misread raises [`FORMAT_VERSION`] and teaches the readers the older versions
//! (tests/data/formats holds a run directory of each version, which the tests resume).

use crate::io::IoError;
use hdf5_pure::{AttrValue, FileBuilder};
use std::collections::HashMap;
use std::path::Path;

/// The format version this motile writes, and the newest it reads.
pub const FORMAT_VERSION: u64 = 1;

/// Stamp a file being built with the format version and the motile version writing it.
pub fn stamp(b: &mut FileBuilder) {
    b.set_attr("format_version", AttrValue::U64(FORMAT_VERSION));
    b.set_attr(
        "motile_version",
        AttrValue::VarLenString(env!("CARGO_PKG_VERSION").into()),
    );
}

/// Check an HDF5 file's root attributes: no `format_version` (written before versioning)
/// or one up to [`FORMAT_VERSION`] is read; a newer or unreadable one is refused.
pub fn check_hdf5(attrs: &HashMap<String, AttrValue>, path: &Path) -> Result<(), IoError> {
    let version = match attrs.get("format_version") {
        None => return Ok(()),
        Some(AttrValue::U64(v)) => Some(*v),
        Some(AttrValue::I64(v)) => u64::try_from(*v).ok(),
        Some(_) => None,
    };
    let writer = match attrs.get("motile_version") {
        Some(AttrValue::VarLenString(s) | AttrValue::String(s)) => s.clone(),
        _ => "an unknown version".into(),
    };
    check(version, &writer, path)
}

/// Check a version read from `path` (`None`: present but not a whole number).
pub fn check(version: Option<u64>, writer: &str, path: &Path) -> Result<(), IoError> {
    match version {
        Some(v) if v <= FORMAT_VERSION && v > 0 => Ok(()),
        Some(v) => Err(IoError::Content {
            path: path.to_path_buf(),
            message: format!(
                "format version {v}, written by motile {writer}; this motile ({}) reads format versions 1 to {FORMAT_VERSION}: read it with motile {writer} or newer",
                env!("CARGO_PKG_VERSION")
            ),
        }),
        None => Err(IoError::Content {
            path: path.to_path_buf(),
            message:
                "attribute 'format_version' is not a whole number: damaged or not written by motile"
                    .into(),
        }),
    }
}
