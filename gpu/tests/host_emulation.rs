//! The host emulation against what it stands in for: kernels run every thread once, arguments
//! are checked against the kernel's parameter types, and the transforms have cuFFT's layout
//! and scaling (a plane wave lands on the one mode the layout in the crate doc names).
//!
//! Launching a kernel is unsafe (nothing checks its indices): every launch below says why its
//! indices fit.
#![allow(unsafe_code)]

use motile_gpu::{Arg, Device, Direction, GpuError};

const SOURCE: &str = r#"
extern "C" __global__ void axpy(const double* x, double* y, double a, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    y[i] += a * x[i];
}
extern "C" __global__ void count(double* c, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    atomicAdd(&c[0], 1.0);
}
"#;

/// The emulation, or `None` (and why) where no C++ compiler runs; `MOTILE_REQUIRE_CXX=1`
/// makes that a failure.
fn device() -> Option<Device> {
    match Device::host_emulation(SOURCE, &["axpy", "count"]) {
        Ok(d) => Some(d),
        Err(GpuError::NoDevice(why)) if std::env::var("MOTILE_REQUIRE_CXX").is_err() => {
            eprintln!("skipped: {why}");
            None
        }
        Err(e) => panic!("host emulation: {e}"),
    }
}

#[test]
fn kernels_run_every_thread_once_and_arguments_are_checked() {
    let Some(dev) = device() else { return };
    let n = 1000; // four blocks, the last one partly idle
    let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let xb = dev.upload(&x).unwrap();
    let mut yb = dev.upload(&vec![1.0; n]).unwrap();
    // SAFETY: axpy(const double* x, double* y, double a, int n) reads x[i] and writes y[i]
    // for i < n = len(x) = len(y).
    unsafe {
        dev.launch(
            "axpy",
            n,
            &mut [
                Arg::In(&xb),
                Arg::Out(&mut yb),
                Arg::Real(2.0),
                Arg::Int(n as i32),
            ],
        )
    }
    .unwrap();
    let y = dev.download(&yb).unwrap();
    for (i, v) in y.iter().enumerate() {
        assert_eq!(*v, 1.0 + 2.0 * i as f64, "y[{i}]");
    }
    let mut c = dev.zeros(1).unwrap();
    // SAFETY: count(double* c, int n) adds to c[0] only.
    unsafe { dev.launch("count", n, &mut [Arg::Out(&mut c), Arg::Int(n as i32)]) }.unwrap();
    assert_eq!(
        dev.download(&c).unwrap(),
        vec![n as f64],
        "threads that ran"
    );
    // Arguments in the wrong order, and an unknown kernel: errors, nothing run.
    // SAFETY: refused before the kernel runs (the types do not match).
    let wrong = unsafe {
        dev.launch(
            "axpy",
            n,
            &mut [
                Arg::Out(&mut yb),
                Arg::In(&xb),
                Arg::Real(2.0),
                Arg::Int(n as i32),
            ],
        )
    };
    let msg = wrong.expect_err("swapped arguments").to_string();
    assert!(
        msg.contains("takes parameters (iorn) but was given (oirn)"),
        "{msg}"
    );
    // SAFETY: refused: no such kernel.
    let unknown = unsafe { dev.launch("nope", 1, &mut []) };
    assert!(unknown.is_err(), "an unknown kernel");
    assert_eq!(dev.download(&yb).unwrap(), y, "nothing ran");
}

#[test]
fn transforms_have_the_cufft_layout_and_scaling() {
    let Some(dev) = device() else { return };
    let (m, batch) = (8, 2);
    let plan = dev.fft3(m, batch, Direction::Both).unwrap();
    let h = m / 2 + 1;
    // Field b: cos(2 pi (kx x + ky y + kz z) / m) with (kx, ky, kz) = (1, 2, 3) and (3, 0, 1).
    let modes = [[1usize, 2, 3], [3, 0, 1]];
    let mut real = vec![0.0; batch * m * m * m];
    for (b, k) in modes.iter().enumerate() {
        for z in 0..m {
            for y in 0..m {
                for x in 0..m {
                    let ph = 2.0 * std::f64::consts::PI * (k[0] * x + k[1] * y + k[2] * z) as f64
                        / m as f64;
                    real[b * m * m * m + (z * m + y) * m + x] = ph.cos();
                }
            }
        }
    }
    let rb = dev.upload(&real).unwrap();
    let mut sb = dev.zeros(plan.complex_len()).unwrap();
    dev.forward(&plan, (&rb, 0), (&mut sb, 0)).unwrap();
    let s = dev.download(&sb).unwrap();
    let n3 = (m * m * m) as f64;
    let slen = plan.spectrum_len();
    for (b, k) in modes.iter().enumerate() {
        for i in 0..slen {
            let (re, im) = (s[2 * (b * slen + i)], s[2 * (b * slen + i) + 1]);
            // The cosine's half-spectrum coefficient n^3 / 2 sits at ((kz m + ky) h + kx).
            let want = if i == (k[2] * m + k[1]) * h + k[0] {
                n3 / 2.0
            } else {
                0.0
            };
            assert!(
                (re - want).abs() < 1e-9 && im.abs() < 1e-9,
                "field {b} mode {i}: ({re}, {im}), expected {want}"
            );
        }
    }
    // Inverse: unnormalised, so the round trip is n^3 times the input.
    let mut back = dev.zeros(plan.real_len()).unwrap();
    dev.inverse(&plan, (&mut sb, 0), (&mut back, 0)).unwrap();
    let back = dev.download(&back).unwrap();
    let err = back
        .iter()
        .zip(&real)
        .map(|(a, b)| (a / n3 - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-13, "round trip error {err:e}");
    // A plan made for one direction refuses the other.
    let forward_only = dev.fft3(m, batch, Direction::Forward).unwrap();
    let mut out = dev.zeros(plan.real_len()).unwrap();
    assert!(
        dev.inverse(&forward_only, (&mut sb, 0), (&mut out, 0))
            .is_err()
    );
}

/// A source with block reductions in shared memory (`__syncthreads`) runs each block's threads
/// concurrently: a tree sum per block gives each block's exact partial.
#[test]
fn block_reductions_in_shared_memory_run() {
    const REDUCE: &str = r#"
extern "C" __global__ void partial_sums(const double* v, long long n, double* partial) {
    __shared__ double shared[256];
    long long i = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    int t = threadIdx.x;
    shared[t] = i < n ? v[i] : 0.0;
    __syncthreads();
    for (int w = 128; w > 0; w /= 2) {
        if (t < w) shared[t] += shared[t + w];
        __syncthreads();
    }
    if (t == 0) partial[blockIdx.x] = shared[0];
}
"#;
    let dev = match Device::host_emulation(REDUCE, &["partial_sums"]) {
        Ok(d) => d,
        Err(GpuError::NoDevice(why)) if std::env::var("MOTILE_REQUIRE_CXX").is_err() => {
            eprintln!("skipped: {why}");
            return;
        }
        Err(e) => panic!("host emulation: {e}"),
    };
    let n = 700usize; // three blocks, the last partly empty
    let v: Vec<f64> = (0..n).map(|i| (i % 7) as f64 + 0.5).collect();
    let vb = dev.upload(&v).unwrap();
    let mut pb = dev.zeros(3).unwrap();
    // SAFETY: partial_sums(const double* v, long long n, double* partial) reads v[i] for
    // i < n and writes partial[block] for the 3 blocks launched.
    unsafe {
        dev.launch(
            "partial_sums",
            n,
            &mut [Arg::In(&vb), Arg::Long(n as i64), Arg::Out(&mut pb)],
        )
    }
    .unwrap();
    let got = dev.download(&pb).unwrap();
    for (b, g) in got.iter().enumerate() {
        let want: f64 = v[b * 256..((b + 1) * 256).min(n)].iter().sum();
        assert_eq!(*g, want, "block {b}");
    }
}
