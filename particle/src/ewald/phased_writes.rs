//! Deterministic parallel writes over slabs of planes: the shared skeleton of the Gaussian
//! grid's spreading and the symmetric real-space pair sum.

use rayon::prelude::*;

/// Slab boundaries for `n` planes: an even number of slabs `thickness` planes thick (the last
/// takes the remainder), or one slab when fewer than two fit. A function of `n` and
/// `thickness` only; as thin as the writes allow, so each phase of [`phased`] has many slabs
/// to share among threads (three per phase ran 2:1 on two threads).
pub(crate) fn bounds(n: usize, thickness: usize) -> Vec<usize> {
    let count = (n / thickness) & !1;
    if count < 2 {
        return vec![0, n];
    }
    (0..count).map(|s| s * thickness).chain([n]).collect()
}

/// Run `task(s, window, window_start, wrap)` for every slab `s` of `bounds` (plane indices;
/// `bounds.len() - 1` slabs, an even number or one), where slab `s` writes the planes
/// `bounds[s]..bounds[s + 1] + reach`, those past the last plane wrapping to `0..reach`.
/// `start(z)` is the first element of plane `z` in `data` (`start(n)` its length). `window`
/// holds the elements from `window_start` to the end of the slab's reach (at most the last
/// plane), `wrap` the elements of planes `0..reach` for the last slab and nothing for the
/// others; a single slab gets all of `data` and must wrap by itself.
///
/// The even slabs run in parallel, then the odd ones. With every slab at least `reach` planes
/// thick, the windows of one phase are disjoint, so each element receives its writes in an
/// order fixed by `bounds` alone: results do not depend on the thread count.
pub(crate) fn phased<T: Send>(
    data: &mut [T],
    bounds: &[usize],
    reach: usize,
    start: impl Fn(usize) -> usize,
    task: impl Fn(usize, &mut [T], usize, &mut [T]) + Sync,
) {
    let nslab = bounds.len() - 1;
    let n = bounds[nslab];
    if nslab == 1 {
        task(0, data, 0, &mut []);
        return;
    }
    for phase in 0..2 {
        // Windows of this phase's slabs, split off in increasing order.
        let head_len = if phase == 1 { start(reach) } else { 0 };
        let (mut head, mut rest) = data.split_at_mut(head_len);
        let mut offset = head_len;
        let mut jobs = Vec::new();
        for s in (phase..nslab).step_by(2) {
            let (a, b) = (start(bounds[s]), start((bounds[s + 1] + reach).min(n)));
            let (_, r) = std::mem::take(&mut rest).split_at_mut(a - offset);
            let (win, r) = r.split_at_mut(b - a);
            rest = r;
            offset = b;
            let wrap = if s == nslab - 1 {
                std::mem::take(&mut head)
            } else {
                &mut [][..]
            };
            jobs.push((s, win, a, wrap));
        }
        jobs.into_par_iter()
            .for_each(|(s, win, a, wrap)| task(s, win, a, wrap));
    }
}
