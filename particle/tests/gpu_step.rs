//! The rooms of the particle step on a device (feature `gpu`, `motile_particle::step::gpu`)
//! against their twins:
//! - the rods' cell list and neighbour pairs against the obviously-correct twin, every pair by
//!   brute force (minimum image), on what the simulations produce: non-overlapping rods at the
//!   paper's nu = 0.625 and the demo's nu = 5 with the stepper's reach (rod length + diameter +
//!   contact margin), and centres on the box's faces;
//! - the rods' update against the CPU's (`RodSet::translate`, `quat_exp`, `quat_mul`, as the
//!   stepper applies them) with swimming velocities, turning rates up to 10 beta and rods on
//!   the faces moving out of the box;
//! - the contact constraints of the pairs against the CPU's (`constraints`) on dense rods with
//!   touching, parallel and boundary-crossing pairs;
//! - the contact solver against the CPU's (`ContactSolver::solve`, local drag) on dense
//!   swimming, turning rods, cold and warm;
//! - steps of the local-drag level against the CPU's stepper, the resident stepper repeating
//!   bit for bit whatever order the blocks run in, and its warm start (fewer iterations;
//!   a restart from rods and multipliers continuing bit for bit);
//! - steps of the `dipole` and `sbt-explicit` levels (their flow from the host, contacts and
//!   the move on the device) against the CPU's stepper with the same mobility.
//!
//! On the host emulation (skipped with the reason where no C++ compiler runs, a failure with
//! `MOTILE_REQUIRE_CXX=1`), blocks in order and in shuffled orders (the scatter's atomics then
//! take other orders: the list must not change); on CUDA in the `#[ignore]`d test that
//! `scripts/device_run.sh parity` runs.

use motile_gpu::{Backend, Counters};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::explicit::ExplicitSlender;
use motile_particle::hydro::mobility::{LocalDrag, Mobility, RodVelocities};
use motile_particle::hydro::slender::SlenderParams;
use motile_particle::model::geometry::{
    Vec3, axpy, cross, dot, min_image, norm, quat_exp, quat_mul, scale, sub,
};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::SWIM_SPEED;
use motile_particle::model::units::{DEFAULT_DIAMETER, ROD_LENGTH};
use motile_particle::step::constraints::constraints;
use motile_particle::step::contact::{Constraint, ContactParams, ContactReport, WarmStart};
use motile_particle::step::contact::{ContactProblem, ContactSolver};
use motile_particle::step::gpu::GpuStep;
use motile_particle::step::gpu::{DeviceContactProblem, DeviceStepper};
use motile_particle::step::stepper::Stepper;

/// The stepper's reach with the default contact margin.
fn reach() -> f64 {
    ROD_LENGTH + DEFAULT_DIAMETER + ContactParams::default().margin
}

fn brute_force(x: &[Vec3], l: f64, cutoff: f64) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for i in 0..x.len() {
        for j in i + 1..x.len() {
            let d = min_image(sub(x[j], x[i]), l);
            if dot(d, d) < cutoff * cutoff {
                out.push((i as u32, j as u32));
            }
        }
    }
    out
}

/// The configurations: (label, centres, box, cutoff).
fn cases() -> Vec<(String, Vec<Vec3>, f64, f64)> {
    let mut out = Vec::new();
    for (nu, l, seed) in [(0.625f64, 20.0f64, 1u64), (5.0, 8.0, 2), (5.0, 4.2, 3)] {
        let n = (nu * l * l * l).round() as usize;
        let rods = random_nonoverlapping(n, l, DEFAULT_DIAMETER, seed, 1_000_000)
            .expect("initial configuration");
        out.push((
            format!("nu = {nu}, L/l = {l}, {n} rods"),
            rods.x,
            l,
            reach(),
        ));
    }
    // Centres on the faces and corners of the box and just inside its far faces.
    let l = 6.0;
    let e = l * (1.0 - f64::EPSILON);
    let mut x: Vec<Vec3> = vec![[0.0; 3], [e, 0.0, 0.0], [0.0, e, e], [e; 3], [0.5, 0.0, e]];
    for k in 0..200 {
        let t = k as f64 * 0.37;
        x.push([(t * 1.3) % l, (t * 2.9) % l, (t * 0.7) % l]);
    }
    out.push(("centres on the faces, L = 6".into(), x, l, 1.9));
    out
}

/// The update on the device against the CPU's: bit for bit where the device's sin and cos are
/// the C library's (the emulation), else within `tol` (CUDA's differ by an ulp or so).
fn check_update(dev: &GpuStep, tol: f64) {
    let l = 8.0;
    let mut rods = random_nonoverlapping(320, l, DEFAULT_DIAMETER, 9, 1_000_000).unwrap();
    let n = rods.len();
    // Rods on the faces (x = 0 moving out backwards, x just under L moving out forwards).
    rods.x[0] = [0.0, 0.0, 0.0];
    rods.x[1] = [l * (1.0 - f64::EPSILON); 3];
    rods.x[2] = [1e-17, 4.0, l - 1e-15];
    let dt = 0.05;
    let mut v: Vec<Vec3> = (0..n)
        .map(|i| {
            let p = rods.p(i);
            let k = i as f64;
            [
                p[0] + 0.3 * (k * 0.7).sin(),
                p[1] + 0.3 * (k * 1.3).cos(),
                p[2] - 0.2 * (k * 0.1).sin(),
            ]
        })
        .collect();
    v[0] = [-1.0, -1e-18, -2.0];
    v[1] = [1.0, 0.5, 1e-16];
    v[2] = [-1.0, 0.0, 1.0];
    let w: Vec<Vec3> = (0..n)
        .map(|i| {
            let k = i as f64;
            [
                10.0 * (k * 0.37).sin(),
                3.0 * (k * 0.11).cos(),
                0.1 * k.sin(),
            ]
        })
        .collect();
    let mut on_device = dev.upload_rods(&rods).unwrap();
    let (dv, dw) = (
        dev.upload_triples(&v).unwrap(),
        dev.upload_triples(&w).unwrap(),
    );
    let mut cpu = rods.clone();
    for _ in 0..21 {
        dev.update(&mut on_device, &dv, &dw, dt).unwrap();
        for i in 0..n {
            cpu.translate(i, scale(dt, v[i]));
            cpu.q[i] = quat_mul(quat_exp(scale(dt, w[i])), cpu.q[i]);
        }
    }
    let mut got = rods.clone();
    dev.download_rods(&on_device, &mut got).unwrap();
    if let Some(i) = (0..n).find(|&i| got.image[i] != cpu.image[i]) {
        panic!(
            "rod {i}: images crossed {:?} on the device, {:?} on the CPU (centre {:?} and {:?})",
            got.image[i], cpu.image[i], got.x[i], cpu.x[i]
        );
    }
    let dx = (0..n)
        .flat_map(|i| (0..3).map(move |d| (i, d)))
        .map(|(i, d)| (got.x[i][d] - cpu.x[i][d]).abs() / l)
        .fold(0.0, f64::max);
    let dq = (0..n)
        .flat_map(|i| (0..4).map(move |d| (i, d)))
        .map(|(i, d)| (got.q[i][d] - cpu.q[i][d]).abs())
        .fold(0.0, f64::max);
    assert!(
        dx <= tol && dq <= tol,
        "after 21 updates the device's centres differ by {dx:.1e} L, quaternions by {dq:.1e} \
         (bound {tol:.0e})"
    );
    assert!(
        got.x.iter().flatten().all(|&c| (0.0..l).contains(&c)),
        "a centre left the box"
    );
    eprintln!(
        "update: 21 steps of {n} rods, centres within {dx:.1e} L, quaternions within {dq:.1e}"
    );
}

/// The constraints of the pairs on the device against the CPU's (`constraints`), bit for bit
/// where the arithmetic is the same (the emulation), on dense rods (nu = 5) with collinear
/// touching, parallel and boundary-crossing pairs placed among them.
fn check_constraints(dev: &GpuStep, tol: f64) {
    let l = 6.0;
    let mut rods = random_nonoverlapping(1080, l, DEFAULT_DIAMETER, 4, 1_000_000).unwrap();
    // Rod 1 on rod 0's axis (touching centerlines: the normal along the centres' line), rod 3
    // parallel to rod 2 at 0.25 (the parallel branch), rod 5 across the box's face from rod 4.
    let p0 = rods.p(0);
    rods.x[1] = wrap(axpy(rods.x[0], 0.1, p0), l);
    rods.q[1] = rods.q[0];
    let (p2, x2) = (rods.p(2), rods.x[2]);
    let c = cross(p2, [0.3, 0.5, 0.81]);
    let side = scale(1.0 / norm(c), c);
    rods.x[3] = wrap(axpy(x2, 0.25, side), l);
    rods.q[3] = rods.q[2];
    rods.x[4] = [0.05, 3.0, 3.0];
    rods.x[5] = [l - 0.1, 3.2, 3.0];
    let p: Vec<Vec3> = rods.orientations();
    let pairs = brute_force(&rods.x, l, reach());
    let on_device = dev.upload_rods(&rods).unwrap();
    let device_pairs = dev
        .build(
            &dev.upload_triples(&rods.x).unwrap(),
            rods.len(),
            l,
            reach(),
        )
        .unwrap();
    for margin in [0.15, 0.6] {
        let want = constraints(&rods, &p, &pairs, margin);
        let got = dev
            .download_constraints(&dev.constraints(&on_device, &device_pairs, margin).unwrap())
            .unwrap();
        assert_eq!(
            got.len(),
            want.len(),
            "margin {margin}: constraints on the device and the CPU"
        );
        let mut worst = 0.0f64;
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(
                (g.i, g.j),
                (w.i, w.j),
                "margin {margin}: pairs out of order"
            );
            for (a, b) in
                g.ri.iter()
                    .chain(&g.rj)
                    .chain(&g.n)
                    .zip(w.ri.iter().chain(&w.rj).chain(&w.n))
            {
                worst = worst.max((a - b).abs());
            }
            worst = worst.max((g.phi - w.phi).abs());
        }
        assert!(
            worst <= tol,
            "margin {margin}: constraints differ by {worst:.1e} (bound {tol:.0e})"
        );
        for k in [(0u32, 1u32), (2, 3), (4, 5)] {
            assert!(
                want.iter().any(|c| (c.i, c.j) == k),
                "margin {margin}: no constraint {k:?}"
            );
        }
        eprintln!(
            "constraints, margin {margin}: {} of {} pairs, within {worst:.1e}",
            got.len(),
            pairs.len()
        );
    }
}

/// The contact solver on the device against the CPU's (`ContactSolver::solve` with the local
/// drag), bit for bit where the arithmetic is the same: dense swimming rods that also turn, from
/// zero and from a warm start.
fn check_solver(dev: &GpuStep, tol: f64) {
    let (l, dt, margin) = (6.0, 0.1, 0.3);
    let rods = random_nonoverlapping(1080, l, DEFAULT_DIAMETER, 6, 1_000_000).unwrap();
    let p = rods.orientations();
    let pairs = brute_force(&rods.x, l, ROD_LENGTH + DEFAULT_DIAMETER + margin);
    let cons = constraints(&rods, &p, &pairs, margin);
    let free_v: Vec<Vec3> = p.iter().map(|&q| scale(SWIM_SPEED, q)).collect();
    let free_w: Vec<Vec3> = (0..rods.len())
        .map(|i| {
            let k = i as f64;
            [
                2.0 * (k * 0.31).sin(),
                2.0 * (k * 0.17).cos(),
                (k * 0.05).sin(),
            ]
        })
        .collect();
    let drag = LocalDrag::new(DEFAULT_DIAMETER);
    let on_device = dev.upload_rods(&rods).unwrap();
    let device_pairs = dev
        .build(
            &dev.upload_triples(&rods.x).unwrap(),
            rods.len(),
            l,
            ROD_LENGTH + DEFAULT_DIAMETER + margin,
        )
        .unwrap();
    let device_cons = dev.constraints(&on_device, &device_pairs, margin).unwrap();
    assert_eq!(device_cons.len, cons.len());
    let (dv, dw) = (
        dev.upload_triples(&free_v).unwrap(),
        dev.upload_triples(&free_w).unwrap(),
    );
    let problem = DeviceContactProblem {
        rods: &on_device,
        cons: &device_cons,
        free_v: &dv,
        free_w: &dw,
        drag: drag.coefficients(),
        dt,
    };
    // BBPGD, then APGD from BBPGD's first step (where BBPGD stalls on dense problems).
    let apgd = ContactParams {
        stall_iterations: 0,
        ..ContactParams::default()
    };
    let data = (&cons[..], &p[..], &free_v[..], &free_w[..]);
    let bbpgd = check_solve(dev, problem, data, &ContactParams::default(), tol, "BBPGD");
    let apgd = check_solve(dev, problem, data, &apgd, tol, "APGD");
    check_apgd_work(&bbpgd, &apgd);
}

/// APGD's counted work beside BBPGD's on one problem (the set-up's counts do not depend on the
/// start's values): a BBPGD iteration 4 launches and a download; APGD adds its step's power
/// iteration (`POWER_ITERATIONS` x 4 launches and a download), then per iteration 5 launches
/// (4 in the last) and a download. A change that adds round trips to APGD fails here.
fn check_apgd_work(bbpgd: &[(Counters, ContactReport)], apgd: &[(Counters, ContactReport)]) {
    let power = motile_particle::step::contact::POWER_ITERATIONS as i64;
    for ((cb, rb), (ca, ra)) in bbpgd.iter().zip(apgd) {
        let (kb, ka) = (rb.iterations as i64, ra.accelerated as i64);
        let extra = ra.iterations as i64 - ka - kb; // BBPGD iterations before the stall, beyond
        assert!(ka > 0 && rb.accelerated == 0, "APGD {ra:?}, BBPGD {rb:?}");
        let more = |a: u64, b: u64| a as i64 - b as i64;
        let got = (
            more(ca.launches, cb.launches),
            more(ca.downloads, cb.downloads),
        );
        let want = (4 * extra + 4 * power + 5 * ka - 1, extra + power + ka);
        assert_eq!(
            got, want,
            "APGD's launches and downloads beyond BBPGD's ({ra:?}, {rb:?})"
        );
    }
}

/// One problem of [`check_solver`] on the device and the CPU, cold and warm.
fn check_solve(
    dev: &GpuStep,
    problem: DeviceContactProblem<'_>,
    (cons, p, free_v, free_w): (&[Constraint], &[Vec3], &[Vec3], &[Vec3]),
    params: &ContactParams,
    tol: f64,
    method: &str,
) -> Vec<(Counters, ContactReport)> {
    let (drag, dt) = (LocalDrag::new(DEFAULT_DIAMETER), problem.dt);
    let mut cold: Vec<f64> = Vec::new();
    let mut counted = Vec::new();
    for warm in [false, true] {
        let initial: Vec<f64> = if warm {
            cold.iter().map(|l| 0.7 * l).collect()
        } else {
            Vec::new()
        };
        let (want, want_report) = ContactSolver::default()
            .solve(
                ContactProblem {
                    cons,
                    p,
                    free_v,
                    free_w,
                    mobility: &drag,
                    dt,
                },
                params,
                &initial,
            )
            .unwrap();
        let before = dev.counters();
        let (got, got_report) = dev.solve_contacts(problem, params, &initial).unwrap();
        counted.push((dev.counters().since(&before), got_report.clone()));
        assert_eq!(
            want_report.accelerated > 0,
            params.stall_iterations == 0,
            "{method}, warm {warm}: APGD iterations only where asked for: {want_report:?}"
        );
        assert!(
            want_report.active > 50,
            "too few active contacts to test: {want_report:?}"
        );
        let scale_l = want.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale_l;
        assert!(
            worst <= tol,
            "{method}, warm {warm}: multipliers differ by {worst:.1e} of the largest (bound \
             {tol:.0e}); device {got_report:?}, CPU {want_report:?}"
        );
        if tol == 0.0 {
            assert_eq!(got_report, want_report, "{method}, warm {warm}: reports");
        }
        eprintln!(
            "contact solver {method} (warm start {warm}): {} constraints, {} active, {} \
             iterations, residual {:.1e}; multipliers within {worst:.1e}",
            want_report.constraints,
            want_report.active,
            want_report.iterations,
            want_report.residual
        );
        cold = want;
    }
    counted
}

/// Steps of the local-drag level on the device against the CPU's stepper: the same rods after
/// `STEPS` steps within what the contact solver's tolerance allows. The two order their
/// constraints differently (the CPU by cells, the device by pairs), so their multipliers agree
/// to the complementarity tolerance (1e-7 l per step), not bit for bit.
fn check_steps(dev: &GpuStep) {
    const STEPS: usize = 10;
    let (nu, l, dt) = (2.0f64, 6.0f64, 0.02);
    let n = (nu * l * l * l).round() as usize;
    let rods = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 8, 1_000_000).unwrap();
    let params = ContactParams::default();
    let mut cpu = rods.clone();
    let mut stepper = Stepper::new(Box::new(LocalDrag::new(DEFAULT_DIAMETER)), params.clone());
    let mut on_device = dev.upload_rods(&rods).unwrap();
    let (mut active, mut constraints) = (0, 0);
    for k in 0..STEPS {
        let want = stepper.step(&mut cpu, dt).unwrap();
        let got = dev.step_local_drag(&mut on_device, dt, &params).unwrap();
        assert_eq!(
            got.contact.constraints, want.contact.constraints,
            "step {k}: constraints on the device and the CPU"
        );
        assert!(
            got.max_overlap <= params.overlap_tolerance,
            "step {k}: overlap {}",
            got.max_overlap
        );
        active += want.contact.active;
        constraints += want.contact.constraints;
    }
    assert!(
        active > 20,
        "too few active contacts to test the solver: {active}"
    );
    let mut got = rods.clone();
    dev.download_rods(&on_device, &mut got).unwrap();
    let dx = (0..n)
        .map(|i| norm(min_image(sub(got.x[i], cpu.x[i]), l)))
        .fold(0.0, f64::max);
    let dq = (0..n)
        .flat_map(|i| (0..4).map(move |d| (i, d)))
        .map(|(i, d)| (got.q[i][d] - cpu.q[i][d]).abs())
        .fold(0.0, f64::max);
    let bound = STEPS as f64 * params.tolerance;
    assert!(
        dx <= bound && dq <= bound,
        "after {STEPS} steps the centres differ by {dx:.1e} l, the quaternions by {dq:.1e} \
         (bound: {STEPS} x the solver tolerance = {bound:.0e})"
    );
    assert_eq!(got.image, cpu.image, "images crossed");
    eprintln!(
        "{STEPS} steps of {n} rods (nu = {nu}): {constraints} constraints, {active} active in all; \
         centres within {dx:.1e} l, quaternions within {dq:.1e}"
    );
}

/// Steps of the levels whose flow is computed on the host and whose contacts act through the
/// local drag (`dipole`, `sbt-explicit`): the resident stepper fed each step the free
/// velocities of its own downloaded rods against the CPU's stepper with the same mobility, on
/// suspensions dense enough for contacts every step. The free velocities are the same function
/// of the rods on both sides, so the rods agree within what the contact solver's tolerance
/// allows (as for the `none` level), times the flow's sensitivity to the positions over the
/// steps (a factor 10). The point stresslets' near field turns neighbours fast enough that
/// the move leaves overlaps the projection must remove: both sides project in the same steps.
fn check_flow_steps(open: &dyn Fn() -> DeviceStepper, rods: &RodSet, level: &str) {
    const STEPS: usize = 10;
    let dt = 0.02;
    let l = rods.box_length;
    let params = ContactParams::default();
    let mobility = || -> Box<dyn Mobility> {
        let sum = Box::new(SpectralEwald::new(1e-8).unwrap());
        match level {
            "dipole" => Box::new(Dipole::new(sum, DEFAULT_DIAMETER)),
            _ => Box::new(ExplicitSlender::new(
                SlenderParams::for_diameter(DEFAULT_DIAMETER),
                sum,
            )),
        }
    };
    let mut cpu = rods.clone();
    let mut stepper = Stepper::new(mobility(), params.clone());
    let mut host = mobility();
    let mut device = open();
    let mut on_host = rods.clone();
    let mut free = RodVelocities::zeros(rods.len());
    let (mut active, mut projections, mut flow) = (0, 0, 0.0f64);
    for k in 0..STEPS {
        let want = stepper.step(&mut cpu, dt).unwrap();
        device.download(&mut on_host).unwrap();
        host.free_velocities(&on_host, &on_host.orientations(), &mut free)
            .unwrap();
        let p = on_host.orientations();
        flow = flow.max(
            free.v
                .iter()
                .zip(&p)
                .map(|(v, p)| norm(axpy(*v, -SWIM_SPEED, *p)))
                .fold(0.0, f64::max),
        );
        let got = device.step_from(dt, Some((&free.v, &free.w))).unwrap();
        assert_eq!(
            got.contact.constraints, want.contact.constraints,
            "{level}, step {k}: constraints on the device and the CPU"
        );
        assert_eq!(
            got.projections, want.projections,
            "{level}, step {k}: overlap projections on the device and the CPU"
        );
        active += want.contact.active;
        projections += want.projections;
    }
    assert!(active > 20, "{level}: too few active contacts: {active}");
    assert!(
        flow > 1e-3,
        "{level}: the flow is too weak to test ({flow:.1e})"
    );
    device.download(&mut on_host).unwrap();
    let dx = (0..rods.len())
        .map(|i| norm(min_image(sub(on_host.x[i], cpu.x[i]), l)))
        .fold(0.0, f64::max);
    let dq = (0..rods.len())
        .flat_map(|i| (0..4).map(move |d| (i, d)))
        .map(|(i, d)| (on_host.q[i][d] - cpu.q[i][d]).abs())
        .fold(0.0, f64::max);
    let bound = 10.0 * STEPS as f64 * params.tolerance;
    assert!(
        dx <= bound && dq <= bound,
        "{level}: after {STEPS} steps the centres differ by {dx:.1e} l, the quaternions by \
         {dq:.1e} (bound {bound:.0e})"
    );
    assert_eq!(on_host.image, cpu.image, "{level}: images crossed");
    eprintln!(
        "{level}: {STEPS} steps of {} rods, flow up to {flow:.2e} beta l, {active} active \
         contacts, {projections} overlap projections; centres within {dx:.1e} l, quaternions \
         within {dq:.1e}",
        rods.len()
    );
}

/// The resident stepper's warm start (each contact problem from the last step's multipliers
/// by pair, as the CPU's stepper): 20 steps against the CPU's stepper within 20 x the solver
/// tolerance, in fewer solver iterations than the same steps started from zero, and a run
/// stopped after 10 steps and restarted from its rods and warm start (what a checkpoint
/// keeps) ending bit for bit where the uninterrupted run ends.
fn check_warm(open: &dyn Fn(&RodSet, &WarmStart) -> DeviceStepper, cold: &GpuStep) {
    const STEPS: usize = 20;
    let (l, dt) = (6.0, 0.02);
    let rods = random_nonoverlapping(432, l, DEFAULT_DIAMETER, 14, 1_000_000).unwrap();
    let params = ContactParams::default();
    let mut cpu = rods.clone();
    let mut stepper = Stepper::new(Box::new(LocalDrag::new(DEFAULT_DIAMETER)), params.clone());
    let mut whole = open(&rods, &Vec::new());
    let mut cold_rods = cold.upload_rods(&rods).unwrap();
    let (mut it_cpu, mut it_warm, mut it_cold) = (0, 0, 0);
    let mut resumed = None;
    for k in 0..STEPS {
        it_cpu += stepper.step(&mut cpu, dt).unwrap().contact.iterations;
        it_warm += whole.step(dt).unwrap().contact.iterations;
        it_cold += cold
            .step_local_drag(&mut cold_rods, dt, &params)
            .unwrap()
            .contact
            .iterations;
        if k + 1 == STEPS / 2 {
            let mut at = rods.clone();
            whole.download(&mut at).unwrap();
            let warm = whole.warm_start().unwrap();
            assert!(!warm.is_empty(), "no multipliers to start from");
            resumed = Some(open(&at, &warm));
        }
    }
    let mut again = resumed.expect("restarted at the middle");
    for _ in STEPS / 2..STEPS {
        again.step(dt).unwrap();
    }
    let (mut a, mut b) = (rods.clone(), rods.clone());
    whole.download(&mut a).unwrap();
    again.download(&mut b).unwrap();
    assert!(
        a.x == b.x && a.q == b.q && a.image == b.image,
        "restarted from rods and warm start after {} steps, the run differs from the \
         uninterrupted one",
        STEPS / 2
    );
    let dx = (0..a.len())
        .map(|i| norm(min_image(sub(a.x[i], cpu.x[i]), l)))
        .fold(0.0, f64::max);
    let bound = STEPS as f64 * params.tolerance;
    assert!(
        dx <= bound,
        "warm-started: centres {dx:.1e} l from the CPU's (bound {bound:.0e})"
    );
    assert!(
        it_warm < it_cold,
        "warm-started solves took {it_warm} iterations, from zero {it_cold}"
    );
    eprintln!(
        "warm start: {STEPS} steps in {it_warm} solver iterations (from zero {it_cold}, CPU \
         {it_cpu}); centres within {dx:.1e} l of the CPU's; restarted at step {} from rods \
         and multipliers: bit for bit",
        STEPS / 2
    );
}

/// The resident step's host round trips, counted by the device: one download per contact-solver
/// iteration (its four numbers) besides a fixed number per step, and the same launches per
/// iteration, on warm-started steps that solve (at least one iteration) without projecting.
/// A change that adds a round trip per iteration, or per constraint, fails here.
fn check_round_trips(open: &dyn Fn(&RodSet) -> DeviceStepper) {
    let rods = random_nonoverlapping(432, 6.0, DEFAULT_DIAMETER, 16, 1_000_000).unwrap();
    let mut d = open(&rods);
    let mut seen = Vec::new();
    for step in 0..12 {
        let before = d.counters();
        let r = d.step(0.02).unwrap();
        let c = d.counters().since(&before);
        // The first step starts from zero: no warm-start gather and no product of the start
        // (3 launches fewer).
        if step > 0 && r.contact.iterations > 0 && r.projections == 0 {
            let k = r.contact.iterations as i64;
            seen.push((k, c.downloads as i64 - k, c.launches as i64 - 4 * k));
        }
    }
    let ks: std::collections::BTreeSet<i64> = seen.iter().map(|s| s.0).collect();
    assert!(
        ks.len() >= 2,
        "steps with different iteration counts needed: {seen:?}"
    );
    assert!(
        seen.iter().all(|s| s.1 == seen[0].1 && s.2 == seen[0].2),
        "(iterations, downloads - iterations, launches - 4 x iterations) per step: {seen:?}"
    );
    eprintln!(
        "round trips: {} downloads and {} launches per step besides 1 and 4 per solver \
         iteration ({} steps, {:?} iterations)",
        seen[0].1,
        seen[0].2,
        seen.len(),
        ks
    );
}

/// The resident stepper repeats bit for bit: 30 steps with blocks in order and in two shuffled
/// orders (so the integer atomics of the cell and constraint lists take other orders) give the
/// same rods to the last bit.
fn check_repeats() {
    let (l, dt) = (6.0, 0.02);
    let rods = random_nonoverlapping(432, l, DEFAULT_DIAMETER, 10, 1_000_000).unwrap();
    let params = ContactParams::default();
    let mut finals = Vec::new();
    for seed in [0u64, 3, 99] {
        let mut s =
            DeviceStepper::new(Backend::HostEmulation, &rods, params.clone(), &Vec::new()).unwrap();
        s.shuffle_blocks(seed);
        let mut active = 0;
        for _ in 0..30 {
            active += s.step(dt).unwrap().contact.active;
        }
        let mut got = rods.clone();
        s.download(&mut got).unwrap();
        finals.push((got, active));
    }
    assert!(
        finals[0].1 > 20,
        "too few active contacts to test: {}",
        finals[0].1
    );
    for (k, (f, _)) in finals.iter().enumerate().skip(1) {
        assert!(
            f.x == finals[0].0.x && f.q == finals[0].0.q && f.image == finals[0].0.image,
            "run {k} (blocks shuffled) differs from the run with blocks in order"
        );
    }
    eprintln!(
        "30 resident steps repeat bit for bit with blocks in order and shuffled twice ({} active contacts)",
        finals[0].1
    );
}

fn wrap(y: Vec3, l: f64) -> Vec3 {
    y.map(|c| c.rem_euclid(l))
}

fn check(open: &dyn Fn() -> GpuStep, shuffles: &[u64]) {
    for (label, x, l, cutoff) in cases() {
        let want = brute_force(&x, l, cutoff);
        assert!(!want.is_empty(), "{label}: no pairs to compare");
        for &seed in shuffles {
            let dev = open();
            let shuffled = seed != 0 && dev.shuffle_blocks(seed);
            let got = dev.pairs(&x, l, cutoff).unwrap();
            let missing = want
                .iter()
                .filter(|p| got.binary_search(p).is_err())
                .count();
            let extra = got
                .iter()
                .filter(|p| want.binary_search(p).is_err())
                .count();
            assert_eq!(
                got,
                want,
                "{label}, blocks {}: {} pairs on the device, {} by brute force; {missing} \
                 missing, {extra} extra, or out of order",
                if shuffled { "shuffled" } else { "in order" },
                got.len(),
                want.len()
            );
            eprintln!(
                "{label}: {} pairs equal ({})",
                got.len(),
                if shuffled {
                    "shuffled blocks"
                } else {
                    "blocks in order"
                }
            );
        }
    }
    // A box narrower than 3 cells is refused with the reason, not searched wrongly.
    let err = open().pairs(&[[0.0; 3], [1.0; 3]], 3.0, 1.35).unwrap_err();
    assert!(err.to_string().contains("at least 3 cells"), "{err}");
}

/// The emulated device's step kernels, or `None` (the reason printed) where no C++ compiler
/// runs and `MOTILE_REQUIRE_CXX` is unset.
fn emulation() -> Option<GpuStep> {
    motile_gpu::open_or_skip(
        GpuStep::open(Backend::HostEmulation),
        Backend::HostEmulation,
    )
}

fn emulated_stepper(rods: &RodSet, warm: &WarmStart) -> DeviceStepper {
    DeviceStepper::new(Backend::HostEmulation, rods, ContactParams::default(), warm).unwrap()
}

// Several tests, so that the test threads run them side by side.
#[test]
fn device_step_rooms_match_their_twins_on_the_host_emulation() {
    let Some(d) = emulation() else {
        return;
    };
    eprintln!("host emulation: {}", d.describe());
    let open = || emulation().expect("opened above");
    check(&open, &[0, 7, 1234567]);
    check_update(&open(), 0.0);
    check_constraints(&open(), 0.0);
    check_solver(&open(), 0.0);
}

#[test]
fn device_steps_match_the_cpu_and_resume_on_the_host_emulation() {
    let Some(d) = emulation() else {
        return;
    };
    check_steps(&d);
    check_warm(&emulated_stepper, &d);
}

#[test]
fn device_steps_repeat_and_round_trip_on_the_host_emulation() {
    if emulation().is_some() {
        check_repeats();
        check_round_trips(&|r| emulated_stepper(r, &Vec::new()));
    }
}

fn check_emulated_flow_steps(level: &str) {
    if emulation().is_some() {
        let rods = random_nonoverlapping(432, 6.0, DEFAULT_DIAMETER, 12, 1_000_000).unwrap();
        check_flow_steps(&|| emulated_stepper(&rods, &Vec::new()), &rods, level);
    }
}

#[test]
fn dipole_steps_on_the_host_emulation_match_the_cpu() {
    check_emulated_flow_steps("dipole");
}

#[test]
fn explicit_slender_body_steps_on_the_host_emulation_match_the_cpu() {
    check_emulated_flow_steps("sbt-explicit");
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/device_run.sh parity runs it)"]
fn device_step_rooms_match_their_twins_on_cuda() {
    let Some(d) = motile_gpu::open_or_skip(GpuStep::open(Backend::Cuda), Backend::Cuda) else {
        return;
    };
    eprintln!("CUDA: {}", d.describe());
    check(&|| GpuStep::open(Backend::Cuda).unwrap(), &[0]);
    check_update(&GpuStep::open(Backend::Cuda).unwrap(), 1e-14);
    check_constraints(&GpuStep::open(Backend::Cuda).unwrap(), 1e-13);
    check_solver(&GpuStep::open(Backend::Cuda).unwrap(), 1e-10);
    check_steps(&GpuStep::open(Backend::Cuda).unwrap());
    check_warm(
        &|r, w| DeviceStepper::new(Backend::Cuda, r, ContactParams::default(), w).unwrap(),
        &GpuStep::open(Backend::Cuda).unwrap(),
    );
    let rods = random_nonoverlapping(432, 6.0, DEFAULT_DIAMETER, 12, 1_000_000).unwrap();
    let stepper =
        || DeviceStepper::new(Backend::Cuda, &rods, ContactParams::default(), &Vec::new());
    for level in ["dipole", "sbt-explicit"] {
        check_flow_steps(&|| stepper().unwrap(), &rods, level);
    }
}
