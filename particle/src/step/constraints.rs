//! The contact constraints of docs/MODEL.md §3: one per pair of rods whose centerlines are
//! closer than `b + margin`, at their closest points, and the true (nonlinear) overlap of the
//! constrained pairs.

use crate::model::geometry::{Vec3, axpy, min_image, norm, scale, segment_distance, sub};
use crate::model::rods::RodSet;
use crate::model::units::ROD_LENGTH;
use crate::step::contact::Constraint;
use rayon::prelude::*;

/// Largest true overlap `b - dist` over the pairs of `cons` (internal indices mapped through
/// `order` to `rods`, axes `p`), and its pair numbered by `gid` (ties: the smallest pair).
pub(crate) fn true_overlap(
    rods: &RodSet,
    p: &[Vec3],
    cons: &[Constraint],
    order: &[u32],
    gid: &(impl Fn(usize) -> u32 + Sync),
) -> (f64, (u32, u32)) {
    cons.par_iter()
        .map(|c| {
            let (i, j) = (order[c.i as usize] as usize, order[c.j as usize] as usize);
            let d = min_image(sub(rods.x[j], rods.x[i]), rods.box_length);
            let (_, _, dist) =
                segment_distance(rods.x[i], p[i], axpy(rods.x[i], 1.0, d), p[j], ROD_LENGTH);
            let (gi, gj) = (gid(i), gid(j));
            (rods.diameter - dist, (gi.min(gj), gi.max(gj)))
        })
        .reduce(
            || (0.0, (0, 0)),
            |a, b| {
                if b.0 > a.0 || (b.0 == a.0 && b.1 < a.1) {
                    b
                } else {
                    a
                }
            },
        )
}

/// The constraint between rods `i` and `j` of diameter `b` (centres `x`, axes `p`; `d`:
/// minimum-image vector from `x_i` to `x_j`), if their centerlines are closer than
/// `b + margin`.
pub fn constraint(
    x: &[Vec3],
    p: &[Vec3],
    i: u32,
    j: u32,
    d: Vec3,
    diameter: f64,
    margin: f64,
) -> Option<Constraint> {
    let (iu, ju) = (i as usize, j as usize);
    let xj = axpy(x[iu], 1.0, d);
    let (s, t, dist) = segment_distance(x[iu], p[iu], xj, p[ju], ROD_LENGTH);
    let phi = dist - diameter;
    if phi >= margin {
        return None;
    }
    let ri = scale(s, p[iu]);
    let rj = scale(t, p[ju]);
    let sep = sub(axpy(x[iu], 1.0, ri), axpy(xj, 1.0, rj));
    // Touching centerlines (dist = 0) have no direction: push along the centres' line.
    let n = if dist > 1e-12 {
        scale(1.0 / dist, sep)
    } else {
        scale(-1.0 / norm(d).max(1e-300), d)
    };
    Some(Constraint {
        i,
        j,
        ri,
        rj,
        n,
        phi,
    })
}

/// Constraints for the given pairs (slow path for tests and small problems).
pub fn constraints(
    rods: &RodSet,
    p: &[Vec3],
    pairs: &[(u32, u32)],
    margin: f64,
) -> Vec<Constraint> {
    pairs
        .iter()
        .filter_map(|&(i, j)| {
            let d = min_image(sub(rods.x[j as usize], rods.x[i as usize]), rods.box_length);
            constraint(&rods.x, p, i, j, d, rods.diameter, margin)
        })
        .collect()
}
