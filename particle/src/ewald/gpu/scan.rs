//! The prefix sums of the device's counting sorts (`scan.cu`): one block for up to
//! [`SCAN_ONE_BLOCK`] counts, three passes beyond.
#![allow(unsafe_code)]

use super::signatures::{BinScan, ScanSpread, ScanTiles};
use motile_gpu::check_len as check;
use motile_gpu::{Buffer, Device, GpuError, THREADS, kernel_int as int};

/// Counts up to which one block scans them alone ([`prefix_sum`]).
pub(crate) const SCAN_ONE_BLOCK: usize = 1 << 16;

/// `start[0..=n]`: the exclusive prefix sum of `count[0..n]`, the last value the total. Up to
/// [`SCAN_ONE_BLOCK`] counts one block (`bin_scan`); more in three passes (`scan_tiles`, whose
/// at most 16 384 tile sums `bin_scan` scans, then `scan_spread`): a single block over millions
/// of cells took milliseconds. Integer sums: the same starts either way.
pub(crate) fn prefix_sum(
    dev: &Device,
    count: &Buffer<i32>,
    start: &mut Buffer<i32>,
    n: usize,
) -> Result<(), GpuError> {
    assert_eq!(
        THREADS, 256,
        "bin_scan's shared array holds 256 partial sums"
    );
    check("counts", count, n)?;
    check("starts", start, n + 1)?;
    let ni = int(n, "counts")?;
    if n <= SCAN_ONE_BLOCK {
        // SAFETY: one block of THREADS = 256 threads (its shared array's size, asserted): each
        // thread reads count[k] and writes start[k] for k in its chunk of 0..n, thread 0
        // start[n] (n + 1 checked).
        return unsafe {
            dev.launch(
                THREADS as usize,
                BinScan {
                    count,
                    start,
                    nbins: ni,
                },
            )
        };
    }
    let tile = n.div_ceil(1 << 14).max(32);
    let ntiles = n.div_ceil(tile);
    let mut sums = dev.zeros::<i32>(ntiles)?;
    let mut tile_start = dev.zeros::<i32>(ntiles + 1)?;
    let ti = int(tile, "scan tile")?;
    // SAFETY: thread t < ntiles reads count[t tile..min((t + 1) tile, n)] (n checked) and
    // writes sums[t] (ntiles).
    unsafe {
        dev.launch(
            ntiles,
            ScanTiles {
                count,
                sums: &mut sums,
                nbins: ni,
                tile: ti,
            },
        )?;
    }
    // SAFETY: as above, over the ntiles sums into ntiles + 1 starts.
    unsafe {
        dev.launch(
            THREADS as usize,
            BinScan {
                count: &sums,
                start: &mut tile_start,
                nbins: int(ntiles, "scan tiles")?,
            },
        )?;
    }
    // SAFETY: thread t < ntiles reads tile_start[t] (ntiles + 1) and count over its tile, and
    // writes start over its tile, the last tile's thread start[n] (n + 1 checked).
    unsafe {
        dev.launch(
            ntiles,
            ScanSpread {
                count,
                tile_start: &tile_start,
                start,
                nbins: ni,
                tile: ti,
            },
        )
    }
}
