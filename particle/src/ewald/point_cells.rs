//! Points sorted into cells for the real-space part of the spectral Ewald sums
//! ([`crate::ewald::spectral`]): neighbour hits within the cutoff, gathered per target or
//! visited once per pair (the symmetric sum), in an order fixed by the cells so that results
//! do not depend on the thread count.

use crate::ewald::phased_writes::{self, phased};
use crate::model::geometry::{Vec3, dot, floor_i64, min_image, wrap_position};
use rayon::prelude::*;

/// Points sorted into cells of side at least half the cutoff (a 5^3 stencil then covers the
/// cutoff sphere with 3.7 times its volume, against 6.4 for cells of the full cutoff), with a
/// cell-ordered copy of the positions so the inner loop streams through memory.
#[derive(Debug)]
pub(crate) struct PointCells {
    pub(crate) n: usize,
    pub(crate) l: f64,
    pub(crate) start: Vec<usize>,
    pub(crate) members: Vec<u32>,
    pub(crate) sorted: Vec<Vec3>,
    /// The same, by coordinate.
    pub(crate) xs: Vec<f64>,
    pub(crate) ys: Vec<f64>,
    pub(crate) zs: Vec<f64>,
    /// Group of each point, in cell order.
    pub(crate) group: Vec<u32>,
    /// Points `0..owned` (in the caller's order) are targets; the rest are sources only
    /// ([`Self::own_first`]).
    owned: usize,
}

impl PointCells {
    pub(crate) fn build(y: &[Vec3], l: f64, cutoff: f64, group: usize) -> Self {
        let n = ((2.0 * l / cutoff).floor() as usize).max(1);
        // The cell comes from the wrapped position itself, so a point and its cell always
        // agree: a coordinate just below 0 wraps to L by rounding and is stored as 0, and a
        // cell computed from the unwrapped fraction (1.0 after rounding) put it in the last
        // cell, about L from its stored position, losing all its real-space pairs.
        let scale = n as f64 / l;
        let cell_of: Vec<u32> = y
            .par_iter()
            .map(|p| {
                let idx = wrap_position(*p, l).map(|c| ((c * scale) as usize).min(n - 1));
                ((idx[2] * n + idx[1]) * n + idx[0]) as u32
            })
            .collect();
        let mut start = vec![0usize; n * n * n + 1];
        for &k in &cell_of {
            start[k as usize + 1] += 1;
        }
        for c in 0..n * n * n {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut members = vec![0u32; y.len()];
        for (i, &k) in cell_of.iter().enumerate() {
            members[next[k as usize]] = i as u32;
            next[k as usize] += 1;
        }
        // Wrapped into [0, L) so that a neighbour cell's periodic shift is one vector per cell.
        let sorted: Vec<Vec3> = members
            .par_iter()
            .map(|&i| wrap_position(y[i as usize], l))
            .collect();
        let group = members
            .iter()
            .map(|&i| (i as usize / group) as u32)
            .collect();
        let (xs, ys, zs) = (
            sorted.iter().map(|p: &Vec3| p[0]).collect(),
            sorted.iter().map(|p: &Vec3| p[1]).collect(),
            sorted.iter().map(|p: &Vec3| p[2]).collect(),
        );
        Self {
            n,
            l,
            start,
            members,
            sorted,
            xs,
            ys,
            zs,
            group,
            owned: y.len(),
        }
    }

    /// The same cells with only the first `owned` points (in the caller's order) as targets:
    /// the others (a rank's copies of other ranks' points) are sources, and pairs of two
    /// sources are skipped. The sources' results are partial (or zero) and must not be used.
    pub(crate) fn own_first(mut self, owned: usize) -> Self {
        self.owned = owned;
        self
    }

    /// Whether every point is a target (no source-only copies).
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn all_own(&self) -> bool {
        self.owned == self.members.len()
    }

    /// Whether sorted point `k` is a target.
    #[inline]
    fn is_own(&self, k: usize) -> bool {
        (self.members[k] as usize) < self.owned
    }

    /// Values in cell order (`members()[k]`'s value at `k`), for streaming in [`Self::gather`].
    pub(crate) fn sorted_values<T: Copy + Send + Sync>(&self, v: &[T]) -> Vec<T> {
        self.members.par_iter().map(|&i| v[i as usize]).collect()
    }

    /// For each target, `f(acc, hits)` with its hits: every point `k` of another group (cell
    /// order, see [`Self::sorted_values`]) with the minimum-image `r = y_t - y_k`,
    /// `0 < |r| < cutoff`, in an order fixed by the cells; results in the targets' own order.
    ///
    /// Each target visits the 5 x 5 rows of neighbour cells along x, skips a row whose
    /// y-z distance exceeds the cutoff and takes from the others only the cells its cutoff
    /// sphere reaches (one or two contiguous runs of points, cells being ordered x fastest).
    /// The runs are filtered without branches (distances in a straight loop, hits compacted),
    /// then `f` runs on the hits. A distance test that branched mispredicted on about a third
    /// of the candidates, and a fixed 5^3 stencil visited 3.7 times the cutoff sphere.
    pub(crate) fn gather<A: Send + Default + Clone>(
        &self,
        cutoff: f64,
        f: impl Fn(&mut A, &mut Hits) + Sync,
    ) -> Vec<A> {
        let c2 = cutoff * cutoff;
        let n = self.n as i64;
        let l = self.l;
        let per_cell: Vec<Vec<A>> = (0..self.n * self.n * self.n)
            .into_par_iter()
            .map_init(Hits::default, |hits, c| {
                let range = self.start[c]..self.start[c + 1];
                let mut out = vec![A::default(); range.len()];
                if range.is_empty() {
                    return out;
                }
                if self.n < 5 {
                    // Few cells: every point, minimum image per pair.
                    for (k, acc) in out.iter_mut().enumerate() {
                        let tk = range.start + k;
                        if !self.is_own(tk) {
                            continue;
                        }
                        let yt = self.sorted[tk];
                        let gt = self.group[tk];
                        hits.clear();
                        for (jk, yj) in self.sorted.iter().enumerate() {
                            let r = min_image([yt[0] - yj[0], yt[1] - yj[1], yt[2] - yj[2]], l);
                            let r2 = dot(r, r);
                            hits.push(r, jk, r2 < c2 && r2 > 0.0 && self.group[jk] != gt);
                        }
                        f(acc, hits);
                    }
                    return out;
                }
                let c = c as i64;
                let (cx, cy, cz) = (c % n, (c / n) % n, c / (n * n));
                for (k, acc) in out.iter_mut().enumerate() {
                    let tk = range.start + k;
                    if !self.is_own(tk) {
                        continue;
                    }
                    hits.clear();
                    self.collect_hits(tk, [cx, cy, cz], cutoff, false, hits);
                    f(acc, hits);
                }
                out
            })
            .collect();
        let mut result = vec![A::default(); self.members.len()];
        for (k, a) in per_cell.into_iter().flatten().enumerate() {
            result[self.members[k] as usize] = a;
        }
        result
    }

    /// The hits of sorted point `tk` in cell `[cx, cy, cz]` (needs at least 5 cells per
    /// axis): the 5 x 5 rows of neighbour cells along x, a row skipped when its y-z distance
    /// exceeds the cutoff, and from the others only the cells the cutoff sphere reaches (one or
    /// two contiguous runs of points, cells being ordered x fastest). With `half`, only the
    /// forward half of the stencil: rows with `(dz, dy) > (0, 0)`, and in the target's own
    /// row the points after it (its own cell included), so each pair is found once.
    fn collect_hits(
        &self,
        tk: usize,
        [cx, cy, cz]: [i64; 3],
        cutoff: f64,
        half: bool,
        hits: &mut Hits,
    ) {
        let c2 = cutoff * cutoff;
        let n = self.n as i64;
        let l = self.l;
        let side = l / self.n as f64;
        let inv_side = 1.0 / side;
        let (xs, ys, zs) = (&self.xs, &self.ys, &self.zs);
        let yt = self.sorted[tk];
        let gt = self.group[tk];
        hits.target = tk;
        for dz in if half { 0..=2 } else { -2..=2 } {
            let uz = cz + dz;
            let gz = gap(yt[2], uz as f64 * side, side);
            if gz >= cutoff {
                continue;
            }
            let (wz, sz) = wrap(uz, n, l);
            for dy in if half && dz == 0 { 0..=2 } else { -2..=2 } {
                let uy = cy + dy;
                let gy = gap(yt[1], uy as f64 * side, side);
                let g2 = gy * gy + gz * gz;
                if g2 >= c2 {
                    continue;
                }
                let own_row = half && dz == 0 && dy == 0;
                let (wy, sy) = wrap(uy, n, l);
                let rx = (c2 - g2).sqrt();
                let lo = if own_row {
                    cx
                } else {
                    floor_i64((yt[0] - rx) * inv_side).max(cx - 2)
                };
                let hi = floor_i64((yt[0] + rx) * inv_side).min(cx + 2);
                let row = (wz * n + wy) * n;
                // The run of cells lo..=hi, cut where it wraps around the box.
                let mut ux = lo;
                while ux <= hi {
                    let (wx, sx) = wrap(ux, n, l);
                    let last = if ux < 0 {
                        hi.min(-1)
                    } else if ux < n {
                        hi.min(n - 1)
                    } else {
                        hi
                    };
                    let mut a = self.start[(row + wx) as usize];
                    if own_row && ux == cx {
                        a = tk + 1;
                    }
                    let b = self.start[(row + wx + last - ux) as usize + 1];
                    let t = [yt[0] - sx, yt[1] - sy, yt[2] - sz];
                    hits.push_run(t, gt, a..b, [xs, ys, zs], &self.group, c2);
                    ux = last + 1;
                }
            }
        }
    }

    /// Symmetric pair sum (at least 5 cells per axis): every pair of points of different
    /// groups within the cutoff once: after `prepare(hits)` for a target's hits,
    /// `pair(hits, h, target, other)` adds hit `h`'s contributions to the target's and the
    /// other point's accumulators (`hits.index[h]` in cell order, `r = y_target - y_other`);
    /// a target's own sum is added with `add` when its hits are done. Results in the points'
    /// own order.
    ///
    /// Each target looks at the forward half of its stencil (see [`Self::collect_hits`]), so
    /// it writes to points up to two cell planes further in z. The z-planes are cut into an
    /// even number of slabs of at least two planes (a function of the cell grid only); the even
    /// slabs run in parallel, then the odd ones, each writing only its own planes and the two
    /// after them (the last slab also the first two planes). Every point then receives its
    /// contributions in an order fixed by the cells, for any thread count.
    pub(crate) fn symmetric<A: Send + Default + Clone>(
        &self,
        cutoff: f64,
        prepare: impl Fn(&mut Hits) + Sync,
        pair: impl Fn(&Hits, usize, &mut A, &mut A) + Sync,
        add: impl Fn(&mut A, &A) + Sync,
    ) -> Vec<A> {
        self.symmetric_with(
            |tk, c3, hits| {
                self.collect_hits(tk, c3, cutoff, true, hits);
                prepare(hits);
            },
            pair,
            add,
        )
    }

    /// [`Self::symmetric`] over the pairs of `list` ([`Self::forward_pairs`], found once):
    /// each target's hits rebuilt from the list (the same separations, bit for bit), then
    /// `prepare` and `pair` as there. The same pairs in the same order: the same sums.
    pub(crate) fn symmetric_listed<A: Send + Default + Clone>(
        &self,
        list: &PairList,
        prepare: impl Fn(&mut Hits) + Sync,
        pair: impl Fn(&Hits, usize, &mut A, &mut A) + Sync,
        add: impl Fn(&mut A, &A) + Sync,
    ) -> Vec<A> {
        self.symmetric_with(
            |tk, _, hits| {
                list.fill(self, tk, hits);
                prepare(hits);
            },
            pair,
            add,
        )
    }

    /// Every target's forward-half hits ([`Self::collect_hits`]): the other point and the
    /// periodic shift between them, 5 bytes a pair. What [`Self::symmetric_listed`] reads
    /// instead of searching the stencil again (the sums of one GMRES solve share the points).
    pub(crate) fn forward_pairs(&self, cutoff: f64) -> PairList {
        let n = self.n;
        let l = self.l;
        let per_cell: Vec<(Vec<usize>, Vec<u32>, Vec<u8>)> = (0..n * n * n)
            .into_par_iter()
            .map_init(Hits::default, |hits, c| {
                let c3 = [(c % n) as i64, ((c / n) % n) as i64, (c / (n * n)) as i64];
                let mut out = (Vec::new(), Vec::new(), Vec::new());
                for tk in self.start[c]..self.start[c + 1] {
                    hits.clear();
                    self.collect_hits(tk, c3, cutoff, true, hits);
                    out.0.push(hits.len);
                    let yt = self.sorted[tk];
                    for h in 0..hits.len {
                        let j = hits.index[h] as usize;
                        let r = [hits.x[h], hits.y[h], hits.z[h]];
                        // r = (y_t - shift) - y_j with shift in {-L, 0, L} per axis.
                        let code = [0, 1, 2].iter().rev().fold(0u8, |acc, &d| {
                            let shift = yt[d] - self.sorted[j][d] - r[d];
                            3 * acc + (1.0 + (shift / l).round()) as u8
                        });
                        out.1.push(hits.index[h]);
                        out.2.push(code);
                    }
                }
                out
            })
            .collect();
        let mut list = PairList {
            start: Vec::with_capacity(self.members.len() + 1),
            index: Vec::new(),
            shift: Vec::new(),
        };
        list.start.push(0);
        for (counts, index, shift) in per_cell {
            for k in counts {
                list.start.push(list.start.last().copied().unwrap_or(0) + k);
            }
            list.index.extend(index);
            list.shift.extend(shift);
        }
        list
    }

    /// The phased traversal of [`Self::symmetric`], each target's hits from `fill`.
    fn symmetric_with<A: Send + Default + Clone>(
        &self,
        fill: impl Fn(usize, [i64; 3], &mut Hits) + Sync,
        pair: impl Fn(&Hits, usize, &mut A, &mut A) + Sync,
        add: impl Fn(&mut A, &A) + Sync,
    ) -> Vec<A> {
        let n = self.n;
        assert!(n >= 5, "the symmetric sum needs at least 5 cells per axis");
        let nn = n * n;
        let plane_start = |z: usize| self.start[z * nn];
        // Slabs at least two cell planes thick: a target writes up to two planes ahead.
        let bounds = phased_writes::bounds(n, 2);
        let mut acc = vec![A::default(); self.members.len()];
        let task = |s: usize, main: &mut [A], main_start: usize, wrap: &mut [A]| {
            let mut hits = Hits::default();
            for z in bounds[s]..bounds[s + 1] {
                for c in z * nn..(z + 1) * nn {
                    let c3 = [(c % n) as i64, ((c / n) % n) as i64, z as i64];
                    for tk in self.start[c]..self.start[c + 1] {
                        hits.clear();
                        fill(tk, c3, &mut hits);
                        let mut own = A::default();
                        let target = self.is_own(tk);
                        for h in 0..hits.len {
                            let j = hits.index[h] as usize;
                            if !target && !self.is_own(j) {
                                continue;
                            }
                            let other = if j >= main_start && j - main_start < main.len() {
                                &mut main[j - main_start]
                            } else {
                                &mut wrap[j]
                            };
                            pair(&hits, h, &mut own, other);
                        }
                        add(&mut main[tk - main_start], &own);
                    }
                }
            }
        };
        phased(&mut acc, &bounds, 2, plane_start, task);
        let mut result = vec![A::default(); self.members.len()];
        for (k, v) in acc.into_iter().enumerate() {
            result[self.members[k] as usize] = v;
        }
        result
    }
}

/// Distance along one axis from `x` to the interval `[lo, lo + side)`.
#[inline]
fn gap(x: f64, lo: f64, side: f64) -> f64 {
    (lo - x).max(x - lo - side).max(0.0)
}

/// Cell coordinate `u` (possibly one box outside) wrapped into `0..n`, and the shift that
/// moves the wrapped cell's points next to the target (subtracted from the target instead).
#[inline]
fn wrap(u: i64, n: i64, l: f64) -> (i64, f64) {
    if u < 0 {
        (u + n, -l)
    } else if u >= n {
        (u - n, l)
    } else {
        (u, 0.0)
    }
}

/// Every target's forward-half pairs ([`PointCells::forward_pairs`]), in cell order: target
/// `t`'s are `start[t]..start[t + 1]`, each the other point (cell order) and the periodic shift
/// between them (`sx + 3 sy + 9 sz`, each in 0..3 for -L, 0, L).
#[derive(Debug)]
pub(crate) struct PairList {
    start: Vec<usize>,
    index: Vec<u32>,
    shift: Vec<u8>,
}

impl PairList {
    #[cfg(test)]
    /// Pairs stored.
    pub(crate) fn len(&self) -> usize {
        self.index.len()
    }

    /// Target `t`'s hits into `hits`, the separations computed as [`Hits::push_run`] does
    /// (the shifted target minus the other point): the same bits.
    fn fill(&self, cells: &PointCells, t: usize, hits: &mut Hits) {
        let run = self.start[t]..self.start[t + 1];
        let l = cells.l;
        let yt = cells.sorted[t];
        hits.clear();
        hits.reserve(run.len());
        for (h, k) in run.clone().enumerate() {
            let j = self.index[k] as usize;
            let code = self.shift[k];
            let sx = (f64::from(code % 3) - 1.0) * l;
            let sy = (f64::from((code / 3) % 3) - 1.0) * l;
            let sz = (f64::from(code / 9) - 1.0) * l;
            let tt = [yt[0] - sx, yt[1] - sy, yt[2] - sz];
            hits.x[h] = tt[0] - cells.xs[j];
            hits.y[h] = tt[1] - cells.ys[j];
            hits.z[h] = tt[2] - cells.zs[j];
            hits.index[h] = j as u32;
        }
        hits.len = run.len();
        hits.target = t;
    }
}

/// The hits of one target: separation vectors and point indices (cell order), `len` of them.
#[derive(Default)]
pub(crate) struct Hits {
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) z: Vec<f64>,
    pub(crate) index: Vec<u32>,
    pub(crate) len: usize,
    /// The target (cell order).
    pub(crate) target: usize,
    /// Scratch for the caller: distances and their inverses.
    pub(crate) dist: Vec<f64>,
    pub(crate) inv: Vec<f64>,
}

impl Hits {
    fn clear(&mut self) {
        self.len = 0;
    }

    fn reserve(&mut self, extra: usize) {
        let need = self.len + extra;
        if self.x.len() < need {
            let size = need.next_power_of_two();
            self.x.resize(size, 0.0);
            self.y.resize(size, 0.0);
            self.z.resize(size, 0.0);
            self.index.resize(size, 0);
        }
    }

    /// Append `(r, k)` if `keep`.
    fn push(&mut self, r: Vec3, k: usize, keep: bool) {
        self.reserve(1);
        self.x[self.len] = r[0];
        self.y[self.len] = r[1];
        self.z[self.len] = r[2];
        self.index[self.len] = k as u32;
        self.len += usize::from(keep);
    }

    /// Append the points `run` of groups other than `gt` within the cutoff of `t` (shifted
    /// target) and not on it (a coincident point has no defined direction; such pairs were
    /// always left out), without branches: every candidate is written at `len`, which
    /// advances only for hits.
    #[inline]
    fn push_run(
        &mut self,
        t: Vec3,
        gt: u32,
        run: std::ops::Range<usize>,
        [xs, ys, zs]: [&[f64]; 3],
        group: &[u32],
        c2: f64,
    ) {
        let n = run.len();
        if n == 0 {
            return;
        }
        self.reserve(n);
        let (px, py, pz) = (&xs[run.clone()], &ys[run.clone()], &zs[run.clone()]);
        let pg = &group[run.clone()];
        // Local windows of the hit arrays: the write position `k <= i < n` is clamped to `n - 1`
        // (a no-op) so the compiler drops the bounds checks.
        let base = self.len;
        let (hx, hy, hz) = (
            &mut self.x[base..base + n],
            &mut self.y[base..base + n],
            &mut self.z[base..base + n],
        );
        let hi = &mut self.index[base..base + n];
        let mut k = 0;
        for i in 0..n {
            let r = [t[0] - px[i], t[1] - py[i], t[2] - pz[i]];
            let r2 = dot(r, r);
            let slot = k.min(n - 1);
            hx[slot] = r[0];
            hy[slot] = r[1];
            hz[slot] = r[2];
            hi[slot] = (run.start + i) as u32;
            k += usize::from((r2 < c2) & (r2 > 0.0) & (pg[i] != gt));
        }
        self.len = base + k;
    }
}
