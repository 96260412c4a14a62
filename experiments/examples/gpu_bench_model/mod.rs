//! `gpu_bench --model`: the work model's tables (no device needed), kept apart from the timed
//! cases.

use crate::shared::{meanfield_state, random_points};
use motile_gpu::{Backend, Counters};
use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
use motile_meanfield::gpu::GpuMeanField;
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::MeanFieldParams;
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};
use motile_particle::ewald::gpu::{GpuFourier, STRESSLET_FIELDS, SpreadMethod};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::explicit::ExplicitSlender;
use motile_particle::hydro::mobility::Mobility;
use motile_particle::hydro::slender::{SlenderBody, SlenderParams};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::gpu::DeviceStepper;

/// The mean-field step's work model (`motile_meanfield::gpu::work_model`, `--model`): per
/// phase the launches, transforms, round trips and global-memory bytes per grid point of a
/// step with a history for 3 and 4 fixed-point iterations (the paper's case takes 3-4 from the
/// warm start, 4-5 before it), with transforms of 2 and 3
/// passes, and the step's bytes at 256^3 over the HBM bandwidth of an H100 (3.35 TB/s) and
/// an H200 (4.8 TB/s): a floor on the step's time, not a measurement.
pub(crate) fn meanfield_model_table() {
    use motile_meanfield::gpu::work_model;
    println!(
        "\nMean-field step, per grid point (kernels' fields read and written; a transform as 2 \
         or 3 passes that read and write its field):\n"
    );
    println!(
        "| K | phase | launches | transforms | downloads | kernel bytes/point | with transforms, 2 passes | 3 passes |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for k in [3, 4] {
        let model = work_model(k, true);
        for p in &model {
            println!(
                "| {k} | {} | {} | {} | {} | {:.0} | {:.0} | {:.0} |",
                p.phase,
                p.launches,
                p.transforms,
                p.downloads,
                p.kernel_bytes,
                p.bytes(2.0),
                p.bytes(3.0)
            );
        }
        let total = |passes: f64| model.iter().map(|p| p.bytes(passes)).sum::<f64>();
        let kernels: f64 = model.iter().map(|p| p.kernel_bytes).sum();
        let points = 256f64.powi(3);
        println!(
            "| {k} | **step** | {} | {} | {} | {kernels:.0} | {:.0} | {:.0} |",
            model.iter().map(|p| p.launches).sum::<usize>(),
            model.iter().map(|p| p.transforms).sum::<usize>(),
            model.iter().map(|p| p.downloads).sum::<usize>(),
            total(2.0),
            total(3.0)
        );
        for passes in [2.0, 3.0] {
            let gb = total(passes) * points / 1e9;
            println!(
                "|  | 256^3, {passes} passes: {gb:.0} GB per step; at 3.35 TB/s {:.1} ms, at 4.8 TB/s {:.1} ms | | | | | | |",
                gb / 3.35,
                gb / 4.8
            );
        }
    }
}

/// Launches, transforms and host round trips of whole steps, counted by the device as they
/// are issued (the same counts as on CUDA), on the host emulation (`--model`): the mean-field
/// step (16^3, the paper's zeta and D) and the particle step resident on the device at each
/// level it runs (432 rods, nu = 2: contacts every step), per step.
pub(crate) fn counted_table() {
    if !counted_meanfield_steps() {
        return;
    }
    let rods = random_nonoverlapping(432, 6.0, DEFAULT_DIAMETER, 12, 1_000_000).expect("rods");
    for level in ["none", "dipole", "sbt-explicit"] {
        counted_particle_steps(&rods, level);
    }
    // The same levels with the flow summed on the device (what runs use): the stepper's and
    // the sum's device together.
    for level in ["dipole", "sbt-explicit", "sbt"] {
        counted_resident_flow_steps(&rods, level);
    }
}

/// The table's header and the mean-field step's rows (16^3, three steps); `false` where the
/// host emulation cannot be opened (the whole table is then skipped).
fn counted_meanfield_steps() -> bool {
    let closure = BinghamClosure::new(DEFAULT_DEGREE).expect("closure tables");
    let n = 16;
    let grid = SpectralGrid::new(n);
    let params = MeanFieldParams {
        zeta: 0.1421,
        diffusion: 1e-4,
        ..MeanFieldParams::default()
    };
    let cpu = MeanFieldStepper::new(&grid, &meanfield_state(n), SBDF2);
    let rhs = MeanFieldRhs {
        grid: &grid,
        closure: &closure,
        params: &params,
        with_entropy: false,
    };
    let mut gpu = match GpuMeanField::open(Backend::HostEmulation, &rhs, &cpu) {
        Ok(g) => g,
        Err(e) => {
            println!("(counts on the host emulation skipped: {e})");
            return false;
        }
    };
    println!(
        "\nCounted on the host emulation, per step (the device counts what it is asked for: \
         the same on CUDA):\n"
    );
    println!(
        "| step | fixed-point / solver iterations | launches | transforms (forward + inverse) | downloads (bytes) | uploads (bytes) | copies on the device (bytes) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for k in 0..3 {
        let before = gpu.counters();
        let r = gpu.step(0.01, false).expect("mean-field step");
        let c = gpu.counters().since(&before);
        println!(
            "| mean-field {n}^3, step {} | {} | {} | {} + {} | {} |",
            k + 1,
            r.rhs.iterations,
            c.launches,
            c.forward,
            c.inverse,
            transfers(&c)
        );
    }
    true
}

/// Three steps of the particle stepper resident on the device at `level`, the flow (if any)
/// summed on the host.
fn counted_particle_steps(rods: &RodSet, level: &str) {
    let mut mobility: Option<Box<dyn Mobility>> = match level {
        "dipole" => Some(Box::new(Dipole::new(
            Box::new(SpectralEwald::new(1e-4).unwrap()),
            DEFAULT_DIAMETER,
        ))),
        "sbt-explicit" => Some(Box::new(ExplicitSlender::new(
            SlenderParams::default(),
            Box::new(SpectralEwald::new(1e-4).unwrap()),
        ))),
        _ => None,
    };
    let mut stepper = DeviceStepper::new(
        Backend::HostEmulation,
        rods,
        ContactParams::default(),
        &Vec::new(),
    )
    .expect("device stepper");
    let mut at = rods.clone();
    for k in 0..3 {
        let before = stepper.counters();
        let r = match &mut mobility {
            Some(m) => {
                stepper.download(&mut at).expect("download");
                stepper.step_with_flow(0.02, m.as_mut(), &at)
            }
            None => stepper.step(0.02),
        }
        .expect("device step");
        let c = stepper.counters().since(&before);
        println!(
            "| particle `{level}`, 432 rods, step {} | {} ({} projections) | {} | - | {} |",
            k + 1,
            r.contact.iterations,
            r.projections,
            c.launches,
            transfers(&c)
        );
    }
}

/// Three steps of the particle stepper at `level` with the flow summed on the device too.
fn counted_resident_flow_steps(rods: &RodSet, level: &str) {
    let sum = || {
        let gpu = GpuFourier::open(Backend::HostEmulation).expect("host emulation");
        SpectralEwald::with_device(1e-4, gpu).expect("tolerance")
    };
    let mut mobility: Box<dyn Mobility> = match level {
        "dipole" => Box::new(Dipole::new(Box::new(sum()), DEFAULT_DIAMETER)),
        "sbt" => Box::new(SlenderBody::new(SlenderParams::default(), Box::new(sum()))),
        _ => Box::new(ExplicitSlender::new(
            SlenderParams::default(),
            Box::new(sum()),
        )),
    };
    let mut stepper = DeviceStepper::new(
        Backend::HostEmulation,
        rods,
        ContactParams::default(),
        &Vec::new(),
    )
    .expect("device stepper");
    let counted = |stepper: &DeviceStepper, m: &mut dyn Mobility| {
        let mut c = stepper.counters();
        if let Some(s) = m.resident().and_then(|r| r.sum_counters()) {
            c.add(&s);
        }
        c
    };
    for k in 0..3 {
        let before = counted(&stepper, mobility.as_mut());
        let r = stepper
            .step_with_resident_flow(0.02, mobility.as_mut())
            .expect("device step");
        let c = counted(&stepper, mobility.as_mut()).since(&before);
        let gmres = if level == "sbt" {
            format!(", {} GMRES", r.hydro.gmres_iterations)
        } else {
            String::new()
        };
        println!(
            "| particle `{level}` (flow on the device), 432 rods, step {} | {} ({} projections{gmres}) | {} | {} + {} | {} |",
            k + 1,
            r.contact.iterations,
            r.projections,
            c.launches,
            c.forward,
            c.inverse,
            transfers(&c)
        );
    }
}

/// The last three cells of a counted row: downloads, uploads and copies on the device, each
/// with its bytes.
fn transfers(c: &Counters) -> String {
    format!(
        "{} ({}) | {} ({}) | {} ({})",
        c.downloads, c.download_bytes, c.uploads, c.upload_bytes, c.copies, c.copy_bytes
    )
}

/// The work model's table (`--model`): per case and spreading method, each phase's launches,
/// bytes, global and shared atomics per point, and the sum's totals.
pub(crate) fn model_table(small: bool) {
    use motile_particle::ewald::gpu::{FourierPart, work_model};
    use motile_particle::ewald::params::{EwaldParams, STRESSLET_PAIR_COST, SumOutput};
    let scale = if small { 100 } else { 1 };
    let rods = |l: f64| {
        // Rod centres at nu = 0.625, uniform; four nodes per rod at s = +-0.15, +-0.4 along p.
        let n = (0.625 * l * l * l / scale as f64).round() as usize;
        let (_, x, p) = random_points(n);
        let side = (n as f64 / 0.625).cbrt();
        let x: Vec<[f64; 3]> = x
            .iter()
            .map(|c| c.map(|v| v / (n as f64 / 2.5).cbrt() * side))
            .collect();
        (side, x, p)
    };
    // (name, box, points, (grid, support), (fields, gradient))
    type Case = (String, f64, Vec<[f64; 3]>, (usize, usize), (usize, bool));
    let mut cases: Vec<Case> = Vec::new();
    for n in [100_000usize, 1_000_000, 10_000_000] {
        let n = n / scale;
        let (l, y, _) = random_points(n);
        for tol in [1e-4, 1e-8] {
            let prm = EwaldParams::choose(tol, n, l);
            cases.push((
                format!("RPY {n:.0e} points, tol {tol:.0e}"),
                l,
                y.clone(),
                (prm.modes, prm.support),
                (3, false),
            ));
        }
    }
    for big in [100.0, 175.0] {
        let (l, x, _) = rods(big);
        let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
        let prm = EwaldParams::choose_for(1e-4, x.len(), l, &outputs, STRESSLET_PAIR_COST);
        cases.push((
            format!("dipole L/l = {big} ({} rods), tol 1e-4", x.len()),
            l,
            x,
            (prm.modes, prm.support),
            (STRESSLET_FIELDS, true),
        ));
    }
    // The explicit level's nodes: 4 per rod (the series' M = 4, near the Gauss-Legendre
    // nodes at s = +-0.17, +-0.43; `motile study quadrature_points` puts M = 2 8-11% off on
    // the series' statistics).
    const NODES: [f64; 4] = [-0.4, -0.15, 0.15, 0.4];
    for big in [100.0, 175.0] {
        let (l, x, p) = rods(big);
        let nodes: Vec<[f64; 3]> = x
            .iter()
            .zip(&p)
            .flat_map(|(c, q)| {
                let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt().max(1e-12);
                NODES.map(|s| std::array::from_fn(|d| c[d] + s * q[d] / norm))
            })
            .collect();
        let prm = EwaldParams::choose(1e-2, nodes.len(), l);
        // The real-space side: neighbours within the cutoff per point (uniform density).
        let neighbours =
            nodes.len() as f64 / l.powi(3) * 4.0 / 3.0 * std::f64::consts::PI * prm.cutoff.powi(3);
        println!(
            "sbt-explicit L/l = {big}, M = 4: {} nodes, grid {}^3, support {}, cutoff {:.3} l, {neighbours:.1} real-space neighbours per node",
            nodes.len(),
            prm.modes,
            prm.support,
            prm.cutoff
        );
        cases.push((
            format!(
                "sbt-explicit L/l = {big}, M = 4 ({} nodes), tol 1e-2",
                nodes.len()
            ),
            l,
            nodes,
            (prm.modes, prm.support),
            (3, false),
        ));
    }
    println!(
        "Requested bytes: loads and stores as the kernels issue them (atomics apart). Grid \
         lines: the distinct 128-byte lines of the grids each warp (for the tiles, each bin's \
         block) touches, summed; the traffic at the cache, where the points' order shows.\n"
    );
    println!(
        "| case | grid, support | method | phase | launches | requested bytes/point | grid lines/point | global atomics/point | shared atomics/point |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, l, pts, (m, p), fields) in &cases {
        let n = pts.len() as f64;
        for method in [
            SpreadMethod::Atomic,
            SpreadMethod::Sorted,
            SpreadMethod::Cells,
        ] {
            let (nf, gradient) = *fields;
            let part = FourierPart {
                m: *m,
                p: *p,
                nf,
                gradient,
            };
            let rows = work_model(pts, *l, part, method);
            let (mut launches, mut bytes, mut lines, mut ga, mut sa) = (0, 0.0, 0.0, 0.0, 0.0);
            for r in &rows {
                println!(
                    "| {name} | {m}^3, {p} | {method:?} | {} | {} | {:.0} | {:.1} | {:.1} | {:.1} |",
                    r.phase,
                    r.launches,
                    r.bytes / n,
                    r.grid_lines / n,
                    r.global_atomics / n,
                    r.shared_atomics / n
                );
                launches += r.launches;
                bytes += r.bytes;
                lines += r.grid_lines;
                ga += r.global_atomics;
                sa += r.shared_atomics;
            }
            println!(
                "| {name} | {m}^3, {p} | {method:?} | **per sum** | {launches} | {:.0} ({:.2} GB) | {:.1} ({:.2} GB) | {:.1} ({:.2e}) | {:.1} |",
                bytes / n,
                bytes / 1e9,
                lines / n,
                lines * 128.0 / 1e9,
                ga / n,
                ga,
                sa / n
            );
        }
    }
}
