//! The kernels of `kernels.cu`, each one's parameters declared once as a struct of named, typed
//! arguments (checked against `kernels.cu` when a device opens them, and by a test here).

use motile_gpu::Buffer;

motile_gpu::kernels! {
    /// `kernels.cu` (with the resident sums' `resident.cu` and the prefix sum of `scan.cu`)
    /// and its kernels.
    pub(crate) const KERNELS = concat!(
        include_str!("kernels.cu"),
        include_str!("gather_tiles.cu"),
        include_str!("resident.cu"),
        include_str!("scan.cu")
    );

    /// Spread `nf` fields of `n` points onto `nf` grids of `m^3` (atomic adds, the points'
    /// order): the binned spreaders' slow twin.
    pub(crate) struct Spread = "spread" {
        pts: &'a Buffer<f64>,
        vals: &'a Buffer<f64>,
        grid: &'a mut Buffer<f64>,
        n: i32,
        nf: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        alpha: f64,
        norm: f64,
    }

    /// Each point's bin (of `b^3` grid points, `nb` per axis) and its rank in the bin; the
    /// bins' counts (zeroed by the caller).
    pub(crate) struct BinCount = "bin_count" {
        pts: &'a Buffer<f64>,
        bin: &'a mut Buffer<i32>,
        rank: &'a mut Buffer<i32>,
        count: &'a mut Buffer<i32>,
        n: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        b: i32,
        nb: i32,
    }

    /// The sums of each tile of `tile` counts (one thread per tile): a long prefix sum's
    /// first pass.
    pub(crate) struct ScanTiles = "scan_tiles" {
        count: &'a Buffer<i32>,
        sums: &'a mut Buffer<i32>,
        nbins: i32,
        tile: i32,
    }

    /// Each tile's starts from the tiles' scanned sums: a long prefix sum's last pass.
    pub(crate) struct ScanSpread = "scan_spread" {
        count: &'a Buffer<i32>,
        tile_start: &'a Buffer<i32>,
        start: &'a mut Buffer<i32>,
        nbins: i32,
        tile: i32,
    }

    /// The bins' starts: the exclusive prefix sum of their counts (one block).
    pub(crate) struct BinScan = "bin_scan" {
        count: &'a Buffer<i32>,
        start: &'a mut Buffer<i32>,
        nbins: i32,
    }

    /// The points in bin order.
    pub(crate) struct BinScatter = "bin_scatter" {
        bin: &'a Buffer<i32>,
        rank: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        perm: &'a mut Buffer<i32>,
        n: i32,
    }

    /// Each bin's points in ascending point order (after the scatter's atomics).
    pub(crate) struct BinOrder = "bin_order" {
        start: &'a Buffer<i32>,
        perm: &'a mut Buffer<i32>,
        nbins: i32,
    }

    /// Output-driven spreading: each bin's cells summed from the points that reach them.
    pub(crate) struct SpreadCells = "spread_cells" {
        pts: &'a Buffer<f64>,
        vals: &'a Buffer<f64>,
        perm: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        grid: &'a mut Buffer<f64>,
        n: i32,
        nf: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        alpha: f64,
        norm: f64,
        b: i32,
        nb: i32,
        reach: i32,
    }

    /// The global-memory spreader over the points in bin order.
    pub(crate) struct SpreadSorted = "spread_sorted" {
        pts: &'a Buffer<f64>,
        vals: &'a Buffer<f64>,
        perm: &'a Buffer<i32>,
        grid: &'a mut Buffer<f64>,
        n: i32,
        nf: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        alpha: f64,
        norm: f64,
    }

    /// The gather over the points in bin order.
    pub(crate) struct GatherSorted = "gather_sorted" {
        pts: &'a Buffer<f64>,
        grid: &'a Buffer<f64>,
        perm: &'a Buffer<i32>,
        out: &'a mut Buffer<f64>,
        n: i32,
        gradient: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        alpha: f64,
        norm: f64,
    }

    /// The gather over the bins of the output-driven sort, each field's tile in shared memory.
    pub(crate) struct GatherTiles = "gather_tiles" {
        pts: &'a Buffer<f64>,
        grid: &'a Buffer<f64>,
        perm: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        out: &'a mut Buffer<f64>,
        n: i32,
        gradient: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        alpha: f64,
        norm: f64,
        b: i32,
        nb: i32,
    }

    /// The RPY multiplication of three force spectra (sphere radius `a`), in place.
    pub(crate) struct RpyModes = "rpy_modes" {
        spectra: &'a mut Buffer<f64>,
        m: i32,
        l: f64,
        xi: f64,
        a: f64,
        eta: f64,
        h: f64,
    }

    /// The point-force velocities of the force density of five trace-free stresslet spectra.
    pub(crate) struct StressletModes = "stresslet_modes" {
        spectra: &'a mut Buffer<f64>,
        m: i32,
        l: f64,
        xi: f64,
        eta: f64,
        h: f64,
    }

    /// Gather three fields at `n` points, with the window's derivative if `gradient` is 1.
    pub(crate) struct Gather = "gather" {
        pts: &'a Buffer<f64>,
        grid: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        n: i32,
        gradient: i32,
        m: i32,
        p: i32,
        l: f64,
        h: f64,
        alpha: f64,
        norm: f64,
    }

    /// The real-space RPY sum at every point of a cell list.
    pub(crate) struct RpyReal = "rpy_real" {
        pos: &'a Buffer<f64>,
        force: &'a Buffer<f64>,
        group: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        table: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        npts: i32,
        ncell: i32,
        nt: i32,
        l: f64,
        cutoff: f64,
        inv_h: f64,
        c: f64,
        ca: f64,
        cb: f64,
        a: f64,
        r0sq: f64,
    }

    /// The real-space stresslet sum at every point of a cell list.
    pub(crate) struct StressletReal = "stresslet_real" {
        pos: &'a Buffer<f64>,
        orient: &'a Buffer<f64>,
        sigma: &'a Buffer<f64>,
        group: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        table: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        npts: i32,
        ncell: i32,
        nt: i32,
        l: f64,
        cutoff: f64,
        inv_h: f64,
        xi: f64,
        r_direct: f64,
        r0sq: f64,
    }

    /// Each point's wrapped position, cell (`nc` per axis) and rank in it; the cells' counts
    /// (zeroed by the caller).
    pub(crate) struct PointCell = "point_cell" {
        y: &'a Buffer<f64>,
        wrapped: &'a mut Buffer<f64>,
        cell: &'a mut Buffer<i32>,
        rank: &'a mut Buffer<i32>,
        count: &'a mut Buffer<i32>,
        n: i32,
        nc: i32,
        l: f64,
    }

    /// Rows of `width` values moved by a permutation: gathered (`rows_out[k] =
    /// rows_in[idx[k]]`) or, with `scatter` 1, scattered (`rows_out[idx[k]] = rows_in[k]`).
    pub(crate) struct PermuteRows = "permute_rows" {
        rows_in: &'a Buffer<f64>,
        idx: &'a Buffer<i32>,
        rows_out: &'a mut Buffer<f64>,
        n: i32,
        width: i32,
        scatter: i32,
    }

    /// Each cell member's group.
    pub(crate) struct MemberGroup = "member_group" {
        members: &'a Buffer<i32>,
        group: &'a mut Buffer<i32>,
        n: i32,
        size: i32,
    }

    /// The rods' axes from their quaternions.
    pub(crate) struct RodAxes = "rod_axes" {
        q: &'a Buffer<f64>,
        p: &'a mut Buffer<f64>,
        n: i32,
    }

    /// The five trace-free stresslet components (field-major).
    pub(crate) struct StressletValues = "stresslet_values" {
        p: &'a Buffer<f64>,
        sigma: f64,
        vals: &'a mut Buffer<f64>,
        n: i32,
    }

    /// The stresslet real-space sum of one strength written at each point's own place
    /// (`members`).
    pub(crate) struct StressletRealPoints = "stresslet_real_points" {
        pos: &'a Buffer<f64>,
        orient: &'a Buffer<f64>,
        sigma: f64,
        group: &'a Buffer<i32>,
        start: &'a Buffer<i32>,
        table: &'a Buffer<f64>,
        members: &'a Buffer<i32>,
        u: &'a mut Buffer<f64>,
        grad: &'a mut Buffer<f64>,
        weighted: &'a mut Buffer<f64>,
        npts: i32,
        ncell: i32,
        nt: i32,
        l: f64,
        cutoff: f64,
        inv_h: f64,
        xi: f64,
        r_direct: f64,
        r0sq: f64,
    }

    /// The stresslet sum's velocity, gradient (in place on the real part's) and error-model
    /// inputs per point.
    pub(crate) struct StressletAssemble = "stresslet_assemble" {
        weighted: &'a Buffer<f64>,
        back: &'a Buffer<f64>,
        p: &'a Buffer<f64>,
        u: &'a mut Buffer<f64>,
        grad: &'a mut Buffer<f64>,
        parts: &'a mut Buffer<f64>,
        n: i32,
        sigma: f64,
        own_c: f64,
        mu: f64,
    }

    /// The error model's reductions in fixed chunks.
    pub(crate) struct EstimateChunks = "estimate_chunks" {
        parts: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        out: &'a mut Buffer<f64>,
        n: i32,
        nout: i32,
        chunk: i32,
    }

    /// The dipole level's free velocities (swimming and Jeffery's rotation).
    pub(crate) struct JefferyVelocities = "jeffery_velocities" {
        p: &'a Buffer<f64>,
        u: &'a Buffer<f64>,
        grad: &'a Buffer<f64>,
        v: &'a mut Buffer<f64>,
        w: &'a mut Buffer<f64>,
        n: i32,
        swim: f64,
    }

    /// The explicit level's nodes and their weighted forces (triples and field-major).
    pub(crate) struct NodeValues = "node_values" {
        x: &'a Buffer<f64>,
        p: &'a Buffer<f64>,
        s: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        nodes: &'a mut Buffer<f64>,
        force: &'a mut Buffer<f64>,
        fields: &'a mut Buffer<f64>,
        n: i32,
        m: i32,
        c: f64,
    }

    /// The RPY sum's velocities and error-model inputs per point.
    pub(crate) struct RpyAssemble = "rpy_assemble" {
        real: &'a Buffer<f64>,
        back: &'a Buffer<f64>,
        pts: &'a Buffer<f64>,
        force: &'a Buffer<f64>,
        u: &'a mut Buffer<f64>,
        parts: &'a mut Buffer<f64>,
        n: i32,
        g: i32,
        l: f64,
        xi: f64,
        a: f64,
        r0sq: f64,
        mu: f64,
    }

    /// The rods' velocities from the flow at their nodes.
    pub(crate) struct RodFlowVelocities = "rod_flow_velocities" {
        p: &'a Buffer<f64>,
        u: &'a Buffer<f64>,
        s: &'a Buffer<f64>,
        w: &'a Buffer<f64>,
        v: &'a mut Buffer<f64>,
        omega: &'a mut Buffer<f64>,
        n: i32,
        m: i32,
        swim: f64,
        rod: f64,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn declarations_match_the_source() {
        assert_eq!(super::KERNELS.check(), Ok(()));
    }

    /// Every kernel compiles as CUDA device code (clang's CUDA front end, no GPU needed) and
    /// keeps no stack (`motile_gpu::frontend`), those named apart.
    ///
    /// The spreaders that keep a point's window weights in an array of the support's length
    /// (known at run time) have a stack: the atomic one (the slow twin) and the sorted one (a
    /// run takes it only when its config asks); the default, `spread_cells`, has none.
    #[test]
    fn the_kernels_compile_for_a_device_without_a_stack() {
        let said =
            motile_gpu::frontend::check_set_in_test(&super::KERNELS, &["spread", "spread_sorted"]);
        eprintln!("{}", said.unwrap_or_else(|e| panic!("{e}")));
    }
}
