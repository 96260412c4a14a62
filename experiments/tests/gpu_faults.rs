//! The GPU path's failures end to end, through the `motile` binary on the host emulation of the
//! kernels (`MOTILE_GPU_BACKEND=emulation`):
//! - a resident step that fails stops the run with the reason and the state before it, which
//!   resumes on the CPU to the CPU run's end;
//! - a device failure injected mid-step (a launch that fails; a device unusable after it) stops
//!   either model's run with the last good state saved or the newest checkpoint named, and
//!   the run resumes to the CPU run's end;
//! - a run whose GPU memory need exceeds what it may use is refused before it allocates.
//!
//! Skipped, with the reason, where no C++ compiler runs (a failure with `MOTILE_REQUIRE_CXX=1`).

mod support;

use std::process::Command;
use support::emulated::*;

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
