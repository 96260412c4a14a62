//! Cross-crate validation of motile: the tests in `tests/` check the models against each other
//! and against references. This library holds helpers they share.

use std::path::Path;
use std::process::Command;

/// Whether `python3` with h5py and numpy is available. When `MOTILE_REQUIRE_H5PY=1` (set by
/// `.ci/run`), its absence is an error rather than a reason to skip.
pub fn h5py_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import h5py, numpy"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok && std::env::var("MOTILE_REQUIRE_H5PY").as_deref() == Ok("1") {
        panic!("MOTILE_REQUIRE_H5PY=1 but python3 cannot import h5py and numpy");
    }
    ok
}

/// Run a Python snippet with arguments; panics with its output if it fails.
pub fn run_python(script: &str, args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .expect("python3 runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "python failed:\n{text}");
    text
}

/// Copy the directory `from` to `to`, recursively (a committed run directory into a test's
/// temporary one).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dest = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dest);
        } else {
            std::fs::copy(&p, &dest).unwrap();
        }
    }
}
