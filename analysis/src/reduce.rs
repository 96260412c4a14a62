//! Reductions in a fixed order, shared by every crate: the range `0..n` cut into chunks of
//! [`CHUNK`] elements, each chunk's partial computed in parallel in element order, the partials
//! returned in chunk order for the caller to fold in that order. The result is the same bits
//! for any thread count (and, below one chunk, the plain sequential loop's). The GPU kernels'
//! reductions use the same chunks, so theirs are the CPU's.

use rayon::prelude::*;
use std::ops::Range;

/// Elements per chunk of the fixed-order reductions.
pub const CHUNK: usize = 4096;

/// `partial` of each chunk of `0..n` (in parallel), in chunk order.
pub fn chunk_partials<T: Send>(n: usize, partial: impl Fn(Range<usize>) -> T + Sync) -> Vec<T> {
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| partial(c * CHUNK..((c + 1) * CHUNK).min(n)))
        .collect()
}

/// Sum of `f(k)` for `k` in `0..n`: each chunk's sum in order, then the chunks' in order.
pub fn det_sum(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    chunk_partials(n, |r| r.map(&f).sum::<f64>()).iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sum is the sequential sum of the chunks' sequential sums, whatever the pool size.
    #[test]
    fn the_sum_is_the_same_bits_for_any_thread_count() {
        let n = 3 * CHUNK + 17;
        let f = |k: usize| ((k * 7919) % 1009) as f64 * 1e-3 + 1.0 / (k + 1) as f64;
        let want: f64 = (0..n.div_ceil(CHUNK))
            .map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(f).sum::<f64>())
            .sum();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let got = pool.install(|| det_sum(n, f));
            assert_eq!(got.to_bits(), want.to_bits(), "{threads} threads");
        }
        assert_eq!(det_sum(0, f), 0.0);
        let ranges = chunk_partials(n, |r| (r.start, r.end));
        assert_eq!(ranges.first(), Some(&(0, CHUNK)));
        assert_eq!(ranges.last(), Some(&(3 * CHUNK, n)));
    }
}
