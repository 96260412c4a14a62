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
/// ([`super::GpuMeanField::step`]), in order; fields of 8 bytes per point. `with_history`:
/// the step has a previous state (every step but a run's first), so the fixed point starts
/// from the warm start's kernel rather than a copy of the last velocity.
pub fn work_model(iterations: usize, with_history: bool) -> Vec<PhaseWork> {
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
        // The fixed point's first iterate: with a history warm_start (Q, Q before and u: 15
        // spectra -> 3), else a copy of u (3 read and written); a copy of Q (6 read and
        // written); 6 inverse transforms.
        if with_history {
            phase("Q to the grid", 1, 6, 0, (15.0 + 3.0) + 2.0 * 6.0)
        } else {
            phase("Q to the grid", 0, 6, 0, 2.0 * (3.0 + 6.0))
        },
        // closure_field: Q (6) in, the 21 fourth-moment components out (its tables are small
        // and cached); its partials read at the end of the step.
        phase("closure field", 1, 0, 0, 6.0 + 21.0),
        // Per iteration (E and the deviatoric stress are trace-free: five components each):
        // strain_spectra (u 3 -> 5), 5 inverse, contract (S 21, E 5, Q 6 -> 5), 5 forward,
        // stokes (5 -> 3, scaling and dealiasing as it reads), change (u and its new value:
        // 3 + 3; its partials downloaded).
        phase(
            "Stokes fixed point",
            4 * k,
            10 * k,
            k,
            k as f64 * ((3.0 + 5.0) + (21.0 + 5.0 + 6.0 + 5.0) + (5.0 + 3.0) + 6.0),
        ),
        // Per u component derivative_spectra (1 -> 3), 3 inverse (2 for u_z: d_z u_z =
        // -(d_x u_x + d_y u_y)); contract_gradient for S:E with E from grad u (21, 8 -> 6); u
        // copied (3 spectra read and written), 3 inverse.
        phase(
            "u, grad u, S:E",
            4,
            11,
            0,
            3.0 * (1.0 + 3.0) + (21.0 + 8.0 + 6.0) + 6.0,
        ),
        // report_partials (u 3, grad u 8, Q 6, S:E 6); its partials read at the end.
        phase("report sums", 1, 0, 0, 23.0),
        // Per Q component derivative_spectra (1 -> 3), 3 inverse (18 in all); explicit_terms
        // (u 3, grad u 8, Q 6, grad Q 18, S:E 6 -> 6 over S:E), 6 forward, scale_dealias (6
        // read and written, its non-finite count per block beside).
        phase(
            "explicit terms",
            8,
            24,
            0,
            6.0 * (1.0 + 3.0) + (3.0 + 8.0 + 6.0 + 18.0 + 6.0 + 6.0) + 12.0,
        ),
        // norm_partials (u 3), imex_update (Q, N, Q and N before: 24 -> 6, its non-finite
        // count per block beside); the partials of the step's reductions (the closure's, the
        // report's, the non-finite counts, |u|^2) read in five downloads back to back at the
        // end (only the first waits for the device); at the commit N copied into N before (6
        // spectra read and written).
        phase(
            "checks, IMEX update, commit",
            2,
            0,
            5,
            3.0 + (24.0 + 6.0) + 12.0,
        ),
    ]
}

/// Blocks of [`motile_gpu::THREADS`] threads over `elements`, at least one (launch.rs).
fn blocks(elements: usize) -> usize {
    elements.div_ceil(motile_gpu::THREADS as usize).max(1)
}

/// The sizes, in values, of the device buffers of a step on an `n^3` grid
/// ([`super::GpuMeanField`]); `S = n n (n/2 + 1)` complex values per half spectrum (2 S
/// doubles), `N = n^3` doubles per grid field. One source for the allocation and for
/// [`device_bytes`].
#[derive(Clone, Copy, Debug)]
pub(super) struct Layout {
    /// Complex values of one half spectrum.
    pub(super) s: usize,
    /// Points of the grid.
    pub(super) n3: usize,
}

impl Layout {
    pub(super) fn of(n: usize) -> Self {
        Self {
            s: n * n * (n / 2 + 1),
            n3: n * n * n,
        }
    }

    /// Doubles of `count` half spectra.
    pub(super) fn spectra(&self, count: usize) -> usize {
        2 * count * self.s
    }

    /// Doubles of `count` grid fields.
    pub(super) fn fields(&self, count: usize) -> usize {
        count * self.n3
    }

    /// The scratch that holds nine grid fields (the velocity gradient) or six half spectra (the
    /// stresses, the explicit terms).
    pub(super) fn wide(&self) -> usize {
        self.fields(9).max(self.spectra(6))
    }

    /// The fixed point's change partials: two per block over a spectrum.
    pub(super) fn partials(&self) -> usize {
        2 * blocks(self.s)
    }

    /// The step's other reductions' partials, one buffer each: the closure's (3 per block over
    /// the grid), the report's (4 per block over the grid), the explicit terms' non-finite
    /// counts (one per block over 6 spectra), `|u|^2` and the update's non-finite counts (one
    /// per block over a spectrum).
    pub(super) fn step_partials(&self) -> [usize; 5] {
        [
            3 * blocks(self.n3),
            4 * blocks(self.n3),
            blocks(6 * self.s),
            blocks(self.s),
            blocks(self.s),
        ]
    }

    /// Every buffer's `(f64 values, i32 values)` apart from the closure's coefficients:
    /// Q, Q before, N before, the six-spectra scratch (6 half spectra each); u, its iterate,
    /// the next iterate (3 each); Q on the grid (6 fields), the fourth moments (21 fields), the
    /// wide scratch; the wavenumbers and partials (`f64`); the dealiasing mask (`i32`).
    pub(super) fn values(&self, n: usize) -> (usize, usize) {
        let f64s = 4 * self.spectra(6)
            + 3 * self.spectra(3)
            + self.fields(6)
            + self.fields(21)
            + self.wide()
            + 2 * n
            + self.partials()
            + self.step_partials().iter().sum::<usize>();
        (f64s, n)
    }
}

/// Device bytes that the step's buffers take on an `n^3` grid with a closure table of degree
/// `closure_degree` (as [`super::GpuMeanField::open`] allocates them; the cuFFT plan's work
/// area and the CUDA context apart): 33 half spectra (Q, Q and N before, six of scratch: 6
/// each; u and its two iterates: 3 each), 27 grid fields (Q, the fourth moments) and a scratch
/// of nine grid fields (or six half spectra where that is larger). 9.30 GB at 256^3.
pub fn device_bytes(n: usize, closure_degree: usize) -> usize {
    let (f64s, i32s) = Layout::of(n).values(n);
    let coef = 4 * (closure_degree + 1) * (closure_degree + 1);
    8 * (f64s + coef) + 4 * i32s
}
