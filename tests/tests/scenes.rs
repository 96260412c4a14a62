//! Scenes (`motile run <scene>`): every built-in scene parses and validates; the demo scene,
//! shortened, runs end to end and writes the comparison figures; running it again skips what
//! is done; a run directory with other settings is refused; bad scene files name the problem.

use motile_experiments::campaign::run_config::RunConfig;
use motile_experiments::campaign::scene::{BUILTIN, load_scene, parse_scene, run_scene};

#[test]
fn every_builtin_scene_parses_and_states_its_level() {
    for (name, text) in BUILTIN {
        let s = parse_scene(text, name).unwrap_or_else(|e| panic!("{name}: {e:#}"));
        assert_eq!(s.info.name, name);
        assert!(
            s.info.level.len() > 40 && s.info.description.len() > 40 && !s.info.cost.is_empty(),
            "{name}: says too little about itself"
        );
    }
    let err = format!("{:#}", load_scene("no-such-scene").unwrap_err());
    assert!(
        err.contains("demo, dilute, paper-dilute, concentrated, paper-concentrated, meanfield"),
        "{err}"
    );
}

#[test]
fn bad_scene_files_name_the_run_and_the_field() {
    let head =
        "[scene]\nname = \"x\"\nversion = 1\ndescription = \"d\"\nlevel = \"l\"\ncost = \"c\"\n";
    let cases = [
        (
            "[[run]]\nname = \"a\"\nmodel = \"fluid\"\n",
            "model = \"fluid\" is not one of",
        ),
        (
            "[[run]]\nname = \"a\"\nmodel = \"particle\"\n[run.config]\nbox_lenght = 8.0\n",
            "did you mean `box_length`",
        ),
        (
            "[[run]]\nname = \"a\"\nmodel = \"meanfield\"\n[run.config]\ngrid = 3\n",
            "grid",
        ),
        (
            "[[run]]\nname = \"a/b\"\nmodel = \"particle\"\n",
            "names a directory",
        ),
        ("", "no [[run]] entries"),
    ];
    for (body, want) in cases {
        let text = format!("{head}{body}");
        let text = if body.is_empty() {
            format!("run = []\n{head}")
        } else {
            text
        };
        let err = format!("{:#}", parse_scene(&text, "test.toml").unwrap_err());
        assert!(err.contains(want), "wanted `{want}` in: {err}");
        if !body.is_empty() {
            assert!(err.contains("run 1 (\"a"), "should name the run: {err}");
        }
    }
}

#[test]
fn the_demo_scene_shortened_runs_end_to_end_and_resumes_by_skipping() {
    let mut s = load_scene("demo").unwrap();
    for (_, cfg) in &mut s.runs {
        match cfg {
            RunConfig::Particle(c) => {
                c.t_end = 0.4;
                c.snapshot_interval = 0.2;
                c.checkpoint_interval = 0.2;
                c.diagnostic_interval = 0.04;
            }
            RunConfig::MeanField(c) => {
                c.t_end = 4.0;
                c.snapshot_interval = 2.0;
                c.checkpoint_interval = 2.0;
                c.diagnostic_interval = 0.5;
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let mut lines = Vec::new();
    let report = run_scene(&s, &out, &[], false, &mut |l| lines.push(l.to_string())).unwrap();
    assert_eq!(report.runs.len(), 2);
    assert!(report.runs.iter().all(|r| r.action == "ran" && r.steps > 0));
    for f in [
        "scene.md",
        "scene.toml",
        "compare/velocity_norm.png",
        "compare/velocity_norm.svg",
        "compare/velocity_correlation.png",
        "compare/summary.md",
        "compare/summary.csv",
        "compare/velocity_slice.png",
        "compare/msd.png",
        "particle/analysis/analysis.h5",
        "meanfield/analysis/analysis.h5",
    ] {
        assert!(out.join(f).exists(), "missing {f}; wrote {lines:?}");
    }
    let table = std::fs::read_to_string(out.join("compare/summary.md")).unwrap();
    assert!(
        table.contains("particle L/l = 12")
            && table.contains("mean field 32^3")
            && table.contains("correlation lengths")
            && out.join("compare/correlation_lengths.csv").exists(),
        "{table}"
    );
    // Again: nothing left to do.
    let again = run_scene(&s, &out, &[], false, &mut |_| {}).unwrap();
    assert!(
        again
            .runs
            .iter()
            .all(|r| r.action == "done already" && r.steps == 0),
        "{:?}",
        again.runs
    );
    // The device is not a setting of the physics: the same scene on the GPU (`motile run
    // --device gpu`) finds its runs done, as a run begun on one device resumes on the other.
    let mut on_gpu = s.clone();
    for (_, cfg) in &mut on_gpu.runs {
        cfg.set_device(motile_experiments::run::Device::Gpu);
    }
    let again = run_scene(&on_gpu, &out, &[], false, &mut |_| {}).unwrap();
    assert!(again.runs.iter().all(|r| r.action == "done already"));
    compare_from_compact_products(&out, &["particle", "meanfield"]);
    // Other settings in the same place are refused, and the run is left as it was.
    if let RunConfig::Particle(c) = &mut s.runs[0].1 {
        c.seed = 2;
    }
    let before = std::fs::read(out.join("particle/config.toml")).unwrap();
    let err = format!(
        "{:#}",
        run_scene(&s, &out, &[], false, &mut |_| {}).unwrap_err()
    );
    assert!(err.contains("other settings than the scene's"), "{err}");
    assert_eq!(
        before,
        std::fs::read(out.join("particle/config.toml")).unwrap()
    );
    // Another model's run under this run's name is refused the same way (not a parse error).
    s.runs.swap(0, 1);
    let (a, b) = (s.runs[0].0.clone(), s.runs[1].0.clone());
    s.runs[0].0 = b;
    s.runs[1].0 = a;
    let err = format!(
        "{:#}",
        run_scene(&s, &out, &[], false, &mut |_| {}).unwrap_err()
    );
    assert!(
        err.contains("holds a particle run with other settings"),
        "{err}"
    );
}

/// The scene's runs filed as the series harvest files them (config, time series and the
/// scene's compare/ products, no snapshots) compare to the same rows and curves, bit for bit, as
/// the run directories; a series table's rows for other runs join `series.csv`.
fn compare_from_compact_products(scene_out: &std::path::Path, members: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let mut compact = Vec::new();
    for m in members {
        let d = tmp.path().join(m);
        std::fs::create_dir_all(d.join("compare")).unwrap();
        for f in ["config.toml", "timeseries.csv"] {
            std::fs::copy(scene_out.join(m).join(f), d.join(f)).unwrap();
        }
        for e in std::fs::read_dir(scene_out.join("compare")).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, d.join("compare").join(p.file_name().unwrap())).unwrap();
        }
        compact.push(d);
    }
    let full = std::fs::read_to_string(scene_out.join("compare/series.csv")).unwrap();
    let header = full.lines().next().unwrap();
    let earlier = tmp.path().join("table.csv");
    let other = "L99,particle,99,606095,sbt-explicit,false,1e-2,0e0,1e2,0.5,2,1e-1,6e-3,2e-2,6.4e1,5e-3,3e-4,301,10,4.8e-1";
    std::fs::write(&earlier, format!("{header}\n{other}\n")).unwrap();
    let out = tmp.path().join("compare");
    motile_experiments::report::compare::compare_with_table(&compact, &out, Some(&earlier))
        .unwrap();
    let got = std::fs::read_to_string(out.join("series.csv")).unwrap();
    assert_eq!(got, format!("{full}{other}\n"), "series rows differ");
    for f in [
        "velocity_correlation.csv",
        "trajectories.csv",
        "order_correlations.csv",
        "correlation_lengths.csv",
    ] {
        let (a, b) = (
            std::fs::read_to_string(scene_out.join("compare").join(f)).unwrap(),
            std::fs::read_to_string(out.join(f)).unwrap(),
        );
        // correlation_lengths.csv names each run by its directory: compare the rest.
        let strip = |t: &str| -> Vec<String> {
            t.lines()
                .map(|l| l.split_once(",\"").map_or(l, |(_, rest)| rest).to_string())
                .collect()
        };
        assert_eq!(strip(&a), strip(&b), "{f} differs");
    }
    assert!(out.join("saturated_norm.svg").exists());
    // A file that is not a series table is refused by name.
    let err = motile_experiments::report::compare::compare_with_table(
        &compact,
        &tmp.path().join("again"),
        Some(&compact[0].join("timeseries.csv")),
    )
    .unwrap_err();
    assert!(format!("{err:#}").contains("not a series table"), "{err:#}");
}

/// A tiny dilute box (40 slender-body rods) stepped by `dt` to `t_end`, for the study tests.
fn tiny_scene(dt: f64, t_end: f64) -> motile_experiments::campaign::scene::Scene {
    tiny_scene_at(0.625, dt, t_end)
}

/// A tiny box (L/l = 4, slender-body rods) at volume fraction `nu`.
fn tiny_scene_at(nu: f64, dt: f64, t_end: f64) -> motile_experiments::campaign::scene::Scene {
    parse_scene(
        &format!(
            r#"
[scene]
name = "tiny"
version = 1
description = "a tiny box for the study tests"
level = "slender-body theory"
cost = "seconds"

[[run]]
name = "p"
model = "particle"
[run.config]
box_length = 4.0
volume_fraction = {nu}
dt = {dt}
t_end = {t_end}
hydrodynamics = "sbt"
"#
        ),
        "tiny",
    )
    .unwrap()
}

/// A study of `knob` over `values`, its accuracy 0.5 (the tiny box's runs are short).
fn study_options(knob: &str, values: &[&str]) -> motile_experiments::campaign::study::StudyOptions {
    motile_experiments::campaign::study::StudyOptions {
        knob: knob.into(),
        values: Some(values.iter().map(|v| v.to_string()).collect()),
        accuracy: 0.5,
        ..Default::default()
    }
}

#[test]
fn a_dt_study_shows_first_order_convergence_and_names_the_cheapest_setting() {
    use motile_experiments::campaign::study::{StudyOptions, study};
    let scene = tiny_scene(0.01, 0.4);
    let dir = tempfile::tempdir().unwrap();
    let values = Some(vec!["0.04".to_string(), "0.02".to_string()]);
    let opts = StudyOptions {
        knob: "dt".into(),
        values,
        t_end: None,
        accuracy: 0.5,
        ..Default::default()
    };
    let report = study(&scene, &opts, dir.path(), &mut |_| {}).unwrap();
    let p = &report.points;
    assert_eq!(p.len(), 3);
    assert!(p[2].reference && p[2].value == "0.0025" && p[2].error == 0.0);
    // The contact margin follows the step (2.5 U dt at least), the norm's history is the error.
    let run = dir.path().join("runs").join("dt_0.04");
    let cfg: motile_experiments::run::particle::ParticleRunConfig =
        motile_experiments::io::rundir::read_run_config(
            &run,
            motile_experiments::run::particle::ParticleRunConfig::validate,
        )
        .unwrap();
    assert!(cfg.contact.margin >= 0.1, "margin {}", cfg.contact.margin);
    assert!(
        p.iter().all(|q| q.history_error == q.error),
        "{}",
        report.markdown
    );
    // Explicit Euler: the error against dt_ref halves with dt, (dt - dt_ref) ratio 0.0375/0.0175.
    let ratio = p[0].error / p[1].error;
    assert!(
        p[1].error > 0.0 && (1.5..3.5).contains(&ratio),
        "errors {:.3e}, {:.3e}: ratio {ratio:.2}, expected about 2.1",
        p[0].error,
        p[1].error
    );
    // The cheapest is the fastest measured setting within the accuracy. Which one that is
    // depends on the machine: both runs take about 0.2 s here, mostly fixed costs, and
    // asserting dt = 0.04 failed once when noise put dt = 0.02 ahead.
    let cheapest = report.cheapest.expect("a setting within 0.5");
    let fastest = p[..2]
        .iter()
        .min_by(|a, b| a.seconds.total_cmp(&b.seconds))
        .unwrap();
    assert!(p[..2].iter().all(|q| q.error <= 0.5), "{}", report.markdown);
    assert_eq!(cheapest.value, fastest.value, "{}", report.markdown);
    assert!(
        report
            .markdown
            .contains("cheapest setting meeting the stated accuracy")
    );
    for f in [
        "study_dt.csv",
        "study_dt.md",
        "study_dt.png",
        "study_dt.svg",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing");
    }
}

/// A dt study refuses, before it runs anything, a step its diagnostics (every 0.2/beta) would
/// not fall on.
#[test]
fn a_dt_study_refuses_a_step_that_does_not_divide_its_diagnostic_interval() {
    use motile_experiments::campaign::study::study;
    let scene = tiny_scene(0.01, 0.4);
    let dir = tempfile::tempdir().unwrap();
    let opts = study_options("dt", &["0.15"]);
    let err = study(&scene, &opts, dir.path(), &mut |_| {}).unwrap_err();
    assert!(
        format!("{err:#}").contains("study dt = 0.15")
            && format!("{err:#}").contains("divides 0.2"),
        "{err:#}"
    );
    assert!(!dir.path().join("runs").exists(), "a run was started");
}

/// A GMRES tolerance study sets the tolerance of each run it makes: every run's resolved
/// config holds its setting, and GMRES takes fewer iterations at the looser one.
#[test]
fn a_gmres_tolerance_study_sets_each_runs_tolerance() {
    use motile_experiments::campaign::study::{StudyOptions, study};
    let scene = tiny_scene(0.02, 0.2);
    let dir = tempfile::tempdir().unwrap();
    let opts = StudyOptions {
        reference: Some("1e-8".to_string()),
        ..study_options("gmres_tolerance", &["1e-2"])
    };
    let report = study(&scene, &opts, dir.path(), &mut |_| {}).unwrap();
    assert_eq!(report.points.len(), 2, "{}", report.markdown);
    let iterations = |value: &str| -> f64 {
        let run = dir
            .path()
            .join("runs")
            .join(format!("gmres_tolerance_{value}"));
        let config = std::fs::read_to_string(run.join("config.toml")).unwrap();
        let tol: f64 = value.parse().unwrap();
        assert!(
            config
                .lines()
                .any(|l| l.split_once('=').is_some_and(|(k, v)| {
                    k.trim() == "gmres_tolerance" && v.trim().parse::<f64>() == Ok(tol)
                })),
            "gmres_tolerance = {value} not in {}:\n{config}",
            run.display()
        );
        let ts = std::fs::read_to_string(run.join("timeseries.csv")).unwrap();
        let mut lines = ts.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = header
            .iter()
            .position(|h| h.starts_with("gmres_iterations"))
            .unwrap();
        lines
            .map(|l| l.split(',').nth(col).unwrap().parse::<f64>().unwrap())
            .sum()
    };
    let (loose, tight) = (iterations("1e-2"), iterations("1e-8"));
    assert!(
        loose < tight,
        "GMRES iterations summed over the diagnostics: {loose} at 1e-2, {tight} at 1e-8"
    );
}

/// A level without flow (`hydrodynamics = "none"`) has error 1 by construction: the study's
/// table lists it with that note, its chart leaves it off and names the levels with a flow.
#[test]
fn a_hydrodynamics_study_keeps_the_level_without_flow_off_its_chart() {
    use motile_experiments::campaign::study::{StudyOptions, study};
    let scene = tiny_scene(0.02, 0.2);
    let dir = tempfile::tempdir().unwrap();
    let opts = StudyOptions {
        knob: "hydrodynamics".into(),
        values: Some(vec!["none".to_string(), "dipole".to_string()]),
        t_end: None,
        accuracy: 1e-2,
        ..Default::default()
    };
    let report = study(&scene, &opts, dir.path(), &mut |_| {}).unwrap();
    let p = &report.points;
    assert_eq!(
        p.iter().map(|q| q.value.as_str()).collect::<Vec<_>>(),
        ["none", "dipole", "sbt"]
    );
    assert!(!p[0].has_flow && p[0].error == 1.0, "none: {:?}", p[0]);
    assert!(
        p[1].has_flow && p[1].error > 0.0 && p[1].error < 1.0,
        "{:?}",
        p[1]
    );
    assert!(
        report.markdown.contains("| none | ")
            && report
                .markdown
                .contains("no flow: error 1 by construction (not charted)"),
        "{}",
        report.markdown
    );
    let svg = std::fs::read_to_string(dir.path().join("study_hydrodynamics.svg")).unwrap();
    assert!(
        svg.contains("\ndipole\n") && svg.contains("\nsbt (reference)\n"),
        "the chart labels the dipole level and the reference"
    );
    assert!(
        !svg.contains("\nnone\n"),
        "the chart shows the level without flow"
    );
}

/// On statistics (`--statistics-from`), a study compares levels on what the concentrated
/// figures use, each with its noise; `motile compare` of its runs tables the same statistics.
#[test]
fn a_statistics_study_compares_levels_on_what_the_figures_use() {
    use motile_experiments::campaign::study::{StudyOptions, study};
    let scene = tiny_scene_at(5.0, 0.02, 4.0);
    let dir = tempfile::tempdir().unwrap();
    let opts = StudyOptions {
        knob: "hydrodynamics".into(),
        values: Some(vec!["dipole".to_string()]),
        accuracy: 0.5,
        statistics_from: Some(0.8),
        ..Default::default()
    };
    let report = study(&scene, &opts, dir.path(), &mut |_| {}).unwrap();
    let [dipole, sbt] = &report.points[..] else {
        panic!("two settings: {}", report.markdown)
    };
    let (s, errors) = sbt.statistics.expect("the reference's statistics");
    assert!(sbt.reference && errors == [0.0; 4], "{}", report.markdown);
    assert!(
        s.norm.value > 0.0
            && s.decorrelation_rate.value > 0.0
            && s.msd.value > 0.0
            && s.snapshots == 9,
        "statistics over t = 0.8-4 from snapshots every 0.4: {s:?}"
    );
    let (_, e) = dipole.statistics.expect("the dipole level's statistics");
    assert_eq!(dipole.error, e.iter().copied().fold(0.0, f64::max));
    // The norm's history is compared pathwise beside the statistics.
    assert!(
        dipole.history_error > 0.0 && dipole.history_error < 1.0 && sbt.history_error == 0.0,
        "norm history errors {} / {}",
        dipole.history_error,
        sbt.history_error
    );
    assert!(
        report
            .markdown
            .contains("Statistics over t = 0.8-4 (1/beta)")
            && report.markdown.contains("| dipole | "),
        "{}",
        report.markdown
    );
    let csv = std::fs::read_to_string(dir.path().join("study_hydrodynamics.csv")).unwrap();
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .contains("decorrelation_rate [beta]")
    );
    // The comparison of the two runs tables their statistics over each run's later half.
    // A continuum run beside them has its row too, with what the comparison measured.
    let mf = dir.path().join("mf");
    let mcfg = motile_experiments::run::meanfield::MeanFieldRunConfig {
        grid: 8,
        mode_max: 2,
        t_end: 2.0,
        dt_max: 0.05,
        diagnostic_interval: 0.25,
        snapshot_interval: 0.5,
        ..Default::default()
    };
    motile_experiments::run::meanfield::run_meanfield(&mcfg, &mf, false).unwrap();
    let mut runs: Vec<_> = ["dipole", "sbt"]
        .iter()
        .map(|v| dir.path().join("runs").join(format!("hydrodynamics_{v}")))
        .collect();
    runs.push(mf);
    let out = dir.path().join("compare");
    motile_experiments::report::compare::compare(&runs, &out).unwrap();
    let table = std::fs::read_to_string(out.join("particle_statistics.csv")).unwrap();
    assert_eq!(table.lines().count(), 4, "{table}");
    assert!(
        table.contains("hydrodynamics_sbt,particle,5,4,320,sbt,2,4,")
            && table.contains("\nmf,meanfield,NaN,NaN,NaN,continuum,NaN,NaN,"),
        "{table}"
    );
    let columns = table.lines().next().unwrap().split(',').count();
    assert!(
        table.lines().all(|l| l.split(',').count() == columns),
        "{columns} columns in every row: {table}"
    );
    // Every row's norm in mean-field units is the comparison's summary (same window, same
    // average).
    let summary = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    for row in table.lines().skip(1) {
        let cells: Vec<&str> = row.split(',').collect();
        let listed = summary
            .lines()
            .find(|l| {
                l.split(',')
                    .next()
                    .unwrap()
                    .ends_with(&format!("/{}", cells[0]))
            })
            .unwrap_or_else(|| panic!("{} not in {summary}", cells[0]));
        // summary.csv: run,"label",t0,t1,mean_u_l2,std_error and 10 more columns (the label
        // has commas: counted from the end).
        let mean: f64 = listed.rsplit(',').nth(11).unwrap().parse().unwrap();
        let got: f64 = cells[columns - 5].parse().unwrap();
        assert!(
            (got - mean).abs() <= 1e-15 * mean.abs() && mean > 0.0,
            "{row}: {got} against the summary's {mean}"
        );
    }
    // The concentrated runs' pair correlations: three fields per run against r in l (0.05 l
    // apart, to L/2 = 2 l), finite, and a figure per field.
    let pairs = std::fs::read_to_string(out.join("pair_correlations.csv")).unwrap();
    for run in ["hydrodynamics_dipole", "hydrodynamics_sbt"] {
        for field in ["c", "n", "Q"] {
            let rows: Vec<Vec<f64>> = pairs
                .lines()
                .filter(|l| l.starts_with(&format!("\"{run}\",{field},")))
                .map(|l| l.split(',').skip(2).map(|v| v.parse().unwrap()).collect())
                .collect();
            assert_eq!(rows.len(), 41, "{run} {field}: {} radii", rows.len());
            assert!(
                rows[0][0] == 0.0
                    && (rows[40][0] - 2.0).abs() < 1e-9
                    && rows.iter().all(|r| r[1].is_finite()),
                "{run} {field}: {rows:?}"
            );
        }
    }
    for f in ["c", "n", "Q"] {
        assert!(out.join(format!("pair_correlation_{f}.svg")).exists());
    }
}

/// The cost estimate times real steps: a large particle run at a proxy size (same volume
/// fraction), a small mean-field run at its own size, and counts the run's steps.
#[test]
fn cost_estimates_time_steps_at_a_proxy_size_and_count_the_run() {
    use motile_experiments::campaign::estimate::{PROXY_RODS, estimate};
    use motile_experiments::run::memory::HostMemoryNeed;
    let text = r#"
[scene]
name = "est"
version = 1
description = "cost estimate test: a large particle run and a small mean-field run"
level = "no hydrodynamics for the particles (the estimate's arithmetic is what is tested)"
cost = "seconds"
estimate = true
[[run]]
name = "p"
model = "particle"
[run.config]
box_length = 32.0
volume_fraction = 0.625
dt = 0.01
t_end = 3.0
[[run]]
name = "m"
model = "meanfield"
[run.config]
grid = 16
t_end = 10.0
dt_max = 0.2
diagnostic_interval = 1.0
"#;
    let s = parse_scene(text, "est").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = estimate(&s.runs[0].1, &dir.path().join("p")).unwrap();
    assert_eq!(p.size, 20_480);
    assert!(
        p.measured_size.abs_diff(PROXY_RODS) < 100,
        "proxy of {} rods",
        p.measured_size
    );
    assert_eq!(p.steps, 300);
    assert!(!p.steps_at_least);
    let ratio =
        (20_480.0 * 20_480f64.ln()) / (p.measured_size as f64 * (p.measured_size as f64).ln());
    assert!(
        p.measured_step_seconds > 0.0
            && (p.step_seconds / p.measured_step_seconds - ratio).abs() < 1e-9 * ratio,
        "{p:?}"
    );
    assert!(!dir.path().join("p").exists(), "scratch left behind");
    // The memory the runs will be checked against: the measured figures per rod and point.
    let host = |need: HostMemoryNeed| need.bytes();
    assert_eq!(p.memory_bytes, host(HostMemoryNeed::particle(20_480)));
    assert!(
        p.describe().contains("0.21 GB of memory"),
        "{}",
        p.describe()
    );
    let m = estimate(&s.runs[1].1, &dir.path().join("m")).unwrap();
    assert_eq!(m.memory_bytes, host(HostMemoryNeed::meanfield(16)));
    // dt = min(dt_max, diagnostic_interval / 10) = 0.1: at least 100 steps, timed at 16^3.
    assert_eq!((m.size, m.measured_size, m.steps), (4096, 4096, 100));
    assert!(m.steps_at_least && m.step_seconds > 0.0, "{m:?}");
    assert!(m.describe().contains("grid points"), "{}", m.describe());
    // The scene prints them before it runs.
    let mut lines = Vec::new();
    let only = vec!["m".to_string()];
    run_scene(&s, &dir.path().join("out"), &only, false, &mut |l| {
        lines.push(l.to_string())
    })
    .unwrap();
    assert!(
        lines[0].starts_with("estimated cost of m: ") && lines.len() > 1,
        "{lines:?}"
    );
}

/// The GPU estimates of the `paper-dilute` members grow with the member's size, and are
/// within 30% of the wall times measured on an H200 node for the members run there (the
/// scene run with its analysis and comparison: L75 582 s, mf128 94 s).
#[test]
fn gpu_estimates_grow_with_size_and_match_the_members_run() {
    let scene = load_scene("paper-dilute").unwrap();
    let of = |name: &str| {
        let (_, cfg) = scene.runs.iter().find(|(n, _)| n == name).unwrap();
        motile_experiments::campaign::estimate::gpu_estimate(cfg).seconds()
    };
    let particle: Vec<f64> = ["L50", "L75", "L100", "L150", "L175"]
        .iter()
        .map(|m| of(m))
        .collect();
    assert!(
        particle.windows(2).all(|w| w[1] > w[0]),
        "not monotone: {particle:?}"
    );
    let continuum: Vec<f64> = ["mf64", "mf128", "mf256"].iter().map(|m| of(m)).collect();
    assert!(
        continuum.windows(2).all(|w| w[1] > w[0]),
        "not monotone: {continuum:?}"
    );
    for (member, measured) in [("L75", 582.0), ("mf128", 94.0)] {
        let e = of(member);
        assert!(
            (e / measured - 1.0).abs() <= 0.3,
            "{member}: estimated {e:.0} s, measured {measured} s"
        );
    }
}

/// `scripts/series_harvest.sh` files a concentrated archive (its `scene_name` says
/// paper-concentrated) into its own table, made with the archive's header where there is none,
/// and its products under `paper-concentrated/MEMBER/`; filing it again adds nothing.
#[test]
fn the_concentrated_harvest_files_its_rows_into_its_own_table() {
    use std::process::Command;
    let tmp = tempfile::tempdir().unwrap();
    let src = tmp.path().join("archive");
    let header = "run,nu,L/l,rods,level";
    let row = "L16,5,16,20480,sbt";
    std::fs::create_dir_all(src.join("compare")).unwrap();
    std::fs::create_dir_all(src.join("L16/analysis")).unwrap();
    std::fs::write(src.join("scene_name"), "paper-concentrated\n").unwrap();
    std::fs::write(
        src.join("compare/particle_statistics.csv"),
        format!("{header}\n{row}\n"),
    )
    .unwrap();
    std::fs::write(src.join("compare/series.csv"), "run,model\nL16,particle\n").unwrap();
    std::fs::write(src.join("L16/config.toml"), "box_length = 16.0\n").unwrap();
    std::fs::write(src.join("L16/analysis/correlations.csv"), "r,c\n").unwrap();
    let archive = tmp.path().join("series-concentrated.tgz");
    assert!(
        Command::new("tar")
            .arg("czf")
            .arg(&archive)
            .arg("-C")
            .arg(&src)
            .arg(".")
            .status()
            .unwrap()
            .success()
    );
    let gallery = tmp.path().join("gallery");
    std::fs::create_dir_all(&gallery).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/series_harvest.sh");
    for pass in 0..2 {
        let o = Command::new("bash")
            .arg(script)
            .arg(&archive)
            .arg(&gallery)
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{said}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let table = std::fs::read_to_string(gallery.join("paper_concentrated_series.csv")).unwrap();
        assert_eq!(table, format!("{header}\n{row}\n"), "pass {pass}: {said}");
        assert!(
            said.contains(if pass == 0 { "L16: filed" } else { "L16: in " }),
            "pass {pass}: {said}"
        );
    }
    for f in [
        "config.toml",
        "analysis/correlations.csv",
        "compare/particle_statistics.csv",
    ] {
        let p = gallery.join("paper-concentrated/L16").join(f);
        assert!(p.is_file(), "{} missing", p.display());
    }
    assert!(!gallery.join("paper_dilute_series.csv").exists());
}

/// Every TOML example in the docs parses as what it shows (a scene file with `[scene]`),
/// so that none can go stale.
#[test]
fn the_docs_toml_examples_parse() {
    let docs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs");
    let mut checked = 0;
    for e in std::fs::read_dir(&docs).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_none_or(|x| x != "md") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        for block in text.split("```toml\n").skip(1) {
            let toml = block.split("```").next().unwrap();
            assert!(
                toml.contains("[scene]"),
                "{}: a TOML example of an unknown kind:\n{toml}",
                path.display()
            );
            parse_scene(toml, &path.display().to_string())
                .unwrap_or_else(|e| panic!("{}: {e:#}\n{toml}", path.display()));
            checked += 1;
        }
    }
    assert!(checked >= 1, "no TOML example found in {}", docs.display());
}
