//! Reductions over ranks in a fixed order, so that every rank gets the same bits: the maximum
//! over ranks with its key. (Sums in fixed chunks are `motile_analysis::reduce`'s.)

use crate::parallel::comm::Comm;

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
