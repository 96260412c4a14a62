//! Eigen-decomposition of symmetric 3x3 matrices.
//!
//! [`sym3_eigen_sorted`], the closure's, is closed-form with one exact 2x2 rotation
//! (after Kopp's hybrid method): the eigenvalues by the trigonometric formula; the eigenvector
//! of the most isolated one (the largest or the smallest; its gap to the other two is at least
//! half the spread) as the largest cross product of two rows of `A - lambda I`; the plane
//! orthogonal to it diagonalised by one Jacobi rotation, which is stable for any gap. The
//! frame is orthonormal to round-off by construction. Its error in an eigenvector is of order
//! `eps |A| / gap` with `gap` at least half the spread, and a rotation that small of a nearly
//! isotropic frame changes `R S R^T` only at round-off (the frame's anisotropy is of the same
//! order as the gap), so near-isotropic states need no special case; matrices whose spread is
//! below `1e-9 |A|` (isotropy to nine digits) go to cyclic Jacobi rotations ([`sym3_eigen`]),
//! the slow twin, which is accurate for any multiplicity. About five times faster than Jacobi
//! sweeps to convergence (`benches/step.rs`, BENCHMARKS.md).

/// Symmetric 3x3 matrix.
pub(crate) type Sym3 = [[f64; 3]; 3];

/// Eigenvalues `w` and orthonormal eigenvectors (columns of `r`): `a = r diag(w) r^T`.
pub(crate) fn sym3_eigen(a: &Sym3) -> ([f64; 3], Sym3) {
    let mut m = *a;
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..50 {
        let off = m[0][1].abs() + m[0][2].abs() + m[1][2].abs();
        let scale = m[0][0].abs() + m[1][1].abs() + m[2][2].abs();
        if off <= 1e-300 || off <= f64::EPSILON * 1e-3 * scale {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if m[p][q] == 0.0 {
                continue;
            }
            let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // m <- J^T m J with the rotation in the (p, q) plane.
            for k in 0..3 {
                let (mkp, mkq) = (m[k][p], m[k][q]);
                m[k][p] = c * mkp - s * mkq;
                m[k][q] = s * mkp + c * mkq;
            }
            for k in 0..3 {
                let (mpk, mqk) = (m[p][k], m[q][k]);
                m[p][k] = c * mpk - s * mqk;
                m[q][k] = s * mpk + c * mqk;
            }
            for k in 0..3 {
                let (rkp, rkq) = (r[k][p], r[k][q]);
                r[k][p] = c * rkp - s * rkq;
                r[k][q] = s * rkp + c * rkq;
            }
        }
    }
    ([m[0][0], m[1][1], m[2][2]], r)
}

/// The eigenvalues in descending order and the eigenvectors as the columns of `r`, in the
/// same order: `a = r diag(w) r^T` (closed form, see the module doc). The Bingham closure
/// tables are most accurate per degree with the largest eigenvalue first (their collapsed
/// coordinate `x = mu_1` then stays in `[1/3, 1]`, away from the corner where the exponent's
/// singular edges meet): at degree 20 the worst error of `S:E` over random `Q` is 6.7e-6
/// against 1.3e-5 for an arbitrary order (`closure_field_is_accurate_at_low_degree` in
/// `solver.rs`).
pub(crate) fn sym3_eigen_sorted(a: &Sym3) -> ([f64; 3], Sym3) {
    let c = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let b = [a[0][0] - c, a[1][1] - c, a[2][2] - c];
    let off2 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    let p2 = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2] + 2.0 * off2) / 6.0;
    let scale = a[0][0].abs() + a[1][1].abs() + a[2][2].abs() + off2.sqrt();
    // sqrt(6 p2) is the Frobenius norm of the traceless part: the spread of the eigenvalues.
    // Not positive also catches NaN.
    if p2.is_nan() || p2 <= 0.0 || (6.0 * p2).sqrt() <= 1e-9 * scale {
        let (w, r) = sym3_eigen(a);
        return sorted(w, r);
    }
    let p = p2.sqrt();
    // det(B / p) / 2 = cos(3 phi), B = A - c I.
    let det = b[0] * (b[1] * b[2] - a[1][2] * a[1][2])
        - a[0][1] * (a[0][1] * b[2] - a[1][2] * a[0][2])
        + a[0][2] * (a[0][1] * a[1][2] - b[1] * a[0][2]);
    let r = (det / (2.0 * p * p2)).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let l1 = c + 2.0 * p * phi.cos();
    let l3 = c + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let l2 = 3.0 * c - l1 - l3;
    // The most isolated eigenvalue: its eigenvector is well conditioned.
    let (isolated, largest) = if l1 - l2 >= l2 - l3 {
        (l1, true)
    } else {
        (l3, false)
    };
    let rows = [
        [a[0][0] - isolated, a[0][1], a[0][2]],
        [a[0][1], a[1][1] - isolated, a[1][2]],
        [a[0][2], a[1][2], a[2][2] - isolated],
    ];
    let crosses = [
        cross(rows[0], rows[1]),
        cross(rows[0], rows[2]),
        cross(rows[1], rows[2]),
    ];
    let norms = crosses.map(|v| dot(v, v));
    let k = if norms[0] >= norms[1] && norms[0] >= norms[2] {
        0
    } else if norms[1] >= norms[2] {
        1
    } else {
        2
    };
    if norms[k].is_nan() || norms[k] <= 0.0 {
        let (w, r) = sym3_eigen(a);
        return sorted(w, r);
    }
    let v = scale3(crosses[k], 1.0 / norms[k].sqrt());
    // An orthonormal pair (u, w) spanning the plane orthogonal to v.
    let axis = if v[0].abs() <= v[1].abs() && v[0].abs() <= v[2].abs() {
        [1.0, 0.0, 0.0]
    } else if v[1].abs() <= v[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let u = cross(v, axis);
    let u = scale3(u, 1.0 / dot(u, u).sqrt());
    let w = cross(v, u);
    // The 2x2 block of A in (u, w), diagonalised by one Jacobi rotation.
    let (au, aw) = (mat_vec(a, u), mat_vec(a, w));
    let (muu, mww, muw) = (dot(u, au), dot(w, aw), dot(u, aw));
    let (e1, e2, t1, t2) = if muw == 0.0 {
        (muu, mww, u, w)
    } else {
        let theta = (mww - muu) / (2.0 * muw);
        let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
        let cs = 1.0 / (t * t + 1.0).sqrt();
        let sn = t * cs;
        (
            muu - t * muw,
            mww + t * muw,
            [0, 1, 2].map(|d| cs * u[d] - sn * w[d]),
            [0, 1, 2].map(|d| sn * u[d] + cs * w[d]),
        )
    };
    let lv = dot(v, mat_vec(a, v));
    let (hi, lo) = if e1 >= e2 {
        ((e1, t1), (e2, t2))
    } else {
        ((e2, t2), (e1, t1))
    };
    let cols = if largest {
        [(lv, v), hi, lo]
    } else {
        [hi, lo, (lv, v)]
    };
    // Round-off can reorder eigenvalues that differ by less than it: keep them descending.
    sorted(
        cols.map(|c| c.0),
        std::array::from_fn(|i| cols.map(|c| c.1[i])),
    )
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn scale3(a: [f64; 3], s: f64) -> [f64; 3] {
    a.map(|v| v * s)
}

fn mat_vec(a: &Sym3, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| dot(a[i], v))
}

/// Eigenvalues `w` in descending order, the eigenvector columns of `r` permuted with them.
fn sorted(w: [f64; 3], r: Sym3) -> ([f64; 3], Sym3) {
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| w[j].total_cmp(&w[i]));
    (
        order.map(|k| w[k]),
        std::array::from_fn(|i| order.map(|k| r[i][k])),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn sorted_decomposition_is_descending_and_reconstructs() {
        let a = [[0.2, 0.05, -0.01], [0.05, 0.5, 0.1], [-0.01, 0.1, 0.3]];
        let (w, r) = sym3_eigen_sorted(&a);
        assert!(w[0] >= w[1] && w[1] >= w[2], "not descending: {w:?}");
        for i in 0..3 {
            for j in 0..3 {
                let rec: f64 = (0..3).map(|k| r[i][k] * w[k] * r[j][k]).sum();
                assert!((rec - a[i][j]).abs() < 1e-14, "reconstruction at ({i},{j})");
            }
        }
    }

    fn check(a: Sym3) {
        let (w, r) = sym3_eigen(&a);
        for i in 0..3 {
            for j in 0..3 {
                let rec: f64 = (0..3).map(|k| r[i][k] * w[k] * r[j][k]).sum();
                assert!(
                    (rec - a[i][j]).abs() < 1e-14,
                    "reconstruction of {a:?} off at ({i},{j}): {rec}"
                );
                let orth: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                assert!((orth - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn reconstructs_generic_and_degenerate_matrices() {
        check([[0.5, 0.1, -0.05], [0.1, 0.3, 0.02], [-0.05, 0.02, 0.2]]);
        check([
            [1.0 / 3.0, 0.0, 0.0],
            [0.0, 1.0 / 3.0, 0.0],
            [0.0, 0.0, 1.0 / 3.0],
        ]);
        check([
            [1.0 / 3.0, 1e-9, 0.0],
            [1e-9, 1.0 / 3.0, 1e-12],
            [0.0, 1e-12, 1.0 / 3.0],
        ]);
        check([[0.4, 0.3, 0.0], [0.3, 0.4, 0.0], [0.0, 0.0, 0.2]]);
    }

    /// Reconstruction, orthonormality and descending order of the closed form within
    /// `tol |A|`.
    fn check_sorted(a: Sym3, tol: f64) {
        let (w, r) = sym3_eigen_sorted(&a);
        assert!(
            w[0] >= w[1] && w[1] >= w[2],
            "not descending: {w:?} for {a:?}"
        );
        let size = a.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
        for i in 0..3 {
            for j in 0..3 {
                let rec: f64 = (0..3).map(|k| r[i][k] * w[k] * r[j][k]).sum();
                assert!(
                    (rec - a[i][j]).abs() <= tol * size,
                    "reconstruction of {a:?} off at ({i},{j}) by {:.2e} |A|",
                    (rec - a[i][j]).abs() / size
                );
                let orth: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (orth - want).abs() < 1e-14,
                    "R^T R off by {:.2e}",
                    orth - want
                );
            }
        }
    }

    /// The rotation of the unit quaternion `v / |v|`.
    pub(crate) fn rotation(v: [f64; 4]) -> Sym3 {
        let nv = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let [w, x, y, z] = v.map(|c| c / nv);
        [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ]
    }

    /// The closed form against its slow twin (Jacobi sweeps to convergence) on the matrices the
    /// closure meets, `Q / tr Q` with unit trace: random eigenvalues on the triangle, and
    /// nearly isotropic ones with spreads from 1e-2 down to 1e-12 (the perturbed isotropic
    /// start), with double and nearly double eigenvalues of either sign of the third, in
    /// random frames. Both reconstruct `A` to 3e-14 |A| (Jacobi itself reaches 1.3e-14 on some of
    /// them); their eigenvalues agree to 1e-14.
    #[test]
    fn closed_form_agrees_with_jacobi_on_the_closures_matrices() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut cases = 0;
        for k in 0..20_000 {
            let spread: f64 = match k % 4 {
                0 => 1.0,
                1 => 10f64.powf(rng.random_range(-12.0..-2.0)),
                _ => 10f64.powf(rng.random_range(-9.0..-1.0)),
            };
            let mut mu: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0) * spread);
            if k % 4 == 2 {
                mu[1] = mu[0] * (1.0 + rng.random_range(-1e-6..1e-6)); // nearly double
            }
            if k % 4 == 3 {
                mu[2] = mu[1]; // exactly double
            }
            let m = (mu[0] + mu[1] + mu[2]) / 3.0;
            let mu = mu.map(|v| 1.0 / 3.0 + v - m);
            if spread == 1.0 && mu.iter().any(|&v| v < 0.0) {
                continue;
            }
            let r = rotation(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let a: Sym3 = std::array::from_fn(|i| {
                std::array::from_fn(|j| (0..3).map(|c| r[i][c] * mu[c] * r[j][c]).sum())
            });
            // Exactly symmetric, as the solver's matrices are.
            let a: Sym3 = std::array::from_fn(|i| std::array::from_fn(|j| a[i.min(j)][i.max(j)]));
            check_sorted(a, 3e-14);
            let (w, _) = sym3_eigen_sorted(&a);
            let (wj, rj) = sym3_eigen(&a);
            let (wj, _) = sorted(wj, rj);
            for c in 0..3 {
                assert!(
                    (w[c] - wj[c]).abs() < 1e-14,
                    "eigenvalues {w:?} vs Jacobi {wj:?}"
                );
            }
            cases += 1;
        }
        assert!(cases > 15_000, "{cases} cases");
        // Exactly isotropic, diagonal and zero matrices take the Jacobi path.
        check_sorted(
            [
                [1.0 / 3.0, 0.0, 0.0],
                [0.0, 1.0 / 3.0, 0.0],
                [0.0, 0.0, 1.0 / 3.0],
            ],
            1e-15,
        );
        check_sorted([[0.5, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.3]], 1e-15);
        check_sorted([[0.0; 3]; 3], 1e-15);
    }
}
