//! The host emulation against what it stands in for: kernels run every thread once, integer
//! buffers keep their type, kernel declarations are checked against their source, and the
//! transforms have cuFFT's layout and scaling (a plane wave lands on the one mode the layout in
//! the crate doc names).
//!
//! Launching a kernel is unsafe (nothing checks its indices): every launch below says why its
//! indices fit.
#![allow(unsafe_code)]

use motile_gpu::{Backend, Buffer, Device, Direction, GpuError, KernelSet};

motile_gpu::kernels! {
    /// The test kernels.
    const KERNELS = r#"
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
extern "C" __global__ void widths(const int* start, const unsigned int* weight,
                                  unsigned int* out, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    out[i] = (unsigned int)(start[i + 1] - start[i]) * weight[i];
}
"#;
    /// `y += a x`.
    struct Axpy = "axpy" { x: &'a Buffer<f64>, y: &'a mut Buffer<f64>, a: f64, n: i32 }
    /// Counts the threads that run.
    struct Count = "count" { c: &'a mut Buffer<f64>, n: i32 }
    /// Integer buffers: `out[i] = (start[i + 1] - start[i]) weight[i]`.
    struct Widths = "widths" {
        start: &'a Buffer<i32>,
        weight: &'a Buffer<u32>,
        out: &'a mut Buffer<u32>,
        n: i32,
    }
}

/// The emulation of `set`, or `None` (and why) where no C++ compiler runs;
/// `MOTILE_REQUIRE_CXX=1` makes that a failure.
fn open(set: &KernelSet) -> Option<Device> {
    motile_gpu::open_or_skip(
        Device::open(Backend::HostEmulation, set),
        Backend::HostEmulation,
    )
}

fn device() -> Option<Device> {
    open(&KERNELS)
}

#[test]
fn kernels_run_every_thread_once() {
    let Some(dev) = device() else { return };
    let n = 1000; // four blocks, the last one partly idle
    let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let xb = dev.upload(&x).unwrap();
    let mut yb = dev.upload(&vec![1.0; n]).unwrap();
    // SAFETY: axpy reads x[i] and writes y[i] for i < n = len(x) = len(y).
    unsafe {
        dev.launch(
            n,
            Axpy {
                x: &xb,
                y: &mut yb,
                a: 2.0,
                n: n as i32,
            },
        )
    }
    .unwrap();
    let y = dev.download(&yb).unwrap();
    for (i, v) in y.iter().enumerate() {
        assert_eq!(*v, 1.0 + 2.0 * i as f64, "y[{i}]");
    }
    let mut c = dev.zeros(1).unwrap();
    // SAFETY: count adds to c[0] only.
    unsafe {
        dev.launch(
            n,
            Count {
                c: &mut c,
                n: n as i32,
            },
        )
    }
    .unwrap();
    assert_eq!(
        dev.download(&c).unwrap(),
        vec![n as f64],
        "threads that ran"
    );
}

#[test]
fn integer_buffers_stay_integers() {
    let Some(dev) = device() else { return };
    let start: Vec<i32> = vec![0, 3, 3, 10, 2_000_000_000];
    let weight: Vec<u32> = vec![1, 7, 2, 2];
    let sb = dev.upload(&start).unwrap();
    let wb = dev.upload(&weight).unwrap();
    let mut out = dev.zeros::<u32>(4).unwrap();
    // SAFETY: widths reads start[i], start[i + 1] (5 values) and weight[i], writes out[i],
    // for i < 4.
    unsafe {
        dev.launch(
            4,
            Widths {
                start: &sb,
                weight: &wb,
                out: &mut out,
                n: 4,
            },
        )
    }
    .unwrap();
    assert_eq!(
        dev.download(&out).unwrap(),
        vec![3, 0, 14, 3_999_999_980],
        "integer arithmetic beyond f64's exact 2^53 is not at stake here, but the types are"
    );
}

#[test]
fn a_declaration_that_differs_from_its_source_is_refused() {
    motile_gpu::kernels! {
        const SWAPPED = r#"extern "C" __global__ void axpy(const double* x, double* y, double a, int n) {}"#;
        struct Axpy2 = "axpy" { y: &'a mut Buffer<f64>, x: &'a Buffer<f64>, a: f64, n: i32 }
    }
    motile_gpu::kernels! {
        const RETYPED = r#"extern "C" __global__ void axpy(const double* x, double* y, double a, int n) {}"#;
        struct Axpy3 = "axpy" { x: &'a Buffer<f64>, y: &'a mut Buffer<f64>, a: f64, n: i64 }
    }
    motile_gpu::kernels! {
        const MISSING = r#"extern "C" __global__ void axpy(const double* x, double* y, double a, int n) {}"#;
        struct Axpy4 = "axpy" { x: &'a Buffer<f64>, y: &'a mut Buffer<f64>, a: f64 }
        struct Absent = "absent" { x: &'a Buffer<f64> }
    }
    let e = SWAPPED.check().unwrap_err();
    assert!(e.contains("parameter 0: the source has `x`"), "{e}");
    let e = RETYPED.check().unwrap_err();
    assert!(e.contains("parameter 3"), "{e}");
    let e = MISSING.check().unwrap_err();
    assert!(
        e.contains("the source has 4 parameters, the declaration 3"),
        "{e}"
    );
    KERNELS.check().unwrap();
    // Opening refuses it before compiling anything.
    let e = Device::open(Backend::HostEmulation, &SWAPPED).unwrap_err();
    assert!(matches!(e, GpuError::Input(_)), "{e}");
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
    dev.forward(&plan, &rb, 0, &mut sb, 0).unwrap();
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
    dev.inverse(&plan, &mut sb, 0, &mut back, 0).unwrap();
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
    assert!(dev.inverse(&forward_only, &mut sb, 0, &mut out, 0).is_err());
}

/// In-place transforms: the real values in cuFFT's padded layout (rows of 2 (m/2 + 1)) give the
/// out-of-place plan's spectra bit for bit over the same memory, whatever the padding holds,
/// and transform back into the padded rows; an in-place plan refuses out-of-place calls and
/// the other way round.
#[test]
fn in_place_transforms_match_the_out_of_place_ones() {
    let Some(dev) = device() else { return };
    for m in [6, 7] {
        let batch = 2;
        let (row, n3) = (2 * (m / 2 + 1), m * m * m);
        let plan = dev.fft3(m, batch, Direction::Both).unwrap();
        let inplace = dev.fft3_in_place(m, batch, Direction::Both).unwrap();
        assert_eq!(inplace.padded_len(), batch * m * m * row);
        let real: Vec<f64> = (0..batch * n3)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) / 7.0)
            .collect();
        // The same values padded, with garbage in the padding.
        let mut padded = vec![f64::NAN; inplace.padded_len()];
        for (dst, src) in padded.chunks_exact_mut(row).zip(real.chunks_exact(m)) {
            dst[..m].copy_from_slice(src);
        }
        let mut grid = dev.upload(&padded).unwrap();
        dev.forward_in_place(&inplace, &mut grid, 0).unwrap();
        let mut spectra = dev.zeros(plan.complex_len()).unwrap();
        dev.forward(&plan, &dev.upload(&real).unwrap(), 0, &mut spectra, 0)
            .unwrap();
        let (a, b) = (
            dev.download(&grid).unwrap(),
            dev.download(&spectra).unwrap(),
        );
        assert_eq!(
            a.len(),
            b.len(),
            "m = {m}: a spectrum over each padded field"
        );
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "m = {m}: in-place spectra differ from the out-of-place ones"
        );
        dev.inverse_in_place(&inplace, &mut grid, 0).unwrap();
        let back = dev.download(&grid).unwrap();
        let err = back
            .chunks_exact(row)
            .zip(real.chunks_exact(m))
            .flat_map(|(p, r)| p[..m].iter().zip(r).map(|(x, y)| (x / n3 as f64 - y).abs()))
            .fold(0.0, f64::max);
        assert!(err < 1e-13, "m = {m}: in-place round trip error {err:e}");
        assert!(dev.forward_in_place(&plan, &mut grid, 0).is_err());
        assert!(
            dev.forward(&inplace, &dev.upload(&real).unwrap(), 0, &mut spectra, 0)
                .is_err()
        );
        let short = &mut dev.zeros(inplace.padded_len() - 2).unwrap();
        assert!(dev.inverse_in_place(&inplace, short, 0).is_err());
    }
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
    motile_gpu::kernels! {
        const SET = REDUCE;
        struct PartialSums = "partial_sums" {
            v: &'a Buffer<f64>,
            n: i64,
            partial: &'a mut Buffer<f64>,
        }
    }
    let Some(dev) = open(&SET) else { return };
    let n = 700usize; // three blocks, the last partly empty
    let v: Vec<f64> = (0..n).map(|i| (i % 7) as f64 + 0.5).collect();
    let vb = dev.upload(&v).unwrap();
    let mut pb = dev.zeros(3).unwrap();
    // SAFETY: partial_sums(const double* v, long long n, double* partial) reads v[i] for
    // i < n and writes partial[block] for the 3 blocks launched.
    unsafe {
        dev.launch(
            n,
            PartialSums {
                v: &vb,
                n: n as i64,
                partial: &mut pb,
            },
        )
    }
    .unwrap();
    let got = dev.download(&pb).unwrap();
    for (b, g) in got.iter().enumerate() {
        let want: f64 = v[b * 256..((b + 1) * 256).min(n)].iter().sum();
        assert_eq!(*g, want, "block {b}");
    }
}

motile_gpu::kernels! {
    /// Integer atomics and a race between blocks.
    const ATOMICS = r#"
extern "C" __global__ void histogram(const int* key, int* count, int* rank, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    rank[i] = atomicAdd(&count[key[i]], 1);
}
extern "C" __global__ void last_block(int* out) {
    if (threadIdx.x == 0) out[0] = blockIdx.x;
}
"#;
    /// `rank[i]`: how many points of `key[i]` came before it; `count`: points per key.
    struct Histogram = "histogram" {
        key: &'a Buffer<i32>,
        count: &'a mut Buffer<i32>,
        rank: &'a mut Buffer<i32>,
        n: i32,
    }
    /// Every block writes its index to `out[0]`: the last block to run wins.
    struct LastBlock = "last_block" { out: &'a mut Buffer<i32> }
}

/// Integer atomics return the value before the add: the ranks within each key are exactly
/// 0..count, and the counts the histogram.
#[test]
fn integer_atomics_return_the_old_value() {
    let Some(dev) = open(&ATOMICS) else { return };
    let n = 1000usize;
    let key: Vec<i32> = (0..n).map(|i| ((i * 7919) % 13) as i32).collect();
    let kb = dev.upload(&key).unwrap();
    let mut cb = dev.zeros::<i32>(13).unwrap();
    let mut rb = dev.zeros::<i32>(n).unwrap();
    // SAFETY: histogram reads key[i] and writes rank[i] for i < n (n values each), and adds to
    // count[key[i]] with key[i] < 13 (13 values).
    unsafe {
        dev.launch(
            n,
            Histogram {
                key: &kb,
                count: &mut cb,
                rank: &mut rb,
                n: n as i32,
            },
        )
    }
    .unwrap();
    let (count, rank) = (dev.download(&cb).unwrap(), dev.download(&rb).unwrap());
    for k in 0..13 {
        let mut ranks: Vec<i32> = (0..n).filter(|&i| key[i] == k).map(|i| rank[i]).collect();
        ranks.sort_unstable();
        assert_eq!(ranks, (0..count[k as usize]).collect::<Vec<_>>(), "key {k}");
    }
    assert_eq!(count.iter().sum::<i32>(), n as i32);
}

/// The block that wrote last in a launch of `blocks` blocks of `last_block`.
fn last_block(dev: &Device, blocks: usize) -> i32 {
    let mut ob = dev.zeros::<i32>(1).unwrap();
    // SAFETY: last_block writes out[0] only (one value).
    unsafe {
        dev.launch(
            blocks * motile_gpu::THREADS as usize,
            LastBlock { out: &mut ob },
        )
    }
    .unwrap();
    dev.download(&ob).unwrap()[0]
}

/// Blocks run in turn (the last block writes last), or in a new order at every launch once
/// shuffled: a race between blocks then shows as results that vary between launches.
#[test]
fn shuffled_blocks_expose_a_race_between_blocks() {
    let Some(dev) = open(&ATOMICS) else { return };
    let blocks = 40usize;
    let run = |dev: &Device| last_block(dev, blocks);
    let in_turn: Vec<i32> = (0..5).map(|_| run(&dev)).collect();
    assert_eq!(in_turn, vec![blocks as i32 - 1; 5]);
    assert!(dev.shuffle_blocks(7));
    let shuffled: std::collections::BTreeSet<i32> = (0..10).map(|_| run(&dev)).collect();
    assert!(
        shuffled.len() > 1,
        "ten shuffled launches all ended with block {shuffled:?}"
    );
    dev.shuffle_blocks(0);
    assert_eq!(run(&dev), blocks as i32 - 1);
}

/// Two devices with the same kernels (the second loads the library the first compiled, from
/// the process's cache) keep their own globals: shuffling one's blocks leaves the other's in
/// turn. (Were the two loads one library, the second would run shuffled too.)
#[test]
fn devices_with_the_same_kernels_keep_their_own_globals() {
    let (Some(a), Some(b)) = (open(&ATOMICS), open(&ATOMICS)) else {
        return;
    };
    let blocks = 40usize;
    let last = |dev: &Device| last_block(dev, blocks);
    assert!(a.shuffle_blocks(11));
    let shuffled: std::collections::BTreeSet<i32> = (0..10).map(|_| last(&a)).collect();
    assert!(shuffled.len() > 1, "the shuffled device ran in turn");
    let in_turn: Vec<i32> = (0..10).map(|_| last(&b)).collect();
    assert_eq!(
        in_turn,
        vec![blocks as i32 - 1; 10],
        "the other device's blocks ran shuffled"
    );
}
