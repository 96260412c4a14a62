//! The periodic Stokes sums of docs/MODEL.md §1-§2: the direct Ewald reference is checked on its
//! own (independence of the splitting parameter; agreement with explicit image sums where
//! those converge), then the spectral Ewald fast sum is checked against it at tolerances 1e-2
//! to 1e-8 and for thread-count independence (the full accuracy contract, on force-free and
//! sparse inputs too, is `tests/accuracy_contract.rs`).

use motile_particle::ewald::params::EwaldParams;
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::reference::EwaldReference;
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::model::geometry::{Vec3, dot, sub};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const A_RPY: f64 = 0.0866;

fn unit(rng: &mut ChaCha8Rng) -> Vec3 {
    loop {
        let v: Vec3 = [0, 1, 2].map(|_| rng.random_range(-1.0..1.0));
        let n = dot(v, v).sqrt();
        if n > 0.1 && n < 1.0 {
            return v.map(|c| c / n);
        }
    }
}

/// Quadrature points of `n` random rods (4 per rod, at s = +-0.394, +-0.106) and random forces.
fn rods(n: usize, l: f64, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let s = [-0.394337567, -0.105662433, 0.105662433, 0.394337567];
    let mut y = Vec::new();
    let mut f = Vec::new();
    for _ in 0..n {
        let x: Vec3 = [0, 1, 2].map(|_| rng.random_range(0.0..l));
        let p = unit(&mut rng);
        for sj in s {
            y.push([0, 1, 2].map(|d| x[d] + sj * p[d]));
            f.push([0, 1, 2].map(|_| rng.random_range(-1.0..1.0)));
        }
    }
    (y, f)
}

fn rel_l2(a: &[Vec3], b: &[Vec3]) -> f64 {
    let num: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| dot(sub(*x, *y), sub(*x, *y)))
        .sum();
    let den: f64 = b.iter().map(|y| dot(*y, *y)).sum();
    (num / den).sqrt()
}

#[test]
fn reference_does_not_depend_on_the_splitting_parameter() {
    let l = 4.0;
    let (y, f) = rods(40, l, 1);
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let base = EwaldReference::with_xi(2.5).rpy(&geo, &y, &f).unwrap();
    for xi in [1.2, 4.0] {
        let other = EwaldReference::with_xi(xi).rpy(&geo, &y, &f).unwrap();
        let e = rel_l2(&other, &base);
        assert!(
            e < 1e-12,
            "RPY: xi {xi} vs 2.5: relative L2 difference {e:e}"
        );
    }
    // Stresslets.
    let x: Vec<Vec3> = y.iter().step_by(4).copied().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let p: Vec<Vec3> = x.iter().map(|_| unit(&mut rng)).collect();
    let sigma: Vec<f64> = x.iter().map(|_| rng.random_range(0.5..1.5)).collect();
    let base = EwaldReference::with_xi(2.5)
        .stresslets(l, &x, &p, &sigma)
        .unwrap();
    for xi in [1.2, 4.0] {
        let o = EwaldReference::with_xi(xi)
            .stresslets(l, &x, &p, &sigma)
            .unwrap();
        let eu = rel_l2(&o.u, &base.u);
        let flat = |g: &[[Vec3; 3]]| g.iter().flat_map(|m| m.iter().copied()).collect::<Vec<_>>();
        let eg = rel_l2(&flat(&o.grad), &flat(&base.grad));
        assert!(
            eu < 1e-12 && eg < 1e-12,
            "stresslets: xi {xi}: u diff {eu:e}, grad diff {eg:e}"
        );
    }
}

/// Explicit sum over the periodic images within radius `r_max` (spherical order) of the far-form
/// RPY tensor, own point's image 0 excluded.
fn image_sum(y: &[Vec3], f: &[Vec3], l: f64, r_max: f64, t: usize) -> Vec3 {
    let nmax = (r_max / l).ceil() as i64;
    let mut u = [0.0; 3];
    for n2 in -nmax..=nmax {
        for n1 in -nmax..=nmax {
            for n0 in -nmax..=nmax {
                let sh = [n0, n1, n2].map(|c| c as f64 * l);
                if dot(sh, sh) > r_max * r_max {
                    continue;
                }
                for (j, (yj, fj)) in y.iter().zip(f).enumerate() {
                    if j == t && n0 == 0 && n1 == 0 && n2 == 0 {
                        continue;
                    }
                    let r = [0, 1, 2].map(|d| y[t][d] - yj[d] - sh[d]);
                    let rn = dot(r, r).sqrt();
                    let (a, b) = motile_particle::ewald::kernels::rpy(rn, A_RPY);
                    let v =
                        motile_particle::ewald::kernels::apply_radial(a, b, r.map(|c| c / rn), *fj);
                    for d in 0..3 {
                        u[d] += v[d];
                    }
                }
            }
        }
    }
    u
}

#[test]
fn reference_agrees_with_explicit_image_sums_of_a_neutral_distribution() {
    // Blocks of four points with forces (f, f, -f, -f) at (c+d, c-d, c+e, c-e): zero net force
    // and zero first moment, so velocity differences converge absolutely over image shells.
    let l = 2.0;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut y, mut f) = (Vec::new(), Vec::new());
    for _ in 0..3 {
        let c: Vec3 = [0, 1, 2].map(|_| rng.random_range(0.0..l));
        let d: Vec3 = [0, 1, 2].map(|_| rng.random_range(-0.4..0.4));
        let e: Vec3 = [0, 1, 2].map(|_| rng.random_range(-0.4..0.4));
        let fv: Vec3 = [0, 1, 2].map(|_| rng.random_range(-1.0..1.0));
        for (sgn, v) in [(1.0, d), (-1.0, d)] {
            y.push([0, 1, 2].map(|k| c[k] + sgn * v[k]));
            f.push(fv);
        }
        for (sgn, v) in [(1.0, e), (-1.0, e)] {
            y.push([0, 1, 2].map(|k| c[k] + sgn * v[k]));
            f.push(fv.map(|c| -c));
        }
    }
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 1,
    };
    let ewald = EwaldReference::default().rpy(&geo, &y, &f).unwrap();
    let diff = |u: &[Vec3], t: usize| sub(u[t], u[0]);
    let mut errors = Vec::new();
    for r_max in [10.0 * l, 20.0 * l, 40.0 * l] {
        let img: Vec<Vec3> = (0..y.len())
            .map(|t| image_sum(&y, &f, l, r_max, t))
            .collect();
        let (mut num, mut den) = (0.0, 0.0);
        for t in 1..y.len() {
            let a = diff(&img, t);
            let b = diff(&ewald, t);
            num += dot(sub(a, b), sub(a, b));
            den += dot(b, b);
        }
        errors.push((num / den).sqrt());
    }
    eprintln!("image sums, R = 10, 20, 40 L: relative errors {errors:?}");
    // Tail of a 1/r^5 field over shells: error ~ R^-2, so each doubling divides it by ~4.
    assert!(
        errors[2] < 2e-4 && errors[0] / errors[2] > 8.0,
        "relative error of velocity differences at R = 10, 20, 40 L: {errors:?}"
    );
}

#[test]
fn fast_rpy_sum_meets_the_requested_tolerance() {
    let mut report = Vec::new();
    for &(nrods, l) in &[(250usize, 7.4), (2500, 15.9)] {
        let (y, f) = rods(nrods, l, 7);
        let geo = RpyGeometry {
            box_length: l,
            radius: A_RPY,
            group: 4,
        };
        let targets: Vec<usize> = (0..y.len()).step_by(y.len() / 300).collect();
        let reference = EwaldReference::default()
            .rpy_at(&geo, &y, &f, &targets)
            .unwrap();
        for tol in [1e-2, 1e-4, 1e-6, 1e-8] {
            let mut fast = SpectralEwald::new(tol).unwrap();
            let u = fast.rpy(&geo, &y, &f).unwrap();
            let sub_u: Vec<Vec3> = targets.iter().map(|&t| u[t]).collect();
            let e = rel_l2(&sub_u, &reference);
            report.push(format!(
                "N {} tol {tol:e}: error {e:.2e} ({:?})",
                y.len(),
                fast.last_params().unwrap()
            ));
            assert!(
                e <= tol,
                "N = {}, tol {tol:e}: relative L2 error {e:.3e}\n{}",
                y.len(),
                report.join("\n")
            );
        }
    }
    eprintln!("{}", report.join("\n"));
}

#[test]
fn fast_stresslet_sum_meets_the_requested_tolerance() {
    let l = 9.0;
    let (y, _) = rods(600, l, 11);
    let x: Vec<Vec3> = y
        .iter()
        .step_by(4)
        .map(|c| c.map(|v| v.rem_euclid(l)))
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let p: Vec<Vec3> = x.iter().map(|_| unit(&mut rng)).collect();
    let sigma = vec![0.85; x.len()];
    let reference = EwaldReference::default()
        .stresslets(l, &x, &p, &sigma)
        .unwrap();
    let flat = |g: &[[Vec3; 3]]| g.iter().flat_map(|m| m.iter().copied()).collect::<Vec<_>>();
    for tol in [1e-2, 1e-4, 1e-6, 1e-8] {
        let fast = SpectralEwald::new(tol)
            .unwrap()
            .stresslets(l, &x, &p, &sigma)
            .unwrap();
        let eu = rel_l2(&fast.u, &reference.u);
        let eg = rel_l2(&flat(&fast.grad), &flat(&reference.grad));
        assert!(
            eu <= tol && eg <= tol,
            "tol {tol:e}: velocity error {eu:.3e}, gradient error {eg:.3e}"
        );
    }
}

#[test]
fn fast_sums_are_bit_identical_for_one_two_and_three_threads() {
    let l = 10.0;
    let (y, f) = rods(1500, l, 21);
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let p: Vec<Vec3> = f
        .iter()
        .map(|v| {
            let n = dot(*v, *v).sqrt();
            v.map(|c| c / n)
        })
        .collect();
    let sigma = vec![0.85; y.len()];
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let u = SpectralEwald::new(1e-6).unwrap().rpy(&geo, &y, &f).unwrap();
            let s = SpectralEwald::new(1e-6)
                .unwrap()
                .stresslets(l, &y, &p, &sigma)
                .unwrap();
            (u, s.u, s.grad)
        })
    };
    let one = run(1);
    for threads in [2, 3] {
        assert!(run(threads) == one, "1 and {threads} threads differ");
    }
    // Swimming rods: force-free, so the sum refines; the decisions are deterministic too.
    let (s, w) = motile_particle::hydro::slender::half_rod_rule(4, 1.0);
    let swim: Vec<Vec3> = (0..y.len())
        .map(|k| {
            let (n, j) = (k / 4, k % 4);
            let q = p[4 * n];
            q.map(|c| c * s[j].signum() * w[j])
        })
        .collect();
    let points: Vec<Vec3> = (0..y.len())
        .map(|k| {
            let (n, j) = (k / 4, k % 4);
            [0, 1, 2].map(|d| y[4 * n][d] + s[j] * p[4 * n][d])
        })
        .collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut sum = SpectralEwald::new(1e-4).unwrap();
            let u = sum.rpy(&geo, &points, &swim).unwrap();
            (u, sum.last_report().unwrap())
        })
    };
    let (u1, r1) = run(1);
    assert!(r1.level > 0, "swimming rods should refine: {r1:?}");
    for threads in [2, 3] {
        let (u, r) = run(threads);
        assert!(
            u == u1 && r == r1,
            "swimming rods: 1 and {threads} threads differ"
        );
    }
}

/// The refinement level stays for the next sum (the products of one GMRES solve): a second
/// sum at the same force-free data takes one attempt at the level the first one reached, and
/// the adaptive state round-trips (what a checkpoint saves).
#[test]
fn the_refinement_level_carries_over_to_the_next_sum() {
    let l = 8.0;
    let (s, w) = motile_particle::hydro::slender::half_rod_rule(4, 1.0);
    let mut rng = ChaCha8Rng::seed_from_u64(71);
    let (mut y, mut f) = (Vec::new(), Vec::new());
    for _ in 0..200 {
        let x: Vec3 = [0, 1, 2].map(|_| rng.random_range(0.0..l));
        let q = unit(&mut rng);
        for (sj, wj) in s.iter().zip(&w) {
            y.push([0, 1, 2].map(|d| x[d] + sj * q[d]));
            f.push(q.map(|c| c * sj.signum() * wj));
        }
    }
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let mut sum = SpectralEwald::new(1e-4).unwrap();
    let first = sum.rpy(&geo, &y, &f).unwrap();
    let r1 = sum.last_report().unwrap();
    assert!(r1.attempts > 1 && r1.met, "first sum: {r1:?}");
    let again = sum.rpy(&geo, &y, &f).unwrap();
    let r2 = sum.last_report().unwrap();
    assert!(
        r2.attempts == 1 && r2.level == r1.level && again == first,
        "second sum: {r2:?}"
    );
    let state = sum.adaptive_state();
    let mut fresh = SpectralEwald::new(1e-4).unwrap();
    fresh.set_adaptive_state(&state);
    assert!(
        fresh.rpy(&geo, &y, &f).unwrap() == first && fresh.last_report().unwrap().attempts == 1,
        "restored state {state:?}"
    );
}

/// A sum at the points of the previous sum reuses their preparation (sorted points, windows,
/// cell list); the result must not depend on it: the same as a fresh sum, bit for bit, also
/// after a sum at other points or with other forces in between.
#[test]
fn repeated_sums_at_the_same_points_match_fresh_sums() {
    let l = 9.0;
    let (y, f) = rods(800, l, 31);
    let (y2, f2) = rods(800, l, 32);
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let fresh = |y: &[Vec3], f: &[Vec3]| SpectralEwald::new(1e-5).unwrap().rpy(&geo, y, f).unwrap();
    let mut sum = SpectralEwald::new(1e-5).unwrap();
    let first = sum.rpy(&geo, &y, &f).unwrap();
    assert!(first == fresh(&y, &f), "first sum");
    assert!(
        sum.rpy(&geo, &y, &f2).unwrap() == fresh(&y, &f2),
        "same points, other forces"
    );
    assert!(
        sum.rpy(&geo, &y2, &f).unwrap() == fresh(&y2, &f),
        "other points"
    );
    assert!(
        sum.rpy(&geo, &y, &f).unwrap() == first,
        "back to the first points"
    );
}

#[test]
fn a_non_finite_point_is_refused_with_its_index() {
    let l = 6.0;
    let (mut y, f) = rods(100, l, 41);
    y[37][1] = f64::NAN;
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let err = SpectralEwald::new(1e-4)
        .unwrap()
        .rpy(&geo, &y, &f)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("point 37") && err.contains("non-finite"),
        "{err}"
    );
}

/// A coordinate just below 0 wraps to L by rounding: the point must still keep its real-space
/// neighbours (it used to be filed in the last cell while stored at 0, about L from its
/// neighbours, and lost every real-space pair). Moving a point from 0 to -1e-16 may change the
/// result by round-off only.
#[test]
fn a_point_just_below_zero_keeps_its_neighbours() {
    let l = 10.0;
    let mut y: Vec<Vec3> = vec![
        [0.0, 5.0, 5.0],
        [0.3, 5.0, 5.1],
        [l - 0.3, 5.1, 5.0],
        [2.0, 2.0, 2.0],
        [7.0, 1.0, 3.0],
        [4.0, 8.0, 6.0],
    ];
    let f: Vec<Vec3> = (0..6)
        .map(|i| [1.0 - 0.3 * i as f64, 0.5, -0.2 * i as f64])
        .collect();
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 1,
    };
    let mut sum = SpectralEwald::new(1e-6).unwrap();
    // Many cells per axis, so the point's cell matters.
    sum.fixed = Some(EwaldParams::choose(1e-6, 200_000, l));
    let at_zero = sum.rpy(&geo, &y, &f).unwrap();
    y[0][0] = -1e-16;
    let below = sum.rpy(&geo, &y, &f).unwrap();
    let scale = at_zero
        .iter()
        .flatten()
        .map(|v| v.abs())
        .fold(0.0, f64::max);
    let diff = at_zero
        .iter()
        .zip(&below)
        .flat_map(|(a, b)| (0..3).map(move |d| (a[d] - b[d]).abs()))
        .fold(0.0, f64::max);
    assert!(
        diff <= 1e-12 * scale,
        "moving a point from 0 to -1e-16 changed the velocities by {diff:e} (scale {scale:e})"
    );
}

/// Two coincident points (different groups) give finite velocities: such a pair has no
/// direction and is left out of the real-space sum, as it always was.
#[test]
fn coincident_points_give_finite_velocities() {
    let l = 8.0;
    let (mut y, f) = rods(200, l, 51);
    y[10] = y[50];
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 1,
    };
    let u = SpectralEwald::new(1e-6).unwrap().rpy(&geo, &y, &f).unwrap();
    assert!(
        u.iter().flatten().all(|v| v.is_finite()),
        "non-finite velocities: {:?} {:?}",
        u[10],
        u[50]
    );
}

/// Points far outside the box (whole box lengths away, up to 1e19) are their periodic images:
/// finite velocities, equal to those of the wrapped points up to the round-off of wrapping.
#[test]
fn points_far_outside_the_box_are_their_images() {
    let l = 6.0;
    let (y, f) = rods(100, l, 61);
    let wrapped: Vec<Vec3> = y.iter().map(|p| p.map(|c| c.rem_euclid(l))).collect();
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 1,
    };
    let base = SpectralEwald::new(1e-6)
        .unwrap()
        .rpy(&geo, &wrapped, &f)
        .unwrap();
    let scale = base.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    for shift in [3.0 * l, -1e6 * l] {
        let mut far = wrapped.clone();
        far[7][0] += shift;
        let u = SpectralEwald::new(1e-6)
            .unwrap()
            .rpy(&geo, &far, &f)
            .unwrap();
        let diff = u
            .iter()
            .zip(&base)
            .flat_map(|(a, b)| (0..3).map(move |d| (a[d] - b[d]).abs()))
            .fold(0.0, f64::max);
        assert!(
            diff <= 1e-8 * scale,
            "shift {shift:e}: velocities moved by {diff:e}"
        );
    }
    let mut huge = wrapped.clone();
    huge[7][0] = 1e19;
    let u = SpectralEwald::new(1e-6)
        .unwrap()
        .rpy(&geo, &huge, &f)
        .unwrap();
    assert!(u.iter().flatten().all(|v| v.is_finite()), "a point at 1e19");
}
