//! The device memory of the mean-field step on the GPU (feature `gpu`), per grid point,
//! counted without a GPU: the process's tally of device buffers (`motile_gpu::live_bytes` and
//! `peak_bytes`) counts the same bytes on the host emulation as on CUDA, and the FFT plans' work
//! areas are added where the backend reports them (cuFFT; none on the emulation).
//!
//! Everything the step holds scales with the grid (the state, its history, the velocity, the
//! closure's per-point values, the transforms' buffers; the closure's tables and the
//! wavenumbers are small), so the peak of a step (the second: the first has no history) divided
//! by `n^3` is the same at every grid. It is measured at 12^3 and 20^3 and must agree to 10%
//! (nothing grows faster than the grid) and stay below `GPU_BYTES_PER_POINT`, the
//! figure a mean-field GPU run's memory check uses (experiments: `MeanFieldRunConfig::gpu_memory`).
//!
//! On the host emulation (skipped with the reason where no C++ compiler runs, a failure with
//! `MOTILE_REQUIRE_CXX=1`). One test in this file: the tally is the process's, so nothing else
//! may allocate device buffers while it runs.

mod common;

use motile_gpu::Backend;
use motile_meanfield::GPU_BYTES_PER_POINT;
use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
use motile_meanfield::gpu::{GpuError, GpuMeanField};
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::MeanFieldParams;
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};

/// The peak device bytes per grid point of the second step on an `n^3` grid, or `None` where
/// the emulation cannot run.
fn peak_per_point(n: usize) -> Option<f64> {
    let grid = SpectralGrid::new(n);
    let closure = BinghamClosure::new(DEFAULT_DEGREE).unwrap();
    let params = MeanFieldParams {
        zeta: 0.5,
        diffusion: 1e-3,
        ..Default::default()
    };
    let cpu = MeanFieldStepper::new(&grid, &common::nonlinear_state(n), SBDF2);
    let rhs = MeanFieldRhs {
        grid: &grid,
        closure: &closure,
        params: &params,
        with_entropy: true,
    };
    let base = motile_gpu::live_bytes();
    motile_gpu::reset_peak();
    let mut gpu = match GpuMeanField::open(Backend::HostEmulation, &rhs, &cpu) {
        Ok(g) => g,
        Err(GpuError::Device(e)) => {
            motile_gpu::open_or_skip::<()>(Err(e), Backend::HostEmulation);
            return None;
        }
        Err(e) => panic!("the device stepper: {e}"),
    };
    gpu.step(0.01, true).unwrap();
    gpu.step(0.01, true).unwrap();
    let peak = motile_gpu::peak_bytes() - base + motile_gpu::fft_work_bytes();
    drop(gpu);
    Some(peak as f64 / (n * n * n) as f64)
}

#[test]
fn the_meanfield_step_fits_its_memory_per_grid_point() {
    let Some(small) = peak_per_point(12) else {
        return;
    };
    let large = peak_per_point(20).expect("the emulation ran at 12^3");
    eprintln!(
        "mean-field GPU step: {small:.0} bytes per grid point at its peak at 12^3, {large:.0} at 20^3; the memory check assumes {GPU_BYTES_PER_POINT:.0}"
    );
    assert!(
        (large - small).abs() <= 0.1 * large,
        "per point: {small:.0} at 12^3, {large:.0} at 20^3: something grows faster than the grid"
    );
    assert!(
        (0.8 * GPU_BYTES_PER_POINT..=GPU_BYTES_PER_POINT).contains(&large),
        "measured {large:.0} bytes per grid point, the check assumes {GPU_BYTES_PER_POINT:.0}: update it"
    );
}
