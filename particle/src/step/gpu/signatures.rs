//! The kernels of `cells.cu`, `update.cu` and `contacts.cu` (with `scan.cu`'s prefix sum), each one's
//! parameters declared once as a struct of named, typed arguments (checked against the source
//! when a device opens it).

use motile_gpu::Buffer;

motile_gpu::kernels! {
    /// `cells.cu`, `update.cu`, `contacts.cu` and the prefix sum, and their kernels.
    pub(crate) const KERNELS = concat!(
        include_str!("cells.cu"),
        include_str!("update.cu"),
        include_str!("contacts.cu"),
        include_str!("step.cu"),
        include_str!("../../ewald/gpu/scan.cu")
    );

    /// Each centre's cell and the cells' counts (zeroed by the caller).
    pub(crate) struct CellCount = "cell_count" {
        x: &'a Buffer<f64>,
        cell: &'a mut Buffer<i32>,
        count: &'a mut Buffer<i32>,
        n: i32,
        nc: i32,
        l: f64,
    }

    /// The sums of each tile of `tile` counts (one thread per tile): a long prefix sum's
    /// first pass.
    #[allow(dead_code)] // launched by the sums' declaration of the same kernel
    pub(crate) struct ScanTiles = "scan_tiles" {
        count: &'a Buffer<i32>,
        sums: &'a mut Buffer<i32>,
        nbins: i32,
        tile: i32,
    }

    /// Each tile's starts from the tiles' scanned sums: a long prefix sum's last pass.
    #[allow(dead_code)] // launched by the sums' declaration of the same kernel
    pub(crate) struct ScanSpread = "scan_spread" {
        count: &'a Buffer<i32>,
        tile_start: &'a Buffer<i32>,
        start: &'a mut Buffer<i32>,
        nbins: i32,
        tile: i32,
    }

    /// The exclusive prefix sum of `nbins` counts (one block); with the two below, declared so
    /// that this set loads them: [`crate::ewald::gpu`]'s `prefix_sum` launches them (scan.cu is
    /// in both sets).
    #[allow(dead_code)] // launched by the sums' declaration of the same kernel
    pub(crate) struct CellScan = "bin_scan" {
        count: &'a Buffer<i32>,
        start: &'a mut Buffer<i32>,
        nbins: i32,
    }

    /// The centres scattered into cell order (`fill` zeroed by the caller).
    pub(crate) struct CellScatter = "cell_scatter" {
        cell: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        fill: &'a mut Buffer<i32>,
        members: &'a mut Buffer<i32>,
        n: i32,
    }

    /// Each cell's members in increasing index.
    pub(crate) struct CellOrder = "cell_order" {
        start: &'a Buffer<i32>,
        members: &'a mut Buffer<i32>,
        ncells: i32,
    }

    /// Each centre's number of neighbours `j > i` within `sqrt(c2)`.
    pub(crate) struct PairCount = "pair_count" {
        x: &'a Buffer<f64>,
        cell: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        members: &'a Buffer<i32>,
        counts: &'a mut Buffer<i32>,
        n: i32,
        nc: i32,
        l: f64,
        c2: f64,
    }

    /// The pairs, sorted by `(i, j)`.
    pub(crate) struct PairWrite = "pair_write" {
        x: &'a Buffer<f64>,
        cell: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        members: &'a Buffer<i32>,
        offset: &'a Buffer<i32>,
        first: &'a mut Buffer<i32>,
        second: &'a mut Buffer<i32>,
        n: i32,
        nc: i32,
        l: f64,
        c2: f64,
    }

    /// The rods moved by `dt` (centres wrapped, images counted, quaternions turned).
    pub(crate) struct RodUpdate = "rod_update" {
        x: &'a mut Buffer<f64>,
        image: &'a mut Buffer<i32>,
        q: &'a mut Buffer<f64>,
        v: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        n: i32,
        dt: f64,
        l: f64,
    }

    /// Whether each pair gets a constraint.
    pub(crate) struct ContactFlag = "contact_flag" {
        x: &'a Buffer<f64>,
        q: &'a Buffer<f64>,
        first: &'a Buffer<i32>,
        second: &'a Buffer<i32>,
        flag: &'a mut Buffer<i32>,
        npairs: i32,
        l: f64,
        b: f64,
        margin: f64,
    }

    /// The constraints at the flags' prefix sums.
    pub(crate) struct ContactWrite = "contact_write" {
        x: &'a Buffer<f64>,
        q: &'a Buffer<f64>,
        first: &'a Buffer<i32>,
        second: &'a Buffer<i32>,
        flag: &'a Buffer<i32>,
        at: &'a Buffer<i32>,
        ci: &'a mut Buffer<i32>,
        cj: &'a mut Buffer<i32>,
        rows: &'a mut Buffer<f64>,
        npairs: i32,
        l: f64,
        b: f64,
        margin: f64,
    }

    /// Each rod's number of constraints (zeroed by the caller).
    pub(crate) struct SolverIndexCount = "solver_index_count" {
        ci: &'a Buffer<i32>,
        cj: &'a Buffer<i32>,
        counts: &'a mut Buffer<i32>,
        m: i32,
    }

    /// Each rod's constraint entries (`2 a + side`) at its start (`fill` zeroed).
    pub(crate) struct SolverIndexScatter = "solver_index_scatter" {
        ci: &'a Buffer<i32>,
        cj: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        fill: &'a mut Buffer<i32>,
        entries: &'a mut Buffer<i32>,
        m: i32,
    }

    /// Each rod's entries in constraint order.
    pub(crate) struct SolverIndexOrder = "solver_index_order" {
        start: &'a Buffer<i32>,
        entries: &'a mut Buffer<i32>,
        n: i32,
    }

    /// The rods' axes.
    pub(crate) struct SolverAxes = "solver_axes" {
        q: &'a Buffer<f64>,
        p: &'a mut Buffer<f64>,
        n: i32,
    }

    /// Each rod's velocity under the contact forces through the local drag.
    pub(crate) struct SolverRods = "solver_rods" {
        p: &'a Buffer<f64>,
        start: &'a Buffer<i32>,
        entries: &'a Buffer<i32>,
        rows: &'a Buffer<f64>,
        lam: &'a Buffer<f64>,
        vel: &'a mut Buffer<f64>,
        ft: &'a mut Buffer<f64>,
        n: i32,
        trans: f64,
        rot: f64,
    }

    /// Each constraint's separation rate times `dt`, plus the shift.
    pub(crate) struct SolverConstraints = "solver_constraints" {
        rows: &'a Buffer<f64>,
        ci: &'a Buffer<i32>,
        cj: &'a Buffer<i32>,
        vel: &'a Buffer<f64>,
        shift: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        m: i32,
        dt: f64,
        has_shift: i32,
    }

    /// The problem's `q = phi + dt D^T V_free`.
    pub(crate) struct SolverQ = "solver_q" {
        rows: &'a Buffer<f64>,
        ci: &'a Buffer<i32>,
        cj: &'a Buffer<i32>,
        v: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        q: &'a mut Buffer<f64>,
        m: i32,
        dt: f64,
    }

    /// The projected step `max(lam - alpha g, 0)`.
    pub(crate) struct SolverProject = "solver_project" {
        lam: &'a Buffer<f64>,
        g: &'a Buffer<f64>,
        lam_new: &'a mut Buffer<f64>,
        m: i32,
        alpha: f64,
    }

    /// The first step's projected gradient.
    pub(crate) struct SolverGp = "solver_gp" {
        lam: &'a Buffer<f64>,
        g: &'a Buffer<f64>,
        gp: &'a mut Buffer<f64>,
        m: i32,
    }

    /// The residual and Barzilai-Borwein products per chunk.
    pub(crate) struct SolverStats = "solver_stats" {
        lam: &'a Buffer<f64>,
        lam_new: &'a Buffer<f64>,
        g: &'a Buffer<f64>,
        g_new: &'a Buffer<f64>,
        partial: &'a mut Buffer<f64>,
        m: i32,
        chunk: i32,
    }

    /// APGD's residual and restart test per chunk.
    pub(crate) struct SolverApgdStats = "solver_apgd_stats" {
        x: &'a Buffer<f64>,
        x_new: &'a Buffer<f64>,
        y: &'a Buffer<f64>,
        g_new: &'a Buffer<f64>,
        partial: &'a mut Buffer<f64>,
        m: i32,
        chunk: i32,
    }

    /// APGD's extrapolated point and its gradient.
    pub(crate) struct SolverExtrapolate = "solver_extrapolate" {
        x_new: &'a Buffer<f64>,
        x: &'a Buffer<f64>,
        g_new: &'a Buffer<f64>,
        g: &'a Buffer<f64>,
        y: &'a mut Buffer<f64>,
        gy: &'a mut Buffer<f64>,
        m: i32,
        beta: f64,
    }

    /// `out = a / d`.
    pub(crate) struct SolverScale = "solver_scale" {
        a: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        m: i32,
        d: f64,
    }

    /// `a.a` and `a.b` per chunk.
    pub(crate) struct SolverDots = "solver_dots" {
        a: &'a Buffer<f64>,
        b: &'a Buffer<f64>,
        partial: &'a mut Buffer<f64>,
        m: i32,
        chunk: i32,
    }

    /// The swimming velocities `u p` and no rotation.
    pub(crate) struct SwimVelocities = "swim_velocities" {
        q: &'a Buffer<f64>,
        v: &'a mut Buffer<f64>,
        w: &'a mut Buffer<f64>,
        n: i32,
        u: f64,
    }

    /// The contact velocities added to the rods' velocities.
    pub(crate) struct AddVelocities = "add_velocities" {
        vel: &'a Buffer<f64>,
        v: &'a mut Buffer<f64>,
        w: &'a mut Buffer<f64>,
        n: i32,
    }

    /// `dst += src` (a correction's contact forces onto the step's).
    pub(crate) struct AddRows = "add_rows" {
        src: &'a Buffer<f64>,
        dst: &'a mut Buffer<f64>,
        len: i32,
    }

    /// Each constraint's starting multiplier from the last step's.
    pub(crate) struct WarmGather = "warm_gather" {
        ci: &'a Buffer<i32>,
        cj: &'a Buffer<i32>,
        oi: &'a Buffer<i32>,
        oj: &'a Buffer<i32>,
        olam: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        m: i32,
        mo: i32,
    }

    /// The overlap projection's move: translation, velocities and contact forces.
    pub(crate) struct ProjectionMove = "projection_move" {
        x: &'a mut Buffer<f64>,
        image: &'a mut Buffer<i32>,
        vel: &'a Buffer<f64>,
        pft: &'a Buffer<f64>,
        v: &'a mut Buffer<f64>,
        ft: &'a mut Buffer<f64>,
        n: i32,
        dt: f64,
        l: f64,
    }

    /// Each constrained pair's true overlap.
    pub(crate) struct PairOverlap = "pair_overlap" {
        x: &'a Buffer<f64>,
        q: &'a Buffer<f64>,
        ci: &'a Buffer<i32>,
        cj: &'a Buffer<i32>,
        out: &'a mut Buffer<f64>,
        m: i32,
        l: f64,
        b: f64,
    }

    /// The step report's partial sums and maxima per chunk of rods.
    pub(crate) struct StepStats = "step_stats" {
        v: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        q: &'a Buffer<f64>,
        ft: &'a Buffer<f64>,
        partial: &'a mut Buffer<f64>,
        n: i32,
        chunk: i32,
        has_ft: i32,
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
    #[test]
    fn the_kernels_compile_for_a_device_without_a_stack() {
        let said = motile_gpu::frontend::check_set_in_test(&super::KERNELS, &[]);
        eprintln!("{}", said.unwrap_or_else(|e| panic!("{e}")));
    }
}
