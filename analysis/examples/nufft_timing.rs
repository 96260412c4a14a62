//! Times one NUFFT configuration and prints one JSON line; driven by
//! `bench/nufft_vs_finufft.py`, which runs FINUFFT on the same problem in the same session.
//!
//! `nufft_timing --type 1 --points 1000000 --modes 64 --tol 1e-6 --threads 2 --reps 5`
//!
//! Points are uniform in [0, 2 pi)^3 with complex strengths (seed 42). `median_s` is the median
//! execute time with the points already sorted (FINUFFT's "plan reused" execute), `setpts_s`
//! the sorting time, and `rel_err` the relative L2 error on 200 modes (type 1) or 200 points
//! (type 2) against the direct sum.

use motile_analysis::nufft::{NufftPlan, direct_type2, mode_of};
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;
use std::time::Instant;

fn arg(args: &[String], name: &str, default: f64) -> f64 {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map(|v| {
            v.parse::<f64>()
                .unwrap_or_else(|_| panic!("{name}: cannot parse '{v}' as a number"))
        })
        .unwrap_or(default)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let ty = arg(&args, "--type", 1.0) as u32;
    let n = arg(&args, "--points", 1e5) as usize;
    let m = arg(&args, "--modes", 32.0) as usize;
    let tol = arg(&args, "--tol", 1e-6);
    let threads = arg(&args, "--threads", 1.0) as usize;
    let reps = arg(&args, "--reps", 5.0) as usize;
    let l = 2.0 * PI;
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let pts: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let len = if ty == 1 { n } else { m * m * m };
    let data: Vec<Complex64> = (0..len)
        .map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let mut plan = NufftPlan::new([m, m, m], tol).expect("plan");
        let t = Instant::now();
        plan.set_points(&pts, l).expect("points");
        let setpts = t.elapsed().as_secs_f64();
        let mut times = Vec::new();
        let mut out = Vec::new();
        for _ in 0..reps + 1 {
            let t = Instant::now();
            out = if ty == 1 { plan.type1(&[&data]) } else { plan.type2(&[&data]) }.expect("transform");
            times.push(t.elapsed().as_secs_f64());
        }
        times.remove(0); // warm-up
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        // Error on a sample against the direct sum.
        let rel_err = if ty == 1 {
            let sample: Vec<usize> = (0..200).map(|i| (i * 7919) % (m * m * m)).collect();
            let mut num = 0.0;
            let mut den = 0.0;
            for &idx in &sample {
                let k = [idx % m, (idx / m) % m, idx / (m * m)].map(|i| mode_of(i, m) as f64);
                let exact: Complex64 = pts
                    .iter()
                    .zip(&data)
                    .map(|(x, f)| f * Complex64::from_polar(1.0, -(k[0] * x[0] + k[1] * x[1] + k[2] * x[2])))
                    .sum();
                num += (out[0][idx] - exact).norm_sqr();
                den += exact.norm_sqr();
            }
            (num / den).sqrt()
        } else {
            let sample: Vec<[f64; 3]> = pts.iter().step_by((n / 200).max(1)).copied().collect();
            let exact = direct_type2(&sample, l, &data, [m, m, m]);
            let got: Vec<Complex64> = out[0].iter().step_by((n / 200).max(1)).copied().collect();
            let num: f64 = got.iter().zip(&exact).map(|(a, b)| (a - b).norm_sqr()).sum();
            let den: f64 = exact.iter().map(|b| b.norm_sqr()).sum();
            (num / den).sqrt()
        };
        println!(
            "{{\"type\":{ty},\"points\":{n},\"modes\":{m},\"tol\":{tol:e},\"threads\":{threads},\"median_s\":{median:.6},\"setpts_s\":{setpts:.6},\"rel_err\":{rel_err:.3e}}}"
        );
    });
}
