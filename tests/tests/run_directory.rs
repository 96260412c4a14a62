//! Run directories: a particle run and a mean-field state are written, read back bit for bit,
//! analysed, and opened by h5py (files written by h5py are read by motile too). The analysis
//! of a mean-field plane wave gives the exact norm `A / sqrt(2)`.

use motile_experiments::campaign::demo::{DemoConfig, write_demo_run};
use motile_experiments::io::rundir::{RunDir, TimeSeries};
use motile_experiments::io::snapshot::{FieldSnapshot, Snapshot, read_snapshot};
use motile_experiments::report::analyze::{AnalyzeOptions, analyze, analyze_run};
use motile_tests::{h5py_available, run_python};
use std::f64::consts::PI;

#[test]
fn particle_run_round_trips_and_is_analysed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let cfg = DemoConfig {
        box_length: 8.0,
        snapshots: 3,
        ..Default::default()
    };
    let run = write_demo_run(&out, &cfg).unwrap();
    let header = RunDir::open(&out).unwrap().header().unwrap();
    assert_eq!(header.model, "particle");
    assert_eq!(header.seed, cfg.seed);
    assert_eq!(header.version, env!("CARGO_PKG_VERSION"));
    let snaps = run.snapshots().unwrap();
    assert_eq!(snaps.len(), 3);
    // Rewrite and reread: identical.
    let p = run.snapshot_path(1);
    let again = read_snapshot(&p).unwrap();
    assert_eq!(again, snaps[1]);
    let report = analyze_run(&out, &AnalyzeOptions::default()).unwrap();
    for f in [
        "timeseries.csv",
        "correlations.csv",
        "analysis.h5",
        "correlations.png",
        "correlations.svg",
        "config.toml",
    ] {
        assert!(
            out.join("analysis").join(f).is_file(),
            "analysis/{f} missing"
        );
    }
    let ts = TimeSeries::read(&out.join("analysis/timeseries.csv")).unwrap();
    assert_eq!(ts, report.timeseries);
    // Free swimmers at U = 1: MSD = t^2 exactly (up to round-off of unwrapping).
    let t = ts.column("t [1/beta]").unwrap();
    let msd = ts.column("msd [l^2]").unwrap();
    for (t, m) in t.iter().zip(&msd) {
        assert!(
            (m - t * t).abs() <= 1e-12 * (1.0 + t * t),
            "MSD {m} at t = {t}, expected {}",
            t * t
        );
    }
    if !h5py_available() {
        eprintln!("SKIPPED h5py checks: python3 with h5py and numpy not found (CI installs them)");
        return;
    }
    let script = r#"
import sys, h5py, numpy as np
snap, ana = sys.argv[1], sys.argv[2]
with h5py.File(snap, "r") as f:
    assert f.attrs["kind"] == "particle", f.attrs["kind"]
    x, p, im = f["positions"][...], f["orientations"][...], f["image_counts"][...]
    assert x.shape == p.shape == im.shape and x.shape[1] == 3, (x.shape, p.shape, im.shape)
    assert im.dtype == np.int64, im.dtype
    assert np.allclose(np.linalg.norm(p, axis=1), 1.0)
    assert f["force_points"].shape == f["point_forces"].shape
    print("rods", x.shape[0], "time", float(f.attrs["time"]))
    for i in (0, 7, x.shape[0] - 1):
        print("row", i, [repr(float(v)) for v in x[i]])
with h5py.File(ana, "r") as f:
    c = f["corr_c"][...]
    assert c.shape == (f["time"].shape[0], f["r_c"].shape[0]), c.shape
    assert np.allclose(c.mean(axis=0), f["corr_mean_c"][...])
    print("analysis ok")
"#;
    let text = run_python(
        script,
        &[
            p.to_str().unwrap(),
            out.join("analysis/analysis.h5").to_str().unwrap(),
        ],
    );
    let Snapshot::Particle(s) = &snaps[1] else {
        panic!("particle snapshot expected")
    };
    assert!(
        text.contains(&format!("rods {}", s.positions.len())),
        "h5py output: {text}"
    );
    for i in [0, 7, s.positions.len() - 1] {
        let row = format!(
            "row {i} ['{:?}', '{:?}', '{:?}']",
            s.positions[i][0], s.positions[i][1], s.positions[i][2]
        );
        assert!(
            text.contains(&row),
            "h5py sees different positions: expected {row}, got\n{text}"
        );
    }
    assert!(text.contains("analysis ok"), "{text}");
}

fn plane_wave(n: usize, amp: f64) -> FieldSnapshot {
    let mut q: [Vec<f64>; 6] = Default::default();
    let mut u: [Vec<f64>; 3] = Default::default();
    for i in 0..n * n * n {
        let x = [i % n, (i / n) % n, i / (n * n)].map(|j| j as f64 / n as f64);
        let wave = (2.0 * PI * 2.0 * x[1]).sin();
        for (c, v) in [1.0 / 3.0, 0.01 * wave, 0.0, 1.0 / 3.0, 0.0, 1.0 / 3.0]
            .iter()
            .enumerate()
        {
            q[c].push(*v);
        }
        u[0].push(amp * wave);
        u[1].push(0.0);
        u[2].push(0.0);
    }
    FieldSnapshot {
        time: 1.5,
        step: 7,
        box_length: 1.0,
        grid: n,
        q,
        u,
    }
}

#[test]
fn field_snapshot_round_trips_and_plane_wave_norm_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let run = RunDir::create(
        &dir.path().join("mf"),
        "meanfield",
        0,
        &DemoConfig::default(),
    )
    .unwrap();
    let snap = plane_wave(16, 0.3);
    snap.write(&run.snapshot_path(0)).unwrap();
    let back = read_snapshot(&run.snapshot_path(0)).unwrap();
    assert_eq!(back, Snapshot::Field(snap.clone()));
    let report = analyze(&[back], &AnalyzeOptions::default()).unwrap();
    let u = report.timeseries.column("u_l2 [L |sigma_a|/mu]").unwrap()[0];
    assert!(
        (u - 0.3 / 2f64.sqrt()).abs() < 1e-12,
        "||u|| = {u}, exact {}",
        0.3 / 2f64.sqrt()
    );
    // Q deviation: only the xy components, amplitude 0.01, counted twice: ||Q'|| = 0.01.
    let qn = report.timeseries.column("Q_l2 [1]").unwrap()[0];
    assert!((qn - 0.01).abs() < 1e-12, "||Q'|| = {qn}, exact 0.01");
    // A uniform trace has no concentration fluctuation.
    assert!(report.timeseries.column("c_l2 [1]").unwrap()[0] < 1e-14);
    if !h5py_available() {
        eprintln!("SKIPPED h5py checks: python3 with h5py and numpy not found (CI installs them)");
        return;
    }
    // h5py reads motile's layout [component, z, y, x] ...
    let script = r#"
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r") as f:
    q, u = f["Q"][...], f["u"][...]
    assert q.shape == (6, 16, 16, 16) and u.shape == (3, 16, 16, 16), (q.shape, u.shape)
    y = np.arange(16) / 16
    assert np.allclose(u[0, 3, :, 5], 0.3 * np.sin(4 * np.pi * y))
# ... and motile reads a file h5py wrote.
with h5py.File(sys.argv[2], "w") as f:
    f.attrs["kind"] = "meanfield"; f.attrs["time"] = 2.0; f.attrs["step"] = 3
    f.attrs["box_length"] = 1.0; f.attrs["grid"] = 4
    q = np.zeros((6, 4, 4, 4)); q[0] = q[3] = q[5] = 1 / 3
    f["Q"] = q
    f["u"] = np.arange(3 * 64, dtype=np.float64).reshape(3, 4, 4, 4)
print("ok")
"#;
    let theirs = dir.path().join("mf/snapshots/snap_000001.h5");
    run_python(
        script,
        &[
            run.snapshot_path(0).to_str().unwrap(),
            theirs.to_str().unwrap(),
        ],
    );
    let Snapshot::Field(f) = read_snapshot(&theirs).unwrap() else {
        panic!("field snapshot expected")
    };
    assert_eq!(f.grid, 4);
    assert_eq!(f.time, 2.0);
    assert_eq!(
        f.u[1][5],
        64.0 + 5.0,
        "layout [component, z, y, x] flattened x fastest"
    );
}

#[test]
fn bad_files_are_named_in_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.h5");
    std::fs::write(&p, b"not hdf5").unwrap();
    let e = read_snapshot(&p).unwrap_err().to_string();
    assert!(e.contains("bad.h5"), "{e}");
    let e = RunDir::open(dir.path()).unwrap_err().to_string();
    assert!(e.contains("no config.toml"), "{e}");
    let e = analyze(&[], &AnalyzeOptions::default()).unwrap_err();
    assert_eq!(e, "the run has no snapshots");
    let bad = AnalyzeOptions {
        tolerance: 1.0,
        ..Default::default()
    };
    assert!(
        bad.validate()
            .unwrap_err()
            .contains("tolerance = 1e0 is outside the allowed range")
    );
}

#[test]
fn analysis_is_bit_identical_for_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = DemoConfig {
        box_length: 10.0,
        snapshots: 2,
        ..Default::default()
    };
    let run = write_demo_run(&dir.path().join("run"), &cfg).unwrap();
    let snaps = run.snapshots().unwrap();
    let report = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| analyze(&snaps, &AnalyzeOptions::default()).unwrap())
    };
    let (a, b) = (report(1), report(2));
    assert_eq!(
        a.timeseries, b.timeseries,
        "time series differ between 1 and 2 threads"
    );
    assert_eq!(
        a.mean, b.mean,
        "time-averaged correlations differ between 1 and 2 threads"
    );
}
