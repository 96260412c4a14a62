//! The accuracy contract of the spectral Ewald sums (`docs/accuracy.md`, docs/MODEL.md §1-§2):
//! for every output a sum returns (RPY velocities, stresslet velocities, stresslet velocity
//! gradients) the largest error over the targets is at most `tol` times the largest exact
//! output, and the L2 norm of the errors at most `tol` times the exact output's (an absolute
//! floor `tol max|sigma| / (8 pi L^2)`, resp. `/ L^3`, where a stresslet output vanishes by
//! symmetry). Checked against the direct Ewald sum on the inputs the simulations produce:
//! swimming (force-free pusher) rods from one isolated rod to 500 rods in boxes of 4 to 16 rod
//! lengths, rods touching in pairs, random point forces with a net force, and point
//! stresslets alone, in pairs, dilute, dense and touching; at tolerances 1e-2 to 1e-8. A
//! second test checks the calibration the contract rests on: with the parameters fixed, the
//! sums' own error estimates bound the measured errors.

mod common;

use common::{errors, matrices, rod_points, rods, vectors};
use motile_particle::ewald::params::{EwaldParams, SumOutput};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry, SumReport};
use motile_particle::ewald::reference::EwaldReference;
use motile_particle::ewald::shared::{RankShare, SharedEwald};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::model::geometry::Vec3;
use motile_particle::parallel::comm::{Comm, ThreadRanks};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

const A_RPY: f64 = 0.0866;
const SIGMA: f64 = 0.68;
const TOLERANCES: [f64; 4] = [1e-2, 1e-4, 1e-6, 1e-8];

/// One RPY case: the direct sum at (a sample of) the points, then a fresh fast sum per
/// tolerance, with or without fixed parameters. Returns the rows of the report.
fn rpy_case(
    (name, y, f, l, group): &RpyCase,
    fixed: bool,
    check: impl Fn(&str, f64, (f64, f64), &SumReport),
) {
    let (l, y, f) = (*l, y.as_slice(), f.as_slice());
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: *group,
    };
    let step = (y.len() / 1200).max(1);
    let targets: Vec<usize> = (0..y.len()).step_by(step).collect();
    let exact = EwaldReference::default()
        .rpy_at(&geo, y, f, &targets)
        .unwrap();
    for tol in TOLERANCES {
        let mut sum = SpectralEwald::new(tol).unwrap();
        if fixed {
            sum.fixed = Some(EwaldParams::choose(tol, y.len(), l));
        }
        let u = sum.rpy(&geo, y, f).unwrap();
        let fast: Vec<Vec3> = targets.iter().map(|&t| u[t]).collect();
        let e = errors(&vectors(&fast), &vectors(&exact), 0.0);
        check(name, tol, e, &sum.last_report().unwrap());
    }
}

/// One stresslet case, as [`rpy_case`]; the check sees velocity and gradient errors.
fn stresslet_case(
    name: &str,
    x: &[Vec3],
    p: &[Vec3],
    l: f64,
    fixed: bool,
    check: impl Fn(&str, f64, [(f64, f64); 2], &SumReport),
) {
    let sigma = vec![SIGMA; x.len()];
    let exact = EwaldReference::default()
        .stresslets(l, x, p, &sigma)
        .unwrap();
    let floor = |k: i32| SIGMA / (8.0 * PI * l.powi(k));
    for tol in TOLERANCES {
        let mut sum = SpectralEwald::new(tol).unwrap();
        if fixed {
            sum.fixed = Some(EwaldParams::choose_for(
                tol,
                x.len(),
                l,
                &[SumOutput::StressletVelocity, SumOutput::StressletGradient],
                0.3,
            ));
        }
        let s = sum.stresslets(l, x, p, &sigma).unwrap();
        let eu = errors(&vectors(&s.u), &vectors(&exact.u), floor(2));
        let eg = errors(&matrices(&s.grad), &matrices(&exact.grad), floor(3));
        check(name, tol, [eu, eg], &sum.last_report().unwrap());
    }
}

/// A named RPY case: points, forces, box side, group size.
type RpyCase = (String, Vec<Vec3>, Vec<Vec3>, f64, usize);

/// The RPY cases: swimming rods (one, two, dilute, moderate, dense, touching), random forces
/// on rods and touching rods, and random point forces with a net force.
fn rpy_cases() -> Vec<RpyCase> {
    let mut cases = Vec::new();
    for (n, l, touching, swimming) in [
        (1, 8.0, false, true),
        (1, 16.0, false, true),
        (2, 16.0, false, true),
        (2, 4.0, false, true),
        (50, 8.0, false, true),
        (500, 8.0, false, true),
        (300, 4.0, false, true),
        (500, 16.0, false, true),
        (100, 6.0, true, true),
        (500, 8.0, false, false),
        (100, 6.0, true, false),
    ] {
        let (x, p) = rods(n, l, touching, 7 + n as u64);
        let (y, f) = rod_points(&x, &p, swimming, 3);
        let name = format!(
            "{n} {} rods{}, L = {l}",
            if swimming { "swimming" } else { "random-force" },
            if touching { " touching in pairs" } else { "" }
        );
        cases.push((name, y, f, l, 4));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let l = 8.0;
    let y: Vec<Vec3> = (0..2000)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let f: Vec<Vec3> = (0..2000)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
        .collect();
    cases.push(("2000 random point forces, L = 8".into(), y, f, l, 1));
    cases
}

fn stresslet_cases() -> Vec<(String, Vec<Vec3>, Vec<Vec3>, f64)> {
    [
        (1, 8.0, false),
        (1, 16.0, false),
        (2, 8.0, false),
        (50, 8.0, false),
        (2000, 8.0, false),
        (200, 6.0, true),
    ]
    .into_iter()
    .map(|(n, l, touching)| {
        let (x, p) = rods(n, l, touching, 17 + n as u64);
        let name = format!(
            "{n} stresslets{}, L = {l}",
            if touching { " touching in pairs" } else { "" }
        );
        (name, x, p, l)
    })
    .collect()
}

#[test]
fn every_output_meets_its_tolerance_against_the_direct_sum() {
    let rows = std::sync::Mutex::new(Vec::<String>::new());
    let failures = std::sync::Mutex::new(Vec::<String>::new());
    let judge = |what: String, tol: f64, (max, l2): (f64, f64), r: &SumReport| {
        let line = format!(
            "{what}, tol {tol:.0e}: max-relative {:.2} tol, relative L2 {:.2} tol (level {}, \
             {} attempts, estimate {:.2} tol)",
            max / tol,
            l2 / tol,
            r.level,
            r.attempts,
            r.worst_ratio()
        );
        if max > tol || l2 > tol || !r.met {
            failures.lock().unwrap().push(line.clone());
        }
        rows.lock().unwrap().push(line);
    };
    for case in rpy_cases() {
        rpy_case(&case, false, |n, tol, e, r| {
            judge(format!("RPY velocity, {n}"), tol, e, r)
        });
    }
    for (name, x, p, l) in stresslet_cases() {
        stresslet_case(&name, &x, &p, l, false, |n, tol, [eu, eg], r| {
            judge(format!("stresslet velocity, {n}"), tol, eu, r);
            judge(format!("stresslet gradient, {n}"), tol, eg, r);
        });
    }
    let rows = rows.into_inner().unwrap();
    eprintln!("{}", rows.join("\n"));
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "outputs off their tolerance:\n{}",
        failures.join("\n")
    );
}

/// The calibration behind the refinement: at the parameters of a tolerance (no refinement)
/// the estimate a sum reports bounds the measured error, both metrics, on every case.
#[test]
fn error_estimates_bound_the_measured_errors() {
    let rows = std::sync::Mutex::new(Vec::<String>::new());
    let failures = std::sync::Mutex::new(Vec::<String>::new());
    let judge = |what: String, tol: f64, (max, l2): (f64, f64), est: (f64, f64)| {
        let line = format!(
            "{what}, tol {tol:.0e}: measured {:.2e} / {:.2e}, estimated {:.2e} / {:.2e} \
             (max-relative / relative L2; ratios {:.2} / {:.2})",
            max,
            l2,
            est.0,
            est.1,
            max / est.0,
            l2 / est.1
        );
        if max > est.0 || l2 > est.1 {
            failures.lock().unwrap().push(line.clone());
        }
        rows.lock().unwrap().push(line);
    };
    for case in rpy_cases() {
        rpy_case(&case, true, |n, tol, e, r| {
            let est = &r.estimates[0];
            judge(
                format!("RPY velocity, {n}"),
                tol,
                e,
                (est.max_relative, est.l2_relative),
            )
        });
    }
    for (name, x, p, l) in stresslet_cases() {
        stresslet_case(&name, &x, &p, l, true, |n, tol, [eu, eg], r| {
            let (u, g) = (&r.estimates[0], &r.estimates[1]);
            // A velocity that vanishes by symmetry (an isolated stresslet's) is round-off,
            // far below the floor: nothing to estimate.
            if eu.0.max(eu.1) > 1e-12 {
                judge(
                    format!("stresslet velocity, {n}"),
                    tol,
                    eu,
                    (u.max_relative, u.l2_relative),
                );
            }
            judge(
                format!("stresslet gradient, {n}"),
                tol,
                eg,
                (g.max_relative, g.l2_relative),
            );
        });
    }
    eprintln!("{}", rows.into_inner().unwrap().join("\n"));
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "estimates below the measured errors:\n{}",
        failures.join("\n")
    );
}

/// Copies within this z distance of a slab (the contact reach of the step) in the shared sums.
const REACH: f64 = 1.3;

/// Periodic z distance from `z` to `[lo, hi)`.
fn gap(z: f64, lo: f64, hi: f64, l: f64) -> f64 {
    if (lo..hi).contains(&z) {
        0.0
    } else {
        (lo - z).rem_euclid(l).min((z - hi).rem_euclid(l))
    }
}

/// Velocities and gradients at every point, summed on `ranks` ranks (equal z slabs), in the
/// points' order.
fn shared(x: &[Vec3], p: &[Vec3], l: f64, tol: f64, ranks: usize) -> Vec<(Vec3, [Vec3; 3])> {
    let handles: Vec<_> =
        ThreadRanks::group(ranks)
            .into_iter()
            .map(|comm| {
                let (x, p) = (x.to_vec(), p.to_vec());
                std::thread::spawn(move || {
                    let (r, size) = (comm.rank(), comm.size());
                    let (lo, hi) = (l * r as f64 / size as f64, l * (r + 1) as f64 / size as f64);
                    let mut order: Vec<usize> = (0..x.len())
                        .filter(|&k| (lo..hi).contains(&x[k][2]))
                        .collect();
                    let owned = order.len();
                    order.extend((0..x.len()).filter(|&k| {
                        !(lo..hi).contains(&x[k][2]) && gap(x[k][2], lo, hi, l) <= REACH
                    }));
                    let xs: Vec<Vec3> = order.iter().map(|&k| x[k]).collect();
                    let ps: Vec<Vec3> = order.iter().map(|&k| p[k]).collect();
                    let sigma = vec![SIGMA; xs.len()];
                    let mut sum = SharedEwald::new(tol).unwrap();
                    let share = RankShare {
                        owned,
                        total: x.len(),
                        reach: REACH,
                    };
                    let f = sum.stresslets(&comm, share, l, &xs, &ps, &sigma).unwrap();
                    let report = sum.last_report().unwrap();
                    (order[..owned].to_vec(), f, report)
                })
            })
            .collect();
    let mut out = vec![([0.0; 3], [[0.0; 3]; 3]); x.len()];
    for h in handles {
        let (ids, f, report) = h.join().unwrap();
        assert!(
            report.met,
            "the estimate says the tolerance was missed: {report:?}"
        );
        assert!(
            report.params.cutoff <= REACH,
            "cutoff {} beyond the copies",
            report.params.cutoff
        );
        for (k, id) in ids.into_iter().enumerate() {
            out[id] = (f.u[k], f.grad[k]);
        }
    }
    out
}

#[test]
fn shared_stresslet_sums_meet_the_tolerance_against_the_direct_sum_on_1_2_3_ranks() {
    for (n, l, touching) in [(300, 8.0, false), (200, 6.0, true)] {
        let (x, p) = rods(n, l, touching, 5 + n as u64);
        let x: Vec<Vec3> = x.iter().map(|y| y.map(|c| c.rem_euclid(l))).collect();
        let sigma = vec![SIGMA; n];
        let exact = EwaldReference::default()
            .stresslets(l, &x, &p, &sigma)
            .unwrap();
        let (eu, eg) = (vectors(&exact.u), matrices(&exact.grad));
        let floor = |k: i32| SIGMA / (8.0 * PI * l.powi(k));
        for tol in [1e-4, 1e-8] {
            for ranks in [1, 2, 3] {
                let s = shared(&x, &p, l, tol, ranks);
                let su = vectors(&s.iter().map(|(u, _)| *u).collect::<Vec<_>>());
                let sg = matrices(&s.iter().map(|(_, g)| *g).collect::<Vec<_>>());
                let (um, u2) = errors(&su, &eu, floor(2));
                let (gm, g2) = errors(&sg, &eg, floor(3));
                eprintln!(
                    "{n} stresslets{} L = {l}, tol {tol:e}, {ranks} rank(s): velocity {um:.1e} max, {u2:.1e} L2; gradient {gm:.1e} max, {g2:.1e} L2",
                    if touching { " touching" } else { "" }
                );
                for (what, e) in [
                    ("velocity max", um),
                    ("velocity L2", u2),
                    ("gradient max", gm),
                    ("gradient L2", g2),
                ] {
                    assert!(
                        e <= tol,
                        "{n} stresslets, L = {l}, {ranks} ranks, tol {tol:e}: {what} error {e:.2e}"
                    );
                }
            }
        }
    }
}

/// RPY velocities at every node of rods with centres `x` (4 nodes each, forces `f` per node),
/// summed on `ranks` ranks: rods owned by equal z slabs of their centres, copies of the rods
/// whose centres lie within the cutoff one process would choose plus a rod length.
fn shared_rpy(x: &[Vec3], y: &[Vec3], f: &[Vec3], l: f64, tol: f64, ranks: usize) -> Vec<Vec3> {
    let g = 4;
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: g,
    };
    let reach = SharedEwald::new(tol)
        .unwrap()
        .preferred_rpy_reach(y.len(), l);
    let handles: Vec<_> =
        ThreadRanks::group(ranks)
            .into_iter()
            .map(|comm| {
                let (x, y, f) = (x.to_vec(), y.to_vec(), f.to_vec());
                std::thread::spawn(move || {
                    let (r, size) = (comm.rank(), comm.size());
                    let (lo, hi) = (l * r as f64 / size as f64, l * (r + 1) as f64 / size as f64);
                    let z = |k: usize| x[k][2].rem_euclid(l);
                    let mut order: Vec<usize> =
                        (0..x.len()).filter(|&k| (lo..hi).contains(&z(k))).collect();
                    let owned = order.len();
                    order.extend((0..x.len()).filter(|&k| {
                        !(lo..hi).contains(&z(k)) && gap(z(k), lo, hi, l) <= reach + 1.0
                    }));
                    let pick = |v: &[Vec3]| -> Vec<Vec3> {
                        order
                            .iter()
                            .flat_map(|&k| v[k * g..(k + 1) * g].to_vec())
                            .collect()
                    };
                    let (ys, fs) = (pick(&y), pick(&f));
                    let mut sum = SharedEwald::new(tol).unwrap();
                    let share = RankShare {
                        owned: owned * g,
                        total: y.len(),
                        reach,
                    };
                    let u = sum.rpy(&comm, share, &geo, &ys, &fs).unwrap();
                    let report = sum.last_report().unwrap();
                    (order[..owned].to_vec(), u, report)
                })
            })
            .collect();
    let mut out = vec![[0.0; 3]; y.len()];
    for h in handles {
        let (ids, u, report) = h.join().unwrap();
        assert!(
            report.met,
            "the estimate says the tolerance was missed: {report:?}"
        );
        for (k, id) in ids.into_iter().enumerate() {
            out[id * g..(id + 1) * g].copy_from_slice(&u[k * g..(k + 1) * g]);
        }
    }
    out
}

/// The slender-body level's sum, shared: swimming (force-free) rods, random forces on rods and
/// touching swimming rods, on 1, 2 and 3 ranks, within the tolerance of the direct sum.
#[test]
fn shared_rpy_sums_meet_the_tolerance_against_the_direct_sum_on_1_2_3_ranks() {
    for (n, l, touching, swimming) in [
        (300, 8.0, false, true),
        (300, 8.0, false, false),
        (100, 6.0, true, true),
    ] {
        let (x, p) = rods(n, l, touching, 31 + n as u64);
        let (y, f) = rod_points(&x, &p, swimming, 3);
        let geo = RpyGeometry {
            box_length: l,
            radius: A_RPY,
            group: 4,
        };
        let targets: Vec<usize> = (0..y.len()).collect();
        let exact = EwaldReference::default()
            .rpy_at(&geo, &y, &f, &targets)
            .unwrap();
        for tol in [1e-4, 1e-8] {
            for ranks in [1, 2, 3] {
                let u = shared_rpy(&x, &y, &f, l, tol, ranks);
                let (emax, e2) = errors(&vectors(&u), &vectors(&exact), 0.0);
                eprintln!(
                    "{n} {} rods{}, L = {l}, tol {tol:e}, {ranks} rank(s): {emax:.1e} max, {e2:.1e} L2",
                    if swimming { "swimming" } else { "random-force" },
                    if touching { " touching" } else { "" }
                );
                assert!(
                    emax <= tol && e2 <= tol,
                    "{n} rods, L = {l}, {ranks} ranks, tol {tol:e}: errors {emax:.2e} max, {e2:.2e} L2"
                );
            }
        }
    }
}
