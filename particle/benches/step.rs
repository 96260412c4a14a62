//! Criterion benchmark of one particle step at nu = 5, L/l = 25 (78 125 rods, local drag,
//! contacts), on 1 and 2 threads. The initial configuration is relaxed by 20 steps first so the
//! contact network is that of a running simulation. Stage split and solver iterations:
//! `cargo run --release -p motile-particle --example step_profile`.

use criterion::{Criterion, criterion_group, criterion_main};
use motile_particle::hydro::mobility::LocalDrag;
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::stepper::Stepper;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let mut rods = random_nonoverlapping(78_125, 25.0, DEFAULT_DIAMETER, 1, 1_000_000)
        .expect("nu = 5 at L = 25");
    let mut warm = Stepper::new(Box::new(LocalDrag::default()), ContactParams::default());
    for _ in 0..20 {
        warm.step(&mut rods, 0.002).expect("relaxation step");
    }
    let mut group = c.benchmark_group("particle_step");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        group.bench_function(format!("nu5_L25_78125rods/{threads}threads"), |b| {
            b.iter_batched(
                || {
                    (
                        rods.clone(),
                        Stepper::new(Box::new(LocalDrag::default()), ContactParams::default()),
                    )
                },
                |(mut r, mut s)| pool.install(|| s.step(&mut r, 0.002).unwrap()),
                criterion::BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
