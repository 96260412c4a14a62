//! Helpers shared by the integration tests that run whole run directories.
#![allow(dead_code)]

use std::path::Path;

#[cfg(feature = "gpu")]
pub mod emulated;

/// Copy a run directory (files and folders, recursively).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}
