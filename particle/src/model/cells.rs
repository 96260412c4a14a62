//! Periodic cell lists (docs/MODEL.md §3: neighbour search is O(N), never all pairs).
//!
//! The box is cut into `n^3` cells of side at least the cutoff; a pair can only be closer than
//! the cutoff if its cells are neighbours (27-cell stencil). Each unordered pair is reported once,
//! `(i, j)` with `i < j`, sorted, so the output does not depend on the thread count. Boxes
//! narrower than 3 cells fall back to the all-pairs search (the stencil would repeat cells).

use crate::model::geometry::{Vec3, dot, min_image, sub};
use rayon::prelude::*;

/// Cell list over particle centres in a periodic cube.
#[derive(Clone, Debug, Default)]
pub(crate) struct CellList {
    n: usize,
    box_length: f64,
    /// `start[c]..start[c + 1]` index `members` for cell `c`.
    start: Vec<usize>,
    members: Vec<u32>,
}

impl CellList {
    /// Sort `x` (centres in `[0, L)^3`) into cells of side at least `cutoff`.
    pub(crate) fn build(x: &[Vec3], box_length: f64, cutoff: f64) -> Self {
        let n = ((box_length / cutoff).floor() as usize).max(1);
        let cell = |p: &Vec3| -> usize {
            let idx = p.map(|c| ((c / box_length * n as f64) as usize).min(n - 1));
            (idx[2] * n + idx[1]) * n + idx[0]
        };
        let keys: Vec<usize> = x.par_iter().map(cell).collect();
        let mut start = vec![0usize; n * n * n + 1];
        for &k in &keys {
            start[k + 1] += 1;
        }
        for c in 0..n * n * n {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut members = vec![0u32; x.len()];
        for (i, &k) in keys.iter().enumerate() {
            members[next[k]] = i as u32;
            next[k] += 1;
        }
        Self {
            n,
            box_length,
            start,
            members,
        }
    }

    /// Cells per dimension.
    #[cfg(test)]
    pub(crate) fn cells_per_side(&self) -> usize {
        self.n
    }

    /// Particle indices in cell order (a spatially coherent ordering).
    pub(crate) fn order(&self) -> &[u32] {
        &self.members
    }

    /// The same cells over particles renumbered in cell order (`order()[k]` becomes `k`).
    pub(crate) fn renumbered(&self) -> Self {
        Self {
            n: self.n,
            box_length: self.box_length,
            start: self.start.clone(),
            members: (0..self.members.len() as u32).collect(),
        }
    }

    /// Every pair `(i, j)`, `i < j`, whose centres are closer than `cutoff` (minimum image),
    /// sorted. `cutoff` must not exceed the cell side used to build the list. (The tests'
    /// comparison with brute force; the step uses [`Self::map_pairs`].)
    #[cfg(test)]
    pub(crate) fn pairs(&self, x: &[Vec3], cutoff: f64) -> Vec<(u32, u32)> {
        let mut pairs = self.map_pairs(x, cutoff, |i, j, _| Some((i.min(j), i.max(j))));
        pairs.par_sort_unstable();
        pairs
    }

    /// `f(i, j, d)` for every unordered pair closer than `cutoff`, with `d` the minimum-image
    /// vector from `i` to `j`, keeping the `Some` results. Each pair is visited once (half
    /// stencil), in an order fixed by the cells, so the output is the same for any thread count.
    pub(crate) fn map_pairs<T: Send>(
        &self,
        x: &[Vec3],
        cutoff: f64,
        f: impl Fn(u32, u32, Vec3) -> Option<T> + Sync + Send,
    ) -> Vec<T> {
        let l = self.box_length;
        let c2 = cutoff * cutoff;
        let visit = |i: u32, j: u32, out: &mut Vec<T>| {
            let d = min_image(sub(x[j as usize], x[i as usize]), l);
            if dot(d, d) < c2
                && let Some(t) = f(i, j, d)
            {
                out.push(t);
            }
        };
        if self.n < 3 {
            return (0..x.len() as u32)
                .into_par_iter()
                .flat_map_iter(|i| {
                    let mut out = Vec::new();
                    for j in i + 1..x.len() as u32 {
                        visit(i, j, &mut out);
                    }
                    out
                })
                .collect();
        }
        let n = self.n as i64;
        // The 13 "forward" neighbour offsets; with the own cell, each pair of cells once.
        let forward: Vec<[i64; 3]> = (-1..=1)
            .flat_map(|dz| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dx| [dx, dy, dz])))
            .filter(|o| o[2] > 0 || (o[2] == 0 && (o[1] > 0 || (o[1] == 0 && o[0] > 0))))
            .collect();
        // With at least 3 cells per side the periodic shift of a neighbour cell is the minimum
        // image of every pair closer than the cutoff, so it is computed once per cell pair.
        let scan = |i: u32, j: u32, shift: Vec3, out: &mut Vec<T>| {
            let (xi, xj) = (x[i as usize], x[j as usize]);
            let d = [
                xj[0] + shift[0] - xi[0],
                xj[1] + shift[1] - xi[1],
                xj[2] + shift[2] - xi[2],
            ];
            if dot(d, d) < c2
                && let Some(t) = f(i, j, d)
            {
                out.push(t);
            }
        };
        (0..self.n.pow(3))
            .into_par_iter()
            .flat_map_iter(|c| {
                let cell = [
                    (c % self.n) as i64,
                    ((c / self.n) % self.n) as i64,
                    (c / (self.n * self.n)) as i64,
                ];
                let own = &self.members[self.start[c]..self.start[c + 1]];
                let mut out = Vec::new();
                for (k, &i) in own.iter().enumerate() {
                    for &j in &own[k + 1..] {
                        scan(i, j, [0.0; 3], &mut out);
                    }
                }
                for o in &forward {
                    let raw = [cell[0] + o[0], cell[1] + o[1], cell[2] + o[2]];
                    let wrapped = raw.map(|v| v.rem_euclid(n));
                    let shift = [0, 1, 2].map(|d| l * ((raw[d] - wrapped[d]) / n) as f64);
                    let nc = ((wrapped[2] * n + wrapped[1]) * n + wrapped[0]) as usize;
                    let other = &self.members[self.start[nc]..self.start[nc + 1]];
                    for &i in own {
                        for &j in other {
                            scan(i, j, shift, &mut out);
                        }
                    }
                }
                out
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn cell_list_pairs_equal_all_pairs() {
        for (n, l, cutoff, seed) in [
            (2000, 10.0, 1.3, 1u64),
            (500, 3.5, 1.2, 2),
            (300, 2.0, 1.3, 3),
            (4000, 13.0, 1.0, 4),
        ] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let x: Vec<Vec3> = (0..n)
                .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
                .collect();
            let cl = CellList::build(&x, l, cutoff);
            let fast = cl.pairs(&x, cutoff);
            let mut slow = Vec::new();
            for i in 0..n {
                for j in i + 1..n {
                    let d = min_image(sub(x[j], x[i]), l);
                    if dot(d, d) < cutoff * cutoff {
                        slow.push((i as u32, j as u32));
                    }
                }
            }
            assert!(!slow.is_empty());
            assert_eq!(
                fast,
                slow,
                "n = {n}, L = {l}, cutoff {cutoff} ({} cells per side)",
                cl.cells_per_side()
            );
        }
    }
}
