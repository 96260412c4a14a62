//! The particle core against exact answers (docs/MODEL.md §1, §3): an isolated rod swims `U t` along
//! `p` without turning; two collinear rods swimming head-on stop touching, held by the contact
//! force `lambda = U l / (2 eta)`; BBPGD agrees with projected Gauss-Seidel on a small dense
//! problem; a dense suspension (nu = 5) never overlaps beyond tolerance and its contact forces
//! sum to zero; trajectories are bit-identical for 1 and 2 threads.

use motile_particle::hydro::mobility::{LocalDrag, Mobility, MobilityState};
use motile_particle::model::geometry::{Vec3, dot, quat_from_axis, segment_distance, sub};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::{DEFAULT_DIAMETER, eta};
use motile_particle::step::constraints::constraints;
use motile_particle::step::contact::{Constraint, ContactParams, ContactProblem, ContactSolver};
use motile_particle::step::stepper::Stepper;

fn rods(box_length: f64, x: Vec<Vec3>, p: Vec<Vec3>) -> RodSet {
    let n = x.len();
    RodSet {
        box_length,
        diameter: motile_particle::model::units::DEFAULT_DIAMETER,
        x,
        q: p.iter().map(|p| quat_from_axis(*p)).collect(),
        image: vec![[0; 3]; n],
    }
}

fn stepper() -> Stepper {
    Stepper::new(Box::new(LocalDrag::default()), ContactParams::default())
}

#[test]
fn isolated_rod_swims_u_t_along_p_without_rotation() {
    let p = [0.36, -0.48, 0.8];
    let mut r = rods(6.0, vec![[5.5, 0.2, 3.0]], vec![p]);
    let mut s = stepper();
    let (dt, steps) = (0.01, 700);
    for _ in 0..steps {
        s.step(&mut r, dt).unwrap();
    }
    let t = dt * steps as f64;
    let xu = r.unwrapped()[0];
    let expected = [5.5 + p[0] * t, 0.2 + p[1] * t, 3.0 + p[2] * t];
    let err = sub(xu, expected)
        .iter()
        .map(|v| v.abs())
        .fold(0.0, f64::max);
    assert!(
        err < 1e-12,
        "unwrapped position {xu:?} vs x0 + U p t = {expected:?}: error {err:.2e}"
    );
    assert!(
        r.image[0] != [0, 0, 0],
        "the rod must have crossed the boundary"
    );
    let pe = r.p(0);
    assert!(
        sub(pe, p).iter().all(|v| v.abs() < 1e-14),
        "orientation changed: {pe:?}"
    );
}

/// Rods on the x axis swimming towards each other, tips 0.4 apart, come to rest touching:
/// centerlines `b` apart, pushed apart by the propulsion-balancing force `U l / (2 eta(b))`.
/// `b` is a run parameter: checked at the default `l/5` and at `l/10`.
fn head_on_rods_come_to_rest_touching(b: f64) -> (f64, f64) {
    let gap = 0.4;
    let half = 0.5 + (b + gap) / 2.0;
    let mut r = rods(
        10.0,
        vec![[5.0 - half, 5.0, 5.0], [5.0 + half, 5.0, 5.0]],
        vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
    );
    r.diameter = b;
    let mut s = Stepper::new(Box::new(LocalDrag::new(b)), ContactParams::default());
    let dt = 0.005;
    for _ in 0..200 {
        s.step(&mut r, dt).unwrap();
    }
    let (_, _, dist) = segment_distance(r.x[0], r.p(0), r.x[1], r.p(1), 1.0);
    assert!(
        (dist - b).abs() < 1e-9,
        "rods should touch: centerline distance {dist}, diameter {b}"
    );
    let v = s.velocities();
    assert!(
        v.v.iter().all(|v| v.iter().all(|c| c.abs() < 1e-9)),
        "rods should be at rest: {:?}",
        v.v
    );
    let f = s.contact_forces();
    let lambda = 1.0 / (2.0 * eta(b));
    assert!(
        (f[0][0] + lambda).abs() < 1e-7,
        "b = {b}: contact force {:?}, expected -U l/(2 eta) = {:.6} along x",
        f[0],
        -lambda
    );
    assert!(
        (f[0][0] + f[1][0]).abs() < 1e-15,
        "forces not equal and opposite: {:?}",
        f
    );
    (dist, lambda)
}

#[test]
fn head_on_rods_stop_touching_with_the_propulsion_balancing_force() {
    let (_, lambda) = head_on_rods_come_to_rest_touching(DEFAULT_DIAMETER);
    assert!((lambda - 2.7288).abs() < 1e-4);
    // Thinner rods: ln(20)/(4 pi) = 0.238393, force 1/(2 eta) = 2.0974.
    let (dist, lambda) = head_on_rods_come_to_rest_touching(0.1);
    assert!(
        (dist - 0.1).abs() < 1e-9 && (lambda - 2.0974).abs() < 1e-4,
        "{dist} {lambda}"
    );
}

#[test]
fn a_stepper_refuses_rods_of_another_diameter() {
    let mut r = rods(6.0, vec![[1.0, 1.0, 1.0]], vec![[1.0, 0.0, 0.0]]);
    r.diameter = 0.1;
    let e = stepper().step(&mut r, 0.01).unwrap_err();
    assert!(
        matches!(
            e,
            motile_particle::step::report::StepError::DiameterMismatch { .. }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("diameter 0.1"), "{e}");
}

/// A time step that is not positive and finite is refused before anything moves (a NaN step
/// would otherwise turn every position into NaN without an error).
#[test]
fn a_stepper_refuses_a_time_step_that_is_not_positive_and_finite() {
    for dt in [f64::NAN, 0.0, -0.01, f64::INFINITY] {
        let mut r = rods(6.0, vec![[1.0, 1.0, 1.0]], vec![[1.0, 0.0, 0.0]]);
        let r0 = r.clone();
        let e = stepper().step(&mut r, dt).unwrap_err();
        assert!(
            matches!(
                e,
                motile_particle::step::report::StepError::InvalidTimeStep(_)
            ),
            "dt = {dt}: {e}"
        );
        assert!(e.to_string().contains("must be positive and finite"), "{e}");
        assert!(r == r0, "dt = {dt}: the rods moved");
    }
}

#[test]
fn rods_meeting_at_an_angle_never_overlap() {
    for (angle, offset) in [
        (0.3f64, 0.0),
        (1.0, 0.2),
        (1.57, -0.3),
        (2.5, 0.1),
        (3.0, 0.35),
    ] {
        // Both rods reach the meeting point (6, 6, 6) at t = 2: A along +x, B along pb at the
        // given angle to A, shifted along A's axis by `offset` and slightly out of plane.
        let pb = [-(angle.cos()), angle.sin(), 0.0];
        let xb = [6.0 - 2.0 * pb[0] + offset, 6.0 - 2.0 * pb[1], 6.02];
        let mut r = rods(12.0, vec![[4.0, 6.0, 6.0], xb], vec![[1.0, 0.0, 0.0], pb]);
        let mut s = stepper();
        let mut min_sep = f64::INFINITY;
        for _ in 0..600 {
            s.step(&mut r, 0.005).unwrap();
            let d = motile_particle::model::geometry::min_image(sub(r.x[1], r.x[0]), 12.0);
            let xb = [r.x[0][0] + d[0], r.x[0][1] + d[1], r.x[0][2] + d[2]];
            let (_, _, dist) = segment_distance(r.x[0], r.p(0), xb, r.p(1), 1.0);
            min_sep = min_sep.min(dist - DEFAULT_DIAMETER);
        }
        let tol = ContactParams::default().overlap_tolerance;
        assert!(
            min_sep > -tol,
            "angle {angle}: overlap {:.2e} beyond tolerance {tol:.0e}",
            -min_sep
        );
        assert!(
            min_sep < 0.05,
            "angle {angle}: the rods never met (closest {min_sep:.3}), test is void"
        );
    }
}

/// Dense `A = dt D^T M D` and `q` of a small problem, for the slow twin.
fn dense_problem(r: &RodSet, cons: &[Constraint], dt: f64) -> (Vec<Vec<f64>>, Vec<f64>) {
    let p = r.orientations();
    let mob = LocalDrag::default();
    let m = cons.len();
    let mut a = vec![vec![0.0; m]; m];
    let mut solver = ContactSolver::default();
    let free_v: Vec<Vec3> = p.clone();
    let free_w = vec![[0.0; 3]; p.len()];
    // Column k of A: apply to the unit vector e_k, using the public force assembly.
    for k in 0..m {
        let mut e = vec![0.0; m];
        e[k] = 1.0;
        let ft = {
            // Index the constraints by solving a trivial problem first.
            let problem = ContactProblem {
                cons,
                p: &p,
                free_v: &free_v,
                free_w: &free_w,
                mobility: &mob,
                dt,
            };
            let _ = solver.solve(problem, &ContactParams::default(), &[]);
            solver.forces(cons, &e, p.len())
        };
        for (row, c) in cons.iter().enumerate() {
            let (i, j) = (c.i as usize, c.j as usize);
            let (vi, wi) = mob.local(p[i], ft[i].0, ft[i].1);
            let (vj, wj) = mob.local(p[j], ft[j].0, ft[j].1);
            let ui =
                [0, 1, 2].map(|d| vi[d] + motile_particle::model::geometry::cross(wi, c.ri)[d]);
            let uj =
                [0, 1, 2].map(|d| vj[d] + motile_particle::model::geometry::cross(wj, c.rj)[d]);
            a[row][k] = dt * dot(c.n, sub(ui, uj));
        }
    }
    let q = cons
        .iter()
        .map(|c| {
            let (i, j) = (c.i as usize, c.j as usize);
            c.phi + dt * dot(c.n, sub(free_v[i], free_v[j]))
        })
        .collect();
    (a, q)
}

#[test]
fn bbpgd_agrees_with_projected_gauss_seidel() {
    solver_agrees_with_projected_gauss_seidel(ContactParams::default(), "BBPGD");
}

/// APGD from BBPGD's first step (`stall_iterations = 0`), as where BBPGD stalls on dense
/// problems, reaches the same multipliers.
#[test]
fn apgd_agrees_with_projected_gauss_seidel() {
    let params = ContactParams {
        stall_iterations: 0,
        ..Default::default()
    };
    solver_agrees_with_projected_gauss_seidel(params, "APGD");
}

/// The solver with `settings` (tolerance and cap tightened) against projected Gauss-Seidel on
/// the dense problem of a small cluster.
fn solver_agrees_with_projected_gauss_seidel(settings: ContactParams, method: &str) {
    // A small cluster: 6 rods converging on a point, a few contacts, a positive definite A.
    let dirs: [Vec3; 6] = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.1, 0.0],
        [0.0, 1.0, 0.2],
        [0.1, -1.0, 0.0],
        [0.0, 0.2, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let c = 5.0;
    let x: Vec<Vec3> = dirs
        .iter()
        .map(|d| [c - 0.55 * d[0], c - 0.55 * d[1], c - 0.55 * d[2]])
        .collect();
    let p: Vec<Vec3> = dirs
        .iter()
        .map(|d| {
            let n = dot(*d, *d).sqrt();
            [d[0] / n, d[1] / n, d[2] / n]
        })
        .collect();
    let r = rods(10.0, x, p);
    let po = r.orientations();
    let pairs: Vec<(u32, u32)> = (0..6u32)
        .flat_map(|i| (i + 1..6).map(move |j| (i, j)))
        .collect();
    let cons = constraints(&r, &po, &pairs, 0.3);
    assert!(
        cons.len() >= 4,
        "want several constraints, got {}",
        cons.len()
    );
    let dt = 0.01;
    let (a, q) = dense_problem(&r, &cons, dt);
    let m = cons.len();
    // Slow twin: projected Gauss-Seidel on the dense LCP.
    let mut lam_pgs = vec![0.0; m];
    for _ in 0..200_000 {
        let mut change: f64 = 0.0;
        for k in 0..m {
            let g: f64 = q[k] + (0..m).map(|j| a[k][j] * lam_pgs[j]).sum::<f64>();
            let new = (lam_pgs[k] - g / a[k][k]).max(0.0);
            change = change.max((new - lam_pgs[k]).abs());
            lam_pgs[k] = new;
        }
        if change < 1e-15 {
            break;
        }
    }
    let params = ContactParams {
        tolerance: 1e-13,
        max_iterations: 100_000,
        ..settings
    };
    let mut solver = ContactSolver::default();
    let free_w = vec![[0.0; 3]; 6];
    let (lam, report) = solver
        .solve(
            ContactProblem {
                cons: &cons,
                p: &po,
                free_v: &po,
                free_w: &free_w,
                mobility: &LocalDrag::default(),
                dt,
            },
            &params,
            &[],
        )
        .unwrap();
    let err = lam
        .iter()
        .zip(&lam_pgs)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        report.active >= 2,
        "want several active contacts: {report:?}"
    );
    assert_eq!(
        report.accelerated > 0,
        params.stall_iterations == 0,
        "{method}: APGD iterations only where asked for: {report:?}"
    );
    assert!(
        err < 1e-8,
        "{method} {lam:?} vs PGS {lam_pgs:?}: max difference {err:.2e}"
    );
    for k in 0..m {
        let g: f64 = q[k] + (0..m).map(|j| a[k][j] * lam[j]).sum::<f64>();
        assert!(
            lam[k] >= 0.0 && g >= -1e-12 && (lam[k] * g).abs() < 1e-12,
            "complementarity fails at {k}: lambda {} gap {g}",
            lam[k]
        );
    }
}

#[test]
fn dense_suspension_never_overlaps_and_contact_forces_balance() {
    let r0 = random_nonoverlapping(2560, 8.0, DEFAULT_DIAMETER, 7, 100_000).unwrap(); // nu = 5
    let mut r = r0.clone();
    let mut s = stepper();
    let mut worst: f64 = 0.0;
    let mut active = 0;
    let mut hist = [0usize; 6];
    for _ in 0..1000 {
        let rep = s.step(&mut r, 0.002).unwrap();
        worst = worst.max(rep.max_overlap);
        hist[((rep.max_overlap.max(1e-9).log10() + 9.0) as usize).min(5)] += 1;
        active += rep.contact.active;
        let scale: f64 = s
            .contact_forces()
            .iter()
            .map(|f| dot(*f, *f).sqrt())
            .sum::<f64>()
            .max(1.0);
        let net = dot(rep.net_contact_force, rep.net_contact_force).sqrt();
        assert!(
            net <= 1e-12 * scale,
            "net contact force {net:.2e} (sum of |F| {scale:.2e})"
        );
    }
    eprintln!(
        "nu = 5, 2560 rods, 1000 steps: max overlap {worst:.2e} l, {active} active contacts in total; per-step max overlap histogram (1e-9..1e-4+): {hist:?}"
    );
    assert!(
        active > 1000,
        "the test needs contacts to mean anything ({active})"
    );
    assert!(
        worst <= ContactParams::default().overlap_tolerance,
        "overlap {worst:.2e}"
    );
}

#[test]
fn trajectories_are_bit_identical_for_one_and_two_threads() {
    let r0 = random_nonoverlapping(1500, 7.0, DEFAULT_DIAMETER, 3, 100_000).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut r = r0.clone();
            let mut s = stepper();
            for _ in 0..100 {
                s.step(&mut r, 0.002).unwrap();
            }
            r
        })
    };
    let (a, b) = (run(1), run(2));
    assert!(a == b, "trajectories differ between 1 and 2 threads");
}

#[test]
fn initialiser_reports_unreachable_densities() {
    let e = random_nonoverlapping(50_000, 6.0, DEFAULT_DIAMETER, 1, 2000)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("could not place rod") && e.contains("of 50000"),
        "{e}"
    );
    assert!(
        random_nonoverlapping(1, 1.0, DEFAULT_DIAMETER, 1, 10)
            .unwrap_err()
            .to_string()
            .contains("too small")
    );
}

#[test]
fn iteration_cap_gives_a_structured_error() {
    let r0 = random_nonoverlapping(2560, 8.0, DEFAULT_DIAMETER, 11, 100_000).unwrap();
    let mut r = r0.clone();
    let mut s = stepper();
    for _ in 0..20 {
        s.step(&mut r, 0.002).unwrap();
    }
    let mut capped = Stepper::new(
        Box::new(LocalDrag::default()),
        ContactParams {
            max_iterations: 2,
            ..Default::default()
        },
    );
    let e = capped.step(&mut r, 0.002).unwrap_err();
    match e {
        motile_particle::step::report::StepError::Contact(
            motile_particle::step::contact::ContactError::NoConvergence {
                iterations,
                residual,
                ..
            },
        ) => {
            assert_eq!(iterations, 2);
            assert!(residual > 1e-7, "residual {residual}");
        }
        other => panic!("expected NoConvergence, got {other:?}"),
    }
}

/// Local drag, but rod 0 is spun about z at `omega` and nothing swims: a turning rod, which
/// the linearised contact constraints only see to first order.
#[derive(Debug)]
struct Turning {
    omega: f64,
    drag: LocalDrag,
}

impl MobilityState for Turning {}

impl Mobility for Turning {
    fn name(&self) -> &'static str {
        "turning"
    }

    fn diameter(&self) -> f64 {
        self.drag.diameter()
    }

    fn free_velocities(
        &mut self,
        _rods: &RodSet,
        p: &[Vec3],
        out: &mut motile_particle::hydro::mobility::RodVelocities,
    ) -> Result<(), motile_particle::hydro::mobility::MobilityError> {
        for r in 0..p.len() {
            out.v[r] = [0.0; 3];
            out.w[r] = [0.0, 0.0, if r == 0 { self.omega } else { 0.0 }];
        }
        Ok(())
    }

    fn local(&self, p: Vec3, f: Vec3, t: Vec3) -> (Vec3, Vec3) {
        self.drag.local(p, f, t)
    }
}

#[test]
fn nearly_parallel_rods_turning_into_each_other_are_projected_apart() {
    // Rod 1 lies beside rod 0, tilted by 0.01 so its closest point is at the left ends
    // (gap 0.005) while the right ends are 0.015 apart. Rod 0 turns counterclockwise: its left
    // end moves away (the one contact point sees no approach), its right end closes
    // 0.5 omega dt = 0.03 in the step. The linearised problem alone would leave an overlap of
    // about 0.015 l, three times the tolerance; the projection must remove it in one round.
    let th: f64 = 0.01;
    let p1 = [th.cos(), th.sin(), 0.0];
    let mut r = rods(
        8.0,
        vec![[4.0, 4.0, 4.0], [4.0, 4.0 + 0.205 + 0.5 * th.sin(), 4.0]],
        vec![[1.0, 0.0, 0.0], p1],
    );
    let (dt, omega) = (0.01, 6.0);
    let mut s = Stepper::new(
        Box::new(Turning {
            omega,
            drag: LocalDrag::default(),
        }),
        ContactParams::default(),
    );
    // The premise: turned freely (what one contact point at the left ends allows), the right
    // ends overlap beyond the tolerance.
    let a = omega * dt;
    let p0 = [a.cos(), a.sin(), 0.0];
    let (_, _, free_dist) = segment_distance(r.x[0], p0, r.x[1], p1, 1.0);
    let free_overlap = DEFAULT_DIAMETER - free_dist;
    assert!(
        free_overlap > 2.0 * ContactParams::default().overlap_tolerance,
        "premise: free overlap {free_overlap:.3e}"
    );
    let report = s.step(&mut r, dt).unwrap();
    let p = r.orientations();
    let d = sub(r.x[1], r.x[0]);
    let (_, _, dist) =
        segment_distance(r.x[0], p[0], [0, 1, 2].map(|k| r.x[0][k] + d[k]), p[1], 1.0);
    let overlap = DEFAULT_DIAMETER - dist;
    let turned = p[0][1].atan2(p[0][0]);
    eprintln!(
        "free overlap {free_overlap:.2e} l; projections {}, overlap after the step {overlap:.2e} l, rod 0 turned {turned:.4} (free {:.4})",
        report.projections,
        omega * dt
    );
    assert_eq!(report.projections, 1, "one round of projection should do");
    assert!(
        overlap <= 0.5 * ContactParams::default().overlap_tolerance,
        "overlap {overlap:.3e} l after projection"
    );
    // The projection translates (the segment distance is convex under translation, so its
    // linearised constraints are conservative): rod 0 keeps its free turn, and the centres
    // move apart across the rods by about the free overlap.
    assert!(
        (turned - omega * dt).abs() < 1e-12,
        "rod 0 turned {turned}, free {}",
        omega * dt
    );
    let apart = d[1] - (0.205 + 0.5 * th.sin());
    assert!(
        apart > 0.5 * free_overlap && apart < 2.0 * free_overlap,
        "centres moved apart by {apart:.3e} for a free overlap of {free_overlap:.3e}"
    );
}
