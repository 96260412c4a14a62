//! Helpers of the tests that run the GPU path through the `motile` binary on the host
//! emulation (`gpu_runs.rs`, `gpu_faults.rs`).
#![allow(dead_code)]

use motile_experiments::io::rundir::TimeSeries;
use std::path::{Path, PathBuf};
use std::process::Command;

/// `motile args` (on the emulation where `emulated`), whatever its exit status.
pub fn motile_output(args: &[&str], emulated: bool) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_motile"));
    c.args(args).arg("--threads").arg("2");
    if emulated {
        c.env("MOTILE_GPU_BACKEND", "emulation");
    }
    c.output().expect("running motile")
}

/// `motile args`, which must succeed.
pub fn motile(args: &[&str], emulated: bool) -> std::process::Output {
    let out = motile_output(args, emulated);
    assert!(
        out.status.success(),
        "motile {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Whether the emulation can run here; prints why not (or fails with `MOTILE_REQUIRE_CXX=1`).
pub fn emulation_available() -> bool {
    let found = ["c++", "g++", "clang++"].iter().any(|c| {
        Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    }) || std::env::var("CXX").is_ok_and(|c| !c.is_empty());
    if !found {
        assert!(
            std::env::var("MOTILE_REQUIRE_CXX").is_err(),
            "MOTILE_REQUIRE_CXX is set but no C++ compiler runs"
        );
        eprintln!("skipped: no C++ compiler for the host emulation");
    }
    found
}

/// A particle config's text spreading with the global-memory spreader in bin order on the
/// GPU: the default output-driven one runs each of its many small blocks as 256 OS threads with
/// a barrier on the emulation (6.5 s a sum of 1 728 points here, against 0.05 s); it is checked
/// against the CPU's sums in particle/tests/gpu_ewald.rs and in resident steps in
/// particle/tests/gpu_slender.rs and gpu_resident.rs.
pub fn sorted_spreader(text: &str) -> String {
    format!("gpu_spreader = \"sorted\"\n{text}")
}

/// `motile MODEL run CONFIG` into `dir/cpu`, and with `--device gpu` on the emulation into
/// `dir/gpu` (a particle run with the sorted spreader, [`sorted_spreader`]).
pub fn cpu_and_gpu(model: &str, cfg: &Path, dir: &Path) -> (PathBuf, PathBuf) {
    let (cpu, gpu) = (dir.join("cpu"), dir.join("gpu"));
    motile(
        &[
            model,
            "run",
            cfg.to_str().unwrap(),
            "--out",
            cpu.to_str().unwrap(),
        ],
        false,
    );
    let gpu_cfg = dir.join("gpu.toml");
    let text = std::fs::read_to_string(cfg).unwrap();
    let text = if model == "particle" {
        sorted_spreader(&text)
    } else {
        text
    };
    std::fs::write(&gpu_cfg, text).unwrap();
    let gpu_args = [
        model,
        "run",
        gpu_cfg.to_str().unwrap(),
        "--out",
        gpu.to_str().unwrap(),
        "--device",
        "gpu",
    ];
    motile(&gpu_args, true);
    (cpu, gpu)
}

/// A run's time series: header and rows.
pub fn rows(dir: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let ts = TimeSeries::read(&dir.join("timeseries.csv")).unwrap();
    (ts.columns, ts.rows)
}

/// Every column but `skip` of the rows of `b` at the times of `a`'s rows, within `tol` relative
/// (absolute below `floor`); returns the largest difference.
pub fn compare(a: &Path, b: &Path, skip: &[&str], tol: f64, floor: f64) -> f64 {
    let ((h, ra), (_, rb)) = (rows(a), rows(b));
    let mut worst: f64 = 0.0;
    for r in &rb {
        let s = ra
            .iter()
            .find(|s| (s[0] - r[0]).abs() < 1e-9)
            .unwrap_or_else(|| panic!("no row at t = {} in {}", r[0], a.display()));
        for (k, name) in h.iter().enumerate() {
            if skip.iter().any(|x| name.starts_with(x)) {
                continue;
            }
            let d = (s[k] - r[k]).abs() / s[k].abs().max(floor);
            worst = worst.max(d);
            assert!(
                d <= tol,
                "{name} at t = {}: {} ({}) vs {} ({}): {d:.1e}",
                r[0],
                s[k],
                a.display(),
                r[k],
                b.display()
            );
        }
    }
    worst
}

/// The time-series columns a resident run need not share with the CPU's: the wall-clock rate,
/// and what depends on the order of the contact solver's constraints (iterations, residual,
/// active count, overlap left, corrections).
pub const SOLVER_COLUMNS: [&str; 6] = [
    "steps_per_second",
    "solver_iterations",
    "solver_residual",
    "active_contacts",
    "max_overlap",
    "contact_corrections",
];

/// A slender-body run of 16 rods in a box of 4 to `t_end` (dt 0.01), written into `dir`.
pub fn sbt_config(dir: &Path, t_end: f64) -> PathBuf {
    let cfg = dir.join("sbt.toml");
    let text = format!(
        "box_length = 4\nrods = 16\nhydrodynamics = \"sbt\"\ndt = 0.01\nt_end = {t_end}\n\
         diagnostic_interval = 0.02\nsnapshot_interval = 0.1\ncheckpoint_interval = 0.1\n\
         vtk = false\n"
    );
    std::fs::write(&cfg, text).unwrap();
    cfg
}
