//! The real-space parts of the spectral Ewald sums (docs/MODEL.md §1, the Hasimoto split):
//! every pair within the cutoff from the point cell list, with the error model's weighted
//! strengths accumulated per target.

use crate::ewald::kernels::{
    RealSpaceTable, StressletTable, rpy_fourier_free_apply, rpy_overlap_correction,
    stresslet_from_derivatives,
};
use crate::ewald::params::{ERROR_MODEL_RANGE, EwaldParams};
use crate::ewald::periodic::RpyGeometry;
use crate::ewald::point_cells::{Hits, PairList, PointCells};
use crate::model::geometry::{Vec3, dot, min_image};
use crate::model::units::VISCOSITY;
use rayon::prelude::*;

/// The most real-space pairs per point [`RpyPairCache`] keeps, expected in the cutoff sphere
/// (5 bytes each: at most 1.3 kB per point).
pub(crate) const MAX_CACHED_PAIRS_PER_POINT: f64 = 256.0;

/// The RPY real-space pairs of one preparation ([`PairList`]: the other point and the periodic
/// shift), kept for the sums that follow at the same points (the products of one GMRES solve)
/// instead of searching the cells' stencil again. Built at the preparation's second sum, so
/// that a preparation summed once (the explicit levels) pays nothing, and only where the pairs
/// expected within the cutoff are at most [`MAX_CACHED_PAIRS_PER_POINT`] per point. The sums
/// see the same pairs with the same separations in the same order: bit for bit those without.
#[derive(Debug, Default)]
pub(crate) struct RpyPairCache {
    sums: u32,
    list: Option<(f64, PairList)>,
}

impl RpyPairCache {
    #[cfg(test)]
    /// Pairs held (0 before the second sum or where they would not be kept).
    pub(crate) fn pairs(&self) -> usize {
        self.list.as_ref().map_or(0, |(_, l)| l.len())
    }
}

/// Pairs of distinct points expected within `cutoff` of `points` uniform points in a box of
/// side `l`.
fn expected_pairs(points: usize, cutoff: f64, l: f64) -> f64 {
    let n = points as f64;
    0.5 * n * n * (4.0 / 3.0) * std::f64::consts::PI * cutoff.powi(3) / l.powi(3)
}

/// The real-space part of the RPY sum at every point of `cells` (forces `forces` in the points'
/// order): every neighbour outside the own group plus the overlap correction, and the error
/// model's weighted squared strengths, `[u_0, u_1, u_2, e2]` per point. `cache` holds the
/// preparation's pairs from its second sum on ([`RpyPairCache`]).
pub(crate) fn rpy_real(
    cells: &PointCells,
    cache: &mut RpyPairCache,
    p: &EwaldParams,
    a: f64,
    l: f64,
    forces: &[Vec3],
) -> Vec<[f64; 4]> {
    let xi = p.xi;
    let table = RealSpaceTable::new(p.cutoff, xi, a);
    let sorted_forces = cells.sorted_values(forces);
    let sorted_f2: Vec<f64> = sorted_forces.par_iter().map(|f| dot(*f, *f)).collect();
    let r0 = ERROR_MODEL_RANGE * p.spacing(l);
    let r02 = r0 * r0;
    // Distances first, in a loop of independent iterations (square roots and divisions
    // overlap), then the table: `(A, B / r^2)` per hit.
    let distances = |hits: &mut Hits| {
        let n = hits.len;
        hits.dist.resize(hits.x.len(), 0.0);
        hits.inv.resize(hits.x.len(), 0.0);
        for h in 0..n {
            let r2 = hits.x[h] * hits.x[h] + hits.y[h] * hits.y[h] + hits.z[h] * hits.z[h];
            let rn = r2.sqrt();
            hits.dist[h] = rn;
            hits.inv[h] = 1.0 / rn;
        }
    };
    let kernel = |hits: &Hits, h: usize| {
        let rn = hits.dist[h];
        let (mut ar, mut br2) = table.eval_a_b_r2(rn, hits.inv[h]);
        if rn < 2.0 * a {
            let (ac, bc) = rpy_overlap_correction(rn, a);
            ar += ac;
            br2 += bc / (rn * rn);
        }
        let rn2 = rn * rn;
        (ar, br2, r02 / (r02 + rn2))
    };
    if cells.n < 5 {
        return cells.gather(p.cutoff, |acc: &mut [f64; 4], hits| {
            distances(hits);
            for h in 0..hits.len {
                let (ar, br2, w) = kernel(hits, h);
                let r = [hits.x[h], hits.y[h], hits.z[h]];
                let j = hits.index[h] as usize;
                let f = sorted_forces[j];
                let s = br2 * dot(r, f);
                for d in 0..3 {
                    acc[d] += ar * f[d] + s * r[d];
                }
                acc[3] += w * sorted_f2[j];
            }
        });
    }
    // Per point: velocity and the weighted squared strengths of its neighbours. Both points of
    // a pair get A f + (B / r^2)(r . f) r of the other's force.
    let f = &sorted_forces;
    let pair = |hits: &Hits, h: usize, own: &mut [f64; 4], other: &mut [f64; 4]| {
        let (ar, br2, w) = kernel(hits, h);
        let r = [hits.x[h], hits.y[h], hits.z[h]];
        let (j, t) = (hits.index[h] as usize, hits.target);
        let (fj, ft) = (f[j], f[t]);
        let (sj, st) = (br2 * dot(r, fj), br2 * dot(r, ft));
        for d in 0..3 {
            own[d] += ar * fj[d] + sj * r[d];
            other[d] += ar * ft[d] + st * r[d];
        }
        own[3] += w * sorted_f2[j];
        other[3] += w * sorted_f2[t];
    };
    let add = |a: &mut [f64; 4], b: &[f64; 4]| {
        for d in 0..4 {
            a[d] += b[d];
        }
    };
    cache.sums += 1;
    let points = cells.members.len();
    if cache.sums >= 2
        && cache.list.as_ref().is_none_or(|(c, _)| *c != p.cutoff)
        && expected_pairs(points, p.cutoff, l) <= MAX_CACHED_PAIRS_PER_POINT * points as f64
    {
        cache.list = Some((p.cutoff, cells.forward_pairs(p.cutoff)));
    }
    match &cache.list {
        Some((c, list)) if *c == p.cutoff => cells.symmetric_listed(list, distances, pair, add),
        _ => cells.symmetric(p.cutoff, distances, pair, add),
    }
}

/// The RPY velocities of the first `real.len()` points from their real-space parts `real`
/// ([`rpy_real`]) and Fourier parts `fourier(t)`: the own group's direct Fourier-part terms come
/// out (the point itself included), and the own group enters the error model with the same
/// weights (the `points` and `forces` of the sum, its parameters `p` and `geometry`). Returns
/// the velocities and the error model's weighted strengths.
pub(crate) fn rpy_assemble(
    real: Vec<[f64; 4]>,
    fourier: impl Fn(usize) -> Vec3 + Sync,
    points: &[Vec3],
    forces: &[Vec3],
    p: &EwaldParams,
    geometry: &RpyGeometry,
) -> (Vec<Vec3>, Vec<f64>) {
    let (l, a, g, xi) = (geometry.box_length, geometry.radius, geometry.group, p.xi);
    let r0 = ERROR_MODEL_RANGE * p.spacing(l);
    let r02 = r0 * r0;
    real.into_par_iter()
        .enumerate()
        .map(|(t, acc)| {
            let base = (t / g) * g;
            let uf = fourier(t);
            let mut ut = [acc[0] + uf[0], acc[1] + uf[1], acc[2] + uf[2]];
            let mut e2 = acc[3];
            for j in base..base + g {
                let r = min_image(
                    [
                        points[t][0] - points[j][0],
                        points[t][1] - points[j][1],
                        points[t][2] - points[j][2],
                    ],
                    l,
                );
                let v = rpy_fourier_free_apply(r, forces[j], xi, a);
                for d in 0..3 {
                    ut[d] -= v[d];
                }
                e2 += r02 / (r02 + dot(r, r)) * dot(forces[j], forces[j]);
            }
            (ut.map(|c| c / VISCOSITY), e2)
        })
        .unzip()
}

/// Per point of `cells`: the real-space stresslet velocity, gradient, and the error model's
/// weighted squared strengths of its neighbours (`p`, `sigma` in the points' order).
pub(crate) fn stresslet_real(
    cells: &PointCells,
    prm: &EwaldParams,
    l: f64,
    p: &[Vec3],
    sigma: &[f64],
) -> Vec<(Vec3, [Vec3; 3], f64)> {
    let (ps, ss) = (cells.sorted_values(p), cells.sorted_values(sigma));
    let table = StressletTable::new(prm.cutoff, prm.xi);
    let r0 = ERROR_MODEL_RANGE * prm.spacing(l);
    let r02 = r0 * r0;
    type Acc = (Vec3, [Vec3; 3], f64);
    // The full stencil: a symmetric sum would share the table but not the contractions,
    // which dominate here (measured: no faster).
    cells.gather(prm.cutoff, |acc: &mut Acc, hits| {
        for h in 0..hits.len {
            let j = hits.index[h] as usize;
            let r = [hits.x[h], hits.y[h], hits.z[h]];
            let r2 = dot(r, r);
            let rn = r2.sqrt();
            let dv = table.eval(rn);
            let (du, dg) = stresslet_from_derivatives(r, rn, ps[j], ss[j], &dv);
            for i in 0..3 {
                acc.0[i] += du[i];
                for m in 0..3 {
                    acc.1[i][m] += dg[i][m];
                }
            }
            acc.2 += r02 / (r02 + r2) * ss[j] * ss[j];
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// A GMRES solve's sums at one preparation: the first searches the stencil, the second
    /// keeps the pairs, the third reads them; all three bit for bit the sum without a cache,
    /// and the list holds exactly the pairs of distinct rods within the cutoff (direct count).
    #[test]
    fn kept_pairs_give_the_same_sums_and_every_pair_once() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (l, group, a) = (6.0, 4, 0.05);
        let points: Vec<Vec3> = (0..800)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(-0.5..l + 0.5)))
            .collect();
        let forces: Vec<Vec3> = (0..800)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let p = EwaldParams::choose(1e-4, points.len(), l);
        let cells = PointCells::build(&points, l, p.cutoff, group);
        assert!(
            cells.n >= 5,
            "{} cells per axis: the symmetric sum needs 5",
            cells.n
        );
        let without = rpy_real(&cells, &mut RpyPairCache::default(), &p, a, l, &forces);
        let mut cache = RpyPairCache::default();
        for sum in 1..=3 {
            let got = rpy_real(&cells, &mut cache, &p, a, l, &forces);
            assert!(
                got == without,
                "sum {sum} differs from the sum without kept pairs"
            );
        }
        let mut direct = 0;
        for i in 0..points.len() {
            for j in i + 1..points.len() {
                let r = min_image([0, 1, 2].map(|d| points[i][d] - points[j][d]), l);
                let r2 = dot(r, r);
                direct += usize::from(i / group != j / group && r2 > 0.0 && r2 < p.cutoff.powi(2));
            }
        }
        assert!(direct > 0, "no pairs within the cutoff {}", p.cutoff);
        assert_eq!(cache.pairs(), direct, "pairs kept against the direct count");
    }
}
