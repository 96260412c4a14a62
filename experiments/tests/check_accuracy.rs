//! `motile check-accuracy`: the audit of a run's fast sums against the direct Ewald sum
//! (`docs/accuracy.md`). On short slender-body and dipole runs the errors it reports agree with
//! an independent computation in the test (the same sums, the direct one at another splitting
//! parameter), every output is within the run's tolerance, and the command refuses runs and
//! snapshots it cannot audit with a message saying why.

use motile_experiments::io::snapshot::{Snapshot, read_snapshot};
use motile_experiments::report::accuracy::{Audit, audit, render};
use motile_experiments::run::particle::{ParticleRunConfig, run_particle};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::reference::EwaldReference;
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::stresslet_strength;
use motile_particle::model::geometry::{Vec3, dot, sub};
use motile_particle::model::units::DEFAULT_DIAMETER;
use std::path::Path;

fn short_run(hydrodynamics: &str, box_length: f64, out: &Path) -> ParticleRunConfig {
    let mut cfg = ParticleRunConfig {
        box_length,
        volume_fraction: 1.0,
        dt: 0.02,
        t_end: 0.06,
        hydrodynamics: hydrodynamics.parse().unwrap(),
        snapshot_interval: 0.06,
        vtk: false,
        ..ParticleRunConfig::default()
    };
    cfg.hydro.sum_tolerance = 1e-3;
    run_particle(&cfg, out, false).unwrap();
    cfg
}

/// Max-relative and relative-L2 errors over rows.
fn errors(fast: &[Vec3], exact: &[Vec3]) -> (f64, f64) {
    let (mut e2, mut x2, mut emax, mut xmax): (f64, f64, f64, f64) = (0.0, 0.0, 0.0, 0.0);
    for (a, b) in fast.iter().zip(exact) {
        let d = dot(sub(*a, *b), sub(*a, *b));
        e2 += d;
        x2 += dot(*b, *b);
        emax = emax.max(d.sqrt());
        xmax = xmax.max(dot(*b, *b).sqrt());
    }
    (emax / xmax, (e2 / x2).sqrt())
}

fn agree(what: &str, audited: (f64, f64), here: (f64, f64), a: &Audit) {
    for (x, y) in [(audited.0, here.0), (audited.1, here.1)] {
        assert!(
            (x - y).abs() <= 1e-6 * y + 1e-13,
            "{what}: the audit says {audited:?}, the test computes {here:?}\n{}",
            render(a)
        );
    }
    assert!(
        here.0 <= a.tolerance && here.1 <= a.tolerance,
        "{what}: error {here:?} above the run's tolerance {}",
        a.tolerance
    );
}

#[test]
fn the_audit_of_a_slender_body_run_matches_a_direct_computation() {
    audit_of_an_rpy_run("sbt");
}

/// The explicit level's sum is of force-free data: every rod an isolated swimmer's density.
#[test]
fn the_audit_of_an_explicit_density_run_matches_a_direct_computation() {
    audit_of_an_rpy_run("sbt-explicit");
}

fn audit_of_an_rpy_run(level: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(level);
    let cfg = short_run(level, 5.0, &out);
    let a = audit(&out, None, 64).unwrap();
    assert_eq!(a.targets, 64, "16 rods of 4 points");
    let Snapshot::Particle(snap) = read_snapshot(&a.snapshot).unwrap() else {
        panic!("particle snapshot")
    };
    let pf = snap.forces.expect("force data");
    if level == "sbt-explicit" {
        // Force-free rods: each rod's weighted forces sum to zero.
        for (k, rod) in pf.forces.chunks_exact(4).enumerate() {
            let net: f64 = (0..3)
                .map(|d| rod.iter().map(|f| f[d]).sum::<f64>().abs())
                .sum();
            assert!(net < 1e-14, "rod {k}: net force {net:e}");
        }
    }
    let geo = RpyGeometry {
        box_length: snap.box_length,
        radius: cfg.hydro.slender(cfg.diameter).rpy_radius,
        group: 4,
    };
    let idx: Vec<usize> = a
        .rods
        .iter()
        .flat_map(|r| (0..4).map(move |j| 4 * r + j))
        .collect();
    let fast = SpectralEwald::new(1e-3)
        .unwrap()
        .rpy(&geo, &pf.points, &pf.forces)
        .unwrap();
    let exact = EwaldReference::default()
        .rpy_at(&geo, &pf.points, &pf.forces, &idx)
        .unwrap();
    let fast: Vec<Vec3> = idx.iter().map(|&i| fast[i]).collect();
    let row = &a.rows[0];
    agree(
        "RPY velocity",
        (row.max_relative, row.l2_relative),
        errors(&fast, &exact),
        &a,
    );
    let text = render(&a);
    assert!(
        text.contains("| RPY velocity at the quadrature points | 1e-3 |")
            && text.contains("rod rotation rate from the flow"),
        "{text}"
    );
}

#[test]
fn the_audit_of_a_dipole_run_matches_a_direct_computation() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dipole");
    short_run("dipole", 8.0, &out);
    let a = audit(&out, None, 100).unwrap();
    let Snapshot::Particle(snap) = read_snapshot(&a.snapshot).unwrap() else {
        panic!("particle snapshot")
    };
    let (x, p, l) = (&snap.positions, &snap.orientations, snap.box_length);
    let sigma = vec![stresslet_strength(DEFAULT_DIAMETER); x.len()];
    let fast = SpectralEwald::new(1e-3)
        .unwrap()
        .stresslets(l, x, p, &sigma)
        .unwrap();
    let exact = EwaldReference::default().stresslets_at(l, x, p, &sigma, &a.rods);
    let pick = |v: &[Vec3]| -> Vec<Vec3> { a.rods.iter().map(|&r| v[r]).collect() };
    let flat =
        |g: &[[Vec3; 3]]| -> Vec<Vec3> { g.iter().flat_map(|m| m.iter().copied()).collect() };
    let fast_g: Vec<[Vec3; 3]> = a.rods.iter().map(|&r| fast.grad[r]).collect();
    agree(
        "stresslet velocity",
        (a.rows[0].max_relative, a.rows[0].l2_relative),
        errors(&pick(&fast.u), &exact.u),
        &a,
    );
    // Gradients compared row by row of the matrices: the same Frobenius L2, and a max over
    // rows bounded by the max over matrices (checked by the audit's own value below).
    let (gm, gl) = errors(&flat(&fast_g), &flat(&exact.grad));
    let (am, al) = (a.rows[1].max_relative, a.rows[1].l2_relative);
    assert!(
        (al - gl).abs() <= 1e-6 * gl + 1e-13 && am <= a.tolerance && gm <= a.tolerance,
        "gradient: audit ({am:e}, {al:e}), test ({gm:e}, {gl:e})"
    );
}

#[test]
fn check_accuracy_prints_the_table_and_refuses_what_it_cannot_audit() {
    let bin = env!("CARGO_BIN_EXE_motile");
    let dir = tempfile::tempdir().unwrap();
    let sbt = dir.path().join("sbt");
    short_run("sbt", 4.0, &sbt);
    let run = |args: &[&str]| {
        let o = std::process::Command::new(bin).args(args).output().unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr),
        )
    };
    let s = sbt.to_str().unwrap();
    let (ok, text) = run(&["check-accuracy", s, "--targets", "32"]);
    assert!(
        ok && text.contains("| rod velocity from the flow"),
        "{text}"
    );
    let (ok, text) = run(&["check-accuracy", s, "--snapshot", "0"]);
    assert!(
        !ok && text.contains("no force data") && text.contains("--snapshot N"),
        "{text}"
    );
    let (ok, text) = run(&["check-accuracy", s, "--snapshot", "9"]);
    assert!(!ok && text.contains("does not exist"), "{text}");
    let none = dir.path().join("none");
    short_run("none", 4.0, &none);
    let (ok, text) = run(&["check-accuracy", none.to_str().unwrap()]);
    assert!(
        !ok && text.contains("hydrodynamics = \"none\"") && text.contains("nothing to audit"),
        "{text}"
    );
}
