//! The GPU path end to end, through the `motile` binary, on the host emulation of the kernels
//! (`MOTILE_GPU_BACKEND=emulation`: the same CUDA source compiled by the C++ compiler and run
//! on the CPU), so the adapters around the kernels (the run loop's engine, the state downloaded
//! for snapshots and checkpoints, a checkpoint moving between devices, the particle sums on the
//! device) are tested where there is no GPU:
//! - a mean-field run with `--device gpu` writes the CPU run's time series (8^3, adaptive
//!   steps to t = 1: every diagnostic within 1e-6 relative; the fixed point stops at its
//!   tolerance of 1e-8, so the two may stop an iteration apart);
//! - the golden mean-field run's mid-run checkpoint, written by the CPU, resumes on the
//!   emulated GPU and ends where the CPU run ends;
//! - particle runs without hydrodynamics and at the `dipole`, `sbt-explicit` and `sbt` levels
//!   with `--device gpu`, whose whole step runs on the device (the flow's sum and, at `sbt`,
//!   GMRES included), write the CPU run's time series within the contact solver's tolerance,
//!   flow norms included, and their mid-run checkpoints (downloaded from the device, the
//!   slender-body solution with them) resume on the CPU to the same end;
//! - the series harvest runs the members missing from its table.
//!
//! Failed steps, failing devices and runs too large for the device: `gpu_faults.rs`.
//!
//! Skipped, with the reason, where no C++ compiler runs (a failure with `MOTILE_REQUIRE_CXX=1`).

mod support;

use std::path::{Path, PathBuf};
use std::process::Command;
use support::copy_dir;
use support::emulated::*;

fn golden() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/golden")
}

#[test]
fn a_meanfield_run_on_the_emulated_gpu_matches_the_cpu_and_resumes_from_a_cpu_checkpoint() {
    if !emulation_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (cpu, gpu) = cpu_and_gpu("meanfield", &golden().join("meanfield.toml"), tmp.path());
    let log = std::fs::read_to_string(gpu.join("run.log")).unwrap();
    assert!(
        log.contains("host emulation"),
        "the run says where it ran:\n{log}"
    );
    // The fixed point's count and residual, the energy identity's residual (a cancellation)
    // and the step sizes' last bits may differ.
    let skip = ["fixed_point", "energy_identity", "dt", "steps"];
    let worst = compare(&cpu, &gpu, &skip, 1e-6, 1e-12);
    eprintln!("mean-field run, emulated GPU against CPU: largest difference {worst:.1e}");
    // The golden run's directory as it stood after its mid-run checkpoint (written by the CPU),
    // resumed with device = "gpu".
    let resumed = tmp.path().join("resumed");
    copy_dir(&golden().join("meanfield"), &resumed);
    let config = resumed.join("config.toml");
    let text = std::fs::read_to_string(&config).unwrap();
    std::fs::write(&config, format!("device = \"gpu\"\n{text}")).unwrap();
    motile(&["resume", resumed.to_str().unwrap()], true);
    let log = std::fs::read_to_string(resumed.join("run.log")).unwrap();
    assert!(
        log.contains("host emulation"),
        "the resumed run ran on the device:\n{log}"
    );
    let worst = compare(&cpu, &resumed, &skip, 1e-6, 1e-12);
    eprintln!("resumed on the emulated GPU from a CPU checkpoint: largest difference {worst:.1e}");
}

/// A run at `level` with `--device gpu` of `steps` steps, resident on the device (nu = 2 in a
/// box of 6 rod lengths: contacts every step), against the CPU's run, then its checkpoint five
/// steps before the end (downloaded from the device) resumed on the CPU, against the CPU's run
/// again.
///
/// The device orders its constraints by pair, the CPU by cell: iterations and residuals may
/// differ, and the multipliers are guaranteed to agree only to the solver's complementarity
/// tolerance, 1e-7 l of separation per step: velocities to about 1e-7 / dt = 5e-6 beta l (rotation rates, over arms of about l/2,
/// twice that), i.e. 1e-5 of rates of order 1; positions to 1e-7 l per step. The flow of the
/// levels with hydrodynamics is the same function of the rods on both sides (summed on the
/// emulated device, rods and all, to round-off of the CPU's sum), so the same bound holds.
fn resident_run(level: &str, says: &str, steps: usize) {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join(format!("{level}.toml"));
    // Diagnostics every second step, a snapshot at the end; checkpoints five steps before the
    // end (an odd step: no output there) and at the end.
    assert!(steps.is_multiple_of(2) && steps > 5);
    let dt = 0.02;
    let text = format!(
        "box_length = 6\nvolume_fraction = 2\nhydrodynamics = \"{level}\"\ndt = {dt}\n\
         t_end = {}\ndiagnostic_interval = 0.04\nsnapshot_interval = {}\n\
         checkpoint_interval = {}\nvtk = false\n",
        steps as f64 * dt,
        steps as f64 * dt,
        (steps - 5) as f64 * dt,
    );
    std::fs::write(&cfg, text).unwrap();
    let (cpu, gpu) = cpu_and_gpu("particle", &cfg, tmp.path());
    let log = std::fs::read_to_string(gpu.join("run.log")).unwrap();
    assert!(
        log.contains(says),
        "{level}: the run says where it ran:\n{log}"
    );
    let skip = SOLVER_COLUMNS;
    let worst = compare(&cpu, &gpu, &skip, 2e-5, 1e-9);
    let ((h, rc), (_, rg)) = (rows(&cpu), rows(&gpu));
    let col = |name: &str| h.iter().position(|c| c.starts_with(name)).unwrap();
    let k = col("constraints");
    assert!(
        rc.iter().all(|r| r[k] > 10.0),
        "{level}: too few contacts to test: {rc:?}"
    );
    let flow = rc
        .iter()
        .map(|r| r[col("velocity_norm")])
        .fold(0.0, f64::max);
    assert!(
        level == "none" || flow > 1e-3,
        "{level}: no flow to compare (velocity norm {flow:.1e})"
    );
    let active = col("active_contacts");
    for (a, b) in rc.iter().zip(&rg) {
        assert!(
            (a[active] - b[active]).abs() <= 0.02 * a[active] + 2.0,
            "{level}: active {a:?} {b:?}"
        );
    }
    eprintln!(
        "{level} run, emulated GPU against CPU: largest difference {worst:.1e} (flow norm up to {flow:.2e})"
    );
    // The GPU run's checkpoint five steps before the end (no output there, so the warm state
    // is the one kept on the device) resumed on the CPU.
    let last = format!("ckpt_{steps:09}");
    let resumed = tmp.path().join("resumed");
    copy_dir(&gpu, &resumed);
    for f in std::fs::read_dir(resumed.join("checkpoints")).unwrap() {
        let p = f.unwrap().path();
        if p.file_name().unwrap().to_str().unwrap().starts_with(&last) {
            std::fs::remove_file(p).unwrap();
        }
    }
    let newest = std::fs::read_dir(resumed.join("checkpoints"))
        .unwrap()
        .map(|f| f.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".h5"))
        .max();
    let from = format!("ckpt_{:09}.h5", steps - 5);
    assert_eq!(
        newest.as_deref(),
        Some(from.as_str()),
        "{level}: the newest checkpoint left to resume from"
    );
    let config = resumed.join("config.toml");
    let text = std::fs::read_to_string(&config).unwrap();
    std::fs::write(
        &config,
        text.replace("device = \"gpu\"", "device = \"cpu\""),
    )
    .unwrap();
    motile(&["resume", resumed.to_str().unwrap()], false);
    let worst = compare(&cpu, &resumed, &skip, 2e-5, 1e-9);
    eprintln!("{level}: its checkpoint resumed on the CPU: largest difference {worst:.1e}");
}

#[test]
fn a_run_without_hydrodynamics_steps_on_the_emulated_gpu_and_resumes_on_the_cpu() {
    if emulation_available() {
        resident_run("none", "the whole step runs on the GPU", 20);
    }
}

#[test]
fn dipole_runs_step_on_the_emulated_gpu_and_resume_on_the_cpu() {
    if emulation_available() {
        resident_run("dipole", "the flow's sum included", 20);
    }
}

#[test]
fn explicit_slender_runs_step_on_the_emulated_gpu_and_resume_on_the_cpu() {
    if emulation_available() {
        resident_run("sbt-explicit", "the flow's sum included", 20);
    }
}

#[test]
fn slender_body_runs_step_on_the_emulated_gpu_and_resume_on_the_cpu() {
    if emulation_available() {
        // Ten steps: each is two GMRES solves of sums on the emulation.
        resident_run("sbt", "the flow's sum included", 10);
    }
}

/// A `gpu_spreader` that does not exist is refused by name, with the allowed ones.
#[test]
fn an_unknown_spreader_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = sbt_config(tmp.path(), 0.01);
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(&cfg, format!("gpu_spreader = \"bins\"\n{text}")).unwrap();
    let out = tmp.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_motile"))
        .args(["particle", "run", cfg.to_str().unwrap(), "--out"])
        .arg(&out)
        .args(["--device", "gpu", "--threads", "1", "--dry-run"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "ran with gpu_spreader = bins");
    assert!(
        err.contains("gpu_spreader") && err.contains("bins") && err.contains("cells"),
        "the error names the key, the value and the allowed ones: {err}"
    );
}

/// The small scene the series harvest runs in the test: a particle member at the paper's
/// settings in a box of 8 rods (10 steps), a member already in the table, one whose estimate
/// exceeds the time limit, and a mean-field member.
const SERIES_SCENE: &str = r#"[scene]
name = "series-test"
version = 1
description = "A small series for the harvest's test."
level = "sbt-explicit, as the paper-dilute scene"
cost = "seconds"

[[run]]
name = "L8"
model = "particle"
[run.config]
box_length = 8.0
volume_fraction = 0.625
dt = 0.05
t_end = 0.5
hydrodynamics = "sbt-explicit"
gpu_spreader = "sorted"
diagnostic_interval = 0.1
snapshot_interval = 0.25
checkpoint_interval = 0.25
lowest_modes = true
vtk = false
[run.config.contact]
margin = 0.15
[run.config.hydro]
sum_tolerance = 1e-2
quadrature_points = 4

[[run]]
name = "L9"
model = "particle"
[run.config]
box_length = 9.0
t_end = 0.5

[[run]]
name = "L300"
model = "particle"
[run.config]
box_length = 300.0
volume_fraction = 0.625
dt = 0.05
t_end = 300.0
hydrodynamics = "sbt-explicit"
diagnostic_interval = 1.0
snapshot_interval = 10.0
checkpoint_interval = 10.0
[run.config.contact]
margin = 0.15

[[run]]
name = "mf8"
model = "meanfield"
[run.config]
grid = 8
mode_max = 2
t_end = 0.5
diagnostic_interval = 0.1
snapshot_interval = 0.25
checkpoint_interval = 0.25
"#;

/// `scripts/device_run.sh series` end to end on the emulation: the members not in the table
/// run in order on the (emulated) GPU, a member in the table and one that would not fit the
/// time limit are not started, and only the compact products come back (no snapshot or
/// checkpoint), with the comparison's rows named by member.
#[test]
fn the_series_harvest_runs_the_missing_members_on_the_emulated_gpu() {
    if !emulation_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene.toml");
    std::fs::write(&scene, SERIES_SCENE).unwrap();
    let table = tmp.path().join("series.csv");
    std::fs::write(&table, "run,model\nL9,particle\n").unwrap();
    let out = tmp.path().join("out");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/device_run.sh");
    let o = Command::new("bash")
        .args([script, "series"])
        .env("OUT", &out)
        .env("MOTILE_BIN", env!("CARGO_BIN_EXE_motile"))
        .env("MOTILE_GPU_BACKEND", "emulation")
        .env("SERIES_SCENE", &scene)
        .env("SERIES_MEMBERS", "L8 L9 L300 mf8")
        .env("SERIES_CSV", &table)
        .env("SERIES_DIR", tmp.path().join("runs"))
        .env("SERIES_LIMIT", "300")
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "series failed:\n{said}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let log = std::fs::read_to_string(out.join("series.log")).unwrap();
    for line in [
        "L8: exit 0",
        "L9: in ",
        "L300: not started (estimated",
        "mf8: exit 0",
    ] {
        assert!(log.contains(line), "series.log lacks `{line}`:\n{log}");
    }
    // What comes back is one archive (and the log): unpack it.
    let got = tmp.path().join("got");
    std::fs::create_dir_all(&got).unwrap();
    let untar = Command::new("tar")
        .arg("xzf")
        .arg(out.join("series.tgz"))
        .arg("-C")
        .arg(&got)
        .status()
        .unwrap();
    assert!(untar.success(), "series.tgz does not unpack");
    let rows = std::fs::read_to_string(got.join("compare/series.csv")).unwrap();
    let names: Vec<&str> = rows
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(names, ["L8", "mf8"], "series rows:\n{rows}");
    for member in ["L8", "mf8"] {
        for f in ["config.toml", "timeseries.csv", "analysis/correlations.csv"] {
            let p = got.join(member).join(f);
            assert!(p.is_file(), "{} missing", p.display());
        }
        let cfg = std::fs::read_to_string(got.join(member).join("config.toml")).unwrap();
        assert!(
            cfg.contains("device = \"gpu\""),
            "{member} did not run on the GPU"
        );
    }
    assert!(got.join("L8/modes.csv").is_file());
    let mut large = Vec::new();
    let mut stack = vec![got.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "h5") {
                large.push(p);
            }
        }
    }
    assert!(
        large.is_empty(),
        "snapshots or checkpoints came back: {large:?}"
    );
    file_the_harvest(&out.join("series.tgz"), &rows, tmp.path());
}

/// `scripts/series_harvest.sh` files an archive's finished members into a gallery: their rows
/// appended to the table (a member already there left as it is), their compact products under
/// `paper-dilute/MEMBER/`; filing the same archive again adds nothing.
fn file_the_harvest(archive: &Path, rows: &str, tmp: &Path) {
    let gallery = tmp.join("gallery");
    std::fs::create_dir_all(&gallery).unwrap();
    let header = rows.lines().next().unwrap();
    let table = gallery.join("paper_dilute_series.csv");
    std::fs::write(&table, format!("{header}\nL9,particle,9\n")).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/series_harvest.sh");
    let file = || {
        let o = Command::new("bash")
            .arg(script)
            .arg(archive)
            .arg(&gallery)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let said = file();
    assert!(
        said.contains("L8: filed") && said.contains("mf8: filed"),
        "{said}"
    );
    let filed = std::fs::read_to_string(&table).unwrap();
    let names: Vec<&str> = filed
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(names, ["L9", "L8", "mf8"], "{filed}");
    for f in [
        "L8/timeseries.csv",
        "L8/compare/series.csv",
        "mf8/config.toml",
    ] {
        assert!(
            gallery.join("paper-dilute").join(f).is_file(),
            "{f} not filed"
        );
    }
    let again = file();
    assert!(
        again.contains("L8: in ") && again.contains("already"),
        "{again}"
    );
    assert_eq!(std::fs::read_to_string(&table).unwrap(), filed);
}
