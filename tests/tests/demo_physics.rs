//! The README's main job, in full (experiments/scenes/demo.toml, about 3 minutes on 2 cores):
//! both models above the instability from one initial condition, and what the comparison must
//! show (docs/MODEL.md §5, §6): a growth phase in each (grown at least 3x with R^2 >= 0.9), the
//! mean-field peak rate at the linear theory (M3), both saturated at the end, the same time window,
//! the mean-field run's state at its t_end, and correlations sampled at >= 32 radii.

use motile_experiments::campaign::demo::DemoSummary;
use motile_experiments::campaign::scene::{load_scene, run_scene};

#[test]
fn the_demo_grows_and_saturates_in_both_models_over_the_same_window() {
    let s = load_scene("demo").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    run_scene(&s, &out, &[], false, &mut |_| {}).unwrap();
    let d = DemoSummary::read(&out).unwrap();
    let lines = d.lines().join("\n");
    eprintln!("{lines}");
    let (p, p_phase) = d.particle.expect("a particle fit");
    let (m, m_phase) = d.meanfield.expect("a mean-field fit");
    assert!(
        p_phase && m_phase,
        "a growth phase in both models:\n{lines}"
    );
    // Its peak local rate is the linear theory's (the fit over the whole phase includes the bend
    // into saturation).
    let rel = (m.peak_rate - d.theory_rate).abs() / d.theory_rate;
    assert!(
        rel < 0.02,
        "mean-field peak rate {:.4} vs M3 {:.4}: rel {rel:.2e}\n{lines}",
        m.peak_rate,
        d.theory_rate
    );
    // The particle model grows more slowly (swimming decorrelates a box mode) but grows.
    assert!(
        p.peak_rate > 0.3 * d.theory_rate && p.peak_rate < 1.5 * d.theory_rate,
        "particle peak rate {:.4} vs M3 {:.4}\n{lines}",
        p.peak_rate,
        d.theory_rate
    );
    assert!(
        d.late_growth.0 < 1.25 && d.late_growth.1 < 1.25,
        "both saturated: growth over the last fifth {:?}\n{lines}",
        d.late_growth
    );
    assert!(
        (d.t_end.1 - d.meanfield_t_end_config).abs() < 1e-9,
        "the mean-field run's last output is at its t_end\n{lines}"
    );
    assert!(
        (d.t_end.0 - d.t_end.1).abs() < 0.01 * d.t_end.1,
        "the same window in mean-field units\n{lines}"
    );
    assert!(d.radial_points >= 32, "{lines}");
}
