//! The spectral Ewald sums with their Fourier and real-space parts on a device (feature
//! `gpu`), against their
//! CPU twin (the same sum with the CPU grid: agreement to round-off) and against the direct
//! Ewald sum (the accuracy contract), on what the simulations produce: swimming (force-free)
//! rods for the RPY sum, point stresslets for velocities and gradients, at tolerances 1e-4
//! and 1e-8.
//!
//! Two devices: the host emulation (the same kernels compiled by the C++ compiler, run on the
//! CPU: skipped, with the reason, where no C++ compiler runs, a failure with
//! `MOTILE_REQUIRE_CXX=1`) and CUDA (its test is `#[ignore]`d, so a run without a GPU reports
//! it as not run; `scripts/device_run.sh` runs it with `--include-ignored` and
//! `MOTILE_REQUIRE_GPU=1`).

mod common;

use common::{device, emulation, errors, matrices, rod_points, rods, vectors};
use motile_gpu::Backend;
use motile_particle::ewald::gpu::{GpuFourier, OrientedPoints};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::reference::EwaldReference;
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::model::geometry::Vec3;
use std::f64::consts::PI;

const A_RPY: f64 = 0.0866;
const SIGMA: f64 = 0.68;
const TOLERANCES: [f64; 2] = [1e-4, 1e-8];
/// Device against CPU, relative to the largest output: both run the same arithmetic but for
/// the order of the spreading's sums and the window's exponentials (direct on the device, a
/// recurrence on the CPU), a few ulps per term of sums of hundreds of terms.
const PARITY: f64 = 1e-11;

/// The RPY sum of swimming rods and the stresslet sum, on the device against the CPU and the
/// direct sum. Returns the report lines.
fn check_device(open: &dyn Fn() -> GpuFourier) -> Vec<String> {
    let mut rows = Vec::new();
    // 40 swimming rods (four half-rod nodes each) in a box of 5 rod lengths.
    let l = 5.0;
    let (x, p) = rods(40, l, false, 5);
    let (y, f) = rod_points(&x, &p, true, 3);
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let all: Vec<usize> = (0..y.len()).collect();
    let exact = EwaldReference::default()
        .rpy_at(&geo, &y, &f, &all)
        .unwrap();
    let largest = |v: &[Vec<f64>]| {
        v.iter()
            .map(|r| r.iter().map(|c| c * c).sum::<f64>().sqrt())
            .fold(0.0, f64::max)
    };
    for tol in TOLERANCES {
        let mut cpu = SpectralEwald::new(tol).unwrap();
        let mut dev = SpectralEwald::with_device(tol, open()).unwrap();
        let uc = cpu.rpy(&geo, &y, &f).unwrap();
        let ud = dev.rpy(&geo, &y, &f).unwrap();
        let rd = dev.last_report().unwrap();
        // Parity at the CPU's parameters (on a GPU the spreading's order varies, so the
        // refinement could in principle decide differently near a threshold).
        let mut same = SpectralEwald::with_device(tol, open()).unwrap();
        same.fixed = cpu.last_params();
        let parity = errors(
            &vectors(&same.rpy(&geo, &y, &f).unwrap()),
            &vectors(&uc),
            0.0,
        )
        .0;
        let (max, l2) = errors(&vectors(&ud), &vectors(&exact), 0.0);
        rows.push(format!(
            "RPY, {} swimming-rod nodes, tol {tol:.0e}: device vs CPU {parity:.1e} of the \
             largest velocity; vs the direct sum max-relative {:.2} tol, L2 {:.2} tol (grid \
             {}^3, level {})",
            y.len(),
            max / tol,
            l2 / tol,
            dev.last_params().unwrap().modes,
            rd.level
        ));
        assert!(
            parity <= PARITY,
            "RPY device vs CPU: {parity:e} (> {PARITY:e})"
        );
        assert!(
            max <= tol && l2 <= tol && rd.met,
            "RPY contract: {max:e}, {l2:e} at {tol:e}"
        );
        assert!(largest(&vectors(&ud)) > 0.0, "a flow");
        // The resident product (points, forces and velocities on the device) against the
        // direct sum too.
        let ur = dev.rpy_via_device(&geo, &y, &mut None, &f).unwrap();
        let (max, l2) = errors(&vectors(&ur), &vectors(&exact), 0.0);
        rows.push(format!(
            "RPY resident, tol {tol:.0e}: vs the direct sum max-relative {:.2} tol, L2 {:.2} tol",
            max / tol,
            l2 / tol
        ));
        assert!(
            max <= tol && l2 <= tol && dev.last_report().unwrap().met,
            "resident RPY contract: {max:e}, {l2:e} at {tol:e}"
        );
    }
    // 60 point stresslets (the dipole level's sources) in a box of 6.
    let l = 6.0;
    let (x, p) = rods(60, l, false, 9);
    let sigma = vec![SIGMA; x.len()];
    let exact = EwaldReference::default()
        .stresslets(l, &x, &p, &sigma)
        .unwrap();
    let floor = |k: i32| SIGMA / (8.0 * PI * l.powi(k));
    for tol in TOLERANCES {
        let mut cpu = SpectralEwald::new(tol).unwrap();
        let mut dev = SpectralEwald::with_device(tol, open()).unwrap();
        let sc = cpu.stresslets(l, &x, &p, &sigma).unwrap();
        let sd = dev.stresslets(l, &x, &p, &sigma).unwrap();
        let mut same = SpectralEwald::with_device(tol, open()).unwrap();
        same.fixed = cpu.last_params();
        let ss = same.stresslets(l, &x, &p, &sigma).unwrap();
        let pu = errors(&vectors(&ss.u), &vectors(&sc.u), floor(2)).0;
        let pg = errors(&matrices(&ss.grad), &matrices(&sc.grad), floor(3)).0;
        let eu = errors(&vectors(&sd.u), &vectors(&exact.u), floor(2));
        let eg = errors(&matrices(&sd.grad), &matrices(&exact.grad), floor(3));
        rows.push(format!(
            "stresslets, {} points, tol {tol:.0e}: device vs CPU {pu:.1e} (velocity), {pg:.1e} \
             (gradient); vs the direct sum velocity {:.2} / {:.2} tol, gradient {:.2} / {:.2} \
             tol (max-relative / L2)",
            x.len(),
            eu.0 / tol,
            eu.1 / tol,
            eg.0 / tol,
            eg.1 / tol
        ));
        assert!(
            pu <= PARITY && pg <= PARITY,
            "stresslets device vs CPU: {pu:e}, {pg:e}"
        );
        for (what, (max, l2)) in [("velocity", eu), ("gradient", eg)] {
            assert!(
                max <= tol && l2 <= tol,
                "stresslet {what} contract: {max:e}, {l2:e} at {tol:e}"
            );
        }
        assert!(
            dev.last_report().unwrap().met,
            "the device sum met its estimate"
        );
        // The resident sum (centres, axes, velocities and gradients on the device), both
        // outputs against the direct sum.
        let (xb, pb) = (
            dev.upload(x.as_flattened()).unwrap(),
            dev.upload(p.as_flattened()).unwrap(),
        );
        let field = dev
            .stresslets_resident(
                l,
                OrientedPoints {
                    centres: &xb,
                    axes: &pb,
                },
                SIGMA,
                x.len(),
            )
            .unwrap();
        let ru: Vec<Vec<f64>> = dev
            .download(&field.u)
            .unwrap()
            .chunks(3)
            .map(<[f64]>::to_vec)
            .collect();
        let rg: Vec<Vec<f64>> = dev
            .download(&field.grad)
            .unwrap()
            .chunks(9)
            .map(<[f64]>::to_vec)
            .collect();
        let ru_err = errors(&ru, &vectors(&exact.u), floor(2));
        let rg_err = errors(&rg, &matrices(&exact.grad), floor(3));
        rows.push(format!(
            "stresslets resident, tol {tol:.0e}: vs the direct sum velocity {:.2} / {:.2} tol, \
             gradient {:.2} / {:.2} tol",
            ru_err.0 / tol,
            ru_err.1 / tol,
            rg_err.0 / tol,
            rg_err.1 / tol
        ));
        for (what, (max, l2)) in [("velocity", ru_err), ("gradient", rg_err)] {
            assert!(
                max <= tol && l2 <= tol,
                "resident stresslet {what} contract: {max:e}, {l2:e} at {tol:e}"
            );
        }
    }
    rows
}

#[test]
fn emulated_device_sums_match_the_cpu_and_the_direct_sum() {
    let Some(first) = emulation() else {
        return;
    };
    drop(first);
    let rows = check_device(&|| GpuFourier::open(Backend::HostEmulation).unwrap());
    eprintln!("{}", rows.join("\n"));
}

/// Exactly five real-space cells per axis (the smallest stencil, each neighbour cell once) and
/// centres on cell boundaries: the device visits the CPU's pairs.
#[test]
fn five_cells_per_axis_and_points_on_cell_boundaries() {
    let Some(gpu) = emulation() else {
        return;
    };
    let l = 10.0;
    let (mut x, p) = rods(300, l, false, 8);
    // Cells of side 2: boundaries at 0, 2, 4, 6, 8 (and L, which wraps to 0).
    x[0] = [4.0, 6.0, 0.0];
    x[1] = [10.0, 2.0, 8.0];
    x[2] = [2.0, 2.0 + 1e-15, 4.0 - 1e-15];
    let mut cpu = SpectralEwald::new(1e-6).unwrap();
    let sigma = vec![SIGMA; x.len()];
    cpu.stresslets(l, &x, &p, &sigma).unwrap();
    let mut fixed = cpu.last_params().unwrap();
    fixed.cutoff = 2.0 * l / 5.5; // floor(2 L / cutoff) = 5 cells per axis
    cpu.fixed = Some(fixed);
    let mut dev = SpectralEwald::with_device(1e-6, gpu).unwrap();
    dev.fixed = Some(fixed);
    let sc = cpu.stresslets(l, &x, &p, &sigma).unwrap();
    let sd = dev.stresslets(l, &x, &p, &sigma).unwrap();
    let floor = |k: i32| SIGMA / (8.0 * PI * l.powi(k));
    let pu = errors(&vectors(&sd.u), &vectors(&sc.u), floor(2)).0;
    let pg = errors(&matrices(&sd.grad), &matrices(&sc.grad), floor(3)).0;
    let (y, f) = rod_points(&x, &p, true, 8);
    let geo = RpyGeometry {
        box_length: l,
        radius: A_RPY,
        group: 4,
    };
    let pr = errors(
        &vectors(&dev.rpy(&geo, &y, &f).unwrap()),
        &vectors(&cpu.rpy(&geo, &y, &f).unwrap()),
        0.0,
    )
    .0;
    eprintln!("five cells per axis: stresslets {pu:.1e} / {pg:.1e}, RPY {pr:.1e}");
    assert!(
        pu <= PARITY && pg <= PARITY && pr <= PARITY,
        "device vs CPU: stresslet velocity {pu:e}, gradient {pg:e}, RPY {pr:e}"
    );
}

#[test]
#[ignore = "needs a CUDA GPU: scripts/device_run.sh runs it (--include-ignored, MOTILE_REQUIRE_GPU=1)"]
fn gpu_sums_match_the_cpu_and_the_direct_sum() {
    let Some(first) = device(Backend::Cuda) else {
        return;
    };
    drop(first);
    let rows = check_device(&|| GpuFourier::open(Backend::Cuda).unwrap());
    eprintln!("{}", rows.join("\n"));
}

/// A device sum keeps its device's plans from sum to sum and follows a change of grid and of
/// the real-space cells (boxes of four sizes, with fewer and with more than five cells per
/// axis), for both sums.
#[test]
fn a_device_sum_follows_changes_of_grid() {
    let Some(gpu) = emulation() else {
        return;
    };
    let mut dev = SpectralEwald::with_device(1e-4, gpu).unwrap();
    let mut cpu = SpectralEwald::new(1e-4).unwrap();
    // Small boxes have fewer than five real-space cells per axis (every pair by its minimum
    // image); the last, 400 rods in a box of 10, has more (the 5^3 cell stencil). RPY sums of
    // the rods' nodes, stresslet sums of their centres.
    for (l, seed, n) in [
        (5.0, 1, 30),
        (7.0, 2, 30),
        (5.0, 3, 30),
        (3.0, 4, 2),
        (10.0, 5, 400),
    ] {
        let (mut x, mut p) = rods(n, l, false, seed);
        if n == 2 {
            // Two centres 0.004 apart: closer than the stresslet table's first nodes, where the
            // real-space derivatives are evaluated in closed form.
            x[1] = [x[0][0] + 0.004, x[0][1], x[0][2]];
            p[1] = [0.0, 0.6, 0.8];
        }
        let (y, f) = rod_points(&x, &p, true, seed);
        let geo = RpyGeometry {
            box_length: l,
            radius: A_RPY,
            group: 4,
        };
        let ud: Vec<Vec3> = dev.rpy(&geo, &y, &f).unwrap();
        let uc = cpu.rpy(&geo, &y, &f).unwrap();
        let parity = errors(&vectors(&ud), &vectors(&uc), 0.0).0;
        assert!(parity <= PARITY, "L = {l}: device vs CPU {parity:e}");
        // The same points with other forces (a GMRES solve's next product: the device reuses
        // the points and the cells it holds).
        let f2: Vec<Vec3> = f.iter().map(|v| [v[1], -v[0], 0.5 * v[2]]).collect();
        let parity = errors(
            &vectors(&dev.rpy(&geo, &y, &f2).unwrap()),
            &vectors(&cpu.rpy(&geo, &y, &f2).unwrap()),
            0.0,
        )
        .0;
        assert!(
            parity <= PARITY,
            "L = {l}, same points: device vs CPU {parity:e}"
        );
        // The rods' centres as point stresslets (the dipole level's sources).
        let sigma = vec![SIGMA; x.len()];
        let sd = dev.stresslets(l, &x, &p, &sigma).unwrap();
        let sc = cpu.stresslets(l, &x, &p, &sigma).unwrap();
        let floor = |k: i32| SIGMA / (8.0 * PI * l.powi(k));
        let pu = errors(&vectors(&sd.u), &vectors(&sc.u), floor(2)).0;
        let pg = errors(&matrices(&sd.grad), &matrices(&sc.grad), floor(3)).0;
        assert!(
            pu <= PARITY && pg <= PARITY,
            "L = {l}: stresslets device vs CPU {pu:e}, {pg:e}"
        );
    }
}

/// The binned spreaders (shared-memory tiles; the sorted global-memory spreader) against the
/// per-point atomic one, each on the same device at the same parameters, with the blocks
/// shuffled at every launch (a race between blocks would show): swimming rods' RPY sums at
/// tolerances 1e-2 and 1e-4 (tiles: supports 5 and 8, bins 8 and 5 cells wide) and 1e-8
/// (support 15: the sorted spreader), and stresslet sums (six fields: two tile passes), on a
/// grid smaller than a tile and on larger ones. Agreement to round-off (the order of the
/// grid's sums differs).
#[test]
fn binned_spreaders_match_the_atomic_one() {
    use motile_particle::ewald::gpu::SpreadMethod;
    let Some(first) = emulation() else {
        return;
    };
    drop(first);
    let open_seeded = |method: SpreadMethod, seed: u64| {
        let mut g = GpuFourier::open(Backend::HostEmulation).unwrap();
        g.set_spread_method(Some(method));
        assert!(g.shuffle_blocks(seed));
        g
    };
    let open = |method: SpreadMethod| open_seeded(method, 11);
    let mut rows = Vec::new();
    // Grids of 10, 20, 30 (the output-driven spreader's bins of 10 cells, four per thread; at
    // 1e-8 its reach clamped to every bin), 32 (bins of 8 dividing the grid, a reach of one bin
    // of four), 36 (bins of 9, three cells per thread) and 22 (bins of 8, the last one short)
    // points per axis.
    for (l, n, tol, modes) in [
        (5.0, 40, 1e-2, None),
        (8.0, 120, 1e-4, None),
        (5.0, 40, 1e-8, None),
        (8.0, 120, 1e-4, Some(32)),
        (8.0, 120, 1e-4, Some(36)),
        (8.0, 120, 1e-4, Some(22)),
    ] {
        let (x, p) = rods(n, l, false, 21);
        let (y, f) = rod_points(&x, &p, true, 4);
        let geo = RpyGeometry {
            box_length: l,
            radius: A_RPY,
            group: 4,
        };
        let mut cpu = SpectralEwald::new(tol).unwrap();
        cpu.rpy(&geo, &y, &f).unwrap();
        let mut fixed = cpu.last_params();
        if let (Some(f), Some(m)) = (fixed.as_mut(), modes) {
            f.modes = m;
        }
        let run_seeded = |method, seed| {
            let mut s = SpectralEwald::with_device(tol, open_seeded(method, seed)).unwrap();
            s.fixed = fixed;
            vectors(&s.rpy(&geo, &y, &f).unwrap())
        };
        let run = |method| run_seeded(method, 11);
        let atomic = run(SpreadMethod::Atomic);
        let modes = fixed.unwrap().modes;
        // The output-driven spreader sums in the same order whatever order the blocks (and so
        // the sort's atomics) ran in.
        let (c1, c2) = (
            run_seeded(SpreadMethod::Cells, 11),
            run_seeded(SpreadMethod::Cells, 12),
        );
        assert!(
            c1 == c2,
            "Cells at tol {tol:e}: not the same bits under another block order"
        );
        for method in [SpreadMethod::Sorted, SpreadMethod::Cells] {
            let err = errors(&run(method), &atomic, 0.0).0;
            rows.push(format!(
                "RPY tol {tol:.0e}, {} nodes, grid {modes}^3: {method:?} vs Atomic {err:.1e}",
                y.len()
            ));
            assert!(
                err <= PARITY,
                "{method:?} vs Atomic at tol {tol:e}: {err:e}"
            );
        }
    }
    let l = 6.0;
    let (x, p) = rods(60, l, false, 23);
    let sigma = vec![SIGMA; x.len()];
    let floor = |k: i32| SIGMA / (8.0 * PI * l.powi(k));
    let mut cpu = SpectralEwald::new(1e-4).unwrap();
    cpu.stresslets(l, &x, &p, &sigma).unwrap();
    let fixed = cpu.last_params();
    let run = |method| {
        let mut s = SpectralEwald::with_device(1e-4, open(method)).unwrap();
        s.fixed = fixed;
        s.stresslets(l, &x, &p, &sigma).unwrap()
    };
    let atomic = run(SpreadMethod::Atomic);
    for method in [SpreadMethod::Sorted, SpreadMethod::Cells] {
        let s = run(method);
        let eu = errors(&vectors(&s.u), &vectors(&atomic.u), floor(2)).0;
        let eg = errors(&matrices(&s.grad), &matrices(&atomic.grad), floor(3)).0;
        rows.push(format!(
            "stresslets tol 1e-4: {method:?} vs Atomic {eu:.1e} (velocity), {eg:.1e} (gradient)"
        ));
        assert!(eu <= PARITY && eg <= PARITY, "{method:?}: {eu:e}, {eg:e}");
    }
    eprintln!("{}", rows.join("\n"));
}

/// The tiled gather (a block per bin, each field's tile of the grid in shared memory) gives the
/// per-point gather's bits, blocks run in a shuffled order: RPY sums of swimming rods at
/// tolerances 1e-2 to 1e-4 (tiles where the support fits one, among them grids smaller than a
/// tile and with a short last bin; the support of 10 at 1e-4 takes the per-point gather) and
/// point stresslets' velocities with their gradients at 1e-2.
#[test]
fn the_tiled_gather_gives_the_per_point_gathers_bits() {
    use motile_particle::ewald::gpu::{SpreadMethod, cell_bin, tiles_fit};
    let Some(first) = emulation() else {
        return;
    };
    drop(first);
    let open = |tiles: bool| {
        let mut g = GpuFourier::open(Backend::HostEmulation).unwrap();
        g.set_spread_method(Some(SpreadMethod::Cells));
        g.set_tiled_gather(tiles);
        assert!(g.shuffle_blocks(5));
        g
    };
    let tiled_launches = |s: &SpectralEwald| {
        let c = s.device_counters().expect("a device's counters");
        c.by_kernel.get("gather_tiles").copied().unwrap_or(0)
    };
    let fits = |prm: motile_particle::ewald::params::EwaldParams| {
        tiles_fit(
            SpreadMethod::Cells,
            cell_bin(prm.support, prm.modes),
            prm.support,
        )
    };
    let mut rows = Vec::new();
    let mut tiled_cases = 0;
    for (l, n, tol, modes) in [
        (5.0, 40, 1e-2, None),
        (8.0, 120, 1e-2, None),
        (8.0, 120, 1e-3, None),
        (8.0, 120, 1e-2, Some(22)),
        (8.0, 120, 1e-2, Some(32)),
        (8.0, 120, 1e-4, None),
    ] {
        let (x, p) = rods(n, l, false, 21);
        let (y, f) = rod_points(&x, &p, true, 4);
        let geo = RpyGeometry {
            box_length: l,
            radius: A_RPY,
            group: 4,
        };
        let mut cpu = SpectralEwald::new(tol).unwrap();
        cpu.rpy(&geo, &y, &f).unwrap();
        let mut fixed = cpu.last_params();
        if let (Some(f), Some(m)) = (fixed.as_mut(), modes) {
            f.modes = m;
        }
        let prm = fixed.unwrap();
        tiled_cases += usize::from(fits(prm));
        // The values and the tiled kernel's launches.
        let run = |tiles| {
            let mut s = SpectralEwald::with_device(tol, open(tiles)).unwrap();
            s.fixed = fixed;
            let v = vectors(&s.rpy(&geo, &y, &f).unwrap());
            (v, tiled_launches(&s))
        };
        let ((tiled, launched), (per_point, none)) = (run(true), run(false));
        assert!(
            none == 0 && (launched > 0) == fits(prm),
            "tol {tol:e}, grid {}^3: the tiled gather launched {launched} times (fits: {}), \
             {none} times when switched off",
            prm.modes,
            fits(prm)
        );
        assert!(
            tiled == per_point,
            "RPY tol {tol:e}, grid {}^3: the tiled gather differs, by {:e}",
            prm.modes,
            errors(&tiled, &per_point, 0.0).0
        );
        rows.push(format!(
            "RPY tol {tol:.0e}, grid {}^3, support {}{}: the same bits",
            prm.modes,
            prm.support,
            if fits(prm) {
                ""
            } else {
                " (no tile: per point)"
            }
        ));
    }
    assert!(
        tiled_cases >= 4,
        "tiles in {tiled_cases} cases:\n{}",
        rows.join("\n")
    );
    let l = 6.0;
    let (x, p) = rods(60, l, false, 23);
    let sigma = vec![SIGMA; x.len()];
    let mut cpu = SpectralEwald::new(1e-2).unwrap();
    cpu.stresslets(l, &x, &p, &sigma).unwrap();
    let fixed = cpu.last_params();
    assert!(fits(fixed.unwrap()), "stresslets at 1e-2: no tile");
    let run = |tiles| {
        let mut s = SpectralEwald::with_device(1e-2, open(tiles)).unwrap();
        s.fixed = fixed;
        let v = s.stresslets(l, &x, &p, &sigma).unwrap();
        (v, tiled_launches(&s))
    };
    let ((tiled, launched), (per_point, none)) = (run(true), run(false));
    assert!(
        launched > 0 && none == 0,
        "stresslets: the tiled gather launched {launched} and {none} times"
    );
    assert!(
        vectors(&tiled.u) == vectors(&per_point.u)
            && matrices(&tiled.grad) == matrices(&per_point.grad),
        "stresslets: the tiled gather differs"
    );
    rows.push("stresslets tol 1e-2, velocities and gradients: the same bits".into());
    eprintln!("{}", rows.join("\n"));
}
