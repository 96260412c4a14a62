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
//! - a resident step that fails stops the run with the reason and the state before it, which
//!   resumes on the CPU to the CPU run's end;
//! - a device failure injected mid-step (a launch that fails; a device unusable after it) stops
//!   either model's run with the last good state saved or the newest checkpoint named, and
//!   the run resumes to the CPU run's end.
//!
//! Skipped, with the reason, where no C++ compiler runs (a failure with `MOTILE_REQUIRE_CXX=1`).

mod support;

use motile_experiments::io::rundir::TimeSeries;
use std::path::{Path, PathBuf};
use std::process::Command;
use support::copy_dir;

/// `motile args` (on the emulation where `emulated`), whatever its exit status.
fn motile_output(args: &[&str], emulated: bool) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_motile"));
    c.args(args).arg("--threads").arg("2");
    if emulated {
        c.env("MOTILE_GPU_BACKEND", "emulation");
    }
    c.output().expect("running motile")
}

/// `motile args`, which must succeed.
fn motile(args: &[&str], emulated: bool) -> std::process::Output {
    let out = motile_output(args, emulated);
    assert!(
        out.status.success(),
        "motile {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Whether the emulation can run here; prints why not (or fails with `MOTILE_REQUIRE_CXX=1`).
fn emulation_available() -> bool {
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
fn sorted_spreader(text: &str) -> String {
    format!("gpu_spreader = \"sorted\"\n{text}")
}

/// `motile MODEL run CONFIG` into `dir/cpu`, and with `--device gpu` on the emulation into
/// `dir/gpu` (a particle run with the sorted spreader, [`sorted_spreader`]).
fn cpu_and_gpu(model: &str, cfg: &Path, dir: &Path) -> (PathBuf, PathBuf) {
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

fn golden() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/golden")
}

/// A run's time series: header and rows.
fn rows(dir: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let ts = TimeSeries::read(&dir.join("timeseries.csv")).unwrap();
    (ts.columns, ts.rows)
}

/// Every column but `skip` of the rows of `b` at the times of `a`'s rows, within `tol` relative
/// (absolute below `floor`); returns the largest difference.
fn compare(a: &Path, b: &Path, skip: &[&str], tol: f64, floor: f64) -> f64 {
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

/// The time-series columns a resident run need not share with the CPU's: the wall-clock rate,
/// and what depends on the order of the contact solver's constraints (iterations, residual,
/// active count, overlap left, corrections).
const SOLVER_COLUMNS: [&str; 6] = [
    "steps_per_second",
    "solver_iterations",
    "solver_residual",
    "active_contacts",
    "max_overlap",
    "contact_corrections",
];

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

/// A resident step that fails (the contact solver capped at 16 iterations, which one step of
/// the dense suspension needs more than: step 5 here, the first four warm-started ones
/// converge within it) stops the run with the reason and the path of the state before it,
/// downloaded from the device with its warm start; with the cause fixed, the run resumes from
/// that state on the CPU and ends where the CPU's own run of the fixed config ends.
#[test]
fn a_failed_resident_step_saves_the_state_before_it_and_resumes_on_the_cpu() {
    if !emulation_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("dipole.toml");
    let text = "box_length = 6\nvolume_fraction = 2\nhydrodynamics = \"dipole\"\ndt = 0.02\n\
                t_end = 0.2\ndiagnostic_interval = 0.04\nsnapshot_interval = 0.2\n\
                checkpoint_interval = 0.2\nvtk = false\n";
    let capped = "[contact]\nmax_iterations = 16\n";
    std::fs::write(&cfg, sorted_spreader(&format!("{text}{capped}"))).unwrap();
    let gpu = tmp.path().join("gpu");
    let args = [
        "particle",
        "run",
        cfg.to_str().unwrap(),
        "--out",
        gpu.to_str().unwrap(),
        "--device",
        "gpu",
    ];
    let o = motile_output(&args, true);
    let err = String::from_utf8_lossy(&o.stderr);
    let last_good = gpu.join("checkpoints").join("last_good.h5");
    assert!(
        !o.status.success() && err.contains("did not converge") && last_good.is_file(),
        "the failed run says why and saves the state before the step:\n{err}"
    );
    assert!(
        err.contains("last_good.h5"),
        "the message names the saved state:\n{err}"
    );
    let failed_at = err
        .split("step ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .unwrap_or("?")
        .to_string();
    // The cause fixed, resumed on the CPU.
    let config = gpu.join("config.toml");
    let saved = std::fs::read_to_string(&config).unwrap();
    let fixed = saved
        .replace("max_iterations = 16\n", "max_iterations = 2000\n")
        .replace("device = \"gpu\"", "device = \"cpu\"");
    assert_ne!(fixed, saved, "the saved config has the cap and the device");
    std::fs::write(&config, fixed).unwrap();
    motile(&["resume", gpu.to_str().unwrap()], false);
    std::fs::write(&cfg, text).unwrap();
    let cpu = tmp.path().join("cpu");
    motile(
        &[
            "particle",
            "run",
            cfg.to_str().unwrap(),
            "--out",
            cpu.to_str().unwrap(),
        ],
        false,
    );
    let skip = SOLVER_COLUMNS;
    let worst = compare(&cpu, &gpu, &skip, 2e-5, 1e-9);
    eprintln!(
        "failed on the emulated GPU at step {failed_at}, resumed on the CPU from the saved \
         state: largest difference from the CPU's run {worst:.1e}"
    );
}

/// `motile ARGS` on the emulation with the device failure `inject` injected
/// (`MOTILE_GPU_INJECT_FAILURE`); it must fail, and its message is returned.
fn failing_device(args: &[&str], inject: &str) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_motile"))
        .args(args)
        .args(["--threads", "2"])
        .env("MOTILE_GPU_BACKEND", "emulation")
        .env("MOTILE_GPU_INJECT_FAILURE", inject)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(
        !o.status.success(),
        "ran through the injected failure {inject}"
    );
    assert!(
        err.contains("illegal memory access") && err.contains("injected"),
        "the message says the device failed:\n{err}"
    );
    err
}

/// A device that fails in the middle of a step (a launch fails, as on an illegal address) stops
/// the run with the reason and the last good state: where the device still answers (`"1000"`,
/// the 1000th launch, in step 8 of 10 of a resident dipole run), the state before the step,
/// downloaded into last_good.h5; where it is unusable after the failure (`"1000,sticky"`, as
/// CUDA's sticky errors leave a context), the newest regular checkpoint (step 5), named in the
/// message. Either run resumes on the emulated device to the CPU run's end. The mean-field run
/// (adaptive steps on an 8^3 grid) likewise, its state lost with the device at launch 200 (step
/// 7) and continued from its first checkpoint.
#[test]
fn a_device_failure_mid_step_stops_with_the_last_good_state_saved() {
    if !emulation_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("dipole.toml");
    std::fs::write(
        &cfg,
        "box_length = 6\nvolume_fraction = 2\nhydrodynamics = \"dipole\"\ndt = 0.02\n\
         t_end = 0.2\ndiagnostic_interval = 0.04\nsnapshot_interval = 0.2\n\
         checkpoint_interval = 0.1\nvtk = false\n",
    )
    .unwrap();
    let (cpu, _) = cpu_and_gpu("particle", &cfg, tmp.path());
    let gpu_cfg = tmp.path().join("gpu.toml");
    for (inject, saved) in [
        ("1000", "last_good.h5"),
        ("1000,sticky", "ckpt_000000005.h5"),
    ] {
        let out = tmp.path().join(inject.replace(',', "-"));
        let args = [
            "particle",
            "run",
            gpu_cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--device",
            "gpu",
        ];
        let err = failing_device(&args, inject);
        assert!(
            err.contains("step 8 ") && err.contains(saved) && err.contains("motile resume"),
            "{inject}: the message names the state to resume from, {saved}:\n{err}"
        );
        let last_good = out.join("checkpoints").join("last_good.h5");
        assert_eq!(last_good.is_file(), saved == "last_good.h5", "{inject}");
        motile(&["resume", out.to_str().unwrap()], true);
        let worst = compare(&cpu, &out, &SOLVER_COLUMNS, 2e-5, 1e-9);
        eprintln!(
            "device failure {inject}: resumed from {saved}, largest difference from the CPU's run {worst:.1e}"
        );
    }
    let mf = tmp.path().join("mf.toml");
    std::fs::write(&mf, "grid = 8\nt_end = 1.0\ncheckpoint_interval = 0.5\n").unwrap();
    let mf_cpu = tmp.path().join("mf_cpu");
    motile(
        &[
            "meanfield",
            "run",
            mf.to_str().unwrap(),
            "--out",
            mf_cpu.to_str().unwrap(),
        ],
        false,
    );
    let mf_gpu = tmp.path().join("mf_gpu");
    let args = [
        "meanfield",
        "run",
        mf.to_str().unwrap(),
        "--out",
        mf_gpu.to_str().unwrap(),
        "--device",
        "gpu",
    ];
    let err = failing_device(&args, "200,sticky");
    assert!(
        err.contains("could not be saved") && err.contains("ckpt_000000000.h5"),
        "the lost state is said, the checkpoint named:\n{err}"
    );
    motile(&["resume", mf_gpu.to_str().unwrap()], true);
    let skip = ["fixed_point", "energy_identity", "dt", "steps"];
    let worst = compare(&mf_cpu, &mf_gpu, &skip, 1e-6, 1e-12);
    eprintln!(
        "mean-field device failure: resumed, largest difference from the CPU's run {worst:.1e}"
    );
}

/// A slender-body run of 16 rods in a box of 4 to `t_end` (dt 0.01), written into `dir`.
fn sbt_config(dir: &Path, t_end: f64) -> PathBuf {
    let cfg = dir.join("sbt.toml");
    let text = format!(
        "box_length = 4\nrods = 16\nhydrodynamics = \"sbt\"\ndt = 0.01\nt_end = {t_end}\n\
         diagnostic_interval = 0.02\nsnapshot_interval = 0.1\ncheckpoint_interval = 0.1\n\
         vtk = false\n"
    );
    std::fs::write(&cfg, text).unwrap();
    cfg
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

/// A run whose measured GPU memory need exceeds what it may use is refused before its first
/// step, with the figures, and writes no time series (a particle run and a mean-field run); a
/// limit that is not a number is named.
#[test]
fn a_run_that_would_not_fit_the_gpu_memory_is_refused_with_the_figures() {
    if !emulation_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cfg = sbt_config(tmp.path(), 0.02);
    let run = |limit: &str, out: &str| {
        Command::new(env!("CARGO_BIN_EXE_motile"))
            .args(["particle", "run", cfg.to_str().unwrap(), "--out"])
            .arg(tmp.path().join(out))
            .args(["--device", "gpu", "--threads", "1"])
            .env("MOTILE_GPU_BACKEND", "emulation")
            .env("MOTILE_GPU_MEMORY_LIMIT", limit)
            .output()
            .unwrap()
    };
    let o = run("1000", "small");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "ran within 1000 bytes");
    assert!(
        err.contains("GB of GPU memory") && err.contains("16 rods x 6520 bytes"),
        "{err}"
    );
    assert!(!tmp.path().join("small/timeseries.csv").exists());
    let o = run("lots", "named");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("MOTILE_GPU_MEMORY_LIMIT = \"lots\""),
        "{err}"
    );
    // Enough memory: the run goes.
    let o = run("100000000000", "enough");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // A mean-field run likewise, by its bytes per grid point, before its device is opened.
    let mf = tmp.path().join("mf.toml");
    std::fs::write(&mf, "grid = 16\nt_end = 0.1\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_motile"))
        .args(["meanfield", "run", mf.to_str().unwrap(), "--out"])
        .arg(tmp.path().join("mf"))
        .args(["--device", "gpu", "--threads", "1"])
        .env("MOTILE_GPU_BACKEND", "emulation")
        .env("MOTILE_GPU_MEMORY_LIMIT", "100000000")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success()
            && err.contains("4096 grid points x 600 bytes")
            && err.contains("grid = 16"),
        "{err}"
    );
    assert!(!tmp.path().join("mf/timeseries.csv").exists());
}
