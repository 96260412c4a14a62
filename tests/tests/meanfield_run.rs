//! `motile meanfield run` end to end on a small grid: a plane-wave start grows at the linear
//! rate, the flow norm respects `||u||_2 <= sqrt(1/(24 pi^2))`, snapshots are analysed by
//! `motile analyze`, the closure-table cache round-trips, and bad configs name the field.

use motile_experiments::report::analyze::{AnalyzeOptions, analyze_run};
use motile_experiments::run::meanfield::{MeanFieldRunConfig, parse_config, run_meanfield};
use std::f64::consts::PI;
use std::path::Path;

#[test]
fn plane_wave_run_grows_at_the_linear_rate_and_is_analysed() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = MeanFieldRunConfig {
        grid: 8,
        initial: "plane_wave".into(),
        amplitude: 1e-6,
        t_end: 4.0,
        dt_max: 0.02,
        diagnostic_interval: 0.5,
        snapshot_interval: 2.0,
        ..Default::default()
    };
    let out = dir.path().join("mf");
    let s = run_meanfield(&cfg, &out, false).unwrap();
    let t = s.timeseries.column("t [mu/|sigma_a|]").unwrap();
    let u = s.timeseries.column("u_l2 [L |sigma_a|/mu]").unwrap();
    let (i1, i2) = (2, t.len() - 1);
    let rate = (u[i2] / u[i1]).ln() / (t[i2] - t[i1]);
    let exact = 0.2 / (1.0 + cfg.zeta / 15.0) - cfg.diffusion * 4.0 * PI * PI;
    assert!(
        (rate - exact).abs() < 0.01 * exact,
        "||u|| grows at {rate}, linear theory {exact}"
    );
    let bound = (1.0 / (24.0 * PI * PI)).sqrt();
    assert!(
        u.iter().all(|&v| v <= bound),
        "||u||_2 exceeded sqrt(1/(24 pi^2))"
    );
    let report = analyze_run(&out, &AnalyzeOptions::default()).unwrap();
    assert_eq!(report.kind, "meanfield");
    assert_eq!(
        report.snapshots.len(),
        3,
        "snapshots at t = 0, 2 and 4 (t_end)"
    );
    // The analysed velocity norm of a snapshot equals the run's own diagnostic at that time.
    let ua = report.timeseries.column("u_l2 [L |sigma_a|/mu]").unwrap();
    let idx = t.iter().position(|&x| (x - 2.0).abs() < 1e-9).unwrap();
    assert!(
        (ua[1] - u[idx]).abs() < 1e-9 * u[idx],
        "analysed ||u|| {} vs run diagnostic {}",
        ua[1],
        u[idx]
    );
}

/// The outputs due at t_end are written: the last diagnostic row and the last snapshot are at
/// t_end (not one interval early, which would leave a short run's "second half" one
/// snapshot), and the final checkpoint too.
#[test]
fn a_short_run_writes_its_final_state() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = MeanFieldRunConfig {
        grid: 12,
        t_end: 1.0,
        dt_max: 0.1,
        diagnostic_interval: 0.25,
        snapshot_interval: 0.5,
        checkpoint_interval: 0.5,
        ..Default::default()
    };
    let out = dir.path().join("mf");
    let s = run_meanfield(&cfg, &out, false).unwrap();
    let t = s.timeseries.column("t [mu/|sigma_a|]").unwrap();
    assert_eq!(t, vec![0.0, 0.25, 0.5, 0.75, 1.0], "diagnostic times");
    let snaps = motile_experiments::io::rundir::RunDir::open(&out)
        .unwrap()
        .snapshots()
        .unwrap();
    let times: Vec<f64> = snaps.iter().map(|s| s.time()).collect();
    assert_eq!(times, vec![0.0, 0.5, 1.0], "snapshot times");
    let ckpts = motile_experiments::io::rundir::checkpoint_paths(&out.join("checkpoints"));
    let last = ckpts.last().expect("a checkpoint");
    let t_ckpt = motile_experiments::io::checkpoint::H5Reader::open(last)
        .unwrap()
        .attr_f64("time")
        .unwrap();
    assert!(
        (t_ckpt - 1.0).abs() < 1e-12,
        "final checkpoint at t = {t_ckpt}"
    );
    // A t_end that is no multiple of the output intervals ends with its final state too.
    let cfg = MeanFieldRunConfig { t_end: 0.9, ..cfg };
    let out = dir.path().join("mf_unaligned");
    let s = run_meanfield(&cfg, &out, false).unwrap();
    let t = s.timeseries.column("t [mu/|sigma_a|]").unwrap();
    let close = |a: &[f64], b: &[f64]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    };
    assert!(
        close(&t, &[0.0, 0.25, 0.5, 0.75, 0.9]),
        "diagnostic times {t:?}"
    );
    let snaps = motile_experiments::io::rundir::RunDir::open(&out)
        .unwrap()
        .snapshots()
        .unwrap();
    let times: Vec<f64> = snaps.iter().map(|s| s.time()).collect();
    assert!(close(&times, &[0.0, 0.5, 0.9]), "snapshot times {times:?}");
    // Resuming the finished run writes nothing again.
    motile_experiments::run::meanfield::resume_meanfield(&out, false).unwrap();
    let again =
        motile_experiments::io::rundir::TimeSeries::read(&out.join("timeseries.csv")).unwrap();
    assert_eq!(again.column("t [mu/|sigma_a|]").unwrap(), t);
    assert_eq!(
        motile_experiments::io::rundir::RunDir::open(&out)
            .unwrap()
            .snapshots()
            .unwrap()
            .len(),
        3
    );
}

#[test]
fn bad_meanfield_configs_name_the_field() {
    let p = Path::new("mf.toml");
    for (text, expected) in [
        ("grid = 7", "grid = 7 must be even and in [8, 256]"),
        (
            "max_step_ratio = 3.0",
            "max_step_ratio = 3 is outside the allowed range (1, 2.4]",
        ),
        (
            "mode_max = 20",
            "mode_max = 20: need 1 <= mode_min <= mode_max <= grid/3",
        ),
        (
            "initial = \"noise\"",
            "initial = \"noise\": allowed \"random\", \"plane_wave\" or \"snapshot\"",
        ),
        ("zetta = 1", "unknown key `zetta`; did you mean `zeta`?"),
    ] {
        let e = parse_config(text, p).unwrap_err().to_string();
        assert!(e.contains(expected), "`{text}`: got `{e}`");
    }
}

#[test]
fn closure_tables_round_trip_through_bytes() {
    let c = motile_meanfield::closure::BinghamClosure::new(12).unwrap();
    let back = motile_meanfield::closure::BinghamClosure::from_bytes(&c.to_bytes(), 12).unwrap();
    assert_eq!(back.fourth([0.5, 0.3, 0.2]), c.fourth([0.5, 0.3, 0.2]));
    assert!(
        motile_meanfield::closure::BinghamClosure::from_bytes(&c.to_bytes()[..100], 12).is_none()
    );
    assert!(motile_meanfield::closure::BinghamClosure::from_bytes(&c.to_bytes(), 13).is_none());
}

#[test]
fn resume_from_a_checkpoint_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = MeanFieldRunConfig {
        grid: 8,
        mode_max: 2,
        amplitude: 0.05,
        t_end: 3.0,
        dt_max: 0.05,
        diagnostic_interval: 0.25,
        snapshot_interval: 1.5,
        checkpoint_interval: 1.0,
        checkpoints_kept: 2,
        ..Default::default()
    };
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let full = run_meanfield(&cfg, &a, false).unwrap();
    run_meanfield(&cfg, &b, false).unwrap();
    // Checkpoints at t = 0, 1, 2 and the end; the last two are kept. Drop the final one, as if
    // the run had been killed after t = 2, and resume.
    let mut ckpts: Vec<_> = std::fs::read_dir(b.join("checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "h5"))
        .collect();
    ckpts.sort();
    assert_eq!(ckpts.len(), 2, "{ckpts:?}");
    std::fs::remove_file(ckpts.last().unwrap()).unwrap();
    let resumed = motile_experiments::run::meanfield::resume_meanfield(&b, false).unwrap();
    assert!(resumed.steps > 0);
    assert!(
        resumed.q_hat == full.q_hat,
        "resumed state differs from the uninterrupted run"
    );
    assert_eq!(resumed.timeseries.rows.len(), full.timeseries.rows.len());
    for (x, y) in resumed.timeseries.rows.iter().zip(&full.timeseries.rows) {
        assert_eq!(x, y, "time series rows differ after resume");
    }
}

#[test]
fn a_failed_step_saves_the_state_before_it_and_resume_continues_from_there() {
    let dir = tempfile::tempdir().unwrap();
    // An under-resolved run (8^3): Q loses realizability from t ~ 17 and the Stokes fixed
    // point needs more iterations as it does (from its warm start: 5 from t ~ 28.2, 6 from
    // t ~ 28.7, 7 at t = 29; it breaks down at t ~ 29.6).
    let good = MeanFieldRunConfig {
        grid: 8,
        mode_max: 2,
        amplitude: 0.05,
        t_end: 29.0,
        checkpoint_interval: 10.0,
        // Let the unrealizable run go on to the fixed point's breakdown.
        realizability_limit: -1000.0,
        ..Default::default()
    };
    // The same run with an iteration cap that a step near t = 28.7 exceeds.
    let capped = MeanFieldRunConfig {
        fixed_point_max_iterations: 5,
        ..good.clone()
    };
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let full = run_meanfield(&good, &a, false).unwrap();
    let err = format!("{:#}", run_meanfield(&capped, &b, false).unwrap_err());
    assert!(
        err.contains("Stokes fixed point did not converge")
            && err.contains("last_good.h5")
            && err.contains("motile resume"),
        "unexpected message: {err}"
    );
    let saved = b.join("checkpoints").join("last_good.h5");
    assert!(saved.is_file(), "{} missing", saved.display());
    let failed_at: f64 = err
        .split(" at t = ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap();
    assert!(
        failed_at > 20.0,
        "the capped run should fail late (after the checkpoint at t = 20), failed at t = {failed_at}: {err}"
    );
    // Raise the cap in the run's config and resume: the trajectory is the uninterrupted one.
    let cfg_path = b.join("config.toml");
    let text = std::fs::read_to_string(&cfg_path).unwrap();
    assert!(text.contains("fixed_point_max_iterations = 5"), "{text}");
    std::fs::write(
        &cfg_path,
        text.replace(
            "fixed_point_max_iterations = 5",
            "fixed_point_max_iterations = 50",
        ),
    )
    .unwrap();
    let resumed = motile_experiments::run::meanfield::resume_meanfield(&b, false).unwrap();
    assert!(
        resumed.q_hat == full.q_hat,
        "resumed state differs from the uninterrupted run"
    );
    assert!(
        !saved.exists(),
        "last_good.h5 should be superseded by newer checkpoints"
    );
}

#[test]
fn a_run_starts_from_a_snapshot_on_the_same_or_another_grid() {
    let dir = tempfile::tempdir().unwrap();
    let first = MeanFieldRunConfig {
        grid: 8,
        mode_max: 2,
        amplitude: 0.05,
        t_end: 1.5,
        snapshot_interval: 1.0,
        ..Default::default()
    };
    let a = dir.path().join("a");
    run_meanfield(&first, &a, false).unwrap();
    let snap_path = a.join("snapshots").join("snap_000001.h5");
    let snap = match motile_experiments::io::snapshot::read_snapshot(&snap_path).unwrap() {
        motile_experiments::io::snapshot::Snapshot::Field(s) => s,
        _ => panic!("expected a field snapshot"),
    };
    assert!((snap.time - 1.0).abs() < 1e-12);
    for grid in [8, 12] {
        let cfg = MeanFieldRunConfig {
            grid,
            initial: "snapshot".into(),
            snapshot: snap_path.display().to_string(),
            t_end: 0.5,
            snapshot_interval: 0.5,
            ..Default::default()
        };
        let out = dir.path().join(format!("from_snapshot_{grid}"));
        run_meanfield(&cfg, &out, false).unwrap();
        // Its first snapshot (t = 0) holds the loaded Q: equal on the same grid, and on the
        // finer grid equal at the points the two grids share (every third point of 12 is every
        // second of 8), since the state is band-limited below both Nyquist modes (2/3 rule).
        let s0 = match motile_experiments::io::snapshot::read_snapshot(
            &out.join("snapshots").join("snap_000000.h5"),
        )
        .unwrap()
        {
            motile_experiments::io::snapshot::Snapshot::Field(s) => s,
            _ => panic!("expected a field snapshot"),
        };
        let mut err: f64 = 0.0;
        for i2 in (0..8).step_by(2) {
            for i1 in (0..8).step_by(2) {
                for i0 in (0..8).step_by(2) {
                    let p8 = (i2 * 8 + i1) * 8 + i0;
                    let [j0, j1, j2] = [i0, i1, i2].map(|i| i * grid / 8);
                    let pg = (j2 * grid + j1) * grid + j0;
                    for c in 0..6 {
                        err = err.max((s0.q[c][pg] - snap.q[c][p8]).abs());
                    }
                }
            }
        }
        // The snapshot's Q went through a dealiased step: its modes reach |m| = 8/3, below
        // the Nyquist mode 4 of the coarser grid, so resampling is exact to round-off.
        assert!(err < 1e-12, "grid {grid}: loaded Q differs by {err:.2e}");
    }
    // A particle snapshot or a missing file is refused with a message naming it.
    let cfg = MeanFieldRunConfig {
        initial: "snapshot".into(),
        snapshot: dir.path().join("missing.h5").display().to_string(),
        ..Default::default()
    };
    let e = format!(
        "{:#}",
        run_meanfield(&cfg, &dir.path().join("c"), false).unwrap_err()
    );
    assert!(e.contains("missing.h5"), "{e}");
}

/// The flow bound `||u||_2 <= sqrt(1/(24 pi^2))` (docs/MODEL.md §4) over a long nonlinear run at
/// 32^3 through the instability into the saturated state. D = 1e-3: with the paper's
/// D = 1e-4, 32^3 under-resolves the flow (Q loses realizability from t ~ 34 and the Stokes fixed
/// point breaks down at t ~ 62, as the source paper's code does near t = 81; BENCHMARKS.md).
#[test]
fn velocity_norm_stays_below_the_bound_in_a_long_run_at_32_cubed() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = MeanFieldRunConfig {
        grid: 32,
        diffusion: 1e-3,
        t_end: 100.0,
        diagnostic_interval: 1.0,
        snapshot_interval: 1e3,
        checkpoint_interval: 1e3,
        ..Default::default()
    };
    let s = run_meanfield(&cfg, &dir.path().join("long"), false).unwrap();
    let ts = &s.timeseries;
    let u = ts.column("u_l2 [L |sigma_a|/mu]").unwrap();
    let energy = ts.column("energy_identity_residual [1]").unwrap();
    let bound = (1.0 / (24.0 * PI * PI)).sqrt();
    let (imax, umax) = u
        .iter()
        .copied()
        .enumerate()
        .fold((0, 0.0), |a, (i, v)| if v > a.1 { (i, v) } else { a });
    eprintln!(
        "32^3, t = 0..{}: max ||u||_2 = {umax:.4} at t = {} (bound {bound:.4}); {} steps",
        cfg.t_end, ts.rows[imax][0], s.steps
    );
    // The run must have left the linear regime (||u|| starts at ~2e-4).
    assert!(
        umax > 0.02,
        "the run never became nonlinear: max ||u|| {umax:.3e}"
    );
    assert!(
        u.iter().all(|&v| v <= bound),
        "||u||_2 = {umax} exceeds sqrt(1/(24 pi^2)) = {bound}"
    );
    let worst = energy.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        worst < 1e-6,
        "energy identity residual {worst:.2e} at some diagnostic (fixed-point tolerance 1e-8)"
    );
}

#[test]
fn a_plane_wave_that_drives_no_flow_does_not_stall_the_fixed_point() {
    // Regression: Q_xy = A cos(2 pi (x + y)) has an active-stress divergence along k, balanced
    // by pressure, so u is round-off (1e-23); the fixed point's relative criterion had no digits
    // to converge on and the run stopped at t = 11.4. Now the change is measured absolutely
    // below a flow floor and the run reaches its end with the flow still at round-off.
    let dir = tempfile::tempdir().unwrap();
    let cfg = MeanFieldRunConfig {
        grid: 8,
        initial: "plane_wave".into(),
        wavevector: [1, 1, 0],
        amplitude: 1e-6,
        diffusion: 2e-3,
        t_end: 20.0,
        dt_max: 0.02,
        diagnostic_interval: 1.0,
        snapshot_interval: 10.0,
        ..Default::default()
    };
    let out = dir.path().join("mf");
    let run = run_meanfield(&cfg, &out, false).unwrap();
    let u = run.timeseries.column("u_l2 [L |sigma_a|/mu]").unwrap();
    assert!(
        u.iter().all(|v| *v < 1e-18),
        "flow should stay at round-off: {u:?}"
    );
}

#[test]
fn the_random_initial_condition_is_the_same_function_on_every_grid() {
    // A resolution study must start every grid from the same Q: the grid-16 points are the
    // even points of the grid-32 one, and the values there must agree to round-off.
    use motile_experiments::run::meanfield::{MeanFieldRunConfig, initial_state};
    let cfg = |grid| MeanFieldRunConfig {
        grid,
        mode_max: 2,
        amplitude: 0.05,
        ..Default::default()
    };
    let (a, b) = (
        initial_state(&cfg(16)).unwrap(),
        initial_state(&cfg(32)).unwrap(),
    );
    let mut worst = 0.0f64;
    for c in 0..6 {
        for k in 0..16 * 16 * 16 {
            let (i, j, l) = (k % 16, (k / 16) % 16, k / 256);
            let kk = 2 * i + 32 * (2 * j) + 32 * 32 * (2 * l);
            worst = worst.max((a[c][k] - b[c][kk]).abs());
        }
    }
    assert!(
        worst < 1e-14,
        "grids 16 and 32 differ by {worst:e} at common points"
    );
    // Components [xx, xy, xz, yy, yz, zz]: the off-diagonal ones are pure perturbation.
    let peak = [1, 2, 4]
        .iter()
        .fold(0.0f64, |m, &c| b[c].iter().fold(m, |m, v| m.max(v.abs())));
    assert!(
        peak <= 0.05 + 1e-15,
        "off-diagonal peak {peak} above the amplitude"
    );
}
