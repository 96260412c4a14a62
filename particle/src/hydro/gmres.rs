//! Restarted GMRES (Saad and Schultz) for the second-kind slender-body equation (P4).
//!
//! The operator is matrix-free behind [`LinOp`]; the solver keeps the Arnoldi basis as scratch,
//! orthogonalises by modified Gram-Schmidt, and tracks the residual through Givens rotations.
//! It stops when `||b - A x|| <= tol ||b||` and returns what it did ([`GmresInfo`]), or a
//! structured error. Vector operations run in parallel; dot products are summed in fixed
//! chunks and then in chunk order, so results do not depend on the thread count.

use crate::parallel::comm::{Comm, SingleProcess};
use motile_analysis::params::{InvalidParameter, check_range};
use rayon::prelude::*;

/// A linear operator applied matrix-free.
pub trait LinOp {
    /// Error of one application.
    type Error;
    /// Dimension.
    fn dim(&self) -> usize;
    /// `out = A x`.
    fn apply(&mut self, x: &[f64], out: &mut [f64]) -> Result<(), Self::Error>;
}

/// GMRES settings. The defaults are the particle runs' (`[hydro]` in a run's configuration
/// takes them from here): relative residual 1e-5, restart 40, at most 100 iterations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GmresParams {
    /// Relative residual tolerance `||b - Ax|| / ||b||`.
    pub tol: f64,
    /// Krylov dimension before a restart.
    pub restart: usize,
    /// Cap on the total number of iterations (operator applications).
    pub max_iterations: usize,
}

impl GmresParams {
    /// Check every field (the error names it, its value, the allowed range and the unit).
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        check_range("tol", self.tol, 1e-14, 1e-1, false, "relative")?;
        for (name, v, hi) in [
            ("max_iterations", self.max_iterations, 10_000),
            ("restart", self.restart, 1000),
        ] {
            if !(1..=hi).contains(&v) {
                return Err(InvalidParameter {
                    name: name.into(),
                    problem: format!("{v} is outside the allowed range [1, {hi}] (iterations)"),
                });
            }
        }
        Ok(())
    }
}

impl Default for GmresParams {
    fn default() -> Self {
        Self {
            tol: 1e-5,
            restart: 40,
            max_iterations: 100,
        }
    }
}

/// What a solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GmresInfo {
    /// Iterations (operator applications inside the Arnoldi process).
    pub iterations: usize,
    /// Relative residual estimate after each iteration (the first entry is the initial one).
    pub residuals: Vec<f64>,
    /// True relative residual at the end, recomputed from `b - A x`.
    pub final_residual: f64,
}

/// GMRES failures.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GmresError<E> {
    /// The iteration cap was reached.
    #[error(
        "GMRES did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tol:.1e})"
    )]
    NoConvergence {
        /// Iterations done.
        iterations: usize,
        /// Relative residual reached.
        residual: f64,
        /// Requested tolerance.
        tol: f64,
    },
    /// A non-finite value appeared.
    #[error("GMRES produced a non-finite residual after {iterations} iterations")]
    NonFinite {
        /// Iterations done.
        iterations: usize,
    },
    /// The operator failed.
    #[error("operator failed inside GMRES: {0}")]
    Operator(E),
}

/// `a . b`, summed in fixed chunks in parallel and then in chunk order: the same bits for any
/// thread count (and, below one chunk, the plain sequential sum); then over ranks.
fn dot(comm: &dyn Comm, a: &[f64], b: &[f64]) -> f64 {
    let mut s = [motile_analysis::reduce::det_sum(a.len(), |i| a[i] * b[i])];
    comm.sum(&mut s);
    s[0]
}

/// Solve `A x = b` starting from the `x` given (warm start).
pub fn gmres<O: LinOp>(
    op: &mut O,
    b: &[f64],
    x: &mut [f64],
    params: &GmresParams,
) -> Result<GmresInfo, GmresError<O::Error>> {
    gmres_shared(&SingleProcess, op, b, x, params)
}

/// [`gmres`] on vectors split among ranks (collective): each rank holds its part of `b` and
/// `x`, and `op` maps its part of `x` to its part of `A x` (exchanging what it needs); dot
/// products are summed over ranks in rank order, so every rank takes the same iterations.
pub fn gmres_shared<O: LinOp>(
    comm: &dyn Comm,
    op: &mut O,
    b: &[f64],
    x: &mut [f64],
    params: &GmresParams,
) -> Result<GmresInfo, GmresError<O::Error>> {
    let n = op.dim();
    assert!(b.len() == n && x.len() == n, "GMRES: dimension mismatch");
    let mut space = HostSpace {
        comm,
        op,
        b,
        x,
        r: vec![0.0; n],
        w: vec![0.0; n],
        basis: Vec::with_capacity(params.restart.max(1) + 1),
    };
    gmres_in(&mut space, params)
}

/// The vectors of one GMRES solve and the operations on them, on the host or on a device:
/// the right-hand side `b`, the iterate `x` (the warm start on entry), the residual, the
/// Arnoldi basis `v_j` and the operator `A`. The solver ([`gmres_in`]) keeps the Hessenberg
/// matrix, the rotations and the least-squares solve on the host; a space on a device returns
/// only those numbers, its vectors staying there.
pub trait KrylovSpace {
    /// Error of an operation (the operator's, or the device's).
    type Error;
    /// `||b||`.
    fn rhs_norm(&mut self) -> Result<f64, Self::Error>;
    /// `x = 0`.
    fn clear(&mut self) -> Result<(), Self::Error>;
    /// The residual `r = b - A x`, kept for [`Self::start`]; returns `||r||`.
    fn residual(&mut self) -> Result<f64, Self::Error>;
    /// The basis restarted at `v_0 = r / beta`.
    fn start(&mut self, beta: f64) -> Result<(), Self::Error>;
    /// `w = A v_k` orthogonalised by modified Gram-Schmidt against `v_0..=v_k` in basis
    /// order (`h_j = w . v_j`, then `w -= h_j v_j`); returns the `h_j` and `||w||`.
    fn arnoldi(&mut self, k: usize) -> Result<(Vec<f64>, f64), Self::Error>;
    /// The basis's vector `v_k = w / hn`.
    fn extend(&mut self, k: usize, hn: f64) -> Result<(), Self::Error>;
    /// `x += sum_j y_j v_j`, the terms added in basis order at every entry.
    fn update(&mut self, y: &[f64]) -> Result<(), Self::Error>;
}

/// GMRES in `space` from its iterate (warm start): [`gmres_shared`]'s iteration, whatever
/// holds the vectors.
pub fn gmres_in<S: KrylovSpace>(
    space: &mut S,
    params: &GmresParams,
) -> Result<GmresInfo, GmresError<S::Error>> {
    let bnorm = space.rhs_norm().map_err(GmresError::Operator)?;
    let mut info = GmresInfo::default();
    if bnorm == 0.0 {
        space.clear().map_err(GmresError::Operator)?;
        info.residuals.push(0.0);
        return Ok(info);
    }
    let m = params.restart.max(1);
    loop {
        let beta = space.residual().map_err(GmresError::Operator)?;
        let rel = beta / bnorm;
        if !rel.is_finite() {
            return Err(GmresError::NonFinite {
                iterations: info.iterations,
            });
        }
        if info.residuals.is_empty() {
            info.residuals.push(rel);
        }
        info.final_residual = rel;
        if rel <= params.tol {
            return Ok(info);
        }
        if info.iterations >= params.max_iterations {
            return Err(GmresError::NoConvergence {
                iterations: info.iterations,
                residual: rel,
                tol: params.tol,
            });
        }
        space.start(beta).map_err(GmresError::Operator)?;
        let mut h = vec![vec![0.0; m]; m + 1];
        let (mut cs, mut sn) = (vec![0.0; m], vec![0.0; m]);
        let mut g = vec![0.0; m + 1];
        g[0] = beta;
        let mut k = 0;
        while k < m && info.iterations < params.max_iterations {
            let (column, hn) = space.arnoldi(k).map_err(GmresError::Operator)?;
            info.iterations += 1;
            for (j, hj) in column.into_iter().enumerate() {
                h[j][k] = hj;
            }
            h[k + 1][k] = hn;
            for j in 0..k {
                let t = cs[j] * h[j][k] + sn[j] * h[j + 1][k];
                h[j + 1][k] = -sn[j] * h[j][k] + cs[j] * h[j + 1][k];
                h[j][k] = t;
            }
            let d = (h[k][k] * h[k][k] + h[k + 1][k] * h[k + 1][k]).sqrt();
            if d == 0.0 || !d.is_finite() {
                return Err(GmresError::NonFinite {
                    iterations: info.iterations,
                });
            }
            cs[k] = h[k][k] / d;
            sn[k] = h[k + 1][k] / d;
            h[k][k] = d;
            h[k + 1][k] = 0.0;
            g[k + 1] = -sn[k] * g[k];
            g[k] *= cs[k];
            let est = g[k + 1].abs() / bnorm;
            info.residuals.push(est);
            k += 1;
            if est <= params.tol || hn == 0.0 {
                break;
            }
            space.extend(k, hn).map_err(GmresError::Operator)?;
        }
        // Solve the upper-triangular system and update x.
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let s: f64 = (i + 1..k).map(|j| h[i][j] * y[j]).sum();
            y[i] = (g[i] - s) / h[i][i];
        }
        space.update(&y).map_err(GmresError::Operator)?;
    }
}

/// The host's space: vectors in memory (split among ranks), operations in parallel, dot
/// products in fixed chunks.
struct HostSpace<'a, O> {
    comm: &'a dyn Comm,
    op: &'a mut O,
    b: &'a [f64],
    x: &'a mut [f64],
    r: Vec<f64>,
    w: Vec<f64>,
    basis: Vec<Vec<f64>>,
}

impl<O: LinOp> HostSpace<'_, O> {
    fn norm(&self, a: &[f64]) -> f64 {
        dot(self.comm, a, a).sqrt()
    }
}

impl<O: LinOp> KrylovSpace for HostSpace<'_, O> {
    type Error = O::Error;

    fn rhs_norm(&mut self) -> Result<f64, O::Error> {
        Ok(self.norm(self.b))
    }

    fn clear(&mut self) -> Result<(), O::Error> {
        self.x.iter_mut().for_each(|c| *c = 0.0);
        Ok(())
    }

    fn residual(&mut self) -> Result<f64, O::Error> {
        self.op.apply(self.x, &mut self.w)?;
        self.r
            .par_iter_mut()
            .zip(self.b.par_iter().zip(&self.w))
            .for_each(|(r, (b, w))| *r = b - w);
        Ok(self.norm(&self.r))
    }

    fn start(&mut self, beta: f64) -> Result<(), O::Error> {
        self.basis.clear();
        self.basis
            .push(self.r.par_iter().map(|c| c / beta).collect());
        Ok(())
    }

    fn arnoldi(&mut self, k: usize) -> Result<(Vec<f64>, f64), O::Error> {
        self.op.apply(&self.basis[k], &mut self.w)?;
        // Modified Gram-Schmidt: each projection in parallel, in basis order.
        let mut column = Vec::with_capacity(k + 1);
        for v in &self.basis[..=k] {
            let hj = dot(self.comm, &self.w, v);
            column.push(hj);
            self.w.par_iter_mut().zip(v).for_each(|(w, v)| *w -= hj * v);
        }
        Ok((column, self.norm(&self.w)))
    }

    fn extend(&mut self, k: usize, hn: f64) -> Result<(), O::Error> {
        debug_assert_eq!(self.basis.len(), k, "the basis grows one vector at a time");
        self.basis.push(self.w.par_iter().map(|c| c / hn).collect());
        Ok(())
    }

    fn update(&mut self, y: &[f64]) -> Result<(), O::Error> {
        let basis = &self.basis;
        self.x.par_iter_mut().enumerate().for_each(|(i, xi)| {
            for (yj, v) in y.iter().zip(basis) {
                *xi += yj * v[i];
            }
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parallel::comm::ThreadRanks;

    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    fn norm(a: &[f64]) -> f64 {
        dot(a, a).sqrt()
    }

    /// One rank's rows `rows` of a dense matrix; `x` arrives in parts, gathered per product.
    struct RowBlock<'a> {
        comm: &'a ThreadRanks,
        a: Vec<Vec<f64>>,
    }

    impl LinOp for RowBlock<'_> {
        type Error = ();
        fn dim(&self) -> usize {
            self.a.len()
        }
        fn apply(&mut self, x: &[f64], out: &mut [f64]) -> Result<(), ()> {
            let full: Vec<f64> = self.comm.all_gather(x).concat();
            for (o, row) in out.iter_mut().zip(&self.a) {
                *o = dot(row, &full);
            }
            Ok(())
        }
    }

    /// GMRES on a system split by rows among 1, 2 and 3 ranks solves it as one process does:
    /// to the dense solution within the tolerance, every rank through the same iterations.
    #[test]
    fn gmres_on_rows_split_among_ranks_matches_the_dense_solve() {
        let n = 120;
        let op = matrix(n);
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let exact = solve_dense(&op.a, &b);
        let p = GmresParams {
            tol: 1e-12,
            restart: 20,
            max_iterations: 500,
        };
        for ranks in [1, 2, 3] {
            let handles: Vec<_> = ThreadRanks::group(ranks)
                .into_iter()
                .map(|comm| {
                    let (a, b) = (op.a.clone(), b.clone());
                    std::thread::spawn(move || {
                        let rows = comm.rank() * n / ranks..(comm.rank() + 1) * n / ranks;
                        let mut block = RowBlock {
                            comm: &comm,
                            a: a[rows.clone()].to_vec(),
                        };
                        let mut x = vec![0.0; rows.len()];
                        let info = gmres_shared(&comm, &mut block, &b[rows], &mut x, &p).unwrap();
                        (x, info.iterations)
                    })
                })
                .collect();
            let parts: Vec<(Vec<f64>, usize)> =
                handles.into_iter().map(|h| h.join().unwrap()).collect();
            let iterations: Vec<usize> = parts.iter().map(|p| p.1).collect();
            assert!(
                iterations.iter().all(|&i| i == iterations[0]),
                "{ranks} ranks took different iterations: {iterations:?}"
            );
            let x: Vec<f64> = parts.into_iter().flat_map(|p| p.0).collect();
            let err =
                norm(&x.iter().zip(&exact).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(&exact);
            assert!(err < 1e-10, "{ranks} ranks: error vs dense solve {err:e}");
        }
    }

    /// A dense nonsymmetric matrix `I + 0.4 R` (R random), well conditioned.
    struct Dense {
        a: Vec<Vec<f64>>,
    }

    impl LinOp for Dense {
        type Error = ();
        fn dim(&self) -> usize {
            self.a.len()
        }
        fn apply(&mut self, x: &[f64], out: &mut [f64]) -> Result<(), ()> {
            for (o, row) in out.iter_mut().zip(&self.a) {
                *o = dot(row, x);
            }
            Ok(())
        }
    }

    fn matrix(n: usize) -> Dense {
        let mut s = 12345u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| 0.4 * rnd() / (n as f64).sqrt() + if i == j { 1.0 } else { 0.0 })
                    .collect()
            })
            .collect();
        Dense { a }
    }

    /// Dense Gaussian elimination with partial pivoting, the slow twin.
    fn solve_dense(a: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
        let n = b.len();
        let mut m: Vec<Vec<f64>> = a
            .iter()
            .zip(b)
            .map(|(r, bi)| {
                let mut r = r.clone();
                r.push(*bi);
                r
            })
            .collect();
        for c in 0..n {
            let p = (c..n)
                .max_by(|&i, &j| m[i][c].abs().total_cmp(&m[j][c].abs()))
                .unwrap();
            m.swap(c, p);
            for r in c + 1..n {
                let f = m[r][c] / m[c][c];
                for k in c..=n {
                    m[r][k] -= f * m[c][k];
                }
            }
        }
        let mut x = vec![0.0; n];
        for i in (0..n).rev() {
            let s: f64 = (i + 1..n).map(|j| m[i][j] * x[j]).sum();
            x[i] = (m[i][n] - s) / m[i][i];
        }
        x
    }

    #[test]
    fn gmres_matches_a_dense_solve_with_and_without_restarts() {
        let n = 120;
        let mut op = matrix(n);
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let exact = solve_dense(&op.a, &b);
        for restart in [5, 60] {
            let mut x = vec![0.0; n];
            let p = GmresParams {
                tol: 1e-12,
                restart,
                max_iterations: 500,
            };
            let info = gmres(&mut op, &b, &mut x, &p).unwrap();
            let err = x
                .iter()
                .zip(&exact)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
                / norm(&exact);
            assert!(
                info.final_residual <= 1e-12,
                "restart {restart}: residual {:e}",
                info.final_residual
            );
            assert!(
                err < 1e-10,
                "restart {restart}: error vs dense solve {err:e} after {} iterations",
                info.iterations
            );
        }
    }

    #[test]
    fn gmres_reports_no_convergence_and_a_warm_start_saves_iterations() {
        let n = 80;
        let mut op = matrix(n);
        let b: Vec<f64> = (0..n).map(|i| (i as f64).cos()).collect();
        let mut x = vec![0.0; n];
        let p = GmresParams {
            tol: 1e-14,
            restart: 3,
            max_iterations: 4,
        };
        match gmres(&mut op, &b, &mut x, &p) {
            Err(GmresError::NoConvergence {
                iterations,
                residual,
                ..
            }) => {
                assert!(
                    iterations >= 4 && residual > 1e-14,
                    "{iterations} {residual:e}"
                )
            }
            other => panic!("expected NoConvergence, got {other:?}"),
        }
        let p = GmresParams {
            tol: 1e-10,
            ..GmresParams::default()
        };
        let mut cold = vec![0.0; n];
        let a = gmres(&mut op, &b, &mut cold, &p).unwrap();
        let mut warm: Vec<f64> = cold.iter().map(|c| c * (1.0 + 1e-9)).collect();
        let w = gmres(&mut op, &b, &mut warm, &p).unwrap();
        assert!(
            w.iterations < a.iterations / 2,
            "warm {} vs cold {}",
            w.iterations,
            a.iterations
        );
    }
}
