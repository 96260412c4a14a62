//! One initial condition for both models (docs/MODEL.md §5): a particle configuration drawn from a
//! mean-field perturbation `Q'` (orientations from `Psi = (1 + (15/2) Q' : pp) / 4 pi`) carries
//! that `Q'` up to its sampling noise, and a mean-field state made from a particle snapshot
//! (its second-moment density smoothed onto the grid) carries the particles' `Q` with the
//! stated Gaussian damping. Checked mode by mode against the perturbation's own field.

use motile_experiments::io::snapshot::ParticleSnapshot;
use motile_experiments::run::meanfield::particle_state;
use motile_experiments::run::particle::{ParticleRunConfig, PerturbationConfig, initial_rods};
use motile_meanfield::initial::PerturbationField;
use motile_meanfield::solver::grid::SpectralGrid;
use std::f64::consts::PI;
use std::path::Path;

/// Coefficient differences between two fields, mode by mode (`b`'s coefficients damped by the
/// smoothing's Gaussian): the largest at the perturbation's modes (`|m| = 1`), the RMS over all
/// other modes, and the largest perturbation coefficient.
fn spectral_difference(
    a: &[Vec<f64>; 6],
    b: &[Vec<f64>; 6],
    n: usize,
    damp: f64,
) -> (f64, f64, f64) {
    let g = SpectralGrid::new(n);
    let (mut at_modes, mut rest2, mut count, mut peak): (f64, f64, usize, f64) = (0.0, 0.0, 0, 0.0);
    for c in 0..6 {
        let (ca, cb) = (g.forward(&a[c], false), g.forward(&b[c], false));
        for idx in 1..ca.len() {
            let m2 = g.k_squared(idx) / (4.0 * PI * PI);
            let f = (-2.0 * PI * PI * m2 * damp * damp).exp();
            let d = (ca[idx] - cb[idx] * f).norm();
            if (m2 - 1.0).abs() < 1e-9 {
                at_modes = at_modes.max(d);
                peak = peak.max((cb[idx] * f).norm());
            } else if m2 <= (n / 3).pow(2) as f64 {
                rest2 += d * d;
                count += 1;
            }
        }
    }
    (at_modes, (rest2 / count as f64).sqrt(), peak)
}

#[test]
fn both_models_start_from_the_same_field() {
    let perturbation = PerturbationConfig {
        amplitude: 0.05,
        mode_min: 1,
        mode_max: 1,
        seed: 4,
        ..PerturbationConfig::default()
    };
    let cfg = ParticleRunConfig {
        box_length: 25.0,
        volume_fraction: 2.56,
        initial: "perturbation".into(),
        perturbation: perturbation.clone(),
        ..ParticleRunConfig::default()
    };
    let rods = initial_rods(&cfg).unwrap();
    let n_rods = rods.len();
    assert_eq!(n_rods, 40_000);
    let snap = ParticleSnapshot {
        time: 0.0,
        step: 0,
        box_length: 25.0,
        positions: rods.x.clone(),
        orientations: rods.orientations(),
        image_counts: vec![[0; 3]; n_rods],
        forces: None,
        kinematics: None,
    };
    let n = 12;
    let field = PerturbationField::new(&perturbation.perturbation()).on_grid(n);
    // Sampling noise of one coefficient of (1/N) sum p_i p_j exp(-i k.x) (magnitude, RMS):
    // sqrt(<(p_i p_j)^2> / N), 1/5 for a diagonal component and 1/15 for an off-diagonal one of
    // an isotropic p; the RMS over the six components weighs them equally.
    let noise = ((3.0 * 0.2 + 3.0 / 15.0) / 6.0 / n_rods as f64).sqrt();
    for smoothing in [0.0, 0.05] {
        let q = particle_state(&snap, n, smoothing, Path::new("sampled")).unwrap();
        let (at_modes, rest, peak) = spectral_difference(&q, &field, n, smoothing);
        eprintln!(
            "smoothing {smoothing}: difference at the perturbation's modes up to {at_modes:.2e}, RMS elsewhere {rest:.2e}, expected noise {noise:.2e}; perturbation coefficients up to {peak:.2e}"
        );
        let expected_rest = noise * if smoothing > 0.0 { 0.75 } else { 1.0 };
        assert!(
            rest < 1.2 * noise && rest > 0.3 * expected_rest,
            "smoothing {smoothing}: away from the perturbation the particles' Q has RMS coefficients {rest:.2e}; sampling noise predicts {noise:.2e}"
        );
        assert!(
            at_modes < 4.0 * noise,
            "smoothing {smoothing}: at the perturbation's modes the particles' Q differs by {at_modes:.2e}, more than 4 times the sampling noise {noise:.2e}"
        );
        assert!(
            peak > 5.0 * noise && at_modes < 0.5 * peak,
            "the perturbation must stand out of the noise and be recovered: coefficients up to {peak:.2e}, off by up to {at_modes:.2e}"
        );
        // Concentration: mean 1.
        let c: f64 = (0..n * n * n)
            .map(|i| q[0][i] + q[3][i] + q[5][i])
            .sum::<f64>()
            / (n * n * n) as f64;
        assert!((c - 1.0).abs() < 1e-12, "mean concentration {c}");
    }
}
