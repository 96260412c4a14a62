//! Binned spreading and gathering, as cuFINUFFT's: the points sorted into bins of grid cells on
//! the device (a counting sort: each point's bin and rank by an integer atomic, the bins'
//! starts by a prefix sum, the points scattered into bin order), then
//! - [`SpreadMethod::Tiles`] (supports up to [`MAX_TILE_SUPPORT`]): one block per bin
//!   accumulates its points in a shared-memory tile of [`TILE`]^3 cells per field and adds the
//!   tile's nonzero cells to the grid once;
//! - [`SpreadMethod::Sorted`] (wider supports, whose tiles would not fit in shared memory): the
//!   per-point global-memory spreader run in bin order, so that a warp's threads add to
//!   neighbouring cells;
//!
//! and the gather runs over the points in bin order for either. The points of one generation
//! (one GMRES solve) are sorted once. [`SpreadMethod::Atomic`], the per-point spreader in the
//! points' own order, stays as the slow twin for the tests.
//!
//! Launching is unsafe: each launch says why every index it touches lies inside its buffers.
#![allow(unsafe_code)]

use crate::ewald::gpu::launch::Geometry;
use crate::ewald::gpu::signatures::{
    BinCount, BinScan, BinScatter, GatherSorted, SpreadSorted, SpreadTiles,
};
use motile_gpu::{Buffer, Device, GpuError, THREADS};

/// Tile edge (grid cells) of the shared-memory spreader: `TILE` in `kernels.cu`.
pub const TILE: usize = 12;

/// The widest support the tiles take: a bin is `TILE - p + 1` cells wide, at least 5.
pub const MAX_TILE_SUPPORT: usize = 8;

/// Bin edge of the sorted global-memory spreader (for locality only).
const SORTED_BIN: usize = 8;

/// How the Fourier part spreads its values onto the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpreadMethod {
    /// One thread per point in the points' own order, global atomic adds: the slow twin.
    Atomic,
    /// Points sorted into bins, each bin accumulated in a shared-memory tile.
    Tiles,
    /// Points sorted into bins, the global-memory spreader in bin order.
    Sorted,
}

impl SpreadMethod {
    /// The method for support `p`: tiles where they fit ([`MAX_TILE_SUPPORT`], tolerances down
    /// to 1e-4), else the sorted global-memory spreader (as cuFINUFFT does for 3D double
    /// precision at high accuracy).
    pub fn for_support(p: usize) -> Self {
        if p <= MAX_TILE_SUPPORT {
            Self::Tiles
        } else {
            Self::Sorted
        }
    }

    /// Bin edge (grid cells) for support `p`.
    fn bin_edge(self, p: usize) -> usize {
        match self {
            Self::Tiles => TILE + 1 - p,
            _ => SORTED_BIN,
        }
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
    /// Points in bin order.
    perm: Buffer<i32>,
    /// Start of each bin in `perm` (`nb^3 + 1` values).
    start: Buffer<i32>,
}

fn int(v: usize, what: &str) -> Result<i32, GpuError> {
    i32::try_from(v).map_err(|_| GpuError::Input(format!("{what} {v} exceeds an int")))
}

fn check<T: motile_gpu::Element>(
    what: &str,
    b: &Buffer<T>,
    at_least: usize,
) -> Result<(), GpuError> {
    if b.len() < at_least {
        return Err(GpuError::Input(format!(
            "{what}: {} values where the kernel reads or writes {at_least}",
            b.len()
        )));
    }
    Ok(())
}

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
    let b = method.bin_edge(p);
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
    // SAFETY: one block of THREADS = 256 threads (its shared array's size, asserted): each
    // thread reads count[k] and writes start[k] for k in its chunk of 0..nbins, thread 0
    // start[nbins] (nbins + 1 allocated).
    unsafe {
        dev.launch(
            THREADS as usize,
            BinScan {
                count: &count,
                start: &mut start,
                nbins: nbins_i,
            },
        )?;
    }
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
    Ok(Bins {
        method,
        key: (geo.m, p, b),
        nb,
        perm,
        start,
    })
}

/// Spread `nf` fields (field-major values of the `n` points) onto `nf` grids of `m^3` with the
/// bins' method.
pub(crate) fn spread(
    dev: &Device,
    geo: &Geometry,
    bins: &Bins,
    pts: &Buffer,
    vals: &Buffer,
    grid: &mut Buffer,
    (n, nf): (usize, usize),
) -> Result<(), GpuError> {
    let (p, method) = (geo.window.p, bins.method);
    let (m, b) = (geo.m, method.bin_edge(p));
    assert_eq!(bins.key, (m, p, b), "bins of this grid, support and method");
    assert!(
        nf <= 6 && p <= 24 && p <= m,
        "six fields, a support of at most 24"
    );
    check("points", pts, 3 * n)?;
    check("values", vals, nf * n)?;
    check("grid", grid, nf * m.pow(3))?;
    check("bin order", &bins.perm, n)?;
    check("bin starts", &bins.start, bins.nb.pow(3) + 1)?;
    let (ni, mi, pi) = (int(n, "points")?, int(m, "grid size")?, int(p, "support")?);
    int(nf * n, "values")?;
    let w = &geo.window;
    match method {
        SpreadMethod::Atomic => unreachable!("the atomic spreader has no bins"),
        SpreadMethod::Tiles => {
            assert!(
                p <= MAX_TILE_SUPPORT,
                "tiles take supports up to {MAX_TILE_SUPPORT}"
            );
            let nbins = bins.nb.pow(3);
            for f0 in (0..nf).step_by(3) {
                // SAFETY: block k < nbins (nbins THREADS threads launched) reads start[k],
                // start[k + 1] (nbins + 1 checked) and perm[j] for j between them (< n,
                // checked), points and values of i = perm[j] < n (3 n and nf n checked); its
                // tile indices o + q < (b - 1) + p = TILE (b = TILE + 1 - p, p <= 8 asserted),
                // its grid indices reduced into 0..m per axis, fields f0 + c < nf (nf m^3
                // checked).
                unsafe {
                    dev.launch(
                        nbins * THREADS as usize,
                        SpreadTiles {
                            pts,
                            vals,
                            perm: &bins.perm,
                            start: &bins.start,
                            grid,
                            n: ni,
                            f0: f0 as i32,
                            nf: (nf - f0).min(3) as i32,
                            m: mi,
                            p: pi,
                            l: geo.l,
                            h: w.h,
                            alpha: w.alpha,
                            norm: w.norm,
                            b: b as i32,
                            nb: bins.nb as i32,
                        },
                    )?;
                }
            }
            Ok(())
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

/// Gather three fields at the `n` points in bin order (with the window's derivative if
/// `gradient`): `out` as `launch::gather` writes it, in the points' own order.
pub(crate) fn gather(
    dev: &Device,
    geo: &Geometry,
    bins: &Bins,
    pts: &Buffer,
    grid: &Buffer,
    out: &mut Buffer,
    (n, gradient): (usize, bool),
) -> Result<(), GpuError> {
    let (m, p) = (geo.m, geo.window.p);
    assert!(
        p <= 24 && p <= m,
        "a support of at most 24 and at most the grid"
    );
    let outputs = if gradient { 12 } else { 3 };
    check("points", pts, 3 * n)?;
    check("grid", grid, 3 * m.pow(3))?;
    check("gathered values", out, outputs * n)?;
    check("bin order", &bins.perm, n)?;
    let (ni, mi, pi) = (int(n, "points")?, int(m, "grid size")?, int(p, "support")?);
    int(12 * n, "12 x points")?;
    let w = &geo.window;
    // SAFETY: thread j < n reads perm[j] < n (checked), then as launch::gather's thread
    // perm[j]: pts, grid (3 n, 3 m^3 checked) and out[c n + perm[j]] for c < outputs
    // (outputs n checked).
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
