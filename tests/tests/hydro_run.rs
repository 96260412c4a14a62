//! Particle runs with hydrodynamics (docs/MODEL.md §1-§2) through the run machinery: the time series
//! carries GMRES iterations and residuals and the velocity norm; snapshots carry the force
//! densities; a run resumed from a checkpoint (which keeps the GMRES warm start) ends
//! bit-identical to the uninterrupted one; a GMRES that cannot converge stops the run with a
//! message that says so and where the last good state is.

use motile_experiments::io::rundir::TimeSeries;
use motile_experiments::io::snapshot::{Snapshot, read_snapshot};
use motile_experiments::run::particle::{ParticleRunConfig, resume_particle, run_particle};
use motile_particle::model::units::DEFAULT_DIAMETER;

fn small(model: &str) -> ParticleRunConfig {
    ParticleRunConfig {
        box_length: 6.0,
        volume_fraction: 0.625,
        t_end: 0.04,
        hydrodynamics: model.parse().unwrap(),
        snapshot_interval: 0.02,
        checkpoint_interval: 0.02,
        diagnostic_interval: 0.01,
        checkpoints_kept: 3,
        vtk: false,
        ..Default::default()
    }
}

fn column(ts: &TimeSeries, name: &str) -> Vec<f64> {
    let c = ts
        .columns
        .iter()
        .position(|c| c.starts_with(name))
        .unwrap_or_else(|| panic!("no column {name} in {:?}", ts.columns));
    ts.rows.iter().map(|r| r[c]).collect()
}

#[test]
fn hydrodynamic_runs_record_gmres_and_flow_and_resume_bit_identically() {
    for model in ["sbt", "dipole"] {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        let full = run_particle(&small(model), &a, false).unwrap();
        run_particle(&small(model), &b, false).unwrap();
        let ts = TimeSeries::read(&a.join("timeseries.csv")).unwrap();
        let norm = column(&ts, "velocity_norm");
        assert!(
            norm.iter().all(|v| *v > 1e-4 && *v < 1.0),
            "{model}: velocity norms {norm:?}"
        );
        if model == "sbt" {
            let it = column(&ts, "gmres_iterations");
            let res = column(&ts, "gmres_residual");
            assert!(
                it.iter().all(|i| *i < 20.0) && res.iter().all(|r| *r <= 1e-5),
                "GMRES iterations {it:?}, residuals {res:?}"
            );
        }
        let Snapshot::Particle(s) = read_snapshot(&a.join("snapshots/snap_000002.h5")).unwrap()
        else {
            panic!("particle snapshot expected")
        };
        let forces = s
            .forces
            .expect("force densities in a hydrodynamic snapshot");
        assert_eq!(forces.points.len(), 4 * s.positions.len());
        // Drop the newest checkpoint (step 20) and resume from step 10.
        std::fs::remove_file(b.join("checkpoints/ckpt_000000020.h5")).unwrap();
        let resumed = resume_particle(&b, false).unwrap();
        assert_eq!(resumed.steps, 10, "{model}");
        assert!(
            resumed.rods == full.rods,
            "{model}: resumed trajectory differs from the uninterrupted one"
        );
    }
}

#[test]
fn gmres_that_cannot_converge_stops_the_run_with_a_structured_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut cfg = small("sbt");
    cfg.hydro.gmres_max_iterations = 1;
    cfg.hydro.gmres_tolerance = 1e-12;
    let err = format!("{:#}", run_particle(&cfg, &out, false).unwrap_err());
    assert!(
        err.contains("GMRES did not converge") && err.contains("free solve"),
        "message: {err}"
    );
    assert!(err.contains("last_good.h5"), "message: {err}");
    assert!(out.join("checkpoints/last_good.h5").exists());
}

#[test]
fn analyze_handles_a_hydrodynamic_run_whose_first_snapshot_has_no_flow() {
    // Regression: the initial snapshot has no force density (no solve yet), the later ones do;
    // `motile analyze` indexed fields by position and panicked.
    use motile_experiments::report::analyze::{AnalyzeOptions, analyze_run};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    run_particle(&small("sbt"), &out, false).unwrap();
    let report = analyze_run(&out, &AnalyzeOptions::default()).unwrap();
    let u = column(&report.timeseries, "u_l2");
    assert!(u[0].is_nan(), "no flow at t = 0: {u:?}");
    assert!(
        u[1..].iter().all(|v| v.is_finite() && *v > 0.0),
        "flow later: {u:?}"
    );
    // The flow's norm from the snapshots matches the run's own time series at the same time.
    let ts = TimeSeries::read(&out.join("timeseries.csv")).unwrap();
    let run_norm = column(&ts, "velocity_norm");
    let t_run = column(&ts, "t");
    let t_an = column(&report.timeseries, "t");
    let k = t_run
        .iter()
        .position(|t| (t - t_an[1]).abs() < 1e-9)
        .unwrap();
    // The run's norm comes from a transform at 1e-4 (the time series' tolerance), the
    // analysis's at 1e-6: they agree to the first.
    let rel = (run_norm[k] - u[1]).abs() / u[1];
    assert!(
        rel < 1e-4,
        "analysis {} vs run {} at t = {}: rel {rel:e}",
        u[1],
        run_norm[k],
        t_an[1]
    );
}

#[test]
fn compare_puts_particle_and_mean_field_runs_in_one_unit_system() {
    use motile_experiments::report::compare::compare;
    use motile_experiments::run::meanfield::{MeanFieldRunConfig, run_meanfield};
    use motile_particle::model::units::particle_to_meanfield;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("p");
    let m = dir.path().join("m");
    run_particle(&small("sbt"), &p, false).unwrap();
    let mcfg = MeanFieldRunConfig {
        grid: 8,
        mode_max: 2,
        t_end: 2.0,
        dt_max: 0.05,
        diagnostic_interval: 0.5,
        snapshot_interval: 1.0,
        ..Default::default()
    };
    run_meanfield(&mcfg, &m, false).unwrap();
    let out = dir.path().join("cmp");
    let report = compare(&[p.clone(), m.clone()], &out).unwrap();
    for f in [
        "velocity_norm.png",
        "velocity_norm.svg",
        "velocity_norm.csv",
        "summary.csv",
        "summary.md",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // The particle curve is the run's own time series (its box-scale flow) through
    // docs/MODEL.md section 5.
    let ts = TimeSeries::read(&p.join("timeseries.csv")).unwrap();
    let (t, u) = (column(&ts, "t"), column(&ts, "velocity_norm_box"));
    let nu = (0.625f64 * 216.0).round() / 216.0;
    let c = &report.curves[0];
    for k in 0..t.len() {
        let (tm, um) = particle_to_meanfield(t[k], u[k], nu, DEFAULT_DIAMETER);
        assert!(
            (c.t[k] - tm).abs() < 1e-12 && (c.u[k] - um).abs() < 1e-12,
            "row {k}"
        );
    }
    // The mean-field curve is unchanged.
    let mts = TimeSeries::read(&m.join("timeseries.csv")).unwrap();
    assert_eq!(report.curves[1].u, column(&mts, "u_l2"));
    let averages = report.table.split("\n\n").next().unwrap();
    assert_eq!(averages.lines().count(), 4, "{}", report.table);
    // Correlation lengths: the first zero of each run's time-averaged Corr[u], as charted.
    let lengths = std::fs::read_to_string(out.join("correlation_lengths.csv")).unwrap();
    for (k, run) in [&p, &m].iter().enumerate() {
        let c = &report.correlations[k];
        let want = motile_analysis::stats::correlation_length(&c.r, &c.value);
        let row = lengths
            .lines()
            .find(|l| l.starts_with(&format!("{},", run.display())) && l.contains(",u,"))
            .unwrap_or_else(|| panic!("no Corr[u] length for {}: {lengths}", run.display()));
        let got: f64 = row.rsplit(',').nth(1).unwrap().parse().unwrap();
        match want {
            Some(z) => assert!((got - z).abs() < 1e-12, "{row}: want {z}"),
            None => assert!(got.is_nan(), "{row}: no zero expected"),
        }
    }
    // Corr[u](0) of the particle run is the mean square of its velocity norm over the window's
    // snapshots (t_p = 0.02 and 0.04) over all analysis modes, in the same units.
    assert_eq!(report.correlations.len(), 2);
    let corr0 = report.correlations[0].value[0];
    let u_all = column(&ts, "velocity_norm [");
    let sq: Vec<f64> = [0.02, 0.04]
        .iter()
        .map(|tp| {
            let k = t.iter().position(|t| (t - tp).abs() < 1e-9).unwrap();
            let um = particle_to_meanfield(t[k], u_all[k], nu, DEFAULT_DIAMETER).1;
            um * um
        })
        .collect();
    // The time series' norms come from a transform at 1e-4: their squares within twice it.
    let expect = 0.5 * (sq[0] + sq[1]);
    assert!(
        (corr0 - expect).abs() < 2e-4 * expect,
        "Corr[u](0) {corr0} vs {expect}"
    );
    assert!(out.join("velocity_correlation.png").exists());
    // Trajectories: at these early times the rods swim ballistically, MSD ~ (U t)^2 up to the
    // flow's few-percent speed changes; orientations barely move.
    let tr = &report.trajectories[0];
    for k in 1..tr.t.len() {
        let ballistic = tr.t[k] * tr.t[k];
        let dev = (tr.msd[k] - ballistic).abs() / ballistic;
        assert!(
            dev < 0.2,
            "MSD {} vs (U t)^2 = {ballistic} at t = {}",
            tr.msd[k],
            tr.t[k]
        );
        assert!(
            tr.orientation[k] > 0.99,
            "orientation {}",
            tr.orientation[k]
        );
    }
    assert!(out.join("msd.png").exists() && out.join("orientation.svg").exists());
    assert!(out.join("velocity_slice.png").exists() && out.join("velocity_slice.svg").exists());
    for f in ["c", "n", "Q"] {
        assert!(
            out.join(format!("correlation_{f}.png")).exists(),
            "Corr[{f}] chart missing"
        );
    }
    // Concentrated runs (every run a particle run with nu > 1): every order-parameter
    // correlation against r/l, as docs/MODEL.md section 7 reads them.
    let dense = dir.path().join("dense");
    let mut cfg = small("sbt");
    cfg.box_length = 3.0;
    cfg.volume_fraction = 5.0;
    run_particle(&cfg, &dense, false).unwrap();
    let cmp2 = dir.path().join("cmp2");
    compare(&[dense], &cmp2).unwrap();
    let svg = std::fs::read_to_string(cmp2.join("correlation_c.svg")).unwrap();
    assert!(svg.contains("r / l"), "concentrated: r/l axis expected");
    // Dilute runs: c and n decay within a rod length, so they too are read against r/l; Q,
    // which the continuum shares, against r/L.
    let svg = std::fs::read_to_string(out.join("correlation_c.svg")).unwrap();
    assert!(svg.contains("r / l"), "dilute Corr[c]: r/l axis expected");
    let svg = std::fs::read_to_string(out.join("correlation_Q.svg")).unwrap();
    assert!(svg.contains("r / L"), "dilute Corr[Q]: r/L axis expected");
    // A particle run without flow is refused with a reason.
    let none = dir.path().join("none");
    run_particle(&small("none"), &none, false).unwrap();
    let err = format!("{:#}", compare(&[none], &out).unwrap_err());
    assert!(err.contains("no flow to compare"), "{err}");
}

#[test]
fn compare_fits_the_mean_field_growth_rate_of_the_dominant_mode() {
    // A plane wave of Q_xy with wavevector m = (1, 0, 0) on the unit cube grows at
    // gamma = (1/5)/(1 + zeta/15) - D k^2, k = 2 pi |m| (docs/MODEL.md section 4), independent of
    // k apart from diffusion; ||u||_2 grows at the same rate.
    use motile_experiments::report::compare::compare;
    use motile_experiments::report::curves::growth_fit;
    use motile_experiments::run::meanfield::{MeanFieldRunConfig, run_meanfield};
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("m");
    let cfg = MeanFieldRunConfig {
        grid: 8,
        initial: "plane_wave".into(),
        wavevector: [1, 0, 0],
        amplitude: 1e-6,
        diffusion: 2e-3,
        t_end: 20.0,
        dt_max: 0.02,
        diagnostic_interval: 0.5,
        snapshot_interval: 10.0,
        ..Default::default()
    };
    run_meanfield(&cfg, &m, false).unwrap();
    let report = compare(&[m], &dir.path().join("cmp")).unwrap();
    let (fit, phase) = growth_fit(&report.curves[0]).expect("a growth fit");
    assert!(phase, "the plane wave grows: a growth phase expected");
    let k2 = (2.0 * std::f64::consts::PI).powi(2);
    let expected = 0.2 / (1.0 + cfg.zeta / 15.0) - cfg.diffusion * k2;
    let rel = (fit.rate - expected).abs() / expected;
    eprintln!(
        "growth: fitted {:.6} +- {:.1e} over [{}, {}], expected {expected:.6}, rel {rel:.1e}",
        fit.rate, fit.std_error, fit.t0, fit.t1
    );
    assert!(
        rel < 1e-3,
        "fitted {:.6} +- {:.1e} over [{}, {}] vs (1/5)/(1 + zeta/15) - D k^2 = {expected:.6}: rel {rel:e}",
        fit.rate,
        fit.std_error,
        fit.t0,
        fit.t1
    );
    assert!(report.table.contains("growth"), "{}", report.table);
}
