//! Library parameter structs own their defaults and their checks: every default passes its
//! own `validate()`, and a bad value is named with its range and unit, the message the command
//! line reports under the config's key.

use motile_meanfield::control::StepControl;
use motile_meanfield::solver::params::MeanFieldParams;
use motile_particle::hydro::gmres::GmresParams;
use motile_particle::hydro::slender::SlenderParams;
use motile_particle::step::contact::ContactParams;

#[test]
fn library_defaults_pass_their_own_checks() {
    ContactParams::default().validate().unwrap();
    GmresParams::default().validate().unwrap();
    SlenderParams::default().validate().unwrap();
    MeanFieldParams::default().validate().unwrap();
    StepControl::default().validate().unwrap();
}

#[test]
fn bad_values_are_named_with_range_and_unit() {
    let e = ContactParams {
        margin: 2.0,
        ..Default::default()
    }
    .validate()
    .unwrap_err();
    assert_eq!(
        e.in_table("contact").to_string(),
        "contact.margin = 2 is outside the allowed range (0, 1] (rod lengths)"
    );
    let mut s = SlenderParams::default();
    s.gmres.restart = 0;
    assert_eq!(
        s.validate().unwrap_err().to_string(),
        "gmres.restart = 0 is outside the allowed range [1, 1000] (iterations)"
    );
    s = SlenderParams {
        quadrature_points: 5,
        ..Default::default()
    };
    assert!(
        s.validate()
            .unwrap_err()
            .to_string()
            .contains("must be even")
    );
    let e = MeanFieldParams {
        zeta: -1.0,
        ..Default::default()
    }
    .validate()
    .unwrap_err();
    assert_eq!(e.name, "zeta");
    let e = StepControl {
        max_step_ratio: 3.0,
        ..Default::default()
    }
    .validate()
    .unwrap_err();
    assert!(e.to_string().contains("zero-stable"), "{e}");
}

/// A default never contradicts the values the user wrote: output intervals and the contact
/// margin left out follow `dt`, the perturbation's largest mode left out follows the grid; the
/// same values written out are still refused, by name.
#[test]
fn defaults_follow_the_values_given() {
    use motile_experiments::run::meanfield::parse_config as mf;
    use motile_experiments::run::particle::parse_config as particle;
    let p = std::path::Path::new("cfg.toml");
    let c = particle("dt = 0.05\nbox_length = 6\n", p).unwrap();
    assert_eq!(
        (
            c.diagnostic_interval,
            c.snapshot_interval,
            c.checkpoint_interval
        ),
        (0.05, 0.2, 0.5)
    );
    assert!(
        (c.contact.margin - 0.125).abs() < 1e-15,
        "{}",
        c.contact.margin
    );
    let small = particle("dt = 0.001\nbox_length = 6\n", p).unwrap();
    assert_eq!(
        (small.diagnostic_interval, small.contact.margin),
        (0.02, ContactParams::default().margin)
    );
    let err = particle("dt = 0.05\ndiagnostic_interval = 0.02\n", p).unwrap_err();
    assert!(
        format!("{err:#}").contains("diagnostic_interval = 0.02"),
        "{err:#}"
    );
    let err = particle("dt = 0.05\n[contact]\nmargin = 0.1\n", p).unwrap_err();
    assert!(
        format!("{err:#}").contains("contact.margin = 0.1"),
        "{err:#}"
    );
    let m = mf("grid = 8\n", p).unwrap();
    assert_eq!((m.mode_min, m.mode_max), (1, 2));
    let err = mf("grid = 8\nmode_max = 4\n", p).unwrap_err();
    assert!(format!("{err:#}").contains("mode_max = 4"), "{err:#}");
}
