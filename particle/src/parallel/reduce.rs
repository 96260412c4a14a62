//! Reductions in a fixed order, so that results are the same bits for any thread count and on
//! every rank: sums in fixed chunks, and the maximum over ranks with its key.

use crate::parallel::comm::Comm;
use rayon::prelude::*;

/// Elements per chunk of the fixed-order sums.
pub(crate) const CHUNK: usize = 4096;

/// Sum of `f(k)` for `k` in `0..n`, in fixed chunks: the same bits for any thread count.
pub(crate) fn det_sum(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(&f).sum())
        .collect();
    partial.iter().sum()
}

/// The maximum over ranks of `value` and its `key`, ties to the smallest key (compared in
/// order; collective: every rank gets the same pair).
pub(crate) fn max_with_key(comm: &dyn Comm, value: f64, key: [f64; 2]) -> (f64, [f64; 2]) {
    if comm.size() == 1 {
        return (value, key);
    }
    let all = comm.all_gather(&[value, key[0], key[1]]);
    all.iter()
        .fold((f64::NEG_INFINITY, [f64::INFINITY; 2]), |a, b| {
            let k = [b[1], b[2]];
            if b[0] > a.0 || (b[0] == a.0 && k < a.1) {
                (b[0], k)
            } else {
                a
            }
        })
}
