//! The NUFFT against its slow twin, the direct DFT: relative L2 error at or below the requested
//! tolerance for every tolerance from 1e-1 to 1e-12 (the contract: `NufftPlan::new`), type 2 as the adjoint of type 1, several
//! strength vectors at once, and bit-identical results for 1 and 2 threads.

use motile_analysis::nufft::{NufftPlan, direct_type1, direct_type2};
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const L: f64 = 3.7;

fn random_points(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Include points outside [0, L) to exercise the wrapping.
    (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(-L..2.0 * L)))
        .collect()
}

fn random_complex(n: usize, seed: u64) -> Vec<Complex64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
        .collect()
}

fn rel_l2(a: &[Complex64], b: &[Complex64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_sqr()).sum();
    let den: f64 = b.iter().map(|y| y.norm_sqr()).sum();
    (num / den).sqrt()
}

fn dot(a: &[Complex64], b: &[Complex64]) -> Complex64 {
    a.iter().zip(b).map(|(x, y)| x * y.conj()).sum()
}

/// The contract of `NufftPlan::new`: relative L2 error (over all modes for type 1, all points
/// for type 2) at most `tol`, from 1e-1 to 1e-12, for small and moderate mode counts (odd and
/// even, unequal per axis) and points outside the box.
#[test]
fn type1_and_type2_match_direct_dft_at_every_tolerance() {
    for (modes, n, seed) in [([12, 17, 10], 1500, 1), ([32, 37, 30], 800, 11)] {
        let pts = random_points(n, seed);
        let f = random_complex(pts.len(), seed + 1);
        let c = random_complex(modes.iter().product(), seed + 2);
        let exact1 = direct_type1(&pts, L, &f, modes);
        let exact2 = direct_type2(&pts, L, &c, modes);
        for e in 1..=12 {
            let tol = 10f64.powi(-e);
            let mut plan = NufftPlan::new(modes, tol).unwrap();
            plan.set_points(&pts, L).unwrap();
            let e1 = rel_l2(&plan.type1(&[&f]).unwrap()[0], &exact1);
            let e2 = rel_l2(&plan.type2(&[&c]).unwrap()[0], &exact2);
            eprintln!(
                "modes {modes:?}, tol {tol:.0e}: width {}, type-1 error {e1:.2e} ({:.2} tol), \
                 type-2 error {e2:.2e} ({:.2} tol)",
                plan.kernel_width(),
                e1 / tol,
                e2 / tol
            );
            assert!(
                e1 <= tol,
                "modes {modes:?}, type 1 at tol {tol:.0e}: relative L2 error {e1:.3e} = {:.2} tol",
                e1 / tol
            );
            assert!(
                e2 <= tol,
                "modes {modes:?}, type 2 at tol {tol:.0e}: relative L2 error {e2:.3e} = {:.2} tol",
                e2 / tol
            );
        }
    }
}

/// Real strengths two to a transform (`type1_real`): each vector's coefficients against its
/// direct sum within the tolerance, from 1e-1 to 1e-12, for odd and even mode counts (the even
/// ones' most negative mode has its partner only on the fine grid) and an odd number of
/// vectors (the last alone); the strengths of swimming rods' order parameters are real and
/// sum to zero (c' = c - 1 has no k = 0 mode, n and Q average to ~0), like the last vector.
#[test]
fn real_strengths_two_to_a_transform_match_the_direct_sums() {
    for (modes, n, seed) in [([12, 17, 10], 1500, 31), ([32, 37, 30], 800, 41)] {
        let pts = random_points(n, seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
        let mut real: Vec<Vec<f64>> = (0..4)
            .map(|_| (0..n).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        let mean = real[3].iter().sum::<f64>() / n as f64;
        real[3].iter_mut().for_each(|v| *v -= mean);
        let real = [&real[..], &[vec![1.0 / n as f64; n]]].concat();
        let exact: Vec<Vec<Complex64>> = real
            .iter()
            .map(|s| {
                let c: Vec<Complex64> = s.iter().map(|&v| Complex64::new(v, 0.0)).collect();
                direct_type1(&pts, L, &c, modes)
            })
            .collect();
        let refs: Vec<&[f64]> = real.iter().map(|v| v.as_slice()).collect();
        for e in 1..=12 {
            let tol = 10f64.powi(-e);
            let mut plan = NufftPlan::new(modes, tol).unwrap();
            plan.set_points(&pts, L).unwrap();
            let got = plan.type1_real(&refs).unwrap();
            assert_eq!(got.len(), real.len());
            let worst = got
                .iter()
                .zip(&exact)
                .map(|(g, x)| rel_l2(g, x))
                .fold(0.0, f64::max);
            eprintln!(
                "real pairs, modes {modes:?}, tol {tol:.0e}: worst relative L2 error {worst:.2e} \
                 ({:.2} tol)",
                worst / tol
            );
            assert!(
                worst <= tol,
                "modes {modes:?}, real pairs at tol {tol:.0e}: relative L2 error {worst:.3e} = \
                 {:.2} tol",
                worst / tol
            );
        }
        let short = vec![0.0; n - 1];
        let plan = {
            let mut p = NufftPlan::new(modes, 1e-6).unwrap();
            p.set_points(&pts, L).unwrap();
            p
        };
        assert!(
            plan.type1_real(&[&real[0], &short]).is_err(),
            "a short vector"
        );
    }
}

#[test]
fn type2_is_the_adjoint_of_type1() {
    let modes = [16, 16, 16];
    let pts = random_points(3000, 4);
    let f = random_complex(pts.len(), 5);
    let c = random_complex(modes.iter().product(), 6);
    for tol in [1e-3, 1e-6, 1e-9, 1e-12] {
        let mut plan = NufftPlan::new(modes, tol).unwrap();
        plan.set_points(&pts, L).unwrap();
        let f1 = &plan.type1(&[&f]).unwrap()[0];
        let f2 = &plan.type2(&[&c]).unwrap()[0];
        // <F1 f, c> over modes against <f, F2 c> over points.
        let lhs = dot(f1, &c);
        let rhs = dot(&f, f2);
        let scale = (f1.iter().map(|x| x.norm_sqr()).sum::<f64>()
            * c.iter().map(|x| x.norm_sqr()).sum::<f64>())
        .sqrt();
        let err = (lhs - rhs).norm() / scale;
        assert!(
            err <= tol,
            "adjoint mismatch at tol {tol:.0e}: |<F1 f, c> - <f, F2 c>| / (|F1 f||c|) = {err:.3e}"
        );
    }
}

#[test]
fn several_strength_vectors_equal_separate_calls() {
    let modes = [10, 12, 14];
    let pts = random_points(800, 7);
    let mut plan = NufftPlan::new(modes, 1e-8).unwrap();
    plan.set_points(&pts, L).unwrap();
    let vs: Vec<Vec<Complex64>> = (0..3).map(|s| random_complex(pts.len(), 10 + s)).collect();
    let together = plan.type1(&[&vs[0], &vs[1], &vs[2]]).unwrap();
    for (s, v) in vs.iter().enumerate() {
        assert_eq!(
            together[s],
            plan.type1(&[v]).unwrap()[0],
            "type 1, vector {s}"
        );
    }
    let cs: Vec<Vec<Complex64>> = (0..2)
        .map(|s| random_complex(plan.num_modes(), 20 + s))
        .collect();
    let together = plan.type2(&[&cs[0], &cs[1]]).unwrap();
    for (s, c) in cs.iter().enumerate() {
        assert_eq!(
            together[s],
            plan.type2(&[c]).unwrap()[0],
            "type 2, vector {s}"
        );
    }
}

#[test]
fn bit_identical_for_one_and_two_threads() {
    let modes = [32, 32, 32];
    let pts = random_points(20_000, 8);
    let f = random_complex(pts.len(), 9);
    let g = random_complex(pts.len(), 10);
    let c = random_complex(modes.iter().product(), 11);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut plan = NufftPlan::new(modes, 1e-6).unwrap();
            plan.set_points(&pts, L).unwrap();
            (plan.type1(&[&f, &g]).unwrap(), plan.type2(&[&c]).unwrap())
        })
    };
    let (a1, a2) = run(1);
    for threads in [2, 3] {
        let (b1, b2) = run(threads);
        assert!(a1 == b1, "type 1 differs between 1 and {threads} threads");
        assert!(a2 == b2, "type 2 differs between 1 and {threads} threads");
    }
}

#[test]
fn rejects_bad_input() {
    assert!(NufftPlan::new([8, 8, 8], 0.5).is_err());
    assert!(NufftPlan::new([8, 0, 8], 1e-6).is_err());
    let mut plan = NufftPlan::new([8, 8, 8], 1e-6).unwrap();
    assert!(plan.set_points(&[[0.0, f64::NAN, 0.0]], 1.0).is_err());
    assert!(plan.set_points(&[[0.0; 3]], 0.0).is_err());
    plan.set_points(&[[0.1; 3], [0.2; 3]], 1.0).unwrap();
    let err = plan.type1(&[&[Complex64::default(); 3]]).unwrap_err();
    assert_eq!(err.to_string(), "vector 0 has length 3, expected 2");
}
