//! Correlation functions against exact answers: a single Fourier mode gives
//! `Corr(r) = (A^2/2) sin(kr)/(kr)`; `Corr(0)` is the mean square (Parseval); a random (Poisson)
//! configuration of N rods has the shot-noise spectrum `E|Phi~(k)|^2 = E|phi(p)|^2 / N`; the
//! velocity spectrum of a sinusoidal force density is the exact Stokes solution.

use motile_analysis::correlation::{
    CorrelationOptions, OrderParameter, ParticleSpectra, grid_coefficients, particle_coefficients,
    sampled_vector_coefficients, velocity_modes, velocity_spectrum,
};
use motile_analysis::nufft::direct_type1;
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

fn grid_field(n: usize, l: f64, f: impl Fn([f64; 3]) -> f64) -> Vec<f64> {
    let h = l / n as f64;
    (0..n * n * n)
        .map(|i| f([i % n, (i / n) % n, i / (n * n)].map(|j| j as f64 * h)))
        .collect()
}

#[test]
fn single_fourier_mode_gives_half_a_squared_sinc() {
    let (n, l, amp) = (48usize, 2.0, 1.7);
    let m = 2.0;
    let k = 2.0 * PI * m / l;
    // A plane wave along a diagonal-ish direction still has Corr = (A^2/2) sinc(|k| r).
    let field = grid_field(n, l, |x| amp * (k * x[0]).cos());
    let spec = grid_coefficients(&[&field], &[1.0], n, l, false);
    let corr = spec.correlation(None);
    let mean_sq = field.iter().map(|v| v * v).sum::<f64>() / field.len() as f64;
    assert!(
        (corr.at_zero() - mean_sq).abs() < 1e-11 * mean_sq,
        "Corr(0) = {} vs mean square {mean_sq}",
        corr.at_zero()
    );
    assert!((mean_sq - amp * amp / 2.0).abs() < 1e-11);
    // The spherical average of a band-limited correlation is a j0 sum: exact at every radius.
    assert!(
        corr.r.len() >= 65 && corr.r[64] <= l / 2.0,
        "{} radii",
        corr.r.len()
    );
    let mut worst: f64 = 0.0;
    for (r, c) in corr.r.iter().zip(&corr.value).skip(1) {
        let exact = amp * amp / 2.0 * (k * r).sin() / (k * r);
        let err = (c - exact).abs();
        worst = worst.max(err / (amp * amp / 2.0));
        assert!(
            err <= 1e-11 * amp * amp,
            "r = {r:.4}: Corr {c:.5} vs (A^2/2) sinc(kr) {exact:.5}: error {err:.2e}"
        );
    }
    eprintln!("single mode: worst relative error {worst:.3e}");
}

#[test]
fn corr_at_zero_is_the_mean_square_of_a_random_vector_field() {
    let n = 16;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let comps: Vec<Vec<f64>> = (0..3)
        .map(|_| {
            (0..n * n * n)
                .map(|_| rng.random_range(-1.0..1.0))
                .collect()
        })
        .collect();
    let refs: Vec<&[f64]> = comps.iter().map(|v| v.as_slice()).collect();
    let spec = grid_coefficients(&refs, &[1.0; 3], n, 1.0, false);
    let ms = comps
        .iter()
        .map(|c| c.iter().map(|v| v * v).sum::<f64>())
        .sum::<f64>()
        / (n * n * n) as f64;
    let c0 = spec.correlation(None).at_zero();
    assert!(
        (c0 - ms).abs() < 1e-12 * ms,
        "Corr(0) {c0} vs mean square {ms}"
    );
    assert!(
        (spec.l2_norm() - ms.sqrt()).abs() < 1e-12,
        "Parseval norm {} vs {}",
        spec.l2_norm(),
        ms.sqrt()
    );
    assert!((motile_analysis::stats::volume_l2_norm(&refs) - ms.sqrt()).abs() < 1e-14);
}

fn random_rods(n: usize, l: f64, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let x = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let p = (0..n)
        .map(|_| {
            let z: f64 = rng.random_range(-1.0..1.0);
            let phi: f64 = rng.random_range(0.0..2.0 * PI);
            let s = (1.0 - z * z).sqrt();
            [s * phi.cos(), s * phi.sin(), z]
        })
        .collect();
    (x, p)
}

#[test]
fn particle_coefficients_match_the_direct_sum() {
    let l = 10.0;
    let (x, p) = random_rods(500, l, 5);
    let opts = CorrelationOptions {
        modes: Some(8),
        ..Default::default()
    };
    let spec = particle_coefficients(&x, &p, l, OrderParameter::Polarity, &opts).unwrap();
    for d in 0..3 {
        let s: Vec<Complex64> = p
            .iter()
            .map(|q| Complex64::new(q[d] / x.len() as f64, 0.0))
            .collect();
        let exact = direct_type1(&x, l, &s, [8; 3]);
        let err = spec.components[d]
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        let scale = exact.iter().map(|b| b.norm()).fold(0.0, f64::max);
        assert!(
            err <= 10.0 * opts.tolerance * scale,
            "component {d}: max error {err:.2e} (scale {scale:.2e})"
        );
    }
}

/// One rod's value of an order parameter's component.
type Strength = Box<dyn Fn(&[f64; 3]) -> f64>;

/// One plan for c', n and Q, reused for a second configuration of another size: every
/// component against the direct sum of its strengths (relative L2 error within the NUFFT
/// tolerance), each spectrum the one-parameter call's to rounding, c' without its k = 0 mode.
#[test]
fn particle_spectra_share_one_plan_and_match_the_direct_sums() {
    let (l, modes) = (10.0, 8);
    let opts = CorrelationOptions {
        modes: Some(modes),
        ..Default::default()
    };
    let all = [
        OrderParameter::Concentration,
        OrderParameter::Polarity,
        OrderParameter::Nematic,
    ];
    let mut spectra = ParticleSpectra::new(modes, opts.tolerance).unwrap();
    for (n, seed) in [(500, 21), (1300, 22)] {
        let (x, p) = random_rods(n, l, seed);
        let got = spectra.of(&x, &p, l, &all).unwrap();
        for (which, spec) in all.iter().zip(&got) {
            let alone = particle_coefficients(&x, &p, l, *which, &opts).unwrap();
            // The same transforms but for the partner each real component shares a grid with:
            // equal to rounding.
            let diff = spec
                .components
                .iter()
                .flatten()
                .zip(alone.components.iter().flatten())
                .map(|(a, b)| (a - b).norm_sqr())
                .sum::<f64>()
                .sqrt();
            let norm = alone
                .components
                .iter()
                .flatten()
                .map(|b| b.norm_sqr())
                .sum::<f64>()
                .sqrt();
            assert!(
                diff <= 1e-13 * norm && spec.weights == alone.weights,
                "{which:?} at N = {n}: the shared plan's spectrum differs from the one-parameter \
                 call's by {:.1e} of its norm",
                diff / norm
            );
            let strengths: Vec<Strength> = match which {
                OrderParameter::Concentration => vec![Box::new(|_| 1.0)],
                OrderParameter::Polarity => (0..3)
                    .map(|d| Box::new(move |q: &[f64; 3]| q[d]) as Strength)
                    .collect(),
                OrderParameter::Nematic => motile_analysis::correlation::SYM_PAIRS
                    .iter()
                    .map(|&(i, j)| {
                        let iso = if i == j { 1.0 / 3.0 } else { 0.0 };
                        Box::new(move |q: &[f64; 3]| q[i] * q[j] - iso) as Strength
                    })
                    .collect(),
            };
            assert_eq!(spec.components.len(), strengths.len(), "{which:?}");
            for (c, f) in strengths.iter().enumerate() {
                let s: Vec<Complex64> = p
                    .iter()
                    .map(|q| Complex64::new(f(q) / n as f64, 0.0))
                    .collect();
                let mut exact = direct_type1(&x, l, &s, [modes; 3]);
                if *which == OrderParameter::Concentration {
                    let c = modes / 2; // k = 0 sits at the centre of the cube
                    exact[(c * modes + c) * modes + c] = Complex64::default();
                }
                let err = spec.components[c]
                    .iter()
                    .zip(&exact)
                    .map(|(a, b)| (a - b).norm_sqr())
                    .sum::<f64>()
                    .sqrt();
                let norm = exact.iter().map(|b| b.norm_sqr()).sum::<f64>().sqrt();
                assert!(
                    err <= opts.tolerance * norm,
                    "{which:?} component {c} at N = {n}: relative L2 error {:.2e} > {:.0e}",
                    err / norm,
                    opts.tolerance
                );
            }
        }
    }
    let (x, p) = random_rods(10, l, 23);
    assert!(
        spectra.of(&x, &p[..9], l, &all).is_err(),
        "9 orientations for 10 rods"
    );
}

/// Velocities as swimming rods have them (a swim speed along `p` plus a smaller flow part):
/// the sampled spectrum against the direct sums, relative L2 error per component within the
/// NUFFT tolerance (FINUFFT's definition); a length mismatch is an error.
#[test]
fn sampled_vector_coefficients_match_the_direct_sum() {
    let l = 12.0;
    let (x, p) = random_rods(700, l, 9);
    let v: Vec<[f64; 3]> = x
        .iter()
        .zip(&p)
        .map(|(y, q)| {
            let flow = [
                (y[1] * 0.5).sin(),
                (y[2] * 0.5).cos(),
                0.3 * (y[0] * 0.5).sin(),
            ];
            std::array::from_fn(|d| q[d] + 0.2 * flow[d])
        })
        .collect();
    for tol in [1e-3, 1e-6, 1e-9] {
        let opts = CorrelationOptions {
            modes: Some(10),
            tolerance: tol,
            ..Default::default()
        };
        let spec = sampled_vector_coefficients(&x, &v, l, &opts).unwrap();
        for d in 0..3 {
            let s: Vec<Complex64> = v
                .iter()
                .map(|q| Complex64::new(q[d] / x.len() as f64, 0.0))
                .collect();
            let exact = direct_type1(&x, l, &s, [10; 3]);
            let err: f64 = spec.components[d]
                .iter()
                .zip(&exact)
                .map(|(a, b)| (a - b).norm_sqr())
                .sum::<f64>()
                .sqrt();
            let scale: f64 = exact.iter().map(|b| b.norm_sqr()).sum::<f64>().sqrt();
            assert!(
                err <= tol * scale,
                "tol {tol:e}, component {d}: relative L2 error {:.2e}",
                err / scale
            );
        }
    }
    let short = &v[..10];
    assert!(sampled_vector_coefficients(&x, short, l, &CorrelationOptions::default()).is_err());
}

#[test]
fn random_configuration_has_the_shot_noise_spectrum() {
    // For N independent uniform rods, E|Phi~(k)|^2 = E|phi(p)|^2 / N at every k != 0 (and at k = 0
    // for the zero-mean polarity and nematic densities). The estimate sums ~K^3/2 independent
    // exponential variables (Phi~(-k) is the conjugate of Phi~(k)): relative standard deviation
    // sqrt(2 / K^3). We allow 5 standard deviations.
    let (n, l, k) = (20_000usize, 16.0, 8usize);
    let (x, p) = random_rods(n, l, 6);
    let opts = CorrelationOptions::default();
    assert_eq!(opts.modes_for(l), k);
    let modes = (k * k * k) as f64;
    let rel_sd = (2.0 / modes).sqrt();
    for (which, expected) in [
        (OrderParameter::Concentration, (modes - 1.0) / n as f64),
        (OrderParameter::Polarity, modes / n as f64),
        (OrderParameter::Nematic, modes * (2.0 / 3.0) / n as f64),
    ] {
        let spec = particle_coefficients(&x, &p, l, which, &opts).unwrap();
        let c0 = spec.correlation(None).at_zero();
        let rel = (c0 - expected) / expected;
        eprintln!(
            "{which:?}: Corr(0) = {c0:.4e}, shot noise {expected:.4e}, deviation {rel:+.3} ({:.1} sd)",
            rel / rel_sd
        );
        assert!(
            rel.abs() < 5.0 * rel_sd,
            "{which:?}: Corr(0) = {c0:.4e} vs shot noise {expected:.4e}: {rel:+.3} > 5 sd ({rel_sd:.3})"
        );
    }
}

#[test]
fn velocity_spectrum_of_a_sinusoidal_force_is_the_stokes_solution() {
    // Force density f(x) = F0 sin(2 pi x_2 / L) e_1, sampled as point forces f h^3 on an n^3 grid
    // (exact for this band-limited field): u = F0 / (mu k^2) sin(k x_2) e_1, so
    // ||u||_2 = F0 / (sqrt(2) mu k^2).
    let (n, l, f0, mu) = (12usize, 3.0, 0.8, 1.3);
    let h = l / n as f64;
    let k = 2.0 * PI / l;
    let mut y = Vec::new();
    let mut f = Vec::new();
    for i in 0..n * n * n {
        let x = [i % n, (i / n) % n, i / (n * n)].map(|j| j as f64 * h + 0.1 * h);
        y.push(x);
        f.push([f0 * (k * x[1]).sin() * h.powi(3), 0.0, 0.0]);
    }
    for tol in [1e-4, 1e-8] {
        let spec = velocity_spectrum(&y, &f, l, mu, 8, tol).unwrap();
        let exact = f0 / (2f64.sqrt() * mu * k * k);
        let norm = spec.l2_norm();
        assert!(
            (norm - exact).abs() <= 10.0 * tol * exact,
            "tol {tol:.0e}: ||u|| = {norm:.10} vs exact {exact:.10}"
        );
        assert!((spec.correlation(None).at_zero().sqrt() - norm).abs() < 1e-12);
    }
}

#[test]
fn spectrum_to_grid_is_the_inverse_transform_of_a_single_mode() {
    // Phi~(k) = A/2 at m = (1, 0, 2) and its conjugate mode: Phi(x) = A cos(2 pi (x + 2 z)/L).
    use motile_analysis::correlation::Spectrum;
    use motile_analysis::nufft::mode_of;
    let (n, l, a) = (8usize, 3.0, 0.7);
    let mut c = vec![Complex64::default(); n * n * n];
    for (idx, v) in c.iter_mut().enumerate() {
        let m = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| mode_of(i, n));
        if m == [1, 0, 2] || m == [-1, 0, -2] {
            *v = Complex64::new(a / 2.0, 0.0);
        }
    }
    let s = Spectrum {
        modes: n,
        box_length: l,
        components: vec![c],
        weights: vec![1.0],
    };
    let g = s.to_grid(0);
    let mut worst: f64 = 0.0;
    for (idx, v) in g.iter().enumerate() {
        let (x, z) = (
            (idx % n) as f64 * l / n as f64,
            (idx / (n * n)) as f64 * l / n as f64,
        );
        let exact = a * (2.0 * std::f64::consts::PI * (x + 2.0 * z) / l).cos();
        worst = worst.max((v - exact).abs());
    }
    assert!(worst < 1e-14, "worst error {worst:e}");
}

/// The direct modes are the spectrum's coefficients at those modes (to the NUFFT's tolerance),
/// on random points with force-free (swimmer-like) pairs of forces.
#[test]
fn direct_velocity_modes_are_the_spectrum_at_those_modes() {
    let (l, mu, modes) = (7.0, 1.0, 8usize);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut y = Vec::new();
    let mut f = Vec::new();
    for _ in 0..500 {
        let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(0.0..l));
        let p: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        y.push(x);
        f.push(p);
        y.push(std::array::from_fn(|d| x[d] + 0.3 * p[d]));
        f.push(p.map(|v| -v));
    }
    let spec = velocity_spectrum(&y, &f, l, mu, modes, 1e-10).unwrap();
    let wanted = [[1i64, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 2, 1]];
    let direct = velocity_modes(&y, &f, l, mu, &wanted);
    let half = (modes / 2) as i64;
    let scale = spec
        .components
        .iter()
        .flatten()
        .map(|c| c.norm())
        .fold(0.0, f64::max);
    for (m, u) in wanted.iter().zip(&direct) {
        let i = m.map(|c| (c + half) as usize);
        let idx = (i[2] * modes + i[1]) * modes + i[0];
        for d in 0..3 {
            let e = (u[d] - spec.components[d][idx]).norm();
            assert!(
                e < 1e-8 * scale,
                "mode {m:?} component {d}: {} vs {} ({e:.1e})",
                u[d],
                spec.components[d][idx]
            );
        }
    }
}

/// The run's time-series norms use the spectrum at 1e-4 (`experiments` `NORM_TOLERANCE`): on
/// force-free (swimmer-like) pairs, the L2 norm over all modes and over the box-scale modes
/// (every |m_i| <= 1) are within 1e-4 of the direct sums over every mode.
#[test]
fn the_norms_at_1e_4_match_the_direct_sums_on_force_free_pairs() {
    let (l, mu, modes, tol) = (7.0, 1.0, 8usize, 1e-4);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut y = Vec::new();
    let mut f = Vec::new();
    for _ in 0..800 {
        let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(0.0..l));
        let p: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        y.push(x);
        f.push(p);
        y.push(std::array::from_fn(|d| (x[d] + 0.5 * p[d]).rem_euclid(l)));
        f.push(p.map(|v| -v));
    }
    let spec = velocity_spectrum(&y, &f, l, mu, modes, tol).unwrap();
    let all: Vec<[i64; 3]> = (0..modes.pow(3))
        .map(|idx| {
            [idx % modes, (idx / modes) % modes, idx / (modes * modes)]
                .map(|i| motile_analysis::nufft::mode_of(i, modes))
        })
        .collect();
    let direct = velocity_modes(&y, &f, l, mu, &all);
    let power = |u: &[num_complex::Complex64; 3]| -> f64 {
        (0..3).map(|d| spec.weights[d] * u[d].norm_sqr()).sum()
    };
    let box_scale = |m: &[i64; 3]| m.iter().all(|c| c.abs() <= 1);
    let fast_power = spec.power();
    let (mut d_all, mut d_box, mut f_all, mut f_box) = (0.0, 0.0, 0.0, 0.0);
    for (k, (m, u)) in all.iter().zip(&direct).enumerate() {
        d_all += power(u);
        f_all += fast_power[k];
        if box_scale(m) {
            d_box += power(u);
            f_box += fast_power[k];
        }
    }
    for (what, fast, direct) in [("all modes", f_all, d_all), ("box scale", f_box, d_box)] {
        let e = (fast.sqrt() / direct.sqrt() - 1.0).abs();
        assert!(
            e <= tol,
            "{what}: norm {} against direct {} ({e:.1e})",
            fast.sqrt(),
            direct.sqrt()
        );
    }
}

/// The pair part of each order parameter's correlation against its direct twin: at every mode,
/// the sum over distinct pairs `(1/N^2) sum_{i != j} f_i . f_j cos(k.(x_i - x_j))` (for Q the
/// full contraction `Q_i : Q_j`, not the stored components' weights), radially averaged like
/// the correlation; the concentration's k = 0 mode left out.
#[test]
fn pair_correlations_match_the_direct_sum_over_distinct_pairs() {
    use motile_analysis::correlation::pair_correlation;
    use motile_analysis::nufft::mode_of;
    let (n, l, modes) = (40usize, 4.0, 6usize);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let x: Vec<[f64; 3]> = (0..n)
        .map(|_| [0; 3].map(|_| rng.random::<f64>() * l))
        .collect();
    let p: Vec<[f64; 3]> = (0..n)
        .map(|_| {
            let v = [0; 3].map(|_| rng.random::<f64>() - 0.5);
            let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
            v.map(|a| a / norm)
        })
        .collect();
    let q = |v: &[f64; 3], a: usize, b: usize| v[a] * v[b] - if a == b { 1.0 / 3.0 } else { 0.0 };
    let opts = CorrelationOptions {
        modes: Some(modes),
        shell_width: None,
        tolerance: 1e-10,
    };
    for which in [
        OrderParameter::Concentration,
        OrderParameter::Polarity,
        OrderParameter::Nematic,
    ] {
        let product = |i: usize, j: usize| -> f64 {
            match which {
                OrderParameter::Concentration => 1.0,
                OrderParameter::Polarity => (0..3).map(|a| p[i][a] * p[j][a]).sum(),
                OrderParameter::Nematic => (0..9)
                    .map(|ab| q(&p[i], ab / 3, ab % 3) * q(&p[j], ab / 3, ab % 3))
                    .sum(),
            }
        };
        let power: Vec<f64> = (0..modes.pow(3))
            .map(|idx| {
                let m = [idx % modes, (idx / modes) % modes, idx / (modes * modes)]
                    .map(|i| mode_of(i, modes) as f64);
                if which == OrderParameter::Concentration && m == [0.0; 3] {
                    return 0.0;
                }
                let mut sum = 0.0;
                for i in 0..n {
                    for j in (0..n).filter(|&j| j != i) {
                        let phase: f64 = (0..3).map(|a| m[a] * (x[i][a] - x[j][a])).sum();
                        sum += product(i, j) * (2.0 * PI * phase / l).cos();
                    }
                }
                sum / (n * n) as f64
            })
            .collect();
        let direct = motile_analysis::correlation::radial_autocorrelation(&power, modes, l, None);
        let spec = particle_coefficients(&x, &p, l, which, &opts).unwrap();
        let pair = pair_correlation(&spec, which, n, None);
        let full = spec.correlation(None);
        let scale = power.iter().map(|v| v.abs()).sum::<f64>();
        let worst = pair
            .value
            .iter()
            .zip(&direct.value)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "{which:?}: pair correlation vs direct pairs {:.2e} of {scale:.3e}",
            worst / scale
        );
        assert!(
            worst <= 1e-8 * scale,
            "{which:?}: pair correlation off the direct sum by {worst:.3e} (scale {scale:.3e})"
        );
        // The rods' own term is what separates the two at r = 0.
        let own = which.self_power() / n as f64;
        let counted = modes.pow(3) - usize::from(which == OrderParameter::Concentration);
        assert!(
            (full.at_zero() - pair.at_zero() - own * counted as f64).abs() <= 1e-8 * scale,
            "{which:?}: Corr(0) {} - pair(0) {} != own term {}",
            full.at_zero(),
            pair.at_zero(),
            own * counted as f64
        );
    }
}
