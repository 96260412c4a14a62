//! `motile particle run`: a run resumed from a checkpoint ends bit-identical to the
//! uninterrupted run; snapshots carry velocities and contact forces, read back by h5py; the VTK
//! files are well-formed XML; bad configs and bad initial files fail with messages that name
//! the field or the file and the offending rods.

use motile_experiments::io::snapshot::{Snapshot, read_snapshot};
use motile_experiments::run::particle::{
    ParticleRunConfig, load_configuration, parse_config, resume_particle, run_particle,
};
use motile_tests::{h5py_available, run_python};
use std::path::Path;

fn small() -> ParticleRunConfig {
    ParticleRunConfig {
        box_length: 6.0,
        volume_fraction: 5.0,
        t_end: 0.2,
        snapshot_interval: 0.1,
        checkpoint_interval: 0.1,
        diagnostic_interval: 0.02,
        checkpoints_kept: 2,
        ..Default::default()
    }
}

#[test]
fn resume_from_a_checkpoint_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let full = run_particle(&small(), &a, false).unwrap();
    run_particle(&small(), &b, false).unwrap();
    // 100 steps, checkpoints every 50 (the last two kept: 50 and 100). Pretend the run was
    // killed before the last one: drop it and resume from step 50.
    std::fs::remove_file(b.join("checkpoints/ckpt_000000100.h5")).unwrap();
    let kept: Vec<_> = std::fs::read_dir(b.join("checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().ends_with(".h5"))
        .collect();
    assert_eq!(kept.len(), 1, "{kept:?}");
    let resumed = resume_particle(&b, false).unwrap();
    assert_eq!(resumed.steps, 50);
    assert!(
        resumed.rods == full.rods,
        "resumed trajectory differs from the uninterrupted one"
    );
    // Snapshots carry kinematics that balance: contact forces sum to zero.
    let Snapshot::Particle(s) = read_snapshot(&b.join("snapshots/snap_000002.h5")).unwrap() else {
        panic!()
    };
    let k = s.kinematics.expect("kinematics in a solver snapshot");
    let net: f64 = (0..3)
        .map(|d| k.contact_forces.iter().map(|f| f[d]).sum::<f64>().abs())
        .sum();
    let scale: f64 = k
        .contact_forces
        .iter()
        .map(|f| f.iter().map(|c| c.abs()).sum::<f64>())
        .sum();
    assert!(
        scale > 0.0 && net <= 1e-10 * scale,
        "net contact force {net:.2e} of {scale:.2e}"
    );
    if !h5py_available() {
        eprintln!(
            "SKIPPED h5py/XML checks: python3 with h5py and numpy not found (CI installs them)"
        );
        return;
    }
    let out = run_python(
        r#"
import sys, h5py, numpy as np, xml.etree.ElementTree as ET
with h5py.File(sys.argv[1] + "/snapshots/snap_000002.h5") as f:
    v, w, c = f["velocities"][...], f["angular_velocities"][...], f["contact_forces"][...]
    assert v.shape == w.shape == c.shape == f["positions"].shape
    print("net force", np.abs(c.sum(axis=0)).max())
root = ET.parse(sys.argv[1] + "/vtk/rods_000002.vtp").getroot()
piece = root.find("PolyData/Piece")
n = int(piece.get("NumberOfLines"))
pts = np.array(piece.find("Points/DataArray").text.split(), float).reshape(-1, 3)
assert pts.shape == (2 * n, 3)
lengths = np.linalg.norm(pts[1::2] - pts[0::2], axis=1)
assert np.allclose(lengths, 1.0), lengths[:5]
pvd = ET.parse(sys.argv[1] + "/rods.pvd").getroot()
print("pvd entries", len(pvd.findall("Collection/DataSet")))
"#,
        &[b.to_str().unwrap()],
    );
    assert!(out.contains("pvd entries 3"), "{out}");
}

#[test]
fn resume_with_a_smaller_dt_continues_from_the_checkpoint_time() {
    // The answer to a failed step is often "halve dt and resume": the step counter must be
    // rebased, or the run would restart its clock at step * new dt.
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    run_particle(&small(), &a, false).unwrap();
    // Drop the last checkpoint (t = 0.2): resume from t = 0.1 with dt 0.001 to t_end = 0.3.
    std::fs::remove_file(a.join("checkpoints/ckpt_000000100.h5")).unwrap();
    let cfg_path = a.join("config.toml");
    let text = std::fs::read_to_string(&cfg_path).unwrap();
    let text = text
        .replace("dt = 0.002", "dt = 0.001")
        .replace("t_end = 0.2", "t_end = 0.3");
    assert!(
        text.contains("dt = 0.001") && text.contains("t_end = 0.3"),
        "{text}"
    );
    std::fs::write(&cfg_path, text).unwrap();
    let resumed = resume_particle(&a, false).unwrap();
    assert_eq!(resumed.steps, 200, "0.1 to 0.3 at dt = 0.001");
    assert_eq!(resumed.final_step, 300);
    let ts = motile_experiments::io::rundir::TimeSeries::read(&a.join("timeseries.csv")).unwrap();
    let t = ts.column("t [1/beta]").unwrap();
    let gaps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(
        gaps.iter().all(|g| (g - 0.02).abs() < 1e-9) && (t.last().unwrap() - 0.3).abs() < 1e-9,
        "time series should run on evenly to t = 0.3: {t:?}"
    );
    // A dt that does not divide the checkpoint's time is refused, naming both.
    // (Resume from t = 0.2, the checkpoint at step 200 of dt = 0.001.)
    std::fs::remove_file(a.join("checkpoints/ckpt_000000300.h5")).unwrap();
    let text = std::fs::read_to_string(&cfg_path)
        .unwrap()
        .replace("dt = 0.001", "dt = 0.003");
    std::fs::write(&cfg_path, text).unwrap();
    let err = format!("{:#}", resume_particle(&a, false).unwrap_err());
    assert!(
        err.contains("not a whole number of steps of dt = 0.003"),
        "{err}"
    );
}

#[test]
fn bad_configs_name_the_field_and_the_range() {
    let p = Path::new("case.toml");
    let cases = [
        (
            "dt = 0.5",
            "dt = 0.5 is outside the allowed range (0, 0.2] (1/beta)",
        ),
        (
            "box_length = -3",
            "box_length = -3 is outside the allowed range [2, 1000] (rod lengths)",
        ),
        (
            "volume_fraction = 9",
            "volume_fraction = 9 is outside the allowed range (0, 6]",
        ),
        (
            "hydrodynamics = \"stokesian\"",
            "hydrodynamics = \"stokesian\" is not one of \"none\", \"dipole\", \"sbt-explicit\", \"sbt\"",
        ),
        ("dtt = 0.1", "unknown key `dtt`; did you mean `dt`?"),
        (
            "[contact]\nmargin = 0.001",
            "contact.margin = 0.001 is smaller than the distance two rods close in one step",
        ),
        (
            "snapshot_interval = 0.0001",
            "snapshot_interval = 0.0001 is outside the allowed range",
        ),
    ];
    for (text, expected) in cases {
        let e = parse_config(text, p).unwrap_err().to_string();
        assert!(
            e.contains(expected) && e.contains("case.toml"),
            "config `{text}`: got `{e}`, expected `{expected}`"
        );
    }
}

/// The rod diameter is a run parameter: a run of thin rods (b = l/10) at nu = 5 records its
/// diameter and the RPY radius that follows from it in config.toml, keeps its rods at least
/// b apart (within the overlap tolerance) and closer than thicker rods could be, and the
/// overlap check of an initial file uses the run's diameter.
#[test]
fn thin_rods_are_a_run_parameter() {
    let dir = tempfile::tempdir().unwrap();
    let thin = ParticleRunConfig {
        diameter: 0.1,
        hydrodynamics: motile_particle::model::level::Hydrodynamics::Sbt,
        t_end: 0.1,
        ..small()
    };
    let out = dir.path().join("thin");
    let done = run_particle(&thin, &out, false).unwrap();
    let text = std::fs::read_to_string(out.join("config.toml")).unwrap();
    let written = parse_config(&text, &out.join("config.toml")).unwrap();
    assert_eq!(written.diameter, 0.1, "{text}");
    let a = written.hydro.rpy_radius.expect("resolved");
    assert!(
        (a - 3f64.sqrt() / 4.0 * 0.1).abs() < 1e-15,
        "rpy_radius {a}"
    );
    assert_eq!(done.rods.diameter, 0.1);
    let tol = thin.contact.overlap_tolerance;
    assert!(
        motile_particle::model::init::overlapping_pairs(&done.rods, tol).is_empty(),
        "thin rods overlap by more than {tol}"
    );
    let mut probe = done.rods.clone();
    probe.diameter = 0.2;
    let close = motile_particle::model::init::overlapping_pairs(&probe, 0.0);
    assert!(
        !close.is_empty(),
        "at nu = 5 some thin rods come closer than 0.2 l"
    );
    let f = dir.path().join("pair.txt");
    std::fs::write(&f, "1 1 1 1 0 0\n1 1.15 1 1 0 0\n").unwrap();
    assert!(load_configuration(&f, 8.0, 0.1, 5e-3).is_ok());
    let e = load_configuration(&f, 8.0, 0.2, 5e-3)
        .unwrap_err()
        .to_string();
    assert!(e.contains("< diameter 0.2"), "{e}");
}

#[test]
fn bad_initial_files_name_the_line_or_the_overlapping_pair() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("rods.txt");
    std::fs::write(&f, "1 1 1 1 0 0\n1.0 1.1 1.0 1 0 0\n5 5 5 0 0 1\n").unwrap();
    let e = load_configuration(&f, 8.0, 0.2, 5e-3)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("rods 0 and 1 overlap") && e.contains("rods.txt"),
        "{e}"
    );
    std::fs::write(&f, "1 1 1 1 0 0\n2 2 2 0.5 0 0\n").unwrap();
    let e = load_configuration(&f, 8.0, 0.2, 5e-3)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 2") && e.contains("not a unit vector"),
        "{e}"
    );
    std::fs::write(&f, "1 1 1 1 0\n").unwrap();
    let e = load_configuration(&f, 8.0, 0.2, 5e-3)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 1") && e.contains("expected 6 finite numbers"),
        "{e}"
    );
    std::fs::write(&f, "1 1 1 1 0 0\n3 3 3 0 1 0\n").unwrap();
    let rods = load_configuration(&f, 8.0, 0.2, 5e-3).unwrap();
    assert_eq!(rods.len(), 2);
    // Parallel rods one diameter apart are in contact, not overlapping; an overlap within the
    // tolerance (what a run's own steps leave) is accepted, one beyond it is not.
    for (gap, ok) in [(0.2, true), (0.2 - 4e-3, true), (0.2 - 6e-3, false)] {
        std::fs::write(&f, format!("1 1 1 1 0 0\n1 {} 1 1 0 0\n", 1.0 + gap)).unwrap();
        let r = load_configuration(&f, 8.0, 0.2, 5e-3);
        assert_eq!(r.is_ok(), ok, "axes {gap} apart: {:?}", r.err());
    }
    let e = load_configuration(&f, 8.0, 0.2, 5e-3)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("more than contact.overlap_tolerance = 0.005"),
        "{e}"
    );
    // A snapshot of a run is a valid initial configuration, and a run can start from it.
    let first = dir.path().join("first");
    let done = run_particle(
        &ParticleRunConfig {
            t_end: 0.02,
            ..small()
        },
        &first,
        false,
    )
    .unwrap();
    let snap = first.join("snapshots/snap_000000.h5");
    // Of its own box only: a run's config.toml describes its rods.
    let e = load_configuration(&snap, 99.0, 0.2, 5e-3)
        .unwrap_err()
        .to_string();
    assert!(e.contains("set box_length = 6 to start from it"), "{e}");
    let loaded = load_configuration(&snap, 6.0, 0.2, 5e-3).unwrap();
    assert_eq!(loaded.box_length, 6.0);
    assert_eq!(loaded.len(), done.rods.len());
    let cfg = ParticleRunConfig {
        initial: snap.to_string_lossy().into_owned(),
        t_end: 0.02,
        ..small()
    };
    run_particle(&cfg, &dir.path().join("second"), false).unwrap();
    // So is its last snapshot, after steps at nu = 5: rods in contact and within the overlap
    // tolerance (not at distances of at least the diameter less 1e-9, which contacts break).
    let dense = dir.path().join("dense");
    run_particle(&small(), &dense, false).unwrap();
    let last = dense.join("snapshots/snap_000002.h5");
    let cfg = ParticleRunConfig {
        initial: last.to_string_lossy().into_owned(),
        t_end: 0.02,
        ..small()
    };
    run_particle(&cfg, &dir.path().join("third"), false).unwrap();
}
