//! The GPU mean-field step against the CPU step: from the same strongly anisotropic
//! state (the dynamics tests' `nonlinear_state`), three steps (the first SBDF1, then
//! variable-step SBDF2 with a step ratio of 1.25) with the fixed point's iteration count pinned
//! to 6 (so round-off cannot stop the two one iteration apart), the entropy evaluated: Q and u
//! agree to 1e-12 relative, or, where the CPU step itself is more sensitive than that, within
//! the CPU step's own response to perturbing Q by a few ulps (the closure's evaluation
//! amplifies round-off: 1e-15 in Q gives 6e-12 in Q and 2e-10 in u after one step on this
//! state); every number of the step reports within 1e-10, or within ten times the CPU step's
//! own response to that perturbation where that is larger. Each step's transforms, counted by
//! the device as they are asked for, are the stated 41 + 10 K for K fixed-point iterations.
//!
//! Twice: on the host emulation of the kernels (the same source compiled by the C++ compiler
//! and run on the CPU, transforms in cuFFT's layout; 16^3; skipped with the reason where no C++
//! compiler runs, a failure then with `MOTILE_REQUIRE_CXX=1`), and on a CUDA device (32^3; the
//! test is `#[ignore]`d, so a run without a GPU reports it as not run; scripts/device_run.sh
//! runs it with `--include-ignored` and `MOTILE_REQUIRE_GPU=1`, where a missing GPU fails it).
//! The file builds with the feature `gpu` only.

mod common;

use motile_gpu::Backend;

#[test]
#[ignore = "needs a CUDA GPU: scripts/device_run.sh runs it (--include-ignored, MOTILE_REQUIRE_GPU=1)"]
fn gpu_step_matches_the_cpu_step() {
    let Some(info) = motile_gpu::open_or_skip(motile_gpu::probe(), Backend::Cuda) else {
        return;
    };
    eprintln!("gpu parity on {} ({} GB)", info.name, info.memory >> 30);
    parity(32, Backend::Cuda);
}

/// The kernels and the code around them on the CPU, through the host emulation.
#[test]
fn emulated_gpu_step_matches_the_cpu_step() {
    parity(16, Backend::HostEmulation);
}

/// Three steps on an `n^3` grid on the device opened by `open` against the CPU's.
fn parity(n: usize, backend: Backend) {
    use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
    use motile_meanfield::gpu::{GpuError, GpuMeanField};
    use motile_meanfield::solver::grid::SpectralGrid;
    use motile_meanfield::solver::params::MeanFieldParams;
    use motile_meanfield::solver::rhs::MeanFieldRhs;
    use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};
    use num_complex::Complex64;

    let grid = SpectralGrid::new(n);
    let closure = BinghamClosure::new(DEFAULT_DEGREE).unwrap();
    let params = MeanFieldParams {
        zeta: 0.5,
        diffusion: 1e-3,
        fixed_point_iterations: Some(6),
        ..Default::default()
    };
    let q = common::nonlinear_state(n);
    let mut cpu = MeanFieldStepper::new(&grid, &q, SBDF2);
    let rhs = MeanFieldRhs {
        grid: &grid,
        closure: &closure,
        params: &params,
        with_entropy: true,
    };
    let gpu = GpuMeanField::open(backend, &rhs, &cpu);
    let mut gpu = match gpu {
        Ok(g) => g,
        Err(GpuError::Device(e)) => match motile_gpu::open_or_skip(Err(e), backend) {
            Some(never) => never,
            None => return,
        },
        Err(e) => panic!("the device stepper: {e}"),
    };
    eprintln!("parity on {}", gpu.describe());
    let rel = |a: &[Vec<Complex64>], b: &[Vec<Complex64>]| {
        let scale = a.iter().flatten().map(|z| z.norm()).fold(1e-300, f64::max);
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max)
            / scale
    };
    // The CPU step's own round-off sensitivity: the same steps from Q perturbed by a few ulps
    // (relative 1e-15). The closure's evaluation amplifies such perturbations (measured on this
    // state: 6e-12 in Q and 2e-10 in u after one step), so no second implementation can agree
    // closer than that where it is larger than 1e-12; the GPU must agree within 1e-12 or within
    // that sensitivity.
    let mut cpu_ulps = MeanFieldStepper::new(&grid, &q, SBDF2);
    for (c, comp) in cpu_ulps.q_hat.iter_mut().enumerate() {
        for (j, z) in comp.iter_mut().enumerate() {
            *z *= 1.0 + 1e-15 * (((j * 7 + c * 13) % 11) as f64 - 5.0) / 5.0;
        }
    }
    for (k, dt) in [0.02, 0.025, 0.025].into_iter().enumerate() {
        let rhs = MeanFieldRhs {
            grid: &grid,
            closure: &closure,
            params: &params,
            with_entropy: true,
        };
        let rc = cpu.step(&rhs, dt).unwrap();
        let ru = cpu_ulps.step(&rhs, dt).unwrap();
        let before = gpu.counters();
        let rg = gpu.step(dt, true).unwrap();
        // The transforms of a step, counted as the device is asked for them: 6 + 10 K + 11 + 24
        // (Q to the grid; per fixed-point iteration 5 strain components to the grid and 5
        // deviatoric stresses back; u and 8 components of grad u; grad Q and the 6 products
        // back) for K iterations, the count docs/gpu.md and BENCHMARKS.md state; one download
        // per iteration (the change) besides the step's fixed ones.
        let did = gpu.counters().since(&before);
        let iters = rg.rhs.iterations as u64;
        assert_eq!(
            (did.forward, did.inverse),
            (5 * iters + 6, 5 * iters + 35),
            "step {k}: transforms (forward, inverse) for {iters} fixed-point iterations"
        );
        // The work model's launches, transforms and round trips are the step's.
        let model = motile_meanfield::gpu::work_model(rg.rhs.iterations, k > 0);
        let sum = |f: fn(&motile_meanfield::gpu::PhaseWork) -> usize| {
            model.iter().map(f).sum::<usize>() as u64
        };
        assert_eq!(
            (
                sum(|p| p.launches),
                sum(|p| p.transforms),
                sum(|p| p.downloads)
            ),
            (did.launches, did.forward + did.inverse, did.downloads),
            "step {k}: the work model's (launches, transforms, downloads) against the device's \
             counts"
        );
        eprintln!(
            "step {k}: {} forward and {} inverse transforms, {} launches, {} downloads ({} \
             bytes), {iters} fixed-point iterations",
            did.forward, did.inverse, did.launches, did.downloads, did.download_bytes
        );
        let (t, q_hat, _, u_hat) = gpu.state().unwrap();
        let (dq, du) = (rel(&cpu.q_hat, &q_hat), rel(&cpu.u_hat, &u_hat));
        let (sq, su) = (
            rel(&cpu.q_hat, &cpu_ulps.q_hat),
            rel(&cpu.u_hat, &cpu_ulps.u_hat),
        );
        eprintln!(
            "step {k}: Q within {dq:.2e}, u within {du:.2e} (the CPU's own response to 1e-15 in \
             Q: {sq:.2e}, {su:.2e}); CPU {rc:?}, GPU {rg:?}"
        );
        assert!((t - cpu.t).abs() < 1e-15, "time {t} vs {}", cpu.t);
        assert!(
            dq <= sq.max(1e-12) && du <= su.max(1e-12),
            "step {k}: Q off by {dq:.2e}, u by {du:.2e}: more than 1e-12 and more than the CPU \
             step's response to a 1e-15 perturbation of Q ({sq:.2e}, {su:.2e})"
        );
        assert_eq!(rc.rhs.iterations, rg.rhs.iterations, "pinned iterations");
        // Report numbers: within 1e-10, or within ten times the CPU step's own response to the
        // perturbation (of that number, or of u for the numbers computed from u): a maximum
        // over grid points of an inverse transform can move more than the spectrum's largest
        // relative change (measured on an H200: u_max 4.4e-10 apart while u was 2.3e-11
        // apart, against the CPU's 7.5e-11 response in u).
        for (name, a, b, a_ulps, from_u) in [
            ("u_l2", rc.u_l2, rg.u_l2, ru.u_l2, true),
            ("u_max", rc.u_max, rg.u_max, ru.u_max, true),
            ("e_l2", rc.e_l2, rg.e_l2, ru.e_l2, true),
            ("e_dot_q", rc.e_dot_q, rg.e_dot_q, ru.e_dot_q, true),
            (
                "min_eigenvalue",
                rc.min_eigenvalue,
                rg.min_eigenvalue,
                ru.min_eigenvalue,
                false,
            ),
            (
                "max_eigenvalue",
                rc.max_eigenvalue,
                rg.max_eigenvalue,
                ru.max_eigenvalue,
                false,
            ),
            ("entropy", rc.entropy, rg.entropy, ru.entropy, false),
        ] {
            let d = (a - b).abs() / a.abs().max(1e-300);
            let own = (a - a_ulps).abs() / a.abs().max(1e-300);
            let bound = (10.0 * own.max(if from_u { su } else { sq })).max(1e-10);
            assert!(
                d <= bound,
                "step {k}: {name} {a} (CPU) vs {b} (GPU): {d:.2e}, above 1e-10 and ten times \
                 the CPU's own response ({own:.2e}; u {su:.2e}, Q {sq:.2e})"
            );
        }
        // The fixed point's last change is itself relative to |u| and small (about 1e-8 after
        // six iterations): compared absolutely, at the transforms' round-off.
        let dr = (rc.rhs.residual - rg.rhs.residual).abs();
        assert!(
            dr <= 1e-12,
            "step {k}: fixed-point change {} vs {}: {dr:.2e}",
            rc.rhs.residual,
            rg.rhs.residual
        );
    }
}

/// A step whose right-hand side overflows fails on the device as on the CPU, with the same
/// error, and commits nothing: the non-finite counts that the device's scaling and IMEX update
/// return (fused into those kernels) are read. Q scaled by 1e200 keeps the closure's Q/tr Q
/// and a converging fixed point (its change is relative), but its advection overflows.
#[test]
fn emulated_gpu_step_refuses_a_non_finite_right_hand_side() {
    use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
    use motile_meanfield::gpu::{GpuError, GpuMeanField};
    use motile_meanfield::solver::grid::SpectralGrid;
    use motile_meanfield::solver::params::MeanFieldParams;
    use motile_meanfield::solver::rhs::MeanFieldRhs;
    use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};

    let n = 8;
    let grid = SpectralGrid::new(n);
    let closure = BinghamClosure::new(DEFAULT_DEGREE).unwrap();
    let params = MeanFieldParams {
        zeta: 0.5,
        diffusion: 1e-3,
        fixed_point_iterations: Some(3),
        ..Default::default()
    };
    let mut q = common::nonlinear_state(n);
    for comp in q.iter_mut() {
        for v in comp.iter_mut() {
            *v *= 1e200;
        }
    }
    let mut cpu = MeanFieldStepper::new(&grid, &q, SBDF2);
    let rhs = MeanFieldRhs {
        grid: &grid,
        closure: &closure,
        params: &params,
        with_entropy: false,
    };
    let mut gpu = match GpuMeanField::open(Backend::HostEmulation, &rhs, &cpu) {
        Ok(g) => g,
        Err(GpuError::Device(e)) => {
            match motile_gpu::open_or_skip(Err(e), Backend::HostEmulation) {
                Some(never) => never,
                None => return,
            }
        }
        Err(e) => panic!("the device stepper: {e}"),
    };
    let before = gpu.state().unwrap();
    let c = cpu.step(&rhs, 0.01).unwrap_err().to_string();
    let g = gpu.step(0.01, false).unwrap_err().to_string();
    eprintln!("CPU: {c}; device: {g}");
    assert!(
        c.contains("non-finite") || c.contains("not finite"),
        "CPU: {c}"
    );
    assert!(
        g.contains(&c),
        "the device's error {g:?} against the CPU's {c:?}"
    );
    let after = gpu.state().unwrap();
    assert!(
        before.0 == after.0 && before.1 == after.1 && before.3 == after.3,
        "a failed step changed the device's state"
    );
}
