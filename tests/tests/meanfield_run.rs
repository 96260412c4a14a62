//! `motile meanfield run` end to end on a small grid: a plane-wave start grows at the linear
//! rate, the flow norm respects `||u||_2 <= sqrt(1/(24 pi^2))`, snapshots are analysed by
//! `motile analyze`, the closure-table cache round-trips, and bad configs name the field.

use motile_experiments::analyze::{AnalyzeOptions, analyze_run};
use motile_experiments::meanfield_run::{MeanFieldRunConfig, parse_config, run_meanfield};
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
    assert_eq!(report.snapshots.len(), 2);
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
            "initial = \"noise\": allowed \"random\" or \"plane_wave\"",
        ),
        ("zetta = 1", "unknown field `zetta`"),
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
        .collect();
    ckpts.sort();
    assert_eq!(ckpts.len(), 2, "{ckpts:?}");
    std::fs::remove_file(ckpts.last().unwrap()).unwrap();
    let resumed = motile_experiments::meanfield_run::resume_meanfield(&b, false).unwrap();
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
