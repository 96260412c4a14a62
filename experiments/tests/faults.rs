//! Runs that survive faults: killed with SIGKILL at random moments and resumed (bit-identical
//! to the uninterrupted run, no damaged file ever visible), stopped by SIGTERM, damaged
//! checkpoints skipped for the previous one, divergence ending in a structured error with a
//! usable checkpoint, and thread-count independence of both models.

use motile_experiments::io::checkpoint::verify;
use motile_experiments::io::rundir::TimeSeries;
use motile_experiments::io::snapshot::read_snapshot;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_motile");

fn motile(args: &[&str], cwd: &Path) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            v.extend(files(&p));
        } else {
            v.push(p);
        }
    }
    v.sort();
    v
}

/// Every file with a final name is whole: checkpoints with a checksum verify, snapshots and the
/// time series parse. (Temporaries `.NAME.PID.tmp` of a killed write are not final names.)
fn assert_no_damaged_file(run: &Path, when: &str) {
    for p in files(run) {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.ends_with(".tmp") {
            continue;
        }
        let sidecar = PathBuf::from(format!("{}.crc32", p.display()));
        if name.starts_with("ckpt_") && name.ends_with(".h5") && sidecar.exists() {
            verify(&p).unwrap_or_else(|e| panic!("{when}: damaged checkpoint: {e}"));
        } else if name.starts_with("snap_") {
            read_snapshot(&p).unwrap_or_else(|e| panic!("{when}: damaged snapshot: {e}"));
        } else if name == "timeseries.csv" {
            TimeSeries::read(&p).unwrap_or_else(|e| panic!("{when}: damaged time series: {e}"));
        }
    }
}

fn newest_checkpoint(run: &Path) -> PathBuf {
    let mut v: Vec<PathBuf> = files(&run.join("checkpoints"))
        .into_iter()
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            n.starts_with("ckpt_") && n.ends_with(".h5")
        })
        .collect();
    v.sort();
    v.pop().expect("a checkpoint")
}

/// A mean-field run that takes some 1600 steps at 8^3, checkpointing on a wall clock of 20 ms
/// (so progress survives kills) and every 10 time units.
const MEANFIELD: &str = "grid = 8\nmode_max = 2\namplitude = 0.01\ndiffusion = 0.01\nt_end = 80\n\
diagnostic_interval = 0.5\nsnapshot_interval = 20\ncheckpoint_interval = 10\n\
checkpoint_wall_seconds = 0.02\n";

#[test]
fn killed_twenty_times_and_resumed_gives_the_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("mf.toml"), MEANFIELD).unwrap();
    let out = motile(&["meanfield", "run", "mf.toml", "--out", "reference"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut kills = 0;
    let mut finished = false;
    for attempt in 0..200 {
        // A kill before the run wrote its config (on a loaded machine, process start and the
        // closure tables can take longer than the shortest wait) leaves no run to resume:
        // start it again.
        let args: Vec<&str> = if attempt == 0 || !d.join("killed/config.toml").exists() {
            vec!["meanfield", "run", "mf.toml", "--out", "killed"]
        } else {
            vec!["resume", "killed"]
        };
        let mut child = Command::new(BIN)
            .args(&args)
            .current_dir(d)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        if kills < 20 {
            std::thread::sleep(Duration::from_millis(rng.random_range(60..400)));
            child.kill().unwrap(); // SIGKILL
            let status = child.wait().unwrap();
            if status.success() {
                finished = true;
                break;
            }
            kills += 1;
            if d.join("killed").exists() {
                assert_no_damaged_file(&d.join("killed"), &format!("after kill {kills}"));
            }
        } else {
            let out = child.wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            finished = true;
            break;
        }
    }
    assert!(finished, "the run never finished");
    assert!(
        kills >= 20,
        "only {kills} kills before the run finished: make it longer"
    );
    let (a, b) = (
        newest_checkpoint(&d.join("reference")),
        newest_checkpoint(&d.join("killed")),
    );
    assert_eq!(
        a.file_name(),
        b.file_name(),
        "final checkpoints at different steps"
    );
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
        "final state after {kills} kills differs from the uninterrupted run"
    );
    assert_eq!(
        std::fs::read_to_string(d.join("reference/timeseries.csv")).unwrap(),
        std::fs::read_to_string(d.join("killed/timeseries.csv")).unwrap(),
        "time series after {kills} kills differs from the uninterrupted run"
    );
}

#[test]
fn sigterm_checkpoints_and_resume_continues_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = MEANFIELD.replace("t_end = 80", "t_end = 20").replace(
        "checkpoint_wall_seconds = 0.02",
        "checkpoint_wall_seconds = 1000",
    );
    std::fs::write(d.join("mf.toml"), cfg).unwrap();
    assert!(
        motile(&["meanfield", "run", "mf.toml", "--out", "reference"], d)
            .status
            .success()
    );
    let child = Command::new(BIN)
        .args(["meanfield", "run", "mf.toml", "--out", "stopped"])
        .current_dir(d)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let sent = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "{err}");
    assert!(
        err.contains("stopped by signal 15") && err.contains("motile resume"),
        "{err}"
    );
    let resumed = motile(&["resume", "stopped"], d);
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    let (a, b) = (
        newest_checkpoint(&d.join("reference")),
        newest_checkpoint(&d.join("stopped")),
    );
    assert_eq!(a.file_name(), b.file_name());
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
}

#[test]
fn a_truncated_or_bit_flipped_checkpoint_is_skipped_for_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = MEANFIELD
        .replace("t_end = 80", "t_end = 6")
        .replace("checkpoint_interval = 10", "checkpoint_interval = 2")
        .replace(
            "checkpoint_wall_seconds = 0.02",
            "checkpoint_wall_seconds = 1000",
        );
    std::fs::write(d.join("mf.toml"), cfg).unwrap();
    assert!(
        motile(&["meanfield", "run", "mf.toml", "--out", "reference"], d)
            .status
            .success()
    );
    let reference = std::fs::read(newest_checkpoint(&d.join("reference"))).unwrap();
    for damage in ["truncate", "flip"] {
        let run = format!("run_{damage}");
        assert!(
            motile(&["meanfield", "run", "mf.toml", "--out", &run], d)
                .status
                .success()
        );
        // Checkpoints at t = 2, 4 and 6 are kept; damage the newest two.
        let ckpts: Vec<PathBuf> = files(&d.join(&run).join("checkpoints"))
            .into_iter()
            .filter(|p| p.extension().is_some_and(|e| e == "h5"))
            .collect();
        assert_eq!(ckpts.len(), 3, "{ckpts:?}");
        for p in &ckpts[1..] {
            let mut bytes = std::fs::read(p).unwrap();
            if damage == "truncate" {
                bytes.truncate(bytes.len() / 2);
            } else {
                let i = bytes.len() - 100;
                bytes[i] ^= 0x10;
            }
            std::fs::write(p, bytes).unwrap();
        }
        let out = motile(&["resume", &run], d);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        let expected = if damage == "truncate" {
            "truncated"
        } else {
            "checksum mismatch"
        };
        assert_eq!(
            err.matches(expected).count(),
            2,
            "two warnings naming the damage expected: {err}"
        );
        let log = std::fs::read_to_string(d.join(&run).join("run.log")).unwrap();
        assert!(
            log.contains("resuming from") && log.contains("ckpt_"),
            "{log}"
        );
        assert!(
            std::fs::read(newest_checkpoint(&d.join(&run))).unwrap() == reference,
            "{damage}: the run resumed from the oldest checkpoint does not end where the reference does"
        );
    }
}

#[test]
fn forced_divergence_ends_with_the_structured_error_and_a_usable_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Particle model: a dense suspension whose contact solver may take one iteration (the
    // step's projection removes the overlaps the largest dt leaves).
    std::fs::write(
        d.join("p.toml"),
        "box_length = 6\nvolume_fraction = 5\ndt = 0.05\nt_end = 2\ndiagnostic_interval = 0.05\n[contact]\nmargin = 0.2\nmax_iterations = 1\n",
    )
    .unwrap();
    // Mean-field model: a step of 0.5 (dt_max = 1, CFL 2) at D = 0 with a strong perturbation
    // (with the default realizability_limit the run stops a little earlier, on realizability).
    std::fs::write(
        d.join("mf.toml"),
        "grid = 16\namplitude = 0.3\nt_end = 100\ndt_max = 1.0\ncfl = 2.0\nmax_step_ratio = 2.4\ndiffusion = 0\nrealizability_limit = -1000\n",
    )
    .unwrap();
    for (model, file, what) in [
        (
            "particle",
            "p.toml",
            "contact solver (BBPGD, then APGD where it stalls) did not converge",
        ),
        (
            "meanfield",
            "mf.toml",
            "Stokes fixed point did not converge",
        ),
    ] {
        let out = motile(&[model, "run", file, "--out", model], d);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!out.status.success(), "{model}: the run should have failed");
        assert!(
            err.contains(what)
                && err.contains("step")
                && err.contains("t = ")
                && err.contains("last_good.h5")
                && err.contains("motile resume"),
            "{model}: {err}"
        );
        let saved = d.join(model).join("checkpoints/last_good.h5");
        verify(&saved).unwrap();
        // Usable: resume starts from it and meets the same failure at the same step.
        let again = motile(&["resume", model], d);
        let err2 = String::from_utf8_lossy(&again.stderr).into_owned();
        assert!(!again.status.success());
        let first_step = err
            .split("step ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .to_string();
        let second_step = err2
            .split("step ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .to_string();
        assert_eq!(
            first_step, second_step,
            "{model}: resumed run failed elsewhere: {err2}"
        );
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("mf.toml"),
        "grid = 16\nmode_max = 4\namplitude = 0.05\nt_end = 2\n",
    )
    .unwrap();
    std::fs::write(
        d.join("p.toml"),
        "box_length = 6\nvolume_fraction = 5\nt_end = 0.1\nsnapshot_interval = 0.1\ncheckpoint_interval = 0.1\n",
    )
    .unwrap();
    for (model, file) in [("meanfield", "mf.toml"), ("particle", "p.toml")] {
        let mut finals = Vec::new();
        for threads in ["1", "2"] {
            let run = format!("{model}_{threads}");
            let out = motile(
                &["--threads", threads, model, "run", file, "--out", &run],
                d,
            );
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            finals.push((
                std::fs::read(newest_checkpoint(&d.join(&run))).unwrap(),
                files(&d.join(&run).join("snapshots"))
                    .iter()
                    .map(|p| std::fs::read(p).unwrap())
                    .collect::<Vec<_>>(),
            ));
        }
        assert!(
            finals[0].0 == finals[1].0,
            "{model}: final checkpoints differ between 1 and 2 threads"
        );
        assert!(
            finals[0].1 == finals[1].1,
            "{model}: snapshots differ between 1 and 2 threads"
        );
    }
}

/// A comparison that fails half-way (here: one of the runs has a damaged snapshot, found only
/// when its snapshots are analysed, after the velocity norms are read) writes nothing under the
/// final names, and leaves no staging folder behind; the same comparison of intact runs writes
/// its files.
#[test]
fn a_failed_comparison_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("mf.toml");
    std::fs::write(
        &cfg,
        "grid = 12\nt_end = 1.0\ndt_max = 0.1\ndiagnostic_interval = 0.25\nsnapshot_interval = 0.5\n",
    )
    .unwrap();
    let o = motile(&["meanfield", "run", "mf.toml", "--out", "mf"], dir.path());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let good = motile(&["compare", "mf", "--out", "good"], dir.path());
    assert!(
        good.status.success() && dir.path().join("good/velocity_norm.csv").exists(),
        "{}",
        String::from_utf8_lossy(&good.stderr)
    );
    let snap = dir.path().join("mf/snapshots/snap_000001.h5");
    let bytes = std::fs::read(&snap).unwrap();
    std::fs::write(&snap, &bytes[..bytes.len() / 2]).unwrap();
    let bad = motile(&["compare", "mf", "--out", "bad"], dir.path());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("file truncated or not a motile snapshot"),
        "{err}"
    );
    assert!(
        !dir.path().join("bad").exists(),
        "compare left {:?}",
        files(&dir.path().join("bad"))
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty(), "staging folder left: {leftovers:?}");
}
