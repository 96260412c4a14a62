//! The flow of the `dipole` and `sbt-explicit` levels summed on the device the rods are on
//! (feature `gpu`: `Mobility::free_velocities_resident`, `SpectralEwald::stresslets_resident`
//! and `rpy_resident`) against the same mobility summing on the CPU, on what the simulations
//! produce: swimming rods (force-free densities, one stresslet strength), non-overlapping,
//! dense enough for contacts every step, and dilute in a box of many cells.
//! - the free velocities (swimming plus the flow: Jeffery's rotation from its gradient at the
//!   dipole level, the rigid-body projection of the flow at the rods' nodes at the explicit
//!   level) against the CPU's within round-off of the flow, with each spreader, and the sum's
//!   report (sums, refinement level, the error estimate) the CPU's;
//! - ten steps of the resident stepper with the flow on the device against the CPU's stepper:
//!   within what the contact solver's tolerance allows (as the steps with the host's flow).
//!
//! On the host emulation (skipped with the reason where no C++ compiler runs, a failure with
//! `MOTILE_REQUIRE_CXX=1`); on CUDA in the `#[ignore]`d test that `scripts/device_run.sh
//! parity` runs.

mod common;

use motile_gpu::Backend;
use motile_particle::ewald::gpu::{GpuFourier, SpreadMethod};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::explicit::ExplicitSlender;
use motile_particle::hydro::gpu::{DeviceVelocities, RodsOnDevice};
use motile_particle::hydro::mobility::{Mobility, RodVelocities};
use motile_particle::hydro::slender::SlenderParams;
use motile_particle::model::geometry::{Vec3, axpy, norm, sub};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::{DEFAULT_DIAMETER, SWIM_SPEED};
use motile_particle::step::contact::ContactParams;
use motile_particle::step::gpu::{DeviceStepper, GpuStep};
use motile_particle::step::stepper::Stepper;

/// The mobility of `level` (`dipole` or `sbt-explicit`) on the sum `sum`.
fn mobility(level: &str, sum: SpectralEwald) -> Box<dyn Mobility> {
    match level {
        "dipole" => Box::new(Dipole::new(Box::new(sum), DEFAULT_DIAMETER)),
        "sbt-explicit" => Box::new(ExplicitSlender::new(
            SlenderParams::for_diameter(DEFAULT_DIAMETER),
            Box::new(sum),
        )),
        _ => panic!("no level {level}"),
    }
}

/// `level`'s mobility on a sum at tolerance `tol` on `backend`, spreading with `method`.
fn on_device(
    level: &str,
    backend: Backend,
    tol: f64,
    method: Option<SpreadMethod>,
) -> Box<dyn Mobility> {
    let mut gpu = GpuFourier::open(backend).unwrap();
    gpu.set_spread_method(method);
    mobility(level, SpectralEwald::with_device(tol, gpu).unwrap())
}

fn triples(v: &[f64]) -> Vec<Vec3> {
    v.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
}

fn largest_difference(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| norm(sub(*x, *y)))
        .fold(0.0, f64::max)
}

/// The free velocities of `rods` from the resident sum against the CPU's sum at tolerance
/// `tol`: velocities within 1e-12 of the largest flow speed, angular velocities within 1e-12 of
/// the largest rotation rate (round-off: the two sums differ in the order of their additions,
/// measured 1e-15-1e-14), the reports the same.
fn check_free(
    level: &str,
    backend: Backend,
    rods: &RodSet,
    tol: f64,
    method: Option<SpreadMethod>,
) {
    let step = GpuStep::open(backend).unwrap();
    let resident = step.upload_rods(rods).unwrap();
    let mut dev = on_device(level, backend, tol, method);
    let path = dev.resident().expect("a device path");
    assert!(
        path.flows_on_device(),
        "{level} on a device sum flows there"
    );
    let DeviceVelocities { v, w } = path
        .free_velocities_resident(RodsOnDevice {
            x: &resident.x,
            q: &resident.q,
            len: resident.len,
            box_length: resident.box_length,
        })
        .expect("a device path")
        .unwrap();
    let (v, w) = (
        triples(&step.download(&v).unwrap()),
        triples(&step.download(&w).unwrap()),
    );
    let mut cpu = mobility(level, SpectralEwald::new(tol).unwrap());
    assert!(
        !cpu.resident().is_some_and(|r| r.flows_on_device()),
        "{level} on the CPU's sum does not"
    );
    let p = rods.orientations();
    let mut want = RodVelocities::zeros(rods.len());
    cpu.free_velocities(rods, &p, &mut want).unwrap();
    let flow = want
        .v
        .iter()
        .zip(&p)
        .map(|(v, p)| norm(axpy(*v, -SWIM_SPEED, *p)))
        .fold(0.0, f64::max);
    let turn = want.w.iter().map(|w| norm(*w)).fold(0.0, f64::max);
    assert!(
        flow > 1e-3 && turn > 1e-3,
        "the flow is too weak to test: {flow:.1e}, {turn:.1e}"
    );
    let (dv, dw) = (
        largest_difference(&v, &want.v) / flow,
        largest_difference(&w, &want.w) / turn,
    );
    let what = format!(
        "{level}, {} rods, tol {tol:e}, spreader {method:?}",
        rods.len()
    );
    assert!(
        dv <= 1e-12 && dw <= 1e-12,
        "{what}: velocities differ by {dv:.1e} of the largest flow {flow:.2e}, angular \
         velocities by {dw:.1e} of the largest rate {turn:.2e} (bound 1e-12)"
    );
    let (got, want) = (dev.report(), cpu.report());
    assert_eq!(got.sums, want.sums, "{what}: sums");
    assert_eq!(got.sum_level, want.sum_level, "{what}: refinement level");
    let ratio = (got.sum_error_ratio - want.sum_error_ratio).abs() / want.sum_error_ratio;
    assert!(
        ratio <= 1e-10,
        "{what}: estimated error ratios {:.6e} and {:.6e}",
        got.sum_error_ratio,
        want.sum_error_ratio
    );
    eprintln!(
        "{what}: velocities within {dv:.1e} of the flow {flow:.2e}, rates within {dw:.1e} of \
         {turn:.2e}; error ratio {:.3e} (CPU {:.3e}), level {}",
        got.sum_error_ratio, want.sum_error_ratio, got.sum_level
    );
}

/// Ten steps of the resident stepper with its flow on the device against the CPU's stepper
/// with the CPU's sum: the rods within 10 x steps x the solver tolerance (the bound of the
/// steps with the host's flow), the same constraints and projections each step.
fn check_steps(level: &str, backend: Backend, rods: &RodSet) {
    const STEPS: usize = 10;
    let (dt, tol) = (0.02, 1e-8);
    let params = ContactParams::default();
    let mut cpu = rods.clone();
    let mut stepper = Stepper::new(
        mobility(level, SpectralEwald::new(tol).unwrap()),
        params.clone(),
    );
    let mut device = DeviceStepper::new(backend, rods, params.clone(), &Vec::new()).unwrap();
    let mut flow = on_device(level, backend, tol, Some(SpreadMethod::Sorted));
    let mut active = 0;
    for k in 0..STEPS {
        let want = stepper.step(&mut cpu, dt).unwrap();
        let got = device.step_with_resident_flow(dt, flow.as_mut()).unwrap();
        assert_eq!(
            got.contact.constraints, want.contact.constraints,
            "{level}, step {k}: constraints on the device and the CPU"
        );
        assert_eq!(
            got.projections, want.projections,
            "{level}, step {k}: projections"
        );
        assert_eq!(got.hydro.sums, 1, "{level}, step {k}: one sum");
        active += want.contact.active;
    }
    assert!(active > 20, "{level}: too few active contacts: {active}");
    let (dx, dq) = common::assert_device_rods_near(&device, &cpu, (STEPS, params.tolerance), level);
    eprintln!(
        "{STEPS} resident {level} steps of {} rods, {active} active contacts: centres within \
         {dx:.1e} l, quaternions within {dq:.1e}",
        rods.len()
    );
}

/// A sum of host values after a resident sum of other points with the same parameters gives
/// the bits it gave before: no device cache made for the resident sum's points (their bins,
/// their generation) is taken for the host's points.
fn check_caches(backend: Backend) {
    let mut gpu = GpuFourier::open(backend).unwrap();
    gpu.set_spread_method(Some(SpreadMethod::Sorted));
    let mut sum = SpectralEwald::with_device(1e-4, gpu).unwrap();
    let l = 10.0;
    let few = random_nonoverlapping(300, l, DEFAULT_DIAMETER, 5, 1_000_000).unwrap();
    let many = random_nonoverlapping(600, l, DEFAULT_DIAMETER, 6, 1_000_000).unwrap();
    let geometry = RpyGeometry {
        box_length: l,
        radius: 0.1,
        group: 1,
    };
    let forces = |r: &RodSet| r.orientations();
    let first = sum.rpy(&geometry, &few.x, &forces(&few)).unwrap();
    sum.fixed = sum.last_params();
    let other = sum
        .rpy_via_device(&geometry, &many.x, &mut None, &forces(&many))
        .unwrap();
    assert_eq!(other.len(), many.len());
    let again = sum.rpy(&geometry, &few.x, &forces(&few)).unwrap();
    let differ = first.iter().zip(&again).filter(|(a, b)| a != b).count();
    assert_eq!(
        differ, 0,
        "a host sum after a resident sum of 600 other points: {differ} of 300 velocities changed"
    );
}

fn cases() -> Vec<RodSet> {
    vec![
        // Dense (contacts every step) and dilute with a box of many cells.
        random_nonoverlapping(432, 6.0, DEFAULT_DIAMETER, 12, 1_000_000).unwrap(),
        random_nonoverlapping(300, 10.0, DEFAULT_DIAMETER, 5, 1_000_000).unwrap(),
    ]
}

/// One level's resident flow on the emulation against the CPU (a test per level, so that the
/// test threads run them side by side).
fn check_emulated_level(level: &str) {
    if common::emulation().is_none() {
        return;
    }
    let rods = cases();
    let emu = Backend::HostEmulation;
    for tol in [1e-4, 1e-8] {
        check_free(level, emu, &rods[0], tol, Some(SpreadMethod::Sorted));
    }
    check_free(level, emu, &rods[1], 1e-6, Some(SpreadMethod::Atomic));
    check_steps(level, emu, &rods[0]);
}

#[test]
fn resident_dipole_flow_matches_the_cpu_on_the_host_emulation() {
    check_emulated_level("dipole");
    if common::emulation().is_some() {
        check_free("dipole", Backend::HostEmulation, &cases()[1], 1e-4, None);
        check_caches(Backend::HostEmulation);
    }
}

#[test]
fn resident_explicit_slender_flow_matches_the_cpu_on_the_host_emulation() {
    check_emulated_level("sbt-explicit");
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/device_run.sh parity runs it)"]
fn resident_flow_matches_the_cpu_on_cuda() {
    match GpuFourier::open(Backend::Cuda) {
        Ok(d) => eprintln!("CUDA: {}", d.describe()),
        Err(e) if std::env::var("MOTILE_REQUIRE_GPU").is_err() => {
            eprintln!("skipped ({e}); set MOTILE_REQUIRE_GPU=1 to make this a failure");
            return;
        }
        Err(e) => panic!("{e} (and MOTILE_REQUIRE_GPU is set)"),
    }
    let rods = cases();
    for level in ["dipole", "sbt-explicit"] {
        for tol in [1e-4, 1e-8] {
            for method in [None, Some(SpreadMethod::Sorted)] {
                check_free(level, Backend::Cuda, &rods[0], tol, method);
            }
        }
        check_free(level, Backend::Cuda, &rods[1], 1e-6, None);
        check_steps(level, Backend::Cuda, &rods[0]);
    }
}
