//! Periodic cell lists (MODEL.md §3: neighbour search is O(N), never all pairs).
//!
//! The box is cut into `n^3` cells of side at least the cutoff; a pair can only be closer than
//! the cutoff if its cells are neighbours (27-cell stencil). Each unordered pair is reported once,
//! `(i, j)` with `i < j`, sorted, so the output does not depend on the thread count. Boxes
//! narrower than 3 cells fall back to the all-pairs search (the stencil would repeat cells).

use crate::geometry::{Vec3, dot, min_image, sub};
use rayon::prelude::*;

/// Cell list over particle centres in a periodic cube.
#[derive(Clone, Debug, Default)]
pub struct CellList {
    n: usize,
    box_length: f64,
    /// `start[c]..start[c + 1]` index `members` for cell `c`.
    start: Vec<usize>,
    members: Vec<u32>,
}

impl CellList {
    /// Sort `x` (centres in `[0, L)^3`) into cells of side at least `cutoff`.
    pub fn build(x: &[Vec3], box_length: f64, cutoff: f64) -> Self {
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
    pub fn cells_per_side(&self) -> usize {
        self.n
    }

    /// Every pair `(i, j)`, `i < j`, whose centres are closer than `cutoff` (minimum image),
    /// sorted. `cutoff` must not exceed the cell side used to build the list.
    pub fn pairs(&self, x: &[Vec3], cutoff: f64) -> Vec<(u32, u32)> {
        let l = self.box_length;
        let c2 = cutoff * cutoff;
        let close = |i: usize, j: usize| {
            let d = min_image(sub(x[j], x[i]), l);
            dot(d, d) < c2
        };
        let mut pairs: Vec<(u32, u32)> = if self.n < 3 {
            (0..x.len())
                .into_par_iter()
                .flat_map_iter(|i| {
                    ((i + 1)..x.len())
                        .filter(move |&j| close(i, j))
                        .map(move |j| (i as u32, j as u32))
                })
                .collect()
        } else {
            let n = self.n as i64;
            (0..self.n.pow(3))
                .into_par_iter()
                .flat_map_iter(|c| {
                    let (cx, cy, cz) = (
                        (c % self.n) as i64,
                        ((c / self.n) % self.n) as i64,
                        (c / (self.n * self.n)) as i64,
                    );
                    let mut out = Vec::new();
                    for &i in &self.members[self.start[c]..self.start[c + 1]] {
                        for dz in -1..=1 {
                            for dy in -1..=1 {
                                for dx in -1..=1 {
                                    let nc = (((cz + dz).rem_euclid(n) * n
                                        + (cy + dy).rem_euclid(n))
                                        * n
                                        + (cx + dx).rem_euclid(n))
                                        as usize;
                                    for &j in &self.members[self.start[nc]..self.start[nc + 1]] {
                                        if i < j && close(i as usize, j as usize) {
                                            out.push((i, j));
                                        }
                                    }
                                }
                            }
                        }
                    }
                    out
                })
                .collect()
        };
        pairs.par_sort_unstable();
        pairs
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
