//! The slender-body model (docs/MODEL.md §1) and its far-field limit (§2) against exact answers:
//! an isolated rod swims at U along p and turns only through its periodic images, at a rate
//! that falls like (l/L)^3; the force density solving (P4) carries zero net force and torque,
//! meets the GMRES tolerance and does not move with the fast-sum tolerance beyond it; GMRES
//! needs fewer than 20 iterations at nu = 0.625 and 5; two distant rods move as the dipole
//! model says, with a difference that falls like d^-4; quadrature convergence in M; bit-identical
//! results for 1 and 2 threads.

use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::gmres::GmresParams;
use motile_particle::hydro::mobility::{Mobility, RodVelocities};
use motile_particle::hydro::slender::{SlenderBody, SlenderParams};
use motile_particle::model::geometry::{Vec3, cross, dot, norm, quat_from_axis, sub};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::DEFAULT_DIAMETER;

fn rods(box_length: f64, x: Vec<Vec3>, p: Vec<Vec3>) -> RodSet {
    let n = x.len();
    RodSet {
        box_length,
        diameter: DEFAULT_DIAMETER,
        x,
        q: p.iter().map(|p| quat_from_axis(*p)).collect(),
        image: vec![[0; 3]; n],
    }
}

fn sbt(m: usize, sum_tol: f64, gmres_tol: f64) -> SlenderBody {
    SlenderBody::new(
        SlenderParams {
            quadrature_points: m,
            gmres: GmresParams {
                tol: gmres_tol,
                ..GmresParams::default()
            },
            ..SlenderParams::default()
        },
        Box::new(SpectralEwald::new(sum_tol).unwrap()),
    )
}

fn free(mob: &mut dyn Mobility, r: &RodSet) -> RodVelocities {
    let p = r.orientations();
    let mut out = RodVelocities::zeros(r.len());
    mob.free_velocities(r, &p, &mut out).unwrap();
    out
}

fn unit(v: Vec3) -> Vec3 {
    let n = norm(v);
    v.map(|c| c / n)
}

#[test]
fn isolated_rod_swims_at_u_and_turns_only_through_images_like_l_over_l_cubed() {
    let p = unit([0.36, -0.48, 0.8]);
    let mut spins = Vec::new();
    for l in [4.0, 8.0, 16.0] {
        let r = rods(l, vec![[0.3 * l, 0.6 * l, 0.1 * l]], vec![p]);
        let mut mob = sbt(4, 1e-10, 1e-12);
        let v = free(&mut mob, &r);
        let dv = norm(sub(v.v[0], p));
        assert!(dv < 1e-9, "L = {l}: |v - U p| = {dv:e} (zero by symmetry)");
        spins.push(norm(v.w[0]));
        let rep = mob.report();
        assert!(
            rep.gmres_residual <= 1e-12,
            "residual {:e}",
            rep.gmres_residual
        );
    }
    let (r1, r2) = (spins[0] / spins[1], spins[1] / spins[2]);
    eprintln!("isolated rod: |w| at L = 4, 8, 16: {spins:?}; ratios {r1:.3} {r2:.3}");
    assert!(
        (r1 - 8.0).abs() < 0.5 && (r2 - 8.0).abs() < 0.1,
        "image rotation should fall like L^-3: |w| = {spins:?}, ratios {r1}, {r2}"
    );
}

/// Net force and torque of each rod's discrete force density.
fn net_force_torque(mob: &SlenderBody, r: &RodSet) -> (f64, f64) {
    let fd = mob.force_density().unwrap();
    let m = fd.s.len();
    let p = r.orientations();
    let (mut fmax, mut tmax) = (0.0f64, 0.0f64);
    for n in 0..r.len() {
        let (mut f, mut t) = ([0.0; 3], [0.0; 3]);
        for j in 0..m {
            let fj = fd.f[n * m + j];
            let tj = cross(p[n].map(|c| c * fd.s[j]), fj);
            for d in 0..3 {
                f[d] += fd.w[j] * fj[d];
                t[d] += fd.w[j] * tj[d];
            }
        }
        fmax = fmax.max(norm(f));
        tmax = tmax.max(norm(t));
    }
    (fmax, tmax)
}

#[test]
fn force_density_is_force_and_torque_free_and_stable_under_the_sum_tolerance() {
    let r = random_nonoverlapping(625, 10.0, DEFAULT_DIAMETER, 5, 1000).unwrap();
    let f0 = motile_particle::model::units::SWIM_SPEED
        / (2.0 * motile_particle::model::units::eta(DEFAULT_DIAMETER));
    let mut reference = sbt(4, 1e-10, 1e-11);
    free(&mut reference, &r);
    let fref: Vec<Vec3> = reference.force_density().unwrap().f.to_vec();
    let (fm, tm) = net_force_torque(&reference, &r);
    assert!(
        fm < 1e-9 * f0 && tm < 1e-9 * f0,
        "net force {fm:e}, torque {tm:e} (f0 = {f0})"
    );
    let mut table = Vec::new();
    for tol in [1e-3, 1e-5, 1e-7] {
        let mut mob = sbt(4, tol, 1e-9);
        free(&mut mob, &r);
        let rep = mob.report();
        assert!(
            rep.gmres_residual <= 1e-9,
            "GMRES residual {:e}",
            rep.gmres_residual
        );
        let f = mob.force_density().unwrap().f;
        let num: f64 = f
            .iter()
            .zip(&fref)
            .map(|(a, b)| dot(sub(*a, *b), sub(*a, *b)))
            .sum();
        let den: f64 = fref.iter().map(|b| dot(*b, *b)).sum();
        let e = (num / den).sqrt();
        table.push((tol, e, rep.gmres_iterations));
        assert!(
            e <= tol,
            "sum tol {tol:e}: force density moved by {e:.3e} relative to the 1e-10 solve"
        );
    }
    eprintln!("(sum tol, change of f, iterations): {table:?}");
}

#[test]
fn gmres_needs_fewer_than_twenty_iterations_at_nu_0625_and_5() {
    for (nu, l) in [(0.625, 12.0), (5.0, 8.0)] {
        let n = (nu * l * l * l) as usize;
        let r = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 9, 100_000).unwrap();
        let mut mob = sbt(4, 1e-6, 1e-6);
        free(&mut mob, &r);
        let rep = mob.report();
        eprintln!(
            "nu = {nu}, {n} rods: {} GMRES iterations, residual {:.2e}",
            rep.gmres_iterations, rep.gmres_residual
        );
        assert!(
            rep.gmres_iterations < 20,
            "nu = {nu}: {} iterations",
            rep.gmres_iterations
        );
        // Pinned (deterministic for these seeds and any thread count): a change here means the
        // operator, the sums or GMRES changed behaviour; update the pin only knowingly.
        let pinned = if nu < 1.0 { 5 } else { 7 };
        assert_eq!(
            rep.gmres_iterations, pinned,
            "nu = {nu}: GMRES iterations changed"
        );
        assert!(rep.gmres_residual <= 1e-6);
        // Warm start from the previous solution at the same configuration: at most one iteration.
        free(&mut mob, &r);
        assert!(
            mob.report().gmres_iterations <= 1,
            "warm start took {} iterations",
            mob.report().gmres_iterations
        );
    }
}

#[test]
fn two_distant_rods_approach_the_dipole_model_like_d_to_the_minus_four() {
    let l = 64.0;
    let p1 = unit([1.0, 0.4, -0.3]);
    let p2 = unit([-0.2, 1.0, 0.5]);
    let dir = unit([0.3, 0.5, 0.81]);
    let mut rows = Vec::new();
    for d in [3.0, 6.0, 12.0] {
        let c = [20.0, 20.0, 20.0];
        let x2 = [0, 1, 2].map(|k| c[k] + d * dir[k]);
        let r = rods(l, vec![c, x2], vec![p1, p2]);
        let vs = free(&mut sbt(8, 1e-10, 1e-12), &r);
        let mut dip = Dipole::new(
            Box::new(SpectralEwald::new(1e-10).unwrap()),
            DEFAULT_DIAMETER,
        );
        let vd = free(&mut dip, &r);
        let induced = norm(sub(vs.v[0], p1));
        let dv = norm(sub(vs.v[0], vd.v[0]));
        let dw = norm(sub(vs.w[0], vd.w[0]));
        rows.push((d, induced, dv, norm(vs.w[0]), dw));
    }
    eprintln!("(d, |v - Up| sbt, |v_sbt - v_dip|, |w| sbt, |w_sbt - w_dip|):");
    for r in &rows {
        eprintln!("  {r:?}");
    }
    for k in 0..2 {
        let (a, b) = (rows[k], rows[k + 1]);
        let ratio_v = a.2 / b.2;
        let ratio_w = a.4 / b.4;
        // Induced flow ~ d^-2, its gradient ~ d^-3; the finite-length corrections are a factor
        // (l/d)^2 smaller: d^-4 and d^-5. Doubling d should divide them by ~16 and ~32.
        assert!(
            ratio_v > 12.0,
            "velocity difference ratio {ratio_v} at d = {}",
            a.0
        );
        assert!(
            ratio_w > 24.0,
            "rotation difference ratio {ratio_w} at d = {}",
            a.0
        );
        assert!(a.1 / b.1 > 3.5, "induced velocity should fall like d^-2");
    }
}

#[test]
fn quadrature_convergence_in_m_for_a_dense_configuration() {
    let r = random_nonoverlapping(625, 5.0, DEFAULT_DIAMETER, 13, 100_000).unwrap();
    let fine = free(&mut sbt(32, 1e-8, 1e-9), &r);
    let rel = |v: &[Vec3], w: &[Vec3]| {
        let num: f64 = v
            .iter()
            .zip(w)
            .map(|(a, b)| dot(sub(*a, *b), sub(*a, *b)))
            .sum();
        let den: f64 = w.iter().map(|b| dot(*b, *b)).sum();
        (num / den).sqrt()
    };
    let u = |v: &RodVelocities| -> Vec<Vec3> {
        v.v.iter()
            .zip(r.orientations())
            .map(|(a, p)| sub(*a, p))
            .collect()
    };
    let mut table = vec![
        "| M | rel. error of v - Up | rel. error of w | GMRES iterations |".to_string(),
        "|---|---|---|---|".into(),
    ];
    let mut errs = Vec::new();
    for m in [2, 4, 8, 16] {
        let mut mob = sbt(m, 1e-8, 1e-9);
        let v = free(&mut mob, &r);
        let (ev, ew) = (rel(&u(&v), &u(&fine)), rel(&v.w, &fine.w));
        table.push(format!(
            "| {m} | {ev:.2e} | {ew:.2e} | {} |",
            mob.report().gmres_iterations
        ));
        errs.push(ev.max(ew));
    }
    eprintln!(
        "M convergence against M = 32, nu = 5, 625 rods:\n{}",
        table.join("\n")
    );
    assert!(
        errs.windows(2).all(|w| w[1] < w[0]),
        "errors not decreasing: {errs:?}"
    );
    assert!(errs[3] < 0.05, "M = 16 error {:e}", errs[3]);
}

#[test]
fn slender_body_velocities_are_bit_identical_for_one_and_two_threads() {
    let r = random_nonoverlapping(500, 8.0, DEFAULT_DIAMETER, 17, 1000).unwrap();
    let run = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| free(&mut sbt(4, 1e-6, 1e-6), &r))
    };
    assert!(run(1) == run(2), "1 and 2 threads differ");
}

#[test]
fn head_on_rods_stop_at_contact_with_hydrodynamics() {
    // Two collinear rods swimming towards each other stop once touching. The contact solver
    // plans with the local mobility and the previous step's flow, so a residual approach speed
    // remains, of the order of the flow change the splitting misses (measured 1.2e-5 U); it
    // leaves an overlap far below the tolerance, which the next steps hold steady.
    use motile_particle::step::contact::ContactParams;
    use motile_particle::step::stepper::Stepper;
    let l = 12.0;
    let x1 = [5.0, 6.0, 6.0];
    let x2 = [5.0 + 1.0 + 0.2 + 0.02, 6.0, 6.0];
    let mut r = rods(l, vec![x1, x2], vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]);
    let mut s = Stepper::new(Box::new(sbt(4, 1e-8, 1e-10)), ContactParams::default());
    for _ in 0..30 {
        s.step(&mut r, 0.002).unwrap();
    }
    let v = s.velocities();
    let gap = r.x[1][0] - r.x[0][0] - 1.2;
    eprintln!(
        "head-on: residual speeds {:.2e} {:.2e}, tip gap {gap:.2e}",
        norm(v.v[0]),
        norm(v.v[1])
    );
    assert!(gap.abs() < 5e-3, "gap between the rod tips {gap:e}");
    for k in 0..2 {
        assert!(norm(v.v[k]) < 1e-4, "rod {k} still moves: {:?}", v.v[k]);
    }
}
