//! Helpers of the benchmark examples (`scaling`, `gpu_bench`): arguments, medians, and the
//! inputs both time (the same mean-field state, the same random points).
#![allow(dead_code)]

use rand::{RngExt, SeedableRng};
use std::f64::consts::PI;

/// The value after `name` on the command line.
pub fn arg(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
}

/// The comma-separated list after `name` on the command line, each value parsed (a value that
/// does not parse stops the example, naming the option).
pub fn list_arg<T: std::str::FromStr>(name: &str) -> Option<Vec<T>> {
    arg(name).map(|list| {
        list.split(',')
            .map(|x| {
                x.trim()
                    .parse()
                    .unwrap_or_else(|_| panic!("{name}: {x:?} is not a valid value"))
            })
            .collect()
    })
}

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A smooth non-isotropic Q on an `n^3` grid (the benchmarks' mean-field state).
pub fn meanfield_state(n: usize) -> [Vec<f64>; 6] {
    let mut q: [Vec<f64>; 6] = std::array::from_fn(|c| {
        vec![
            if [0, 3, 5].contains(&c) {
                1.0 / 3.0
            } else {
                0.0
            };
            n * n * n
        ]
    });
    for idx in 0..n * n * n {
        let x = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| i as f64 / n as f64);
        q[1][idx] += 0.05 * (2.0 * PI * x[0]).sin() * (2.0 * PI * x[2]).cos();
        q[4][idx] += 0.04 * (2.0 * PI * (x[1] + x[0])).cos();
        q[0][idx] += 0.03 * (2.0 * PI * x[1]).sin();
        q[5][idx] -= 0.03 * (2.0 * PI * x[1]).sin();
    }
    q
}

/// `n` random points at 2.5 per unit volume and random forces in [-1, 1]: `(box side, points,
/// forces)`.
pub fn random_points(n: usize) -> (f64, Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let l = (n as f64 / 2.5).cbrt();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let y: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let f: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
        .collect();
    (l, y, f)
}
