//! Times mean-field steps at one grid size and splits the time by stage:
//! `cargo run --release -p motile-meanfield --example meanfield_step_profile -- --grid 64 --threads 2 --steps 3 [--degree 80]`. Closure tables are built first (not timed).
//!
//! FFTs per step (complex 3D transforms): 6 (Q to the grid) + 12 per fixed-point iteration
//! (6 strain components back, 6 stress components forward) + 6 (final strain) + 9 (grad u)
//! + 3 (u) + 18 (grad Q) + 6 (right-hand side forward) + 3 (u for the CFL diagnostic).

use motile_analysis::fft3::RealFft3;
use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
use motile_meanfield::solver::closure_field::ClosureField;
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::{MeanFieldParams, SYM};
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};
use num_complex::Complex64;
use std::f64::consts::PI;
use std::time::Instant;

fn arg(name: &str, default: f64) -> f64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default, |v| v.parse().expect("number"))
}

fn main() {
    let n = arg("--grid", 32.0) as usize;
    let threads = arg("--threads", 2.0) as usize;
    let steps = arg("--steps", 3.0) as usize;
    let degree = arg("--degree", DEFAULT_DEGREE as f64) as usize;
    // The tables `motile meanfield run` cached, if present (building them takes ~10 s).
    let cached = std::env::var_os("HOME")
        .map(|h| {
            std::path::PathBuf::from(h).join(format!(".cache/motile/bingham_degree{degree}.bin"))
        })
        .and_then(|p| std::fs::read(p).ok())
        .and_then(|b| BinghamClosure::from_bytes(&b, degree));
    let closure = cached.unwrap_or_else(|| BinghamClosure::new(degree).expect("tables"));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let grid = SpectralGrid::new(n);
        let params = MeanFieldParams::default();
        let rhs = MeanFieldRhs { grid: &grid, closure: &closure, params: &params, with_entropy: false };
        let mut q: [Vec<f64>; 6] = std::array::from_fn(|c| vec![if SYM[c].0 == SYM[c].1 { 1.0 / 3.0 } else { 0.0 }; n * n * n]);
        for idx in 0..n * n * n {
            let x = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| i as f64 / n as f64);
            q[1][idx] += 0.05 * (2.0 * PI * x[0]).sin() * (2.0 * PI * x[2]).cos();
            q[4][idx] += 0.04 * (2.0 * PI * (x[1] + x[0])).cos();
        }
        // One real FFT: the mean of a forward (r2c) and an inverse (c2r) transform.
        let fft = RealFft3::new([n; 3]);
        let real: Vec<f64> = (0..n * n * n).map(|i| (i as f64 * 0.1).sin()).collect();
        let mut half = vec![Complex64::default(); fft.complex_len()];
        let mut back = vec![0.0; n * n * n];
        fft.forward(&real, &mut half); // warm-up
        let t = Instant::now();
        for _ in 0..10 {
            fft.forward(&real, &mut half);
            fft.inverse(&mut half, &mut back);
        }
        let one_fft = t.elapsed().as_secs_f64() / 20.0;
        // Closure evaluation alone.
        let mut cf = ClosureField::new(&closure, &q, false); // warm-up
        let t = Instant::now();
        for _ in 0..3 {
            cf = ClosureField::new(&closure, &q, false);
        }
        let closure_s = t.elapsed().as_secs_f64() / 3.0;
        let e: [Vec<f64>; 6] = std::array::from_fn(|c| q[c].iter().map(|v| 0.1 * v).collect());
        let t = Instant::now();
        let _ = cf.contract(&e);
        let contract_s = t.elapsed().as_secs_f64();
        // Whole steps.
        let mut s = MeanFieldStepper::new(&grid, &q, SBDF2);
        let mut iters = 0;
        let t = Instant::now();
        for _ in 0..steps {
            iters += s.step(&rhs, 0.01).expect("step").rhs.iterations;
        }
        let step_s = t.elapsed().as_secs_f64() / steps as f64;
        let k = iters as f64 / steps as f64;
        // Q to the grid, 12 per fixed-point iteration, u and grad u, grad Q, the products back.
        let ffts = 6.0 + 12.0 * k + 3.0 + 9.0 + 18.0 + 6.0;
        println!(
            "{n}^3, {threads} threads, closure degree {degree}: step {step_s:.3} s; fixed-point iterations {k:.1}; closure evaluation {closure_s:.3} s, S:E contraction {contract_s:.4} s per iteration; one FFT {:.2} ms x {ffts:.0} FFTs = {:.3} s ({:.0}% of the step); step / FFT time = {:.2}",
            one_fft * 1e3,
            ffts * one_fft,
            100.0 * ffts * one_fft / step_s,
            step_s / (ffts * one_fft)
        );
    });
}
