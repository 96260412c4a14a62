//! The spreaders' work model ([`work_model`], `gpu_bench --model`): per phase of one Fourier
//! part, counted from the points themselves, the kernel launches, the bytes the kernels
//! request, the distinct grid lines each warp touches, and global and shared-memory atomics,
//! for each [`SpreadMethod`]; no device needed.

use super::binned::{SpreadMethod, tiles_fit};
use super::scan::SCAN_ONE_BLOCK;

/// One phase's work in the work model ([`work_model`]): what its kernels request of global
/// memory (loads and stores; atomics counted apart), their global and shared-memory atomic
/// adds, and its kernel launches (FFTs counted as one launch each).
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseWork {
    /// The phase.
    pub phase: &'static str,
    /// Kernel launches.
    pub launches: usize,
    /// Global-memory bytes loaded and stored (without atomics).
    pub bytes: f64,
    /// Global-memory atomic adds (each a read-modify-write of 8 bytes at the cache).
    pub global_atomics: f64,
    /// Shared-memory atomic adds.
    pub shared_atomics: f64,
    /// Distinct 128-byte lines of the grids that the phase's warps (32 consecutive threads)
    /// touch, summed over warps: the traffic at the cache
    /// (times 128 bytes), where the order of the points shows. Estimated from up to 4096
    /// warps evenly spaced; 0 for phases that do not touch the grids point by point.
    pub grid_lines: f64,
}

/// The first grid index of a window along one axis, as `window_first` in `kernels.cu`.
fn first_index(y: f64, l: f64, m: usize, p: usize) -> usize {
    let h = l / m as f64;
    let mut f = y - l * (y / l).floor();
    if f >= l {
        f = 0.0;
    }
    let i0 = -(0.5 * p as f64 - f / h).floor();
    (i0 as i64).rem_euclid(m as i64) as usize
}

/// One Fourier part as the work model counts it: its grid, its window and the fields it
/// spreads and gathers.
#[derive(Clone, Copy, Debug)]
pub struct FourierPart {
    /// Grid points per axis (an `m^3` grid).
    pub m: usize,
    /// The window's support `p`, grid points per axis.
    pub p: usize,
    /// Fields spread: 3 for RPY forces, [`super::STRESSLET_FIELDS`] for stresslets.
    pub nf: usize,
    /// Whether the three fields gathered come with the window's derivative.
    pub gradient: bool,
}

/// The work of one Fourier `part` on the device with `method`, counted from the points
/// themselves: `nf` fields spread (3 for RPY forces, [`super::STRESSLET_FIELDS`] for
/// stresslets), three gathered (with the window's derivative if `gradient`), on an `m^3` grid
/// with support `p`. Phases:
/// values up, the sort (once per generation: the products of a GMRES solve share it), spread,
/// FFTs and the mode multiplication (each transform counted as two passes over its data, read
/// and written), gather, values down.
pub fn work_model(
    points: &[[f64; 3]],
    l: f64,
    part: FourierPart,
    method: SpreadMethod,
) -> Vec<PhaseWork> {
    let FourierPart { m, p, nf, gradient } = part;
    let n = points.len() as f64;
    let outputs = if gradient { 12.0 } else { 3.0 };
    let (m3, p3) = ((m * m * m) as f64, (p * p * p) as f64);
    let half = (m * m * (m / 2 + 1)) as f64 * 16.0; // one half spectrum's bytes
    let phase = |phase, launches, bytes, global_atomics, shared_atomics| PhaseWork {
        phase,
        launches,
        bytes,
        global_atomics,
        shared_atomics,
        grid_lines: 0.0,
    };
    let first: Vec<[usize; 3]> = points
        .iter()
        .map(|y| std::array::from_fn(|d| first_index(y[d], l, m, p.min(m))))
        .collect();
    let own: Vec<usize> = (0..points.len()).collect();
    let mut rows = vec![phase("values up", 0, 8.0 * nf as f64 * n, 0.0, 0.0)];
    // The grid zeroed, spread; then per point its 3 coordinates and nf values.
    let point_reads = n * 8.0 * (3.0 + nf as f64);
    let zero = 8.0 * nf as f64 * m3;
    match method {
        SpreadMethod::Atomic => rows.push(PhaseWork {
            grid_lines: warp_lines(&own, &first, m, p) * nf as f64,
            ..phase("spread", 2, zero + point_reads, n * p3 * nf as f64, 0.0)
        }),
        SpreadMethod::Sorted | SpreadMethod::Cells => {
            let p = p.min(m);
            let b = method.bin_edge(p, m);
            let nb = m.div_ceil(b);
            let nbins = (nb * nb * nb) as f64;
            let cells = method == SpreadMethod::Cells;
            // bin_count (points, bin and rank out, one int atomic each), bin_scan (counts in,
            // starts out), bin_scatter (bin, rank, start in, perm out), buffers zeroed; for the
            // cells, bin_order (starts in, perm read and written).
            rows.push(phase(
                "sort",
                // A long prefix sum takes three launches instead of one (scan.rs).
                4 + usize::from(cells) + 2 * usize::from(nbins as usize > SCAN_ONE_BLOCK),
                n * 24.0
                    + n * 8.0
                    + 8.0 * nbins
                    + n * 12.0
                    + n * 4.0
                    + 4.0 * nbins
                    + if cells { 8.0 * n + 8.0 * nbins } else { 0.0 },
                n,
                0.0,
            ));
            let order = bin_order(&first, b, nb);
            if cells {
                // Each point staged by the (reach + 1)^3 blocks it can reach (its index, its
                // coordinates and values), each bin's starts read by as many; the grid written
                // once (a warp's 32 cells: 4 rows of 8), not zeroed.
                let loads = (SpreadMethod::reach(p, m, b, nb) + 1).pow(3) as f64;
                rows.push(PhaseWork {
                    grid_lines: nf as f64 * m3 / 8.0,
                    ..phase(
                        "spread",
                        1,
                        loads * (point_reads + 4.0 * n + 8.0 * nbins) + 8.0 * nf as f64 * m3,
                        0.0,
                        0.0,
                    )
                });
            } else {
                rows.push(PhaseWork {
                    grid_lines: warp_lines(&order, &first, m, p) * nf as f64,
                    ..phase(
                        "spread",
                        2,
                        zero + point_reads + 4.0 * n,
                        n * p3 * nf as f64,
                        0.0,
                    )
                });
            }
        }
    }
    // Forward transforms of nf fields, the mode multiplication (nf spectra in, 3 out), the
    // inverse transform of 3.
    let fft = |fields: f64| 2.0 * fields * (8.0 * m3 + half);
    rows.push(phase(
        "FFTs and modes",
        3,
        fft(nf as f64) + half * (nf as f64 + 3.0) + fft(3.0),
        0.0,
        0.0,
    ));
    let sorted = method != SpreadMethod::Atomic;
    let order = if sorted {
        bin_order(
            &first,
            method.bin_edge(p.min(m), m),
            m.div_ceil(method.bin_edge(p.min(m), m)),
        )
    } else {
        own
    };
    let (pb, b) = (p.min(m), method.bin_edge(p.min(m), m));
    if tiles_fit(method, b, pb) {
        // A block per non-empty bin reads its start, each field's tile of t^3 cells (rows of t
        // consecutive values: (t - 1)/16 + 1 lines of 16 doubles on average) and, per field,
        // its points' indices and coordinates again, and writes their outputs.
        let nb = m.div_ceil(b);
        let mut occupied: Vec<usize> = first
            .iter()
            .map(|f| (f[2] / b * nb + f[1] / b) * nb + f[0] / b)
            .collect();
        occupied.sort_unstable();
        occupied.dedup();
        let bins = occupied.len() as f64;
        let t = (b + pb - 1) as f64;
        rows.push(PhaseWork {
            grid_lines: 3.0 * bins * t * t * ((t - 1.0) / 16.0 + 1.0),
            ..phase(
                "gather",
                2,
                8.0 * outputs * n // zeroed output
                + 8.0 * (nb * nb * nb) as f64
                + 3.0 * bins * t * t * t * 8.0
                + 3.0 * n * (4.0 + 24.0)
                + 8.0 * outputs * n,
                0.0,
                0.0,
            )
        });
    } else {
        rows.push(PhaseWork {
            grid_lines: warp_lines(&order, &first, m, p) * 3.0,
            ..phase(
                "gather",
                2,
                8.0 * outputs * n // zeroed output
                + n * 24.0
                + if sorted { 4.0 * n } else { 0.0 }
                + n * p3 * 3.0 * 8.0
                + 8.0 * outputs * n,
                0.0,
                0.0,
            )
        });
    }
    rows.push(phase("values down", 0, 8.0 * outputs * n, 0.0, 0.0));
    rows
}

/// The points in bin order (by bin, then by index), as the sort leaves them up to the order
/// within a bin.
fn bin_order(first: &[[usize; 3]], b: usize, nb: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..first.len()).collect();
    order.sort_by_key(|&i| {
        let f = &first[i];
        (f[2] / b * nb + f[1] / b) * nb + f[0] / b
    });
    order
}

/// Distinct 128-byte grid lines (16 doubles along x; one field) touched by the supports of
/// each warp's 32 points in `order`, summed over warps (from up to 4096 warps evenly spaced,
/// scaled to all).
fn warp_lines(order: &[usize], first: &[[usize; 3]], m: usize, p: usize) -> f64 {
    let p = p.min(m);
    let warps = order.len().div_ceil(32);
    let sample = warps.min(4096);
    let mut lines = Vec::new();
    let mut total = 0usize;
    for k in 0..sample {
        let w = k * warps / sample;
        lines.clear();
        for &i in &order[32 * w..(32 * w + 32).min(order.len())] {
            let f = &first[i];
            for qz in 0..p {
                let z = (f[2] + qz) % m;
                for qy in 0..p {
                    let y = (f[1] + qy) % m;
                    for qx in [0, p - 1] {
                        lines.push((z * m + y) * m.div_ceil(16) + (f[0] + qx) % m / 16);
                    }
                    // A support wider than a line spans the ones between too.
                    let (a, e) = (f[0] / 16, (f[0] + p - 1) / 16);
                    for x in a + 1..e {
                        lines.push((z * m + y) * m.div_ceil(16) + x % m.div_ceil(16));
                    }
                }
            }
        }
        lines.sort_unstable();
        lines.dedup();
        total += lines.len();
    }
    total as f64 * warps as f64 / sample.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The atomic spreader's atomics are `n p^3 nf`; the output-driven spreader has none and
    /// writes the grid once, in one launch.
    #[test]
    fn the_work_model_counts_the_spreaders_atomics() {
        let (l, m, p) = (7.0, 20usize, 5usize);
        let mut points: Vec<[f64; 3]> = (0..300)
            .map(|i| {
                let x = |k: usize| ((i * k * 7919) % 10007) as f64 / 10007.0 * l;
                [x(3), x(5), x(11)]
            })
            .collect();
        points.push([0.0, 0.0, 0.0]);
        points.push([l - 1e-12, 2.8, 3.5]);
        let part = |nf, gradient| FourierPart { m, p, nf, gradient };
        let rows = work_model(&points, l, part(3, false), SpreadMethod::Atomic);
        let spread = rows.iter().find(|r| r.phase == "spread").unwrap();
        assert_eq!(spread.global_atomics, (points.len() * p * p * p * 3) as f64);
        let rows = work_model(&points, l, part(6, true), SpreadMethod::Cells);
        let spread = rows.iter().find(|r| r.phase == "spread").unwrap();
        assert_eq!(spread.global_atomics, 0.0);
        assert_eq!(spread.launches, 1, "one launch, the grid written once");
    }
}
