//! Initial states shared by the mean-field integration tests.
#![allow(dead_code)]

use motile_meanfield::solver::params::SYM;
use std::f64::consts::PI;

/// `I/3` plus `f(x)` added to component `c`, on an `n^3` grid.
pub fn state(n: usize, pert: impl Fn([f64; 3]) -> [f64; 6]) -> [Vec<f64>; 6] {
    let mut q: [Vec<f64>; 6] = Default::default();
    for idx in 0..n * n * n {
        let x = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| i as f64 / n as f64);
        let d = pert(x);
        for c in 0..6 {
            let iso = if SYM[c].0 == SYM[c].1 { 1.0 / 3.0 } else { 0.0 };
            q[c].push(iso + d[c]);
        }
    }
    q
}

/// A smooth, strongly non-isotropic state that stays positive definite.
pub fn nonlinear_state(n: usize) -> [Vec<f64>; 6] {
    state(n, |x| {
        let (a, b, c) = (
            (2.0 * PI * x[0]).sin(),
            (2.0 * PI * x[1]).cos(),
            (2.0 * PI * (x[2] + x[0])).sin(),
        );
        [
            0.12 * a,
            0.08 * b + 0.05 * c,
            0.04 * a * b,
            -0.06 * a + 0.03 * c,
            0.07 * c,
            -0.06 * a - 0.03 * c,
        ]
    })
}
