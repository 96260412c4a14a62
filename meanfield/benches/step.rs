//! Criterion benchmark of one mean-field step (closure, Stokes fixed point, transforms) at
//! 32^3, 64^3 and 128^3 on 1 and 2 threads, from a smooth non-isotropic state. The split by
//! stage is printed by the `meanfield_step_profile` example. The closure tables come from the
//! cache `motile meanfield run` writes (`~/.cache/motile`), or are built (about 10 s).
//!
//! `cargo bench -p motile-meanfield --bench step -- 64`

use criterion::{Criterion, criterion_group, criterion_main};
use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::{MeanFieldParams, SYM};
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};
use std::f64::consts::PI;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let closure = std::env::var_os("HOME")
        .map(|h| std::path::PathBuf::from(h).join(".cache/motile/bingham_degree80.bin"))
        .and_then(|p| std::fs::read(p).ok())
        .and_then(|b| BinghamClosure::from_bytes(&b, DEFAULT_DEGREE))
        .unwrap_or_else(|| BinghamClosure::new(DEFAULT_DEGREE).expect("tables"));
    let params = MeanFieldParams::default();
    let mut group = c.benchmark_group("meanfield_step");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    for n in [32usize, 64, 128] {
        let grid = SpectralGrid::new(n);
        let rhs = MeanFieldRhs {
            grid: &grid,
            closure: &closure,
            params: &params,
            with_entropy: false,
        };
        let mut q: [Vec<f64>; 6] = std::array::from_fn(|c| {
            vec![if SYM[c].0 == SYM[c].1 { 1.0 / 3.0 } else { 0.0 }; n * n * n]
        });
        for idx in 0..n * n * n {
            let x = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| i as f64 / n as f64);
            q[1][idx] += 0.05 * (2.0 * PI * x[0]).sin() * (2.0 * PI * x[2]).cos();
            q[4][idx] += 0.04 * (2.0 * PI * (x[1] + x[0])).cos();
        }
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut stepper = pool.install(|| MeanFieldStepper::new(&grid, &q, SBDF2));
            pool.install(|| stepper.step(&rhs, 0.01).expect("first step"));
            group.bench_function(format!("{n}^3/{threads}threads"), |b| {
                b.iter(|| pool.install(|| stepper.step(&rhs, 0.01).expect("step")))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
