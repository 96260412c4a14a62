//! The kernels of `slender.cu`, each one's parameters declared once as a struct of named, typed
//! arguments (checked against the source when a device opens it).

use motile_gpu::Buffer;

motile_gpu::kernels! {
    /// `slender.cu` and its kernels.
    pub(crate) const KERNELS = include_str!("slender.cu");

    /// The rods' quadrature nodes.
    pub(crate) struct SlenderNodes = "slender_nodes" {
        x: &'a Buffer<f64>,
        p: &'a Buffer<f64>,
        s: &'a Buffer<f64>,
        nodes: &'a mut Buffer<f64>,
        n: i32,
        m: i32,
    }

    /// (P4)'s right-hand side: swimming, and the contact forces and torques with `has_ft`.
    pub(crate) struct SlenderRhs = "slender_rhs" {
        p: &'a Buffer<f64>,
        ft: &'a Buffer<f64>,
        s: &'a Buffer<f64>,
        rhs: &'a mut Buffer<f64>,
        n: i32,
        m: i32,
        c: f64,
        l: f64,
        has_ft: i32,
    }

    /// The RPY sum's forces (triples and field-major) from a density.
    pub(crate) struct SlenderWeighted = "slender_weighted" {
        f: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        force: &'a mut Buffer<f64>,
        fields: &'a mut Buffer<f64>,
        npts: i32,
        m: i32,
    }

    /// The operator of (P4) per rod, from the density and the flow it induces.
    pub(crate) struct SlenderP4 = "slender_p4" {
        f: &'a Buffer<f64>,
        u: &'a Buffer<f64>,
        p: &'a Buffer<f64>,
        s: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        n: i32,
        m: i32,
        e: f64,
        l: f64,
    }

    /// The rods' flow velocities and velocities (with `has_ft`, the contacts' local drag).
    pub(crate) struct SlenderVelocities = "slender_velocities" {
        p: &'a Buffer<f64>,
        u: &'a Buffer<f64>,
        s: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        ft: &'a Buffer<f64>,
        flow: &'a mut Buffer<f64>,
        vel: &'a mut Buffer<f64>,
        omega: &'a mut Buffer<f64>,
        n: i32,
        m: i32,
        l: f64,
        swim: f64,
        trans: f64,
        rot: f64,
        has_ft: i32,
    }

    /// The prediction: swimming plus the last flow velocities.
    pub(crate) struct SlenderPredict = "slender_predict" {
        p: &'a Buffer<f64>,
        flow: &'a Buffer<f64>,
        vel: &'a mut Buffer<f64>,
        omega: &'a mut Buffer<f64>,
        n: i32,
        swim: f64,
    }

    /// Per chunk, the dot product's partial sum in order.
    pub(crate) struct KrylovDotChunks = "krylov_dot_chunks" {
        a: &'a Buffer<f64>,
        b: &'a Buffer<f64>,
        partial: &'a mut Buffer<f64>,
        n: i32,
        chunk: i32,
    }

    /// The partials folded in order into one slot (a square root with `root`).
    pub(crate) struct KrylovFold = "krylov_fold" {
        partial: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        nchunks: i32,
        slot: i32,
        root: i32,
    }

    /// `w -= h[slot] v`.
    pub(crate) struct KrylovAxpy = "krylov_axpy" {
        w: &'a mut Buffer<f64>,
        v: &'a Buffer<f64>,
        h: &'a Buffer<f64>,
        slot: i32,
        n: i32,
    }

    /// `dst = src / d`.
    pub(crate) struct KrylovDiv = "krylov_div" {
        src: &'a Buffer<f64>,
        dst: &'a mut Buffer<f64>,
        d: f64,
        n: i32,
    }

    /// `w = b - w`.
    pub(crate) struct KrylovResidual = "krylov_residual" {
        b: &'a Buffer<f64>,
        w: &'a mut Buffer<f64>,
        n: i32,
    }

    /// `x += y_j v_j`.
    pub(crate) struct KrylovUpdate = "krylov_update" {
        x: &'a mut Buffer<f64>,
        v: &'a Buffer<f64>,
        y: &'a Buffer<f64>,
        j: i32,
        n: i32,
    }
}

#[cfg(test)]
mod tests {
    /// Every declaration matches its kernel's signature in the source.
    #[test]
    fn the_declarations_match_the_source() {
        assert_eq!(super::KERNELS.check(), Ok(()));
    }

    /// Every kernel compiles as CUDA device code (clang's CUDA front end, no GPU needed) and
    /// keeps no stack (`motile_gpu::frontend`), those named apart.
    #[test]
    fn the_kernels_compile_for_a_device_without_a_stack() {
        let said = motile_gpu::frontend::check_set_in_test(&super::KERNELS, &[]);
        eprintln!("{}", said.unwrap_or_else(|e| panic!("{e}")));
    }
}
