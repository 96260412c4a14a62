//! Vectors, unit quaternions (docs/MODEL.md §1: `p = q z q*`, `q <- theta(dt Omega) q`), periodic
//! minimum images and the closest points of two segments.

/// 3-vector.
pub type Vec3 = [f64; 3];

/// `a + s b`.
#[inline]
pub fn axpy(a: Vec3, s: f64, b: Vec3) -> Vec3 {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

/// `a - b`.
#[inline]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a . b`.
#[inline]
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a x b`.
#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `s a`.
#[inline]
pub fn scale(s: f64, a: Vec3) -> Vec3 {
    [s * a[0], s * a[1], s * a[2]]
}

/// `|a|`.
#[inline]
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// Unit quaternion `[w, x, y, z]`.
pub type Quat = [f64; 4];

/// Hamilton product `a b`.
#[inline]
pub fn quat_mul(a: Quat, b: Quat) -> Quat {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// The rotation `theta(a) = [cos(|a|/2), sin(|a|/2) a/|a|]` by the rotation vector `a`.
#[inline]
pub fn quat_exp(a: Vec3) -> Quat {
    let t = norm(a);
    if t < 1e-300 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let s = (0.5 * t).sin() / t;
    [(0.5 * t).cos(), s * a[0], s * a[1], s * a[2]]
}

/// `q z q*`: the body axis of a rod with quaternion `q`.
#[inline]
pub fn quat_axis(q: Quat) -> Vec3 {
    let [w, x, y, z] = q;
    [
        2.0 * (x * z + w * y),
        2.0 * (y * z - w * x),
        1.0 - 2.0 * (x * x + y * y),
    ]
}

/// A unit quaternion whose axis is the unit vector `p` (the shortest rotation from z).
pub fn quat_from_axis(p: Vec3) -> Quat {
    let c = p[2];
    if c < -1.0 + 1e-12 {
        return [0.0, 1.0, 0.0, 0.0]; // rotation by pi about x
    }
    // q = [cos(t/2), sin(t/2) (z x p)/|z x p|] with cos t = c; normalised form:
    let w = ((1.0 + c) / 2.0).sqrt();
    let k = 1.0 / (2.0 * w);
    [w, -p[1] * k, p[0] * k, 0.0]
}

/// Minimum-image vector of `d` in a periodic box of side `l`.
///
/// Differences of wrapped coordinates lie in `(-l, l)` and take the first branch; `round`
/// itself would be a libm call on baseline x86-64, so the rare far case rounds by truncation.
#[inline]
pub fn min_image(d: Vec3, l: f64) -> Vec3 {
    let h = 0.5 * l;
    d.map(|c| {
        if c > h {
            if c - l <= h {
                c - l
            } else {
                c - l * ((c / l).abs() + 0.5).trunc_fast().copysign(c)
            }
        } else if c < -h {
            if c + l >= -h {
                c + l
            } else {
                c - l * ((c / l).abs() + 0.5).trunc_fast().copysign(c)
            }
        } else {
            c
        }
    })
}

/// Truncation toward zero without a libm call (exact below 2^63).
trait TruncFast {
    fn trunc_fast(self) -> f64;
}

impl TruncFast for f64 {
    #[inline]
    fn trunc_fast(self) -> f64 {
        self as i64 as f64
    }
}

/// Closest points of two segments `a0 + s u`, `b0 + t v` with `s, t in [-h, h]` (`h` the
/// half length, `u`, `v` unit): returns `(s, t)`. Robust for parallel and nearly parallel
/// segments (then one of the minimisers, the one nearest the middle of the overlap).
pub fn closest_params(a0: Vec3, u: Vec3, b0: Vec3, v: Vec3, h: f64) -> (f64, f64) {
    let r = sub(a0, b0);
    let b = dot(u, v);
    let c = dot(u, r);
    let f = dot(v, r);
    let denom = 1.0 - b * b; // |u|^2 |v|^2 - (u.v)^2 with unit vectors
    let clamp = |x: f64| x.clamp(-h, h);
    let mut s = if denom > 1e-12 {
        clamp((b * f - c) / denom)
    } else {
        // Parallel: b's points project onto a's line at s = -c + t (u.v), t in [-h, h], i.e.
        // onto [-c - h, -c + h]; take the middle of its overlap with [-h, h], or the nearest end.
        let (lo, hi) = ((-c - h).max(-h), (-c + h).min(h));
        if lo <= hi { 0.5 * (lo + hi) } else { clamp(-c) }
    };
    // Given s, the best t; then re-clamp s for that t (standard two-pass clamping).
    let mut t = clamp(b * s + f);
    s = clamp(b * t - c);
    t = clamp(b * s + f);
    (s, t)
}

/// Closest points and distance of two rods' centerlines (centres `xa`, `xb` already in the same
/// periodic image, unit axes `pa`, `pb`, length `len`): `(s, t, distance)`.
pub fn segment_distance(xa: Vec3, pa: Vec3, xb: Vec3, pb: Vec3, len: f64) -> (f64, f64, f64) {
    let (s, t) = closest_params(xa, pa, xb, pb, 0.5 * len);
    let d = sub(axpy(xa, s, pa), axpy(xb, t, pb));
    (s, t, norm(d))
}

/// A position wrapped into `[0, L)` (a coordinate that rounds to `L` becomes 0).
pub(crate) fn wrap_position(y: Vec3, l: f64) -> Vec3 {
    y.map(|c| {
        let f = c - l * (c / l).floor();
        if f >= l { 0.0 } else { f }
    })
}

/// `floor(x)` for `|x| < 2^62` without a call (the baseline x86-64 target has no rounding
/// instruction, and `f64::floor` is a library call there).
#[inline]
pub(crate) fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    i - i64::from(x < i as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(xa: Vec3, pa: Vec3, xb: Vec3, pb: Vec3, len: f64, n: usize) -> f64 {
        let mut best = f64::INFINITY;
        for i in 0..=n {
            let s = -0.5 * len + len * i as f64 / n as f64;
            let a = axpy(xa, s, pa);
            for j in 0..=n {
                let t = -0.5 * len + len * j as f64 / n as f64;
                best = best.min(norm(sub(a, axpy(xb, t, pb))));
            }
        }
        best
    }

    fn unit(v: Vec3) -> Vec3 {
        scale(1.0 / norm(v), v)
    }

    #[test]
    fn segment_distance_matches_dense_sampling() {
        let n = 2000;
        // The sampled minimum overestimates by at most the sampling step (len/n) along each rod.
        let tol = 2.0 / n as f64;
        let cases: Vec<(Vec3, Vec3, Vec3, Vec3)> = vec![
            ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.3, 0.0], [1.0, 0.0, 0.0]), // parallel, side by side
            ([0.0; 3], [1.0, 0.0, 0.0], [0.7, 0.1, 0.0], [1.0, 0.0, 0.0]), // parallel, offset
            ([0.0; 3], [1.0, 0.0, 0.0], [1.5, 0.0, 0.0], [-1.0, 0.0, 0.0]), // collinear end to end
            ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 0.2], [0.0, 1.0, 0.0]), // crossing
            ([0.0; 3], [1.0, 0.0, 0.0], [0.9, 0.6, 0.1], [0.0, 1.0, 0.0]), // T, end near
            (
                [0.0; 3],
                unit([1.0, 1e-9, 0.0]),
                [0.2, 0.1, 0.0],
                [1.0, 0.0, 0.0],
            ), // nearly parallel
            (
                [0.0; 3],
                unit([1.0, 2.0, 3.0]),
                [0.4, -0.3, 0.5],
                unit([-2.0, 1.0, 0.5]),
            ),
            ([0.0; 3], [0.0, 0.0, 1.0], [0.0, 0.0, 0.9], [0.0, 0.0, -1.0]), // overlapping collinear
        ];
        for (k, (xa, pa, xb, pb)) in cases.into_iter().enumerate() {
            let (_, _, d) = segment_distance(xa, pa, xb, pb, 1.0);
            let exact = brute(xa, pa, xb, pb, 1.0, n);
            // Below an angle of 1e-6 the segments are treated as parallel, which can miss the true
            // minimum by at most angle * l / 2 = 5e-7.
            assert!(
                d <= exact + 5e-7 && exact - d <= tol,
                "case {k}: distance {d} vs sampled {exact}"
            );
        }
    }

    #[test]
    fn segment_distance_across_the_periodic_boundary() {
        let l = 5.0;
        let xa = [0.1, 2.5, 2.5];
        let xb = [4.95, 2.7, 2.5]; // its image at -0.05 is close to xa
        let d = min_image(sub(xb, xa), l);
        let (_, _, dist) =
            segment_distance(xa, [0.0, 1.0, 0.0], axpy(xa, 1.0, d), [0.0, 0.0, 1.0], 1.0);
        assert!(
            (dist - 0.15).abs() < 1e-12,
            "distance {dist}, expected 0.15 through the boundary"
        );
    }

    #[test]
    fn min_image_matches_rounding_everywhere() {
        let l = 3.0;
        for k in -4000..=4000 {
            let c = k as f64 * 0.00377 - 0.0001;
            let fast = min_image([c, -c, 0.5 * c], l);
            let slow = [c, -c, 0.5 * c].map(|c| c - l * (c / l).round());
            for d in 0..3 {
                assert!(
                    (fast[d] - slow[d]).abs() < 1e-12,
                    "c = {c}: {fast:?} vs {slow:?}"
                );
            }
        }
    }

    #[test]
    fn quaternion_exponential_rotates_the_axis() {
        let q = quat_from_axis(unit([0.3, -0.4, 0.8]));
        assert!(norm(sub(quat_axis(q), unit([0.3, -0.4, 0.8]))) < 1e-14);
        // A rotation by angle a about an axis perpendicular to p turns p by a.
        let p = quat_axis(q);
        let axis = unit(cross(p, [1.0, 0.0, 0.0]));
        let q2 = quat_mul(quat_exp(scale(0.3, axis)), q);
        let p2 = quat_axis(q2);
        assert!(
            (dot(p, p2) - 0.3f64.cos()).abs() < 1e-14,
            "angle {}",
            dot(p, p2).acos()
        );
        assert!((norm(p2) - 1.0).abs() < 1e-14);
        assert!(
            norm(sub(
                quat_axis(quat_from_axis([0.0, 0.0, -1.0])),
                [0.0, 0.0, -1.0]
            )) < 1e-14
        );
    }
}
