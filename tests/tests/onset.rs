//! `motile stability onset` end to end on a tiny scan: one particle run per (nu, L nu) from the
//! seeded perturbation, the chart and table written, and a second call reuses the finished runs
//! (same settings) instead of running them again.

use motile_experiments::campaign::onset::{OnsetOptions, onset};
use motile_particle::model::level::Hydrodynamics;

#[test]
fn a_tiny_scan_writes_its_chart_and_reuses_finished_runs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("onset");
    let opts = OnsetOptions {
        fractions: vec![5.0],
        box_nu: vec![15.0, 20.0],
        hydrodynamics: Hydrodynamics::Dipole,
        dt: 0.04,
        t_end_nu: 2.0,
        ..OnsetOptions::default()
    };
    let mut first = Vec::new();
    let points = onset(&opts, &out, |l| first.push(l.to_string())).unwrap();
    assert_eq!(points.len(), 2);
    assert_eq!((points[0].box_length, points[1].box_length), (3.0, 4.0));
    assert_eq!(points[1].rods, 320);
    for f in ["onset.png", "onset.svg", "onset.csv", "onset.md"] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let csv = std::fs::read_to_string(out.join("onset.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    assert!(
        first.iter().all(|l| !l.contains("done already")),
        "{first:?}"
    );
    let mut second = Vec::new();
    let again = onset(&opts, &out, |l| second.push(l.to_string())).unwrap();
    // One headline per point (detail lines such as the lowest modes are indented).
    let headlines: Vec<&String> = second.iter().filter(|l| !l.starts_with(' ')).collect();
    assert_eq!(headlines.len(), 2, "{second:?}");
    assert!(
        headlines.iter().all(|l| l.contains("done already")),
        "{second:?}"
    );
    assert_eq!(
        points.iter().map(|p| p.fit).collect::<Vec<_>>(),
        again.iter().map(|p| p.fit).collect::<Vec<_>>()
    );
}
