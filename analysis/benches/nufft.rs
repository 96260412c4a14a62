//! Criterion benchmarks of the 3D NUFFT: types 1 and 2, 1e5 and 1e6 points, 32^3 / 64^3 / 128^3
//! modes, tolerances 1e-3 / 1e-6 / 1e-9, on 1 and 2 threads (execute only, points already
//! sorted; sorting is benchmarked separately). The side-by-side comparison with FINUFFT is
//! `bench/nufft_vs_finufft.py`; see BENCHMARKS.md.
//!
//! The full matrix takes a long time; filter it, e.g.
//! `cargo bench -p motile-analysis --bench nufft -- 'type1/1000000/64/1e-6'`.
//!
//! `velocity_spectrum/...`: the flow's spectrum from point forces, what a particle run's
//! diagnostics compute at every diagnostic: force-free rods (four points each, as the runs'
//! quadrature) at the `paper-dilute` density (nu = 0.625: 0.625 L^3 rods, L in rod lengths),
//! `floor(L/2)` modes per axis and tolerance 1e-4 as the runs' norms, 2 threads:
//! `cargo bench -p motile-analysis --bench nufft -- velocity_spectrum`.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use motile_analysis::NufftPlan;
use motile_analysis::correlation::velocity_spectrum;
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;
use std::time::Duration;

fn data(n: usize, len: usize) -> (Vec<[f64; 3]>, Vec<Complex64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let pts = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..2.0 * PI)))
        .collect();
    let v = (0..len)
        .map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
        .collect();
    (pts, v)
}

/// Points and forces of `0.625 l^3` force-free rods in a box of side `l`.
fn swimmers(l: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let rods = (0.625 * l * l * l) as usize;
    let (mut y, mut f) = (Vec::with_capacity(4 * rods), Vec::with_capacity(4 * rods));
    for _ in 0..rods {
        let x: [f64; 3] = std::array::from_fn(|_| rng.random_range(0.0..l));
        let mut p: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        p = p.map(|c| c / n);
        // Gauss-Legendre nodes on [-1/2, 1/2], force +-p at the outer, -+p/2 at the inner pair:
        // zero net force, a stresslet along p.
        for (s, w) in [(-0.43, -1.0), (-0.17, 0.5), (0.17, 0.5), (0.43, -1.0)] {
            y.push(std::array::from_fn(|d| (x[d] + s * p[d]).rem_euclid(l)));
            f.push(p.map(|c| w * c * s.signum()));
        }
    }
    (y, f)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("nufft");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for ty in [1u32, 2] {
        for n in [100_000usize, 1_000_000] {
            for m in [32usize, 64, 128] {
                let len = if ty == 1 { n } else { m * m * m };
                let (pts, v) = data(n, len);
                for tol in [1e-3, 1e-6, 1e-9] {
                    for threads in [1usize, 2] {
                        let pool = rayon::ThreadPoolBuilder::new()
                            .num_threads(threads)
                            .build()
                            .unwrap();
                        let mut plan = NufftPlan::new([m; 3], tol).unwrap();
                        pool.install(|| plan.set_points(&pts, 2.0 * PI)).unwrap();
                        let id = BenchmarkId::new(
                            format!("type{ty}/{n}/{m}/{tol:e}"),
                            format!("{threads}threads"),
                        );
                        group.bench_function(id, |b| {
                            b.iter(|| {
                                pool.install(|| {
                                    if ty == 1 {
                                        plan.type1(&[&v])
                                    } else {
                                        plan.type2(&[&v])
                                    }
                                })
                                .unwrap()
                            })
                        });
                    }
                }
            }
        }
    }
    let (pts, _) = data(1_000_000, 0);
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut plan = NufftPlan::new([64; 3], 1e-6).unwrap();
        group.bench_function(
            BenchmarkId::new("set_points/1000000/64", format!("{threads}threads")),
            |b| b.iter(|| pool.install(|| plan.set_points(&pts, 2.0 * PI)).unwrap()),
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    for l in [24.0f64, 50.0] {
        let (y, f) = swimmers(l);
        let modes = (l / 2.0).floor() as usize;
        let id = format!("velocity_spectrum/L{l}/{}points/{modes}modes/1e-4", y.len());
        group.bench_function(id, |b| {
            b.iter(|| pool.install(|| velocity_spectrum(&y, &f, l, 1.0, modes, 1e-4).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
