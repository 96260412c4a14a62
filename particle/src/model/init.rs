//! Initial configurations: uniform random centres and isotropic (or perturbed, docs/MODEL.md §5)
//! orientations without overlaps, by random sequential addition (each new rod is kept only if
//! its centerline stays at least `b` from every other), with a cell grid so each trial costs
//! O(1).

use crate::model::cells::CellList;
use crate::model::geometry::{Vec3, axpy, min_image, quat_from_axis, segment_distance, sub};
use crate::model::rods::RodSet;
use crate::model::units::ROD_LENGTH;
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Why an initial configuration could not be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InitError {
    /// Random sequential addition stalled.
    #[error(
        "could not place rod {placed} of {requested} without overlap after {attempts} trials (box L/l = {box_length}): the volume fraction is beyond what random sequential addition reaches; lower it or start from a relaxed configuration"
    )]
    TooDense {
        /// Rods placed.
        placed: usize,
        /// Rods requested.
        requested: usize,
        /// Consecutive failed trials.
        attempts: usize,
        /// Box side.
        box_length: f64,
    },
    /// Box smaller than a rod plus its diameter.
    #[error("box side L/l = {box_length} is too small: it must exceed l + b = {reach} rod lengths")]
    BoxTooSmall {
        /// Box side.
        box_length: f64,
        /// `l + b`.
        reach: f64,
    },
}

/// A unit vector uniform on the sphere.
pub fn isotropic_orientation<R: Rng>(rng: &mut R) -> Vec3 {
    let z: f64 = rng.random_range(-1.0..1.0);
    let phi: f64 = rng.random_range(0.0..2.0 * PI);
    let s = (1.0 - z * z).sqrt();
    [s * phi.cos(), s * phi.sin(), z]
}

/// `n` rods of diameter `diameter` at uniform random positions with isotropic orientations and
/// no overlap, by random sequential addition; fails after `max_trials` consecutive rejected
/// trials for one rod.
pub fn random_nonoverlapping(
    n: usize,
    box_length: f64,
    diameter: f64,
    seed: u64,
    max_trials: usize,
) -> Result<RodSet, InitError> {
    nonoverlapping_with(n, box_length, diameter, seed, max_trials, |_, rng| {
        isotropic_orientation(rng)
    })
}

/// A unit vector from `Psi(p) = (1 + (15/2) Q' : pp) / 4 pi` (traceless `Q'`, components
/// `xx, xy, xz, yy, yz, zz`), the orientation distribution whose second moment is
/// `I/3 + Q'` (because `int pppp dp / 4 pi = (d d + d d + d d) / 15`), by rejection from the
/// isotropic one. Needs `|Q'|_F < 2/15` so that `Psi > 0`.
pub fn perturbed_orientation<R: Rng>(q: &[f64; 6], rng: &mut R) -> Vec3 {
    let [xx, xy, xz, yy, yz, zz] = *q;
    let frob = (xx * xx + yy * yy + zz * zz + 2.0 * (xy * xy + xz * xz + yz * yz)).sqrt();
    let bound = 1.0 + 7.5 * frob;
    loop {
        let p = isotropic_orientation(rng);
        let qpp = xx * p[0] * p[0]
            + yy * p[1] * p[1]
            + zz * p[2] * p[2]
            + 2.0 * (xy * p[0] * p[1] + xz * p[0] * p[2] + yz * p[1] * p[2]);
        let u: f64 = rng.random_range(0.0..bound);
        if u < 1.0 + 7.5 * qpp {
            return p;
        }
    }
}

/// [`random_nonoverlapping`] with orientations drawn by `orientation(x, rng)` for a rod at
/// centre `x` (called once per trial, after its centre is drawn).
pub fn nonoverlapping_with(
    n: usize,
    box_length: f64,
    diameter: f64,
    seed: u64,
    max_trials: usize,
    mut orientation: impl FnMut(&Vec3, &mut ChaCha8Rng) -> Vec3,
) -> Result<RodSet, InitError> {
    let reach = ROD_LENGTH + diameter;
    if box_length <= reach {
        return Err(InitError::BoxTooSmall { box_length, reach });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nc = ((box_length / reach).floor() as usize).max(1);
    let cell_of = |x: &Vec3| x.map(|c| ((c / box_length * nc as f64) as usize).min(nc - 1));
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); nc * nc * nc];
    let mut xs: Vec<Vec3> = Vec::with_capacity(n);
    let mut ps: Vec<Vec3> = Vec::with_capacity(n);
    let stencil: Vec<i64> = if nc >= 3 {
        vec![-1, 0, 1]
    } else {
        (0..nc as i64).collect()
    };
    while xs.len() < n {
        let mut trials = 0;
        loop {
            let x: Vec3 = [0, 1, 2].map(|_| rng.random_range(0.0..box_length));
            let p = orientation(&x, &mut rng);
            let c = cell_of(&x);
            let mut ok = true;
            'search: for &dz in &stencil {
                for &dy in &stencil {
                    for &dx in &stencil {
                        let cc = if nc >= 3 {
                            [c[0] as i64 + dx, c[1] as i64 + dy, c[2] as i64 + dz]
                                .map(|v| v.rem_euclid(nc as i64) as usize)
                        } else {
                            [dx as usize, dy as usize, dz as usize]
                        };
                        for &j in &grid[(cc[2] * nc + cc[1]) * nc + cc[0]] {
                            let j = j as usize;
                            let d = min_image(sub(xs[j], x), box_length);
                            if d.iter().map(|v| v * v).sum::<f64>() >= reach * reach {
                                continue;
                            }
                            let (_, _, dist) =
                                segment_distance(x, p, axpy(x, 1.0, d), ps[j], ROD_LENGTH);
                            if dist < diameter {
                                ok = false;
                                break 'search;
                            }
                        }
                    }
                }
            }
            if ok {
                grid[(c[2] * nc + c[1]) * nc + c[0]].push(xs.len() as u32);
                xs.push(x);
                ps.push(p);
                break;
            }
            trials += 1;
            if trials >= max_trials {
                return Err(InitError::TooDense {
                    placed: xs.len(),
                    requested: n,
                    attempts: trials,
                    box_length,
                });
            }
        }
    }
    Ok(RodSet {
        box_length,
        diameter,
        q: ps.iter().map(|p| quat_from_axis(*p)).collect(),
        image: vec![[0; 3]; n],
        x: xs,
    })
}

/// Pairs of `rods` whose centerlines are closer than `b - tolerance` (they overlap by more than
/// `tolerance`): `(i, j, distance)` with `i < j`, sorted by pair. A configuration a run may
/// start from has none (its contact solver leaves overlaps up to its own residual).
pub fn overlapping_pairs(rods: &RodSet, tolerance: f64) -> Vec<(u32, u32, f64)> {
    let reach = ROD_LENGTH + rods.diameter;
    let cells = CellList::build(&rods.x, rods.box_length, reach);
    let p = rods.orientations();
    let mut bad = cells.map_pairs(&rods.x, reach, |i, j, d| {
        let (iu, ju) = (i as usize, j as usize);
        let (_, _, dist) = segment_distance(
            rods.x[iu],
            p[iu],
            axpy(rods.x[iu], 1.0, d),
            p[ju],
            ROD_LENGTH,
        );
        (dist < rods.diameter - tolerance).then_some((i.min(j), i.max(j), dist))
    });
    bad.sort_by_key(|b| (b.0, b.1));
    bad
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sampled orientations have the second moment `I/3 + Q'`: the mean of `pp` over many
    /// draws within its statistical error (5 standard errors).
    #[test]
    fn perturbed_orientations_have_the_prescribed_second_moment() {
        let q = [0.06, 0.03, -0.02, -0.04, 0.05, -0.02];
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let n = 200_000;
        let mut m = [0.0f64; 6];
        let idx = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        for _ in 0..n {
            let p = perturbed_orientation(&q, &mut rng);
            for (c, &(i, j)) in idx.iter().enumerate() {
                m[c] += p[i] * p[j];
            }
        }
        for (c, &(i, j)) in idx.iter().enumerate() {
            let mean = m[c] / n as f64;
            let expected = q[c] + if i == j { 1.0 / 3.0 } else { 0.0 };
            // Var(p_i p_j) <= 1/5 under the near-isotropic distribution.
            let se = (0.2 / n as f64).sqrt();
            assert!(
                (mean - expected).abs() < 5.0 * se,
                "<p{i} p{j}> = {mean}, expected {expected} (5 se = {:e})",
                5.0 * se
            );
        }
    }

    /// The overlap test uses the rods' own diameter: two parallel rods 0.15 l apart overlap
    /// as rods of diameter l/5 and do not as rods of diameter l/10; random sequential addition
    /// with either diameter leaves no overlap of its own kind, and thinner rods pack closer.
    #[test]
    fn overlaps_and_placement_follow_the_rods_diameter() {
        let pair = |b: f64| RodSet {
            box_length: 5.0,
            diameter: b,
            x: vec![[1.0, 1.0, 1.0], [1.0, 1.15, 1.0]],
            q: vec![quat_from_axis([1.0, 0.0, 0.0]); 2],
            image: vec![[0; 3]; 2],
        };
        let thick = overlapping_pairs(&pair(0.2), 0.0);
        assert_eq!(thick.len(), 1, "b = 0.2 at distance 0.15: {thick:?}");
        assert!((thick[0].2 - 0.15).abs() < 1e-12, "{thick:?}");
        assert!(
            overlapping_pairs(&pair(0.2), 0.06).is_empty(),
            "0.05 < 0.06 tolerated"
        );
        assert!(
            overlapping_pairs(&pair(0.1), 0.0).is_empty(),
            "b = 0.1 at 0.15 is apart"
        );
        // The closest centerlines among pairs nearer than 0.3 l.
        let closest = |r: &RodSet| {
            let mut probe = r.clone();
            probe.diameter = 0.3;
            overlapping_pairs(&probe, 0.0)
                .iter()
                .map(|o| o.2)
                .fold(f64::INFINITY, f64::min)
        };
        let mut gaps = Vec::new();
        for b in [0.05, 0.2] {
            let r = random_nonoverlapping(1500, 7.0, b, 3, 100_000).unwrap();
            assert_eq!(r.diameter, b);
            assert!(overlapping_pairs(&r, 0.0).is_empty(), "b = {b}");
            let gap = closest(&r);
            assert!(gap >= b, "b = {b}: closest centerlines {gap}");
            gaps.push(gap);
        }
        assert!(
            gaps[0] < 0.2,
            "thin rods (b = 0.05) come closer than 0.2 l: {gaps:?}"
        );
        let err = random_nonoverlapping(10, 1.1, 0.2, 3, 10).unwrap_err();
        assert!(err.to_string().contains("l + b = 1.2"), "{err}");
    }
}
