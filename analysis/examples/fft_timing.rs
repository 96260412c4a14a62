//! Time 3D real FFTs: `cargo run --release -p motile-analysis --example fft_timing -- [n]`.
use motile_analysis::fft3::RealFft3;
use num_complex::Complex64;
use std::time::Instant;

fn main() {
    let n: usize = std::env::args().nth(1).map_or(128, |s| s.parse().unwrap());
    let fft = RealFft3::new([n; 3]);
    let input: Vec<f64> = (0..n * n * n)
        .map(|i| ((i * 7919) % 1000) as f64 / 1000.0)
        .collect();
    let mut spec = vec![Complex64::default(); fft.complex_len()];
    let mut out = vec![0.0; n * n * n];
    let mut times = Vec::new();
    for _ in 0..11 {
        let t = Instant::now();
        fft.forward(&input, &mut spec);
        let f = t.elapsed().as_secs_f64();
        let t = Instant::now();
        fft.inverse(&mut spec, &mut out);
        times.push((f, t.elapsed().as_secs_f64()));
    }
    times.sort_by(|a, b| (a.0 + a.1).total_cmp(&(b.0 + b.1)));
    let (f, i) = times[times.len() / 2];
    println!(
        "real FFT {n}^3: forward {:.2} ms, inverse {:.2} ms (median of 11)",
        f * 1e3,
        i * 1e3
    );
}
