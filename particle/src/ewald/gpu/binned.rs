//! Binned spreading and gathering, as cuFINUFFT's: the points sorted into bins of grid cells on
//! the device (a counting sort: each point's bin and rank by an integer atomic, the bins'
//! starts by a prefix sum, the points scattered into bin order), then
//! - [`SpreadMethod::Sorted`]: the per-point global-memory spreader run in bin order, so that
//!   a warp's threads add to neighbouring cells;
//! - [`SpreadMethod::Cells`] (the default at every support): output-driven, no atomics. One
//!   block per bin of [`CELL_BIN`]^3 grid points sums, for each of its cells, every point whose
//!   window covers it, from the bins below it that its points' windows can reach (bins are by
//!   the window's first index), taken as one list and staged chunk by chunk in shared memory
//!   (two barriers per chunk of 64 points), each bin's points in
//!   ascending order (`bin_order` after the scatter). Each grid value is written once, in the
//!   same order in every run: the spread repeats bit for bit on a GPU. At the particle sums'
//!   densities (0.03-0.1 points per grid point) a shared-memory tile per bin (cuFINUFFT's
//!   "SM" method) holds 4-5 points, fewer than it costs to zero and flush, and the global
//!   atomics of the per-point spreaders run at 1.3-2.7e10 per second on an H100
//!   (BENCHMARKS.md);
//!
//! and the gather runs over the points in bin order for either: over the output-driven sort's
//! bins, where a bin's tile of the grid (`(b + p - 1)^3` cells per field) fits
//! [`GATHER_TILE`] values of shared memory (supports up to 7-9: the explicit level's 6), a
//! block per bin reads each field's tile once, coalesced, and gathers the bin's points from it
//! (the grid read about once per bin instead of `p^3` values per point: [`super::work_model`]
//! counts 2.6x fewer requested bytes in the explicit level's Fourier part), the same bits as
//! the thread per point that gathers otherwise. The points of one generation (one GMRES solve)
//! are sorted once. [`SpreadMethod::Atomic`], the per-point spreader in the
//! points' own order, stays as the slow twin for the tests.
//!
//! Launching is unsafe: each launch says why every index it touches lies inside its buffers.
#![allow(unsafe_code)]

use crate::ewald::gpu::launch::{Fields, Points};
use crate::ewald::gpu::launch::{Geometry, padded_field};
use crate::ewald::gpu::signatures::{
    BinCount, BinOrder, BinScatter, GatherSorted, GatherTiles, SpreadCells, SpreadSorted,
};
use motile_gpu::{Buffer, Device, GpuError, THREADS};

/// Bin edge of the sorted global-memory spreader (for locality only).
const SORTED_BIN: usize = 8;

/// Smallest bin edge of the output-driven spreader (a block of [`THREADS`] threads, two of the
/// bin's 512 cells each); see [`cell_bin`].
pub const CELL_BIN: usize = 8;

/// Largest bin edge of the output-driven spreader (1 000 cells: four per thread).
pub const CELL_BIN_MAX: usize = 10;

/// The output-driven spreader's bin edge for support `p` on a grid of `m`: the smallest edge
/// from [`CELL_BIN`] to [`CELL_BIN_MAX`] that divides the grid (no short last bin) and is at
/// least `p - 1` (a window then reaches one bin below its first index along each axis: 8 near
/// bins instead of 27), else [`CELL_BIN`]. The dipole level's stresslets (support 10) on 270^3
/// take 9, on 480^3 10; supports of 9 or less on grids divisible by 8 keep 8.
pub fn cell_bin(p: usize, m: usize) -> usize {
    (CELL_BIN..=CELL_BIN_MAX)
        .find(|&b| b + 1 >= p && m.is_multiple_of(b))
        .unwrap_or(CELL_BIN)
}

/// How the Fourier part spreads its values onto the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpreadMethod {
    /// One thread per point in the points' own order, global atomic adds: the slow twin.
    Atomic,
    /// Points sorted into bins, the global-memory spreader in bin order.
    Sorted,
    /// Points sorted into bins, each bin's cells summed from the points that reach them.
    Cells,
}

impl SpreadMethod {
    /// The method for support `p`: the output-driven [`SpreadMethod::Cells`] at every support
    /// (its shared memory holds a chunk of points, not a tile of the grid, so it has no
    /// support limit; the sorted global-memory spreader stays selectable).
    pub fn for_support(_p: usize) -> Self {
        Self::Cells
    }

    /// Bin edge (grid cells) for support `p` on a grid of `m`.
    pub(super) fn bin_edge(self, p: usize, m: usize) -> usize {
        match self {
            Self::Cells => cell_bin(p, m),
            _ => SORTED_BIN,
        }
    }

    /// The bins below a bin, per axis, whose points' windows can reach it (support `p`, `nb`
    /// bins of `b` on a grid of `m`): `ceil((p - 1) / b)`, one more where the last bin is
    /// shorter than `b`, and at most `nb - 1` so that no bin is visited twice.
    pub(super) fn reach(p: usize, m: usize, b: usize, nb: usize) -> usize {
        ((p - 1).div_ceil(b) + usize::from(!m.is_multiple_of(b))).min(nb - 1)
    }
}

/// Points of one generation sorted into bins.
#[derive(Debug)]
pub(crate) struct Bins {
    /// The method the bins are for (not [`SpreadMethod::Atomic`]).
    pub(crate) method: SpreadMethod,
    /// `(m, p, bin edge)` the sort was made for.
    pub(crate) key: (usize, usize, usize),
    /// Bins per axis.
    nb: usize,
    /// How many points were sorted.
    pub(crate) n: usize,
    /// Points in bin order.
    perm: Buffer<i32>,
    /// Start of each bin in `perm` (`nb^3 + 1` values).
    start: Buffer<i32>,
}

use motile_gpu::{check_len as check, kernel_int as int};

/// Sort the `n` points `pts` into bins for `method` (not [`SpreadMethod::Atomic`]).
pub(crate) fn sort(
    dev: &Device,
    geo: &Geometry,
    method: SpreadMethod,
    pts: &Buffer,
    n: usize,
) -> Result<Bins, GpuError> {
    let p = geo.window.p;
    assert!(
        method != SpreadMethod::Atomic,
        "the atomic spreader has no bins"
    );
    assert!(
        p <= 24 && p <= geo.m,
        "a support of at most 24 and the grid"
    );
    assert_eq!(
        THREADS, 256,
        "bin_scan's shared array holds 256 partial sums"
    );
    let b = method.bin_edge(p, geo.m);
    let nb = geo.m.div_ceil(b);
    let nbins = nb.pow(3);
    let (ni, mi, pi, bi, nbi, nbins_i) = (
        int(n, "points")?,
        int(geo.m, "grid size")?,
        int(p, "support")?,
        int(b, "bin edge")?,
        int(nb, "bins per axis")?,
        int(nbins, "bins")?,
    );
    int(3 * n, "3 x points")?;
    check("points", pts, 3 * n)?;
    let mut bin = dev.zeros::<i32>(n)?;
    let mut rank = dev.zeros::<i32>(n)?;
    let mut count = dev.zeros::<i32>(nbins)?;
    let mut start = dev.zeros::<i32>(nbins + 1)?;
    let mut perm = dev.zeros::<i32>(n)?;
    // SAFETY: thread i < n reads pts[3 i..3 i + 3] (3 n checked) and writes bin[i], rank[i]
    // (n each); the window's first index lies in 0..m per axis, so its bin index is below
    // nb = ceil(m / b) per axis and the count it adds to below nb^3 (allocated).
    unsafe {
        dev.launch(
            n,
            BinCount {
                pts,
                bin: &mut bin,
                rank: &mut rank,
                count: &mut count,
                n: ni,
                m: mi,
                p: pi,
                l: geo.l,
                h: geo.window.h,
                b: bi,
                nb: nbi,
            },
        )?;
    }
    super::scan::prefix_sum(dev, &count, &mut start, nbins)?;
    // SAFETY: thread i < n reads bin[i] (< nbins), rank[i] and start[bin[i]] and writes
    // perm[start[bin] + rank] < start[bin + 1] <= n: the ranks of a bin are 0..count (the
    // atomic's old values) and the starts their prefix sums.
    unsafe {
        dev.launch(
            n,
            BinScatter {
                bin: &bin,
                rank: &rank,
                start: &start,
                perm: &mut perm,
                n: ni,
            },
        )?;
    }
    if method == SpreadMethod::Cells {
        // SAFETY: thread k < nbins reads start[k], start[k + 1] (nbins + 1 allocated) and
        // permutes perm between them (<= n, the starts' total).
        unsafe {
            dev.launch(
                nbins,
                BinOrder {
                    start: &start,
                    perm: &mut perm,
                    nbins: nbins_i,
                },
            )?;
        }
    }
    Ok(Bins {
        n,
        method,
        key: (geo.m, p, b),
        nb,
        perm,
        start,
    })
}

/// Spread `nf` fields (field-major values of the `n` points) onto `nf` grids of `m^3` (in the
/// padded in-place layout) with the bins' method.
pub(crate) fn spread(
    dev: &Device,
    geo: &Geometry,
    bins: &Bins,
    points: Points<'_>,
    fields: Fields<'_>,
    grid: &mut Buffer,
) -> Result<(), GpuError> {
    let Points { pos: pts, n } = points;
    let Fields { vals, nf } = fields;
    let (p, method) = (geo.window.p, bins.method);
    let (m, b) = (geo.m, method.bin_edge(p, geo.m));
    assert_eq!(bins.key, (m, p, b), "bins of this grid, support and method");
    assert!(
        nf <= 6 && p <= 24 && p <= m,
        "six fields, a support of at most 24"
    );
    check("points", pts, 3 * n)?;
    check("values", vals, nf * n)?;
    check("grid", grid, nf * padded_field(m))?;
    check("bin order", &bins.perm, n)?;
    check("bin starts", &bins.start, bins.nb.pow(3) + 1)?;
    let (ni, mi, pi) = (int(n, "points")?, int(m, "grid size")?, int(p, "support")?);
    int(nf * n, "values")?;
    let w = &geo.window;
    match method {
        SpreadMethod::Atomic => unreachable!("the atomic spreader has no bins"),
        SpreadMethod::Cells => {
            assert_eq!(
                THREADS, 256,
                "the kernel's cells per thread are for 256 threads"
            );
            assert!(
                (CELL_BIN..=CELL_BIN_MAX).contains(&b),
                "bins of {CELL_BIN} to {CELL_BIN_MAX} cells per axis"
            );
            let nbins = bins.nb.pow(3);
            let reach = SpreadMethod::reach(p, m, b, bins.nb);
            assert!(reach <= 4, "CELL_NEAR holds the bins of a reach up to 4");
            // SAFETY: block k < nbins (nbins THREADS threads launched; b^3 <= 1000 cells, at
            // most 4 per thread, the kernel's largest case) reads start[s],
            // start[s + 1] of bins s < nbins (the offsets below k taken modulo nb per axis;
            // nbins + 1 checked) and perm[j] for j between them (< n, checked), the points and
            // values of i = perm[j] < n (3 n and nf n checked; at most CELL_CHUNK staged, its
            // window's p <= 24 = MAX_SUPPORT weights per axis), and writes the grid values of
            // its cells, each below m per axis (checked), fields c < nf (nf padded_field(m)
            // checked); its (reach + 1)^3 <= CELL_NEAR = 125 near bins' starts staged in shared arrays of
            // that size (reach <= 4 asserted).
            unsafe {
                dev.launch(
                    nbins * THREADS as usize,
                    SpreadCells {
                        pts,
                        vals,
                        perm: &bins.perm,
                        start: &bins.start,
                        grid,
                        n: ni,
                        nf: nf as i32,
                        m: mi,
                        p: pi,
                        l: geo.l,
                        h: w.h,
                        alpha: w.alpha,
                        norm: w.norm,
                        b: b as i32,
                        nb: bins.nb as i32,
                        reach: reach as i32,
                    },
                )
            }
        }
        // SAFETY: thread j < n reads perm[j] < n (checked) and then as the atomic spreader's
        // thread perm[j]: points, values and grid indices as in launch::spread (checked
        // above; supports wrap at most once, p <= m asserted).
        SpreadMethod::Sorted => unsafe {
            dev.launch(
                n,
                SpreadSorted {
                    pts,
                    vals,
                    perm: &bins.perm,
                    grid,
                    n: ni,
                    nf: nf as i32,
                    m: mi,
                    p: pi,
                    l: geo.l,
                    h: w.h,
                    alpha: w.alpha,
                    norm: w.norm,
                },
            )
        },
    }
}

/// Values of one field's tile in the tiled gather's shared memory (`GATHER_TILE` in
/// kernels.cu): tiles of up to 16 cells per axis.
pub const GATHER_TILE: usize = 4096;

/// Whether the tiled gather takes bins of edge `b` at support `p`: the output-driven sort's
/// bins (each bin's points in ascending order), a tile of `(b + p - 1)^3` that fits
/// [`GATHER_TILE`]. The explicit level's support 6 takes it (tiles of 13-15 cells), the
/// dipole level's 10 (18-19) does not.
pub fn tiles_fit(method: SpreadMethod, b: usize, p: usize) -> bool {
    method == SpreadMethod::Cells && (b + p - 1).pow(3) <= GATHER_TILE
}

/// Gather three fields at the `n` points in bin order (with the window's derivative if
/// `gradient`): `out` as `launch::gather` writes it, in the points' own order. With `tiles`
/// and bins whose tiles fit ([`tiles_fit`]) a block per bin gathers from each field's tile in
/// shared memory (the same bits as the per-point gather); otherwise a thread per point.
pub(crate) fn gather(
    dev: &Device,
    geo: &Geometry,
    bins: &Bins,
    points: Points<'_>,
    grids: (&Buffer, &mut Buffer),
    gradient: bool,
    tiles: bool,
) -> Result<(), GpuError> {
    let Points { pos: pts, n } = points;
    let (grid, out) = grids;
    let (m, p) = (geo.m, geo.window.p);
    assert!(
        p <= 24 && p <= m,
        "a support of at most 24 and at most the grid"
    );
    let b = bins.method.bin_edge(p, m);
    // The tiled kernel's reads stay inside a bin's tile only for the bins of these points,
    // this grid and this support.
    assert_eq!(bins.key, (m, p, b), "bins of this grid, support and method");
    assert_eq!(bins.n, n, "bins of these points");
    let outputs = if gradient { 12 } else { 3 };
    check("points", pts, 3 * n)?;
    check("grid", grid, 3 * padded_field(m))?;
    check("gathered values", out, outputs * n)?;
    check("bin order", &bins.perm, n)?;
    let (ni, mi, pi) = (int(n, "points")?, int(m, "grid size")?, int(p, "support")?);
    int(12 * n, "12 x points")?;
    let w = &geo.window;
    if tiles && tiles_fit(bins.method, b, p) {
        let nbins = bins.nb.pow(3);
        check("bin starts", &bins.start, nbins + 1)?;
        // SAFETY: block k < nbins reads start[k], start[k + 1] (nbins + 1 checked) and
        // perm[j] < n for j between them (n checked); the grid values of its tile, each index
        // below m per axis (taken modulo m), fields c < 3 (3 padded_field(m) checked), into a
        // shared tile of (b + p - 1)^3 <= GATHER_TILE values (tiles_fit); each point's window
        // starts in its bin (bins by the window's first index, bin_count), so its reads stay
        // inside the tile; out[c n + i] for c < outputs (outputs n checked).
        unsafe {
            dev.launch(
                nbins * THREADS as usize,
                GatherTiles {
                    pts,
                    grid,
                    perm: &bins.perm,
                    start: &bins.start,
                    out,
                    n: ni,
                    gradient: i32::from(gradient),
                    m: mi,
                    p: pi,
                    l: geo.l,
                    h: w.h,
                    alpha: w.alpha,
                    norm: w.norm,
                    b: int(b, "bin edge")?,
                    nb: int(bins.nb, "bins per axis")?,
                },
            )
        }
    } else {
        // SAFETY: thread j < n reads perm[j] < n (checked), then as launch::gather's thread
        // perm[j]: pts, grid (3 n, 3 padded_field(m) checked) and out[c n + perm[j]] for c <
        // outputs (outputs n checked).
        unsafe {
            dev.launch(
                n,
                GatherSorted {
                    pts,
                    grid,
                    perm: &bins.perm,
                    out,
                    n: ni,
                    gradient: i32::from(gradient),
                    m: mi,
                    p: pi,
                    l: geo.l,
                    h: w.h,
                    alpha: w.alpha,
                    norm: w.norm,
                },
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every bin whose points' windows cover a cell of a bin lies at an offset 0..=reach below
    /// it (modulo the bins per axis), and no offset repeats a bin: by brute force over every
    /// first index and cell of one axis, for supports 2-24 and grids 8-100 (bins that divide
    /// the grid and a short last bin).
    #[test]
    fn the_output_driven_spreader_reaches_every_bin_that_reaches_it() {
        for (b, m) in [8usize, 9, 12, 16, 20, 24, 30, 32, 40, 41, 64, 100, 270, 480]
            .into_iter()
            .flat_map(|m| (CELL_BIN..=CELL_BIN_MAX).map(move |b| (b, m)))
            .filter(|&(b, m)| m >= b)
        {
            let nb = m.div_ceil(b);
            for p in 2..=24usize.min(m) {
                let reach = SpreadMethod::reach(p, m, b, nb);
                assert!(
                    reach < nb && reach <= 4,
                    "m {m}, b {b}, p {p}: reach {reach} of {nb}"
                );
                for f in 0..m {
                    for q in 0..p {
                        let c = (f + q) % m;
                        let offset = (c / b + nb - f / b) % nb;
                        assert!(
                            offset <= reach,
                            "m {m}, b {b}, p {p}: a window from {f} covers {c}, {offset} bins up, reach {reach}"
                        );
                    }
                }
            }
        }
    }

    /// The bin edge takes one near bin per axis where an edge of 8-10 divides the grid.
    #[test]
    fn the_output_driven_bins_reach_one_bin_where_they_can() {
        for (p, m, want) in [
            (10, 270, 9),
            (10, 480, 10),
            (9, 240, 8),
            (6, 250, 10),
            (9, 180, 9),
        ] {
            let b = cell_bin(p, m);
            assert_eq!(b, want, "support {p}, grid {m}");
            assert_eq!(
                SpreadMethod::reach(p, m, b, m / b),
                1,
                "support {p}, grid {m}"
            );
        }
        assert_eq!(
            cell_bin(16, 324),
            CELL_BIN,
            "no edge of 8-10 covers a support of 16"
        );
    }
}
