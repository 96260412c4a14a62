//! The slender-body level's (P4) solved on the device (feature `gpu`: `hydro::gpu`), against
//! the CPU's solve, on what the simulations produce: swimming rods close enough to interact
//! strongly, then the same rods with contact forces and torques on some of them (the step's
//! second solve, warm-started from the first).
//! - With the same products (the device's GMRES taking its RPY sums from a CPU sum of the same
//!   tolerance, `P4Sum::Host`): the nodes, the right-hand sides, every iterate and the
//!   velocities are the CPU's bits, and GMRES takes the same iterations with the same residual
//!   estimates. This checks every kernel of the solve (the operator, the chunked dot products
//!   and their fold, the Gram-Schmidt updates, the restarts' residual, the update of `x`, the
//!   velocities with the local drag of the contact forces) against the CPU's arithmetic.
//! - With the resident sum (`SlenderBody` on a `SpectralEwald` with a device): the velocities
//!   within round-off of the CPU's (the sums differ in the order of their additions), the
//!   same iterations and the same sums' report.
//! - Ten steps of the resident stepper at the `sbt` level (`DeviceStepper` with the
//!   prediction, the contact problem, the final solve with the contact forces, the correction
//!   and the move all on the device) against the CPU's stepper: the rods within what the
//!   contact solver's tolerance allows, the same constraints, GMRES iterations and sums each
//!   step, and the warm state kept on the device (downloaded) the CPU's within the same
//!   bound.
//!
//! On the host emulation (skipped with the reason where no C++ compiler runs, a failure with
//! `MOTILE_REQUIRE_CXX=1`).

mod common;

use motile_gpu::Backend;
use motile_particle::ewald::gpu::{GpuFourier, SpreadMethod};
use motile_particle::ewald::periodic::RpyGeometry;
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::gmres::GmresParams;
use motile_particle::hydro::gpu::{
    DeviceP4, DeviceVelocities, P4Sum, RodMotion, SlenderDevice, SlenderFlow,
};
use motile_particle::hydro::mobility::{LocalDrag, Mobility, MobilityState, RodVelocities};
use motile_particle::hydro::slender::{SlenderBody, SlenderParams, half_rod_rule};
use motile_particle::model::geometry::{Vec3, norm, sub};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::{DEFAULT_DIAMETER, ROD_LENGTH, SWIM_SPEED, eta};
use motile_particle::step::contact::ContactParams;
use motile_particle::step::gpu::DeviceStepper;
use motile_particle::step::report::StepError;
use motile_particle::step::stepper::Stepper;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const TOL: f64 = 1e-6;

fn rods() -> RodSet {
    // 96 rods in a box of 4 rod lengths (nu = n l^3 / V = 1.5): neighbours within a rod length.
    random_nonoverlapping(96, 4.0, DEFAULT_DIAMETER, 17, 1_000_000).unwrap()
}

/// Contact forces and torques on every third rod (zero elsewhere), as the contact solver
/// leaves them: a few rods pushed, most free.
fn contact_forces(n: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    (0..n)
        .map(|r| {
            if r % 3 == 0 {
                (
                    [0, 1, 2].map(|_| rng.random_range(-5.0..5.0)),
                    [0, 1, 2].map(|_| rng.random_range(-0.5..0.5)),
                )
            } else {
                ([0.0; 3], [0.0; 3])
            }
        })
        .collect()
}

fn params() -> SlenderParams {
    SlenderParams {
        gmres: GmresParams {
            // Restarts inside the solve, so that they are checked too.
            restart: 4,
            ..GmresParams::default()
        },
        ..SlenderParams::for_diameter(DEFAULT_DIAMETER)
    }
}

/// The CPU's solution of (P4) and flow velocities per rod from its rod state.
fn cpu_state(mobility: &SlenderBody, n: usize) -> (Vec<f64>, Vec<f64>) {
    let rows = mobility.rod_state().expect("a solution");
    let width = rows.len() / n;
    let x = rows.chunks(width).flat_map(|r| r[..width - 6].to_vec());
    let flow = rows.chunks(width).flat_map(|r| r[width - 6..].to_vec());
    (x.collect(), flow.collect())
}

fn bits_differ(a: &[f64], b: &[f64]) -> usize {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count()
}

/// The device's solve with the CPU's products against `SlenderBody` on the CPU: the same bits.
fn check_same_products(backend: Backend) {
    let rods = rods();
    let n = rods.len();
    let p = rods.orientations();
    let prm = params();
    let mut cpu = SlenderBody::new(prm, Box::new(SpectralEwald::new(TOL).unwrap()));
    let mut out = RodVelocities::zeros(n);
    cpu.free_velocities(&rods, &p, &mut out).unwrap();
    let free_iterations = cpu.report().gmres_iterations;
    let (x_free, flow_free) = cpu_state(&cpu, n);
    let ft = contact_forces(n);
    let mut out_ft = RodVelocities::zeros(n);
    cpu.final_velocities(&rods, &p, &ft, &mut out_ft).unwrap();
    let contact_iterations = cpu.report().gmres_iterations;
    let (x_contact, flow_contact) = cpu_state(&cpu, n);
    assert!(
        free_iterations > prm.gmres.restart && contact_iterations > 0,
        "the test needs restarts: {free_iterations} and {contact_iterations} iterations"
    );

    let kern = SlenderDevice::open(backend).unwrap();
    let (s, w) = half_rod_rule(prm.quadrature_points, ROD_LENGTH);
    let rule = kern.rule(&s, &w).unwrap();
    let up = |v: &[f64]| kern.upload(v).unwrap();
    let (xs, axes) = (up(rods.x.as_flattened()), up(p.as_flattened()));
    let nodes = kern.nodes(&xs, &axes, &rule, n).unwrap();
    let points = cpu.node_positions(&rods, &p);
    let nodes_host = kern.download(&nodes).unwrap();
    assert_eq!(
        bits_differ(&nodes_host, points.as_flattened()),
        0,
        "nodes on the device and the CPU"
    );
    let e = eta(prm.diameter);
    let c = SWIM_SPEED / (2.0 * e);
    let mut host_sum = SpectralEwald::new(TOL).unwrap();
    let geometry = RpyGeometry {
        box_length: rods.box_length,
        radius: prm.rpy_radius,
        group: s.len(),
    };
    let drag = LocalDrag::new(prm.diameter).coefficients();
    let ft_flat: Vec<f64> = ft
        .iter()
        .flat_map(|(f, t)| f.iter().chain(t))
        .copied()
        .collect();
    let ft_dev = up(&ft_flat);
    let mut x = None;
    for (stage, ft, iterations, want_x, want_flow, want_v) in [
        ("free", None, free_iterations, &x_free, &flow_free, &out),
        (
            "with contact forces",
            Some(&ft_dev),
            contact_iterations,
            &x_contact,
            &flow_contact,
            &out_ft,
        ),
    ] {
        let b = kern.rhs(&axes, ft, &rule, n, c, ROD_LENGTH).unwrap();
        // The CPU's first warm start is the right-hand side itself.
        let mut xd = x.take().unwrap_or_else(|| up(&kern.download(&b).unwrap()));
        let op = DeviceP4 {
            sum: P4Sum::Host(&mut host_sum, &points),
            geometry,
            nodes: &nodes,
            p: &axes,
            rule: &rule,
            n,
            eta: e,
            l: ROD_LENGTH,
        };
        let solved = kern.solve(op, &b, &mut xd, &prm.gmres).unwrap();
        assert_eq!(
            solved.info.iterations, iterations,
            "{stage}: iterations on the device and the CPU"
        );
        let xh = kern.download(&xd).unwrap();
        let differ = bits_differ(&xh, want_x);
        assert_eq!(
            differ,
            0,
            "{stage}: {differ} of {} unknowns differ",
            xh.len()
        );
        let SlenderFlow {
            flow,
            rods: DeviceVelocities { v, w: om },
        } = kern
            .velocities(
                &axes,
                &solved.u,
                ft,
                &rule,
                n,
                RodMotion {
                    length: ROD_LENGTH,
                    swim: SWIM_SPEED,
                    drag,
                },
            )
            .unwrap();
        let flow = kern.download(&flow).unwrap();
        assert_eq!(bits_differ(&flow, want_flow), 0, "{stage}: flow velocities");
        let (v, om) = (kern.download(&v).unwrap(), kern.download(&om).unwrap());
        assert_eq!(
            bits_differ(&v, want_v.v.as_flattened()),
            0,
            "{stage}: velocities"
        );
        assert_eq!(
            bits_differ(&om, want_v.w.as_flattened()),
            0,
            "{stage}: angular velocities"
        );
        eprintln!(
            "{stage}: {} iterations (restart {}), residual {:.2e}; {} unknowns, {} flow \
             velocities the CPU's bits",
            solved.info.iterations,
            prm.gmres.restart,
            solved.info.final_residual,
            xh.len(),
            flow.len()
        );
        x = Some(xd);
    }
}

/// `SlenderBody` on a resident sum against the same on the CPU's sum: the free and the
/// contact solve's velocities within 1e-12 of the largest flow speed and rotation rate (the
/// sums' round-off, about 1e-15 of the flow per product, through a solve to 1e-5), the same
/// iterations and sums.
fn check_resident_solve(gpu: GpuFourier) {
    let rods = rods();
    let n = rods.len();
    let p = rods.orientations();
    let prm = SlenderParams::for_diameter(DEFAULT_DIAMETER);
    let mut cpu = SlenderBody::new(prm, Box::new(SpectralEwald::new(TOL).unwrap()));
    let mut dev = SlenderBody::new(prm, Box::new(SpectralEwald::with_device(TOL, gpu).unwrap()));
    let ft = contact_forces(n);
    for stage in ["free", "with contact forces"] {
        let (mut want, mut got) = (RodVelocities::zeros(n), RodVelocities::zeros(n));
        if stage == "free" {
            cpu.free_velocities(&rods, &p, &mut want).unwrap();
            dev.free_velocities(&rods, &p, &mut got).unwrap();
        } else {
            cpu.final_velocities(&rods, &p, &ft, &mut want).unwrap();
            dev.final_velocities(&rods, &p, &ft, &mut got).unwrap();
        }
        let flow = want
            .v
            .iter()
            .zip(&p)
            .map(|(v, p)| norm(sub(*v, p.map(|c| SWIM_SPEED * c))))
            .fold(0.0, f64::max);
        let turn = want.w.iter().map(|w| norm(*w)).fold(0.0, f64::max);
        let diff = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| norm(sub(*x, *y)))
                .fold(0.0, f64::max)
        };
        let (dv, dw) = (diff(&got.v, &want.v) / flow, diff(&got.w, &want.w) / turn);
        let (gr, wr) = (dev.report(), cpu.report());
        assert!(
            flow > 1e-2 && turn > 1e-2,
            "{stage}: the flow is too weak to test: {flow:.1e}, {turn:.1e}"
        );
        assert!(
            dv <= 1e-12 && dw <= 1e-12,
            "{stage}: velocities differ by {dv:.1e} of the largest flow {flow:.2e}, angular \
             velocities by {dw:.1e} of the largest rate {turn:.2e} (bound 1e-12)"
        );
        assert_eq!(
            gr.gmres_iterations, wr.gmres_iterations,
            "{stage}: iterations"
        );
        assert_eq!(gr.sums, wr.sums, "{stage}: sums");
        assert_eq!(gr.sum_level, wr.sum_level, "{stage}: refinement level");
        assert!(
            gr.gmres_residual <= prm.gmres.tol,
            "{stage}: residual {:.2e}",
            gr.gmres_residual
        );
        eprintln!(
            "{stage}: velocities within {dv:.1e} of the flow {flow:.2e}, rates within {dw:.1e} \
             of {turn:.2e}; {} iterations, {} sums, residual {:.2e} (CPU {:.2e})",
            gr.gmres_iterations, gr.sums, gr.gmres_residual, wr.gmres_residual
        );
    }
}

/// Ten resident `sbt` steps against the CPU's stepper (see the file's head), resumed on a fresh
/// device stepper and mobility after five (from the rods, the contact multipliers, the warm
/// and the sum's state downloaded, as a checkpoint holds them), then a step that fails after its
/// final solve (no overlap allowed): the warm state on the device is then the one before it,
/// bit for bit. `open` opens the sums' devices.
fn check_steps(backend: Backend, open: impl Fn() -> GpuFourier) {
    const STEPS: usize = 10;
    let rods = random_nonoverlapping(216, 4.8, DEFAULT_DIAMETER, 12, 1_000_000).unwrap();
    let dt = 0.02;
    let params = ContactParams::default();
    let prm = SlenderParams::for_diameter(DEFAULT_DIAMETER);
    let mut cpu = rods.clone();
    let mut stepper = Stepper::new(
        Box::new(SlenderBody::new(
            prm,
            Box::new(SpectralEwald::new(TOL).unwrap()),
        )),
        params.clone(),
    );
    let mut device = DeviceStepper::new(backend, &rods, params.clone(), &Vec::new()).unwrap();
    let mobility = || -> Box<dyn Mobility> {
        Box::new(SlenderBody::new(
            prm,
            Box::new(SpectralEwald::with_device(TOL, open()).unwrap()),
        ))
    };
    let mut flow = mobility();
    let path = flow.resident().expect("a device path");
    assert!(path.flows_on_device() && path.finishes_on_device());
    let (mut active, mut corrections) = (0, 0);
    for k in 0..STEPS {
        if k == STEPS / 2 {
            // A resume on the device: what a checkpoint holds, into a fresh stepper and mobility.
            let warm = flow
                .resident()
                .expect("a device path")
                .resident_warm_state()
                .expect("on the device")
                .unwrap();
            assert_ne!(
                warm,
                flow.warm_state(),
                "the host's copy is behind the device's between outputs"
            );
            let mut at = rods.clone();
            device.download(&mut at).unwrap();
            let contact = device.warm_start().unwrap();
            let mut fresh = mobility();
            fresh.set_sum_state(&flow.sum_state());
            fresh.set_warm_state(warm);
            device = DeviceStepper::new(backend, &at, params.clone(), &contact).unwrap();
            flow = fresh;
        }
        let want = stepper.step(&mut cpu, dt).unwrap();
        let got = device.step_with_resident_flow(dt, flow.as_mut()).unwrap();
        let what = format!("step {k}");
        assert_eq!(
            got.contact.constraints, want.contact.constraints,
            "{what}: constraints on the device and the CPU"
        );
        assert_eq!(got.projections, want.projections, "{what}: projections");
        assert_eq!(
            got.hydro.gmres_iterations, want.hydro.gmres_iterations,
            "{what}: GMRES iterations"
        );
        assert_eq!(got.hydro.sums, want.hydro.sums, "{what}: sums");
        assert_eq!(
            got.correction_active, want.correction_active,
            "{what}: constraints the correction made active"
        );
        active += want.contact.active;
        corrections += want.correction_active;
    }
    assert!(active > 20, "too few active contacts: {active}");
    let (dx, dq) = common::assert_device_rods_near(&device, &cpu, (STEPS, params.tolerance), "sbt");
    let bound = 10.0 * STEPS as f64 * params.tolerance;
    let warm = flow
        .resident()
        .expect("a device path")
        .resident_warm_state()
        .expect("the warm state on the device")
        .unwrap();
    let want = stepper.mobility().warm_state();
    assert_eq!(warm.len(), want.len(), "warm state's length");
    let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let dw = warm
        .iter()
        .zip(&want)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()))
        / scale;
    assert!(
        dw <= bound,
        "the warm state differs by {dw:.1e} of its largest value (bound {bound:.0e})"
    );
    // A failed step leaves the warm state as it was (the rods too: the stepper's own test).
    let mut at = rods.clone();
    device.download(&mut at).unwrap();
    // No overlap allowed: the step fails after its final solve (which moved the state kept on
    // the device), on the overlaps the move leaves.
    let strict = ContactParams {
        overlap_tolerance: 1e-15,
        ..params.clone()
    };
    let contact = device.warm_start().unwrap();
    let mut failing = DeviceStepper::new(backend, &at, strict, &contact).unwrap();
    let failed = failing.step_with_resident_flow(dt, flow.as_mut());
    assert!(
        matches!(failed, Err(StepError::Overlap { .. })),
        "a step allowing no overlap: {failed:?}"
    );
    let after = flow
        .resident()
        .expect("a device path")
        .resident_warm_state()
        .expect("on the device")
        .unwrap();
    assert!(
        after == warm,
        "the warm state after a failed step is not the one before it"
    );
    eprintln!(
        "{STEPS} resident sbt steps of {} rods (resumed on a fresh stepper after {}), {active} \
         active contacts, {corrections} made active by the correction: centres within {dx:.1e} \
         l, quaternions within {dq:.1e}, warm state within {dw:.1e}; a failed step keeps the \
         warm state",
        rods.len(),
        STEPS / 2
    );
}

/// Three resident `sbt` steps with every device's blocks run in order and in a shuffled order
/// (the stepper's, the sum's with its default, output-driven spreader, and the slender-body
/// kernels'): the rods and the warm state are the same bits, as the step has no floating-point
/// atomics and its sorts undo the integer atomics' order, so GPU runs of this level repeat bit
/// for bit. (With the per-point atomic spreader instead, the same shuffle moves the rods
/// differently: the check can fail. 128 rods, so that the per-point and per-rod kernels run
/// several blocks.)
fn check_block_order(open: impl Fn() -> GpuFourier) {
    // Not many more: the output-driven spreader runs each of its blocks as 256 OS threads here.
    let rods = random_nonoverlapping(128, 4.0, DEFAULT_DIAMETER, 12, 1_000_000).unwrap();
    let prm = SlenderParams::for_diameter(DEFAULT_DIAMETER);
    let run = |seed: u64| {
        let mut gpu = open();
        gpu.set_spread_method(None);
        assert!(gpu.shuffle_blocks(seed), "the emulation shuffles");
        let mut flow =
            SlenderBody::new(prm, Box::new(SpectralEwald::with_device(TOL, gpu).unwrap()));
        flow.shuffle_device_blocks(seed);
        let mut device = DeviceStepper::new(
            Backend::HostEmulation,
            &rods,
            ContactParams::default(),
            &Vec::new(),
        )
        .unwrap();
        device.shuffle_blocks(seed);
        let mut contacts = 0;
        for _ in 0..3 {
            let r = device.step_with_resident_flow(0.02, &mut flow).unwrap();
            contacts += r.contact.constraints;
        }
        assert!(contacts > 0, "no contacts to order");
        let mut at = rods.clone();
        device.download(&mut at).unwrap();
        (
            at,
            flow.resident()
                .expect("a device path")
                .resident_warm_state()
                .expect("on the device")
                .unwrap(),
        )
    };
    let (a, wa) = run(0);
    let (b, wb) = run(7);
    let bits = |r: &RodSet| -> Vec<u64> {
        r.x.iter()
            .flatten()
            .chain(r.q.iter().flatten())
            .map(|v| v.to_bits())
            .collect()
    };
    assert!(
        bits(&a) == bits(&b) && a.image == b.image,
        "three sbt steps with the blocks shuffled moved the rods differently"
    );
    assert_eq!(
        bits_differ(&wa, &wb),
        0,
        "the warm state with the blocks shuffled"
    );
    eprintln!("three resident sbt steps, blocks in order and shuffled: the same bits");
}

/// The emulated device with the sorted spreader (the output-driven spreader's many small
/// blocks are slow on the emulation), or `None` where no C++ compiler runs.
fn sorted_emulation() -> Option<GpuFourier> {
    common::emulation().map(|mut g| {
        g.set_spread_method(Some(SpreadMethod::Sorted));
        g
    })
}

// Three tests, so that the test threads run them side by side.
#[test]
fn the_slender_body_solve_on_the_host_emulation_matches_the_cpu() {
    let Some(gpu) = sorted_emulation() else {
        return;
    };
    check_same_products(Backend::HostEmulation);
    check_resident_solve(gpu);
}

#[test]
fn slender_body_steps_on_the_host_emulation_match_the_cpu() {
    if sorted_emulation().is_some() {
        check_steps(Backend::HostEmulation, || {
            sorted_emulation().expect("opened above")
        });
    }
}

#[test]
fn slender_body_steps_on_the_host_emulation_repeat_with_blocks_shuffled() {
    if sorted_emulation().is_some() {
        check_block_order(|| sorted_emulation().expect("opened above"));
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/device_run.sh parity runs it)"]
fn the_slender_body_solve_and_step_on_cuda_match_the_cpu() {
    let cuda = || common::device(Backend::Cuda);
    let Some(gpu) = cuda() else {
        return;
    };
    check_same_products(Backend::Cuda);
    check_resident_solve(gpu);
    check_steps(Backend::Cuda, || cuda().expect("opened above"));
}
