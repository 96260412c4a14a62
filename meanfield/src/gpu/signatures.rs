//! The kernels of `kernels.cu`, each one's parameters declared once as a struct of named, typed
//! arguments (checked against `kernels.cu` when a device opens them, and by a test here).
//! Spectra are `double2` arrays (interleaved `f64` pairs); `N` is the grid's point count.
#![allow(non_snake_case)]

use motile_gpu::Buffer;

motile_gpu::kernels! {
    /// `kernels.cu` and its kernels.
    pub(super) const KERNELS = include_str!("kernels.cu");

    /// Scale `count` spectrum values and zero the modes the 2/3 rule drops; block counts of
    /// non-finite results.
    pub(super) struct ScaleDealias = "scale_dealias" {
        c: &'a mut Buffer<f64>,
        count: i64,
        n: i32,
        scale: f64,
        keep: &'a Buffer<i32>,
        dealias: i32,
        partial: &'a mut Buffer<f64>,
    }

    /// The spectra of E from those of u.
    pub(super) struct StrainSpectra = "strain_spectra" {
        u: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        n: i32,
        k1: &'a Buffer<f64>,
    }

    /// The spectra of the first derivatives of `comps` fields.
    pub(super) struct DerivativeSpectra = "derivative_spectra" {
        c: &'a Buffer<f64>,
        first: i32,
        out: &'a mut Buffer<f64>,
        comps: i32,
        n: i32,
        k1: &'a Buffer<f64>,
    }

    /// The Stokes solve: u from the stress spectra, scaled and dealiased as they are read.
    pub(super) struct Stokes = "stokes" {
        sigma: &'a Buffer<f64>,
        u: &'a mut Buffer<f64>,
        n: i32,
        k1: &'a Buffer<f64>,
        k2: &'a Buffer<f64>,
        scale: f64,
        keep: &'a Buffer<i32>,
    }

    /// The fixed point's first iterate: u_hat plus the Stokes flow of -(Q - Q_prev).
    pub(super) struct WarmStart = "warm_start" {
        q: &'a Buffer<f64>,
        q_prev: &'a Buffer<f64>,
        u_hat: &'a Buffer<f64>,
        u: &'a mut Buffer<f64>,
        n: i32,
        k1: &'a Buffer<f64>,
        k2: &'a Buffer<f64>,
        keep: &'a Buffer<i32>,
    }

    /// The IMEX update of Q; block counts of non-finite results.
    pub(super) struct ImexUpdate = "imex_update" {
        q: &'a Buffer<f64>,
        nl: &'a Buffer<f64>,
        q_prev: &'a Buffer<f64>,
        nl_prev: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        n: i32,
        k2: &'a Buffer<f64>,
        a0: f64,
        a1: f64,
        a2: f64,
        b0: f64,
        b1: f64,
        dt: f64,
        diffusion: f64,
        two: i32,
        partial: &'a mut Buffer<f64>,
    }

    /// Block partials of the fixed point's change `|a - b|^2` and norm `|a|^2`.
    pub(super) struct ChangePartials = "change_partials" {
        a: &'a Buffer<f64>,
        b: &'a Buffer<f64>,
        n: i32,
        partial: &'a mut Buffer<f64>,
    }

    /// Block partials of `|u|^2` over the spectrum.
    pub(super) struct NormPartials = "norm_partials" {
        u: &'a Buffer<f64>,
        n: i32,
        partial: &'a mut Buffer<f64>,
    }

    /// Block partials of the report's grid sums.
    pub(super) struct ReportPartials = "report_partials" {
        ug: &'a Buffer<f64>,
        ug_at: i64,
        g: &'a Buffer<f64>,
        q: &'a Buffer<f64>,
        se: &'a Buffer<f64>,
        N: i64,
        partial: &'a mut Buffer<f64>,
    }

    /// The stress `-Q + zeta S:E` per grid point, over E in place.
    pub(super) struct Contract = "contract" {
        s21: &'a Buffer<f64>,
        e: &'a mut Buffer<f64>,
        q: &'a Buffer<f64>,
        zeta: f64,
        N: i64,
    }

    /// `S:E` per grid point, E from the velocity gradient.
    pub(super) struct ContractGradient = "contract_gradient" {
        s21: &'a Buffer<f64>,
        g: &'a Buffer<f64>,
        se: &'a mut Buffer<f64>,
        N: i64,
    }

    /// The explicit terms of the Q equation per grid point, over `S:E` in place.
    pub(super) struct ExplicitTerms = "explicit_terms" {
        ug: &'a Buffer<f64>,
        ug_at: i64,
        g: &'a Buffer<f64>,
        q: &'a Buffer<f64>,
        dq: &'a Buffer<f64>,
        se: &'a mut Buffer<f64>,
        N: i64,
    }

    /// The closure per grid point (eigenframes and table moments), with block partials of the
    /// eigenvalue bounds and the entropy.
    pub(super) struct ClosureField = "closure_field" {
        q: &'a Buffer<f64>,
        s21: &'a mut Buffer<f64>,
        coef: &'a Buffer<f64>,
        deg: i32,
        with_entropy: i32,
        N: i64,
        partial: &'a mut Buffer<f64>,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn declarations_match_the_source() {
        super::KERNELS.check().unwrap();
    }

    /// Every kernel compiles as CUDA device code (clang's CUDA front end, no GPU needed) and
    /// keeps no stack (`motile_gpu::frontend`), those named apart.
    ///
    /// `closure_field` keeps a small stack (40 bytes per thread by the H100's ptxas, more by
    /// clang's): the mean-field step's memory on a GPU (9.89 GB at 256^3, BENCHMARKS.md) is
    /// with it.
    #[test]
    fn the_kernels_compile_for_a_device_without_a_stack() {
        let said = motile_gpu::frontend::check_set_in_test(&super::KERNELS, &["closure_field"]);
        eprintln!("{}", said.unwrap_or_else(|e| panic!("{e}")));
    }
}
