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
