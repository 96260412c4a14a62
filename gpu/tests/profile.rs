//! The per-operation profile (`motile_gpu::profile`) on the host emulation: every launch,
//! transfer and transform is counted under its name while profiling is on, and nothing while
//! it is off. (Its own test binary: profiling is a switch for the whole process.)
#![allow(unsafe_code)]

use motile_gpu::{Backend, Buffer, Device, Direction, profile};

motile_gpu::kernels! {
    /// The test kernel.
    const KERNELS = r#"
extern "C" __global__ void scale(double* y, double a, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    y[i] *= a;
}
"#;
    /// `y *= a`.
    struct Scale = "scale" { y: &'a mut Buffer<f64>, a: f64, n: i32 }
}

#[test]
fn profiling_counts_each_operation_under_its_name_and_only_while_on() {
    let opened = Device::open(Backend::HostEmulation, &KERNELS);
    let Some(dev) = motile_gpu::open_or_skip(opened, Backend::HostEmulation) else {
        return;
    };
    let n = 4096;
    let run = |launches: usize| {
        let mut y = dev.upload(&vec![1.0; n]).unwrap();
        for _ in 0..launches {
            // SAFETY: scale writes y[i] for i < n = len(y).
            unsafe {
                dev.launch(
                    n,
                    Scale {
                        y: &mut y,
                        a: 2.0,
                        n: n as i32,
                    },
                )
            }
            .unwrap();
        }
        let plan = dev.fft3(16, 1, Direction::Both).unwrap();
        let mut spectra = dev.zeros(2 * plan.spectrum_len()).unwrap();
        dev.forward(&plan, &y, 0, &mut spectra, 0).unwrap();
        let v = dev.download(&y).unwrap();
        assert_eq!(v[0], 2f64.powi(launches as i32));
    };
    profile::enable(false);
    run(3);
    assert!(profile::take().is_empty(), "recorded while off");
    profile::enable(true);
    run(5);
    let p = profile::take();
    profile::enable(false);
    let calls = |name: &str| p.iter().find(|e| e.name == name).map_or(0, |e| e.calls);
    eprintln!("{p:?}");
    assert_eq!(calls("scale"), 5, "{p:?}");
    assert_eq!(calls("upload"), 1, "{p:?}");
    assert_eq!(calls("download"), 1, "{p:?}");
    assert_eq!(calls("forward FFT 16^3 x 1"), 1, "{p:?}");
    assert_eq!(calls("zero"), 0, "zeros() allocates: {p:?}");
    assert!(p.iter().all(|e| e.seconds >= 0.0 && e.seconds.is_finite()));
    assert!(
        p.windows(2).all(|w| w[0].seconds >= w[1].seconds),
        "largest first: {p:?}"
    );
    assert!(profile::take().is_empty(), "take clears the totals");
}
