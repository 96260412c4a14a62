//! The device memory of the dipole level's step resident on the device (feature `gpu`), the
//! quantity of the GPU memory target (at most 3 KB of GPU memory per rod at L/l = 100), counted
//! without a GPU: the process's tally of device buffers (`motile_gpu::live_bytes` and
//! `peak_bytes`) counts the same bytes on the host emulation as on CUDA.
//!
//! A step's memory is the sum's grids (the trace-free stresslet components, one in-place grid
//! each, kept from step to step) plus what scales with the rods (their state, the contacts, the
//! cell lists, bins and the sum's per-point values). The test runs two resident steps at the
//! paper's volume fraction and checks the second step's peak without the grids against the
//! budget the target leaves at L/l = 100: 3 000 bytes per rod, less the CUDA context (0.55 GB,
//! measured on an H100 before any case ran, BENCHMARKS.md) and the grids
//! at L/l = 100 (their size from the sum's parameters there). The per-rod part is measured
//! here at L/l = 16 (2 560 rods); it holds no part that grows faster than the rods.
//!
//! The `sbt` level's resident step has no memory target; its design is guarded the same way:
//! GMRES's basis grows with the iterations a solve takes (not the restart length's 41 vectors
//! of 96 bytes per rod), and what stays between steps is the rods, the solution and flow
//! velocities (with their copies from before the step) and the sum's bins.
//!
//! On the host emulation (skipped with the reason where no C++ compiler runs, a failure with
//! `MOTILE_REQUIRE_CXX=1`). One test in this file: the tally is the process's, so nothing
//! else may allocate device buffers while it runs.

mod common;

use motile_gpu::Backend;
use motile_particle::ewald::gpu::STRESSLET_FIELDS;
use motile_particle::ewald::params::{EwaldParams, PAIR_COST, STRESSLET_PAIR_COST, SumOutput};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::gpu::ResidentMobility;
use motile_particle::hydro::mobility::Mobility;
use motile_particle::hydro::slender::{SlenderBody, SlenderParams};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::gpu::DeviceStepper;
use motile_particle::step::report::StepReport;

/// The paper's volume fraction in rods per unit volume (`nu = n l^3 / L^3`).
const NU: f64 = 0.625;
/// The CUDA context's bytes on an H100 before any case (BENCHMARKS.md: 0.55 GB in each
/// device check).
const CONTEXT_BYTES: f64 = 0.55e9;
/// The target: GPU memory per rod at the dipole level's step peak, L/l = 100.
const TARGET_PER_ROD: f64 = 3_000.0;

/// Bytes of the stresslet sum's grids (one in-place grid of `m^3` per trace-free component:
/// `m m` rows of `2 (m/2 + 1)` values) for `n` rods in a box of `l`, at the dipole level's
/// default tolerance.
fn grid_bytes(n: usize, l: f64) -> (usize, f64) {
    let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
    let m = EwaldParams::choose_for(1e-4, n, l, &outputs, STRESSLET_PAIR_COST).modes;
    let field = m * m * 2 * (m / 2 + 1);
    (m, (STRESSLET_FIELDS * field * 8) as f64)
}

#[test]
fn resident_steps_fit_their_memory() {
    let Some(gpu) = common::emulation() else {
        return;
    };
    check_dipole(gpu);
    check_slender_body(common::emulation().expect("opened above"));
}

/// Two resident steps of `rods` with `flow` (the first makes the grids; the second is a step
/// as every later one): their reports, the device buffers kept after the first and the
/// second's peak, counted from before the stepper was made.
fn two_steps(
    rods: &motile_particle::model::rods::RodSet,
    flow: &mut dyn Mobility,
) -> (StepReport, StepReport, usize, usize) {
    let base = motile_gpu::live_bytes();
    let mut device = DeviceStepper::new(
        Backend::HostEmulation,
        rods,
        ContactParams::default(),
        &Vec::new(),
    )
    .unwrap();
    let dt = 0.01;
    let first = device.step_with_resident_flow(dt, flow).unwrap();
    let kept = motile_gpu::live_bytes() - base;
    motile_gpu::reset_peak();
    let report = device.step_with_resident_flow(dt, flow).unwrap();
    (first, report, kept, motile_gpu::peak_bytes() - base)
}

/// The resident dipole step against the target (see the file's head).
fn check_dipole(gpu: motile_particle::ewald::gpu::GpuFourier) {
    let l = 16.0;
    let n = (NU * l * l * l).round() as usize;
    let rods = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 29, 1_000_000).unwrap();
    let mut flow = Dipole::new(
        Box::new(SpectralEwald::with_device(1e-4, gpu).unwrap()),
        DEFAULT_DIAMETER,
    );
    let (first, report, kept, peak) = two_steps(&rods, &mut flow);
    // One sum per step at the sum's own tolerance (no refinement), so its grid is the one
    // `EwaldParams::choose_for` gives at 1e-4.
    for r in [&first, &report] {
        assert_eq!(r.hydro.sums, 1, "one sum per step");
        assert_eq!(r.hydro.sum_level, 0, "the sum at its own tolerance");
    }
    let (m, grids) = grid_bytes(n, l);
    let per_rod = |b: f64| b / n as f64;
    let rest = per_rod(peak as f64 - grids);
    // The budget at L/l = 100: the target less the context and the grids there.
    let (lb, nb) = (100.0, (NU * 1e6) as usize);
    let (mb, grids_big) = grid_bytes(nb, lb);
    let budget = TARGET_PER_ROD - CONTEXT_BYTES / nb as f64 - grids_big / nb as f64;
    eprintln!(
        "{n} rods, L/l = {l}, grid {m}^3: buffers kept between steps {:.0} B per rod, a step's \
         peak {:.0} B per rod (grids {:.0}, the rest {rest:.0}); at L/l = 100 (grid {mb}^3) \
         the grids take {:.0} B per rod and the context {:.0}, leaving {budget:.0} for the \
         rest, which would make {:.0} B per rod at the step's peak",
        per_rod(kept as f64),
        per_rod(peak as f64),
        per_rod(grids),
        grids_big / nb as f64,
        CONTEXT_BYTES / nb as f64,
        CONTEXT_BYTES / nb as f64 + grids_big / nb as f64 + rest,
    );
    // Guards of this design, tighter than the budget: what stays between steps besides the
    // grids (the rods, the contacts' warm start and pairs, the sum's bins: 239 bytes per rod
    // measured) and what a step adds to it at its peak: 32 values per rod and 112 bytes
    // measured (the stresslet sum's velocities, gradients and weighted strengths, 13 per rod,
    // its gathered Fourier part, 12, the error model's inputs, 4, and the step's own), bound
    // at 32 values per rod and 4 kB. A sixth stresslet grid would add 210 bytes per rod to
    // the first; the old copy of the real-space part in cell order 104 to the second.
    let kept_rest = per_rod(kept as f64 - grids);
    let transient = per_rod(peak as f64 - kept as f64);
    eprintln!(
        "kept besides the grids {kept_rest:.1} B per rod; a step's own {} bytes, {transient:.1} \
         per rod",
        peak - kept
    );
    assert!(
        kept_rest <= 300.0,
        "{kept_rest:.0} bytes per rod stay between steps besides the grids (measured 239)"
    );
    assert!(
        peak - kept <= 32 * 8 * n + 4096,
        "a step adds {} bytes at its peak ({transient:.1} per rod), over 32 values per rod \
         and 4 kB",
        peak - kept
    );
    assert!(
        rest <= budget,
        "a resident dipole step takes {rest:.0} bytes per rod besides the sum's grids, over \
         the {budget:.0} that the 3 KB per rod target leaves at L/l = 100"
    );
}

/// The resident `sbt` step's buffers (see the file's head): two steps of 320 rods at the paper's
/// volume fraction (L/l = 8), the second's own buffers at most 20 + its GMRES iterations
/// vectors of `3 m` values per rod and 4 kB (measured 20.4 at 4 iterations: the basis, 5,
/// GMRES's right-hand side and product, the nodes, the products' forces and flow, the sum's
/// points and values in its cell list's order, the contacts; a basis of the restart's 41
/// vectors would add 36), what stays between steps besides the sum's grids at most 500 bytes
/// per rod (measured 396: the rods and their copy from before the step, the solution and flow
/// velocities and their copies, the contacts' warm start, the sum's bins).
fn check_slender_body(gpu: motile_particle::ewald::gpu::GpuFourier) {
    let l = 8.0;
    let n = (NU * l * l * l).round() as usize;
    let rods = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 29, 1_000_000).unwrap();
    let prm = SlenderParams::for_diameter(DEFAULT_DIAMETER);
    let m = prm.quadrature_points;
    let mut flow = SlenderBody::new(
        prm,
        Box::new(SpectralEwald::with_device(1e-4, gpu).unwrap()),
    );
    let (first, report, kept, peak) = two_steps(&rods, &mut flow);
    // The sum refines where its estimate asks (each level a factor sqrt 10 on the internal
    // tolerance): its grid is the one `choose_for` gives at the second step's level.
    let level = report.hydro.sum_level;
    assert_eq!(first.hydro.sum_level, level, "the sum's level settled");
    let internal = 1e-4 * 10f64.powf(-0.5 * level as f64);
    let rpy = [SumOutput::RpyVelocity];
    let modes = EwaldParams::choose_for(internal, n * m, l, &rpy, PAIR_COST).modes;
    let grids = (3 * modes * modes * 2 * (modes / 2 + 1) * 8) as f64;
    let per_rod = |b: f64| b / n as f64;
    let iterations = report.hydro.gmres_iterations;
    let vector = 3 * m * 8;
    let (kept_rest, own) = (per_rod(kept as f64 - grids), peak - kept);
    eprintln!(
        "sbt: {n} rods, L/l = {l}, grid {modes}^3 (level {level}), {iterations} GMRES iterations: kept besides \
         the grids {kept_rest:.0} B per rod; a step's own {own} bytes, {:.1} vectors of {vector} \
         bytes per rod",
        own as f64 / (vector * n) as f64
    );
    assert!(flow.flows_on_device() && iterations > 0, "a resident solve");
    assert!(
        own <= (20 + iterations) * vector * n + 4096,
        "a resident sbt step adds {own} bytes at its peak, {:.1} vectors of 3 m values per rod, \
         over {} + 4 kB",
        own as f64 / (vector * n) as f64,
        20 + iterations
    );
    assert!(
        kept_rest <= 500.0,
        "{kept_rest:.0} bytes per rod stay between sbt steps besides the grids"
    );
}
