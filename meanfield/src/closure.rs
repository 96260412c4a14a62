//! The fast Bingham closure of docs/MODEL.md §4: in the eigenframe of `Q = R diag(mu) R^T` the
//! fourth moment `S` has only `S_iijj` components (and their index permutations), smooth
//! functions of two eigenvalues, tabulated once as 2D Chebyshev interpolants.
//!
//! Table domain: the admissible triangle `mu_i >= 0`, `sum mu = 1`, through the collapsed
//! coordinates `mu_1 = x`, `mu_2 = (1 - x) y`, `(x, y)` in `[0, 1]^2` (a polynomial map, so the
//! tabulated functions stay smooth; no division by zero at isotropy). The tables accept the
//! eigenvalues in any order, but are most accurate per degree with the largest first
//! (`eigen::sym3_eigen_sorted`, which the closure field uses). Three functions are tabulated, `S_1111`, `S_2222`, `S_1122`; the others follow
//! from `sum_j S_iijj = mu_i`. Nodes are Chebyshev points of the first kind, interior to the
//! triangle, so the exponent `B`, which diverges on the edges, is only ever solved inside.

use crate::bingham::{BinghamError, moments, solve_exponent};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Table degree at which the closure is exact to about 1e-10 (the source paper's numerics;
/// the accuracy tests of this module run at it).
pub const PAPER_DEGREE: usize = 80;

/// Default polynomial degree per direction, from an error budget: the closure's error should
/// stay an order of magnitude below the time discretisation's at the default step. At degree
/// 20 the worst error of `S:E` over random `Q` is 6.7e-6 of `|E|` (RMS 1.1e-6; the test
/// `closure_field_is_accurate_at_low_degree`), and on the demo's run the velocity-norm history
/// moves by 1.8e-6 against degree 80 (`motile study closure_degree`), 30 times less than the
/// SBDF2 error at `dt_max = 0.05` (5.5e-5). Each table costs `2 (d+1) 3 (d+1)` flops per
/// point: 16 times fewer than at degree 80, which made the table product 60% of a step.
pub const DEFAULT_DEGREE: usize = 20;

/// Tabulated Bingham closure.
#[derive(Clone, Debug)]
pub struct BinghamClosure {
    degree: usize,
    /// The four coefficient tables transposed side by side, `(d + 1) x 4 (d + 1)`: row `j`,
    /// column `f (d + 1) + i` holds `c_f[i][j]`, so a block of `T(y)` rows times this matrix gives
    /// every `sum_j c_f[i][j] T_j(y)` at once (one matrix product for many points).
    stacked: ndarray::Array2<f64>,
    /// Chebyshev coefficients `c[f][i * (d + 1) + j]` of function `f`: S_1111, S_2222, S_1122,
    /// and the entropy density `sum_i b_i mu_i - ln Z`.
    coef: [Vec<f64>; 4],
}

/// Reusable buffers of [`BinghamClosure::evaluate_batch_into`].
#[derive(Debug, Default)]
pub struct BatchScratch {
    tx: ndarray::Array2<f64>,
    ty: ndarray::Array2<f64>,
    w: ndarray::Array2<f64>,
}

/// The eigenframe fourth moments `S_iijj` of one point (symmetric 3x3).
pub type EigenFourth = [[f64; 3]; 3];

/// Collapsed coordinates `(x, y)` of eigenvalues `mu` (clamped into the unit square).
fn collapsed(mu: [f64; 3]) -> (f64, f64) {
    let x = mu[0].clamp(0.0, 1.0);
    let y = if x < 1.0 {
        (mu[1] / (1.0 - x)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    (x, y)
}

/// `T_k(2t - 1)` for `k = 0..out.len()`, written in place (no allocation: this runs for every
/// grid point).
fn chebyshev_into(t: f64, out: &mut [f64]) {
    let s = 2.0 * t - 1.0;
    let (mut a, mut b) = (1.0, s);
    for (k, o) in out.iter_mut().enumerate() {
        *o = if k == 0 { 1.0 } else { b };
        if k > 0 {
            let c = 2.0 * s * b - a;
            a = b;
            b = c;
        }
    }
}

/// `(1/2) sum_i ln mu_i`: the entropy density diverges like `-(1/2) ln mu_i` as an eigenvalue
/// vanishes, so the table holds the regular part `h + (1/2) sum ln mu_i`.
fn log_singularity(mu: [f64; 3]) -> f64 {
    0.5 * mu.iter().map(|m| m.max(1e-300).ln()).sum::<f64>()
}

/// Exact entropy density `int psi ln(4 pi psi) dp = sum_i b_i mu_i - ln Z` of the Bingham
/// distribution with second-moment eigenvalues `mu` (slow: Newton plus quadrature).
pub fn exact_entropy(mu: [f64; 3]) -> Result<f64, BinghamError> {
    if mu.iter().all(|&m| (m - 1.0 / 3.0).abs() < 1e-15) {
        return Ok(0.0);
    }
    let b = solve_exponent(mu)?;
    let m = moments(b);
    Ok(b.iter().zip(&mu).map(|(b, m)| b * m).sum::<f64>() - m.log_z)
}

/// Exact eigenframe fourth moments for eigenvalues `mu` (slow: Newton plus quadrature).
pub fn exact_fourth(mu: [f64; 3]) -> Result<EigenFourth, BinghamError> {
    if mu.iter().all(|&m| (m - 1.0 / 3.0).abs() < 1e-15) {
        return Ok(moments([0.0; 3]).fourth);
    }
    Ok(moments(solve_exponent(mu)?).fourth)
}

impl BinghamClosure {
    /// Build the tables at the given degree (about a second per 40^2 nodes per core).
    pub fn new(degree: usize) -> Result<Self, BinghamError> {
        let n = degree + 1;
        let nodes: Vec<f64> = (0..n)
            .map(|k| (PI * (k as f64 + 0.5) / n as f64).cos())
            .collect();
        let to_unit = |t: f64| 0.5 * (t + 1.0);
        // Function values on the tensor grid.
        let values: Vec<[f64; 4]> = (0..n * n)
            .into_par_iter()
            .map(|idx| {
                let (x, y) = (to_unit(nodes[idx / n]), to_unit(nodes[idx % n]));
                let mu = [x, (1.0 - x) * y, (1.0 - x) * (1.0 - y)];
                let iso = mu.iter().all(|&m| (m - 1.0 / 3.0).abs() < 1e-15);
                let b = if iso {
                    Ok([0.0; 3])
                } else {
                    solve_exponent(mu)
                };
                b.map(|b| {
                    let m = moments(b);
                    let h = b.iter().zip(&mu).map(|(b, m)| b * m).sum::<f64>() - m.log_z;
                    [
                        m.fourth[0][0],
                        m.fourth[1][1],
                        m.fourth[0][1],
                        h + log_singularity(mu),
                    ]
                })
            })
            .collect::<Result<_, _>>()?;
        // 2D discrete Chebyshev transform (separable).
        let tmat: Vec<f64> = (0..n)
            .flat_map(|i| (0..n).map(move |k| (PI * i as f64 * (k as f64 + 0.5) / n as f64).cos()))
            .collect();
        let scale = |i: usize| {
            if i == 0 {
                1.0 / n as f64
            } else {
                2.0 / n as f64
            }
        };
        let coef = [0, 1, 2, 3].map(|f| {
            // First along y: tmp[k][j] = sum_l v[k][l] T_j(y_l).
            let mut tmp = vec![0.0; n * n];
            for k in 0..n {
                for j in 0..n {
                    tmp[k * n + j] = scale(j)
                        * (0..n)
                            .map(|l| values[k * n + l][f] * tmat[j * n + l])
                            .sum::<f64>();
                }
            }
            let mut c = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    c[i * n + j] = scale(i)
                        * (0..n)
                            .map(|k| tmp[k * n + j] * tmat[i * n + k])
                            .sum::<f64>();
                }
            }
            c
        });
        Ok(Self::from_coefficients(degree, coef))
    }

    fn from_coefficients(degree: usize, coef: [Vec<f64>; 4]) -> Self {
        let n = degree + 1;
        let stacked = ndarray::Array2::from_shape_fn((n, 4 * n), |(j, col)| {
            let (f, i) = (col / n, col % n);
            coef[f][i * n + j]
        });
        Self {
            degree,
            stacked,
            coef,
        }
    }

    /// Eigenframe fourth moments (and, if asked, entropy densities) for many eigenvalue
    /// triples at once: the same values as [`Self::fourth`] and [`Self::entropy`] up to
    /// round-off, evaluated as one matrix product per block of points.
    pub fn evaluate_batch(
        &self,
        mus: &[[f64; 3]],
        with_entropy: bool,
    ) -> (Vec<EigenFourth>, Vec<f64>) {
        let mut scratch = BatchScratch::default();
        let mut fourth = Vec::new();
        let mut entropy = Vec::new();
        self.evaluate_batch_into(mus, with_entropy, &mut scratch, &mut fourth, &mut entropy);
        (fourth, entropy)
    }

    /// [`Self::evaluate_batch`] into caller-owned buffers, reusing `scratch` (allocation-free
    /// once the scratch has grown to the block size).
    pub fn evaluate_batch_into(
        &self,
        mus: &[[f64; 3]],
        with_entropy: bool,
        scratch: &mut BatchScratch,
        fourth: &mut Vec<EigenFourth>,
        entropy: &mut Vec<f64>,
    ) {
        let n = self.degree + 1;
        let p = mus.len();
        let tables = if with_entropy { 4 } else { 3 };
        if scratch.tx.dim() != (p, n) {
            scratch.tx = ndarray::Array2::zeros((p, n));
            scratch.ty = ndarray::Array2::zeros((p, n));
        }
        if scratch.w.dim() != (p, tables * n) {
            scratch.w = ndarray::Array2::zeros((p, tables * n));
        }
        for (k, mu) in mus.iter().enumerate() {
            let (x, y) = collapsed(*mu);
            chebyshev_into(
                x,
                scratch
                    .tx
                    .row_mut(k)
                    .as_slice_mut()
                    .expect("row-major scratch"),
            );
            chebyshev_into(
                y,
                scratch
                    .ty
                    .row_mut(k)
                    .as_slice_mut()
                    .expect("row-major scratch"),
            );
        }
        ndarray::linalg::general_mat_mul(
            1.0,
            &scratch.ty,
            &self.stacked.slice(ndarray::s![.., ..tables * n]),
            0.0,
            &mut scratch.w,
        );
        fourth.clear();
        entropy.clear();
        for (k, mu) in mus.iter().enumerate() {
            let row = scratch.w.row(k);
            let txk = scratch.tx.row(k);
            let f: [f64; 4] = std::array::from_fn(|t| {
                if t < tables {
                    (0..n).map(|i| txk[i] * row[t * n + i]).sum()
                } else {
                    0.0
                }
            });
            fourth.push(Self::assemble(*mu, [f[0], f[1], f[2]]));
            if with_entropy {
                entropy.push(f[3] - log_singularity(*mu));
            }
        }
    }

    /// The full `S_iijj` from the three tabulated ones and `sum_j S_iijj = mu_i`.
    fn assemble(mu: [f64; 3], f: [f64; 3]) -> EigenFourth {
        let [s11, s22, s12] = f;
        let s13 = mu[0] - s11 - s12;
        let s23 = mu[1] - s22 - s12;
        let s33 = mu[2] - s13 - s23;
        [[s11, s12, s13], [s12, s22, s23], [s13, s23, s33]]
    }

    /// The Chebyshev coefficients of the tables `S_1111`, `S_2222`, `S_1122` and the entropy's
    /// regular part, each `(d+1)^2` with index `i (d+1) + j` (`i` the degree in the collapsed
    /// coordinate `x`, `j` in `y`).
    #[cfg(feature = "gpu")]
    pub(crate) fn coefficients(&self) -> &[Vec<f64>; 4] {
        &self.coef
    }

    /// Polynomial degree per direction.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// The tables as bytes (degree, then the coefficients, little-endian), for a cache file.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = (self.degree as u64).to_le_bytes().to_vec();
        for c in &self.coef {
            for v in c {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        b
    }

    /// Tables from [`Self::to_bytes`]; `None` if the bytes are not tables of that degree.
    pub fn from_bytes(bytes: &[u8], degree: usize) -> Option<Self> {
        let n = (degree + 1) * (degree + 1);
        if bytes.len() != 8 + 4 * n * 8
            || u64::from_le_bytes(bytes[..8].try_into().ok()?) != degree as u64
        {
            return None;
        }
        let vals: Vec<f64> = bytes[8..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        if !vals.iter().all(|v| v.is_finite()) {
            return None;
        }
        let coef = [0, 1, 2, 3].map(|f| vals[f * n..(f + 1) * n].to_vec());
        Some(Self::from_coefficients(degree, coef))
    }

    /// Entropy density `int psi ln(4 pi psi) dp` of the Bingham distribution with eigenvalues
    /// `mu` (clamped into the triangle; it diverges logarithmically at the edges, where the table
    /// is least accurate).
    pub fn entropy(&self, mu: [f64; 3]) -> f64 {
        let (tx, ty) = self.basis(mu);
        Self::sum(&self.coef[3], &tx, &ty) - log_singularity(mu)
    }

    fn basis(&self, mu: [f64; 3]) -> (Vec<f64>, Vec<f64>) {
        let n = self.degree + 1;
        let (mut tx, mut ty) = (vec![0.0; n], vec![0.0; n]);
        let (x, y) = collapsed(mu);
        chebyshev_into(x, &mut tx);
        chebyshev_into(y, &mut ty);
        (tx, ty)
    }

    fn sum(c: &[f64], tx: &[f64], ty: &[f64]) -> f64 {
        let n = tx.len();
        let mut acc = 0.0;
        for i in 0..n {
            let inner: f64 = c[i * n..(i + 1) * n]
                .iter()
                .zip(ty)
                .map(|(a, b)| a * b)
                .sum();
            acc += tx[i] * inner;
        }
        acc
    }

    /// Eigenframe fourth moments `S_iijj` for eigenvalues `mu` (any order, summing to 1;
    /// clamped into the triangle).
    pub fn fourth(&self, mu: [f64; 3]) -> EigenFourth {
        let (tx, ty) = self.basis(mu);
        let f: [f64; 3] = std::array::from_fn(|k| Self::sum(&self.coef[k], &tx, &ty));
        Self::assemble(mu, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::sync::OnceLock;

    fn table() -> &'static BinghamClosure {
        static T: OnceLock<BinghamClosure> = OnceLock::new();
        T.get_or_init(|| BinghamClosure::new(PAPER_DEGREE).expect("closure tables"))
    }

    #[test]
    fn tables_match_direct_quadrature_to_1e_10() {
        let closure = table();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut cases: Vec<[f64; 3]> = vec![
            [1.0 / 3.0; 3],
            [0.3334, 0.3333, 0.3333],
            [0.34, 0.33, 0.33],
            [0.98, 0.01, 0.01],
            [0.995, 0.004, 0.001],
            [0.499, 0.499, 0.002],
            [0.002, 0.001, 0.997],
            [0.6, 0.3999, 0.0001],
        ];
        for _ in 0..60 {
            // Uniform on the triangle.
            let (a, b): (f64, f64) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            cases.push([a, b, 1.0 - a - b]);
        }
        let mut worst: f64 = 0.0;
        for mu in cases {
            if mu.iter().any(|&m| m < 1e-4) {
                continue; // closer to the edge than the tables' nodes (checked below)
            }
            let fast = closure.fourth(mu);
            let exact = exact_fourth(mu).unwrap();
            for i in 0..3 {
                for j in 0..3 {
                    let e = (fast[i][j] - exact[i][j]).abs();
                    worst = worst.max(e);
                    assert!(
                        e < 1e-10,
                        "mu {mu:?}: S_{i}{i}{j}{j} table {} vs quadrature {}: error {e:.2e}",
                        fast[i][j],
                        exact[i][j]
                    );
                }
                let row: f64 = fast[i].iter().sum();
                assert!(
                    (row - mu[i]).abs() < 1e-14,
                    "sum_j S_iijj = {row} vs mu_i {}",
                    mu[i]
                );
            }
        }
        eprintln!("degree {}: worst table error {worst:.2e}", closure.degree());
    }

    #[test]
    fn entropy_table_matches_quadrature_away_from_the_edges() {
        let closure = table();
        for mu in [
            [1.0 / 3.0; 3],
            [0.4, 0.35, 0.25],
            [0.6, 0.3, 0.1],
            [0.8, 0.15, 0.05],
            [0.2, 0.3, 0.5],
        ] {
            let (fast, exact) = (closure.entropy(mu), exact_entropy(mu).unwrap());
            eprintln!("entropy at {mu:?}: table {fast:.15} quadrature {exact:.15}");
            assert!(
                (fast - exact).abs() < 1e-9,
                "mu {mu:?}: entropy table {fast} vs quadrature {exact}"
            );
        }
        assert!(
            closure.entropy([1.0 / 3.0; 3]).abs() < 1e-9,
            "isotropic entropy must vanish"
        );
    }

    #[test]
    fn batch_evaluation_matches_pointwise() {
        let closure = table();
        let mus: Vec<[f64; 3]> = (0..300)
            .map(|k| {
                let a = 0.05 + 0.9 * ((k * 37) % 300) as f64 / 300.0;
                let b = (1.0 - a) * ((k * 91) % 299) as f64 / 299.0;
                [a, b, 1.0 - a - b]
            })
            .collect();
        let (f, h) = closure.evaluate_batch(&mus, true);
        for (k, mu) in mus.iter().enumerate() {
            let single = closure.fourth(*mu);
            for i in 0..3 {
                for j in 0..3 {
                    assert!(
                        (f[k][i][j] - single[i][j]).abs() < 1e-13,
                        "batch vs pointwise at {mu:?}"
                    );
                }
            }
            assert!((h[k] - closure.entropy(*mu)).abs() < 1e-12);
        }
    }

    #[test]
    fn isotropy_and_full_alignment_limits() {
        let closure = table();
        let iso = closure.fourth([1.0 / 3.0; 3]);
        for i in 0..3 {
            for j in 0..3 {
                let exact = if i == j { 3.0 / 15.0 } else { 1.0 / 15.0 };
                assert!(
                    (iso[i][j] - exact).abs() < 1e-12,
                    "isotropic S_{i}{i}{j}{j} = {} vs {exact}",
                    iso[i][j]
                );
            }
        }
        // Full alignment along axis 0: S = pppp, i.e. S_0000 = 1, everything else 0.
        let al = closure.fourth([1.0, 0.0, 0.0]);
        for i in 0..3 {
            for j in 0..3 {
                let exact = if i == 0 && j == 0 { 1.0 } else { 0.0 };
                assert!(
                    (al[i][j] - exact).abs() < 1e-8,
                    "aligned S_{i}{i}{j}{j} = {} vs {exact}",
                    al[i][j]
                );
            }
        }
    }
}
