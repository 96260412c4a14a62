//! The work of one mean-field step on a device, counted from its kernels: per phase the
//! launches, 3D transforms and host round trips (downloads), and the global-memory bytes per
//! grid point that the kernels' arguments ask for (each field a kernel reads or writes, once;
//! a half spectrum of `n^2 (n/2 + 1)` complex values counts as 8 bytes per grid point, as a
//! real field does). A transform is counted as `passes` passes that each read and write its
//! field once (16 bytes per point per pass; cuFFT's double-precision 3D transforms of 128^3
//! to 256^3 make 2 or 3). The launches, transforms and downloads are checked against what the
//! device is asked for in `meanfield/tests/gpu.rs`; the bytes are not measured anywhere.

/// One phase of a step.
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseWork {
    /// What it does.
    pub phase: &'static str,
    /// Kernel launches (transforms apart).
    pub launches: usize,
    /// 3D transforms of one field.
    pub transforms: usize,
    /// Downloads (each a host round trip).
    pub downloads: usize,
    /// Bytes per grid point the kernels read and write (copies included, transforms apart).
    pub kernel_bytes: f64,
}

impl PhaseWork {
    /// Bytes per grid point, the transforms' `passes` passes included.
    pub fn bytes(&self, passes: f64) -> f64 {
        self.kernel_bytes + self.transforms as f64 * 16.0 * passes
    }
}

/// The phases of a step with `iterations` fixed-point iterations
/// ([`super::GpuMeanField::step`]), in order; fields of 8 bytes per point.
pub fn work_model(iterations: usize) -> Vec<PhaseWork> {
    const F: f64 = 8.0;
    let phase = |phase, launches, transforms, downloads, fields: f64| PhaseWork {
        phase,
        launches,
        transforms,
        downloads,
        kernel_bytes: fields * F,
    };
    let k = iterations;
    vec![
        // Copies of u (3 spectra) and Q (6) read and written; 6 inverse transforms.
        phase("Q to the grid", 0, 6, 0, 2.0 * (3.0 + 6.0)),
        // closure_field: Q (6) in, the 21 fourth-moment components out (its tables are small
        // and cached); the eigenvalue and entropy partials downloaded.
        phase("closure field", 1, 0, 1, 6.0 + 21.0),
        // Per iteration: strain_spectra (u 3 -> 6), 6 inverse, contract (S 21, E 6, Q 6 ->
        // 6), 6 forward, scale_dealias (6 read and written), stokes (6 -> 3), change (u and
        // its new value: 3 + 3; its partials downloaded).
        phase(
            "Stokes fixed point",
            5 * k,
            12 * k,
            k,
            k as f64 * ((3.0 + 6.0) + (21.0 + 6.0 + 6.0 + 6.0) + 12.0 + (6.0 + 3.0) + 6.0),
        ),
        // u copied (3 spectra read and written), 3 inverse; derivative_spectra (3 -> 9), 9
        // inverse; strain_from_gradient (9 -> 6); contract for S:E (21, 6, 6 -> 6).
        phase(
            "u, grad u, E, S:E",
            3,
            12,
            0,
            6.0 + (3.0 + 9.0) + (9.0 + 6.0) + (21.0 + 6.0 + 6.0 + 6.0),
        ),
        // derivative_spectra (Q 6 -> 18), 18 inverse; explicit_terms (u 3, grad u 9, Q 6,
        // grad Q 18, S:E 6 -> 6), 6 forward, scale_dealias (6 read and written).
        phase(
            "explicit terms",
            3,
            24,
            0,
            (6.0 + 18.0) + (3.0 + 9.0 + 6.0 + 18.0 + 6.0 + 6.0) + 12.0,
        ),
        // nonfinite (6 spectra), report_partials (u 3, E 6, Q 6, S:E 6), norm_partials (u 3),
        // imex_update (Q, N, Q and N before: 24 -> 6), nonfinite of the update (6); each
        // reduction's partials downloaded.
        phase(
            "checks, reports, IMEX update",
            5,
            0,
            4,
            6.0 + 21.0 + 3.0 + (24.0 + 6.0) + 6.0,
        ),
    ]
}
