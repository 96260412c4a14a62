//! Initial configurations: uniform random centres and isotropic (or perturbed, docs/MODEL.md §5)
//! orientations without overlaps, by random sequential addition (each new rod is kept only if
//! its centerline stays at least `b` from every other), with a cell grid so each trial costs
//! O(1).

use crate::geometry::{Vec3, axpy, min_image, quat_from_axis, segment_distance, sub};
use crate::rods::RodSet;
use crate::units::{DIAMETER, ROD_LENGTH};
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
    #[error("box side L/l = {0} is too small: it must exceed l + b = 1.2 rod lengths")]
    BoxTooSmall(f64),
}

/// A unit vector uniform on the sphere.
pub fn isotropic_orientation<R: Rng>(rng: &mut R) -> Vec3 {
    let z: f64 = rng.random_range(-1.0..1.0);
    let phi: f64 = rng.random_range(0.0..2.0 * PI);
    let s = (1.0 - z * z).sqrt();
    [s * phi.cos(), s * phi.sin(), z]
}

/// `n` rods at uniform random positions with isotropic orientations and no overlap, by random
/// sequential addition; fails after `max_trials` consecutive rejected trials for one rod.
pub fn random_nonoverlapping(
    n: usize,
    box_length: f64,
    seed: u64,
    max_trials: usize,
) -> Result<RodSet, InitError> {
    nonoverlapping_with(n, box_length, seed, max_trials, |_, rng| {
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
    seed: u64,
    max_trials: usize,
    mut orientation: impl FnMut(&Vec3, &mut ChaCha8Rng) -> Vec3,
) -> Result<RodSet, InitError> {
    let reach = ROD_LENGTH + DIAMETER;
    if box_length <= reach {
        return Err(InitError::BoxTooSmall(box_length));
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
                            if dist < DIAMETER {
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
        q: ps.iter().map(|p| quat_from_axis(*p)).collect(),
        image: vec![[0; 3]; n],
        x: xs,
    })
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
}
