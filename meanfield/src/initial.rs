//! Initial conditions of the mean-field model: perturbations `Q' ` of the isotropic state
//! `Q = I/3` on the unit box (docs/MODEL.md §4), as functions of position, so that the same field can
//! be sampled on any grid and, by the particle model, at rod positions (a particle
//! configuration drawn from `Psi(x, p) = (1 + (15/2) Q'(x) : pp) / 4 pi`, whose second moment is
//! `I/3 + Q'`: the comparison of the two models from one initial condition, docs/MODEL.md §5).

use crate::solver::SYM;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// A traceless perturbation of the isotropic state.
#[derive(Clone, Debug, PartialEq)]
pub enum Perturbation {
    /// A sum of Fourier modes with integer wavenumbers `|m|` in `[mode_min, mode_max]`, each with
    /// a random traceless symmetric amplitude and a random phase (seeded), scaled so that the
    /// largest component of `Q'` on a fixed 32^3 sampling of the box equals `amplitude`.
    Random {
        /// Largest `|Q'_ij|`.
        amplitude: f64,
        /// Smallest `|m|`.
        mode_min: usize,
        /// Largest `|m|`.
        mode_max: usize,
        /// Seed of the amplitudes and phases.
        seed: u64,
    },
    /// `Q'_xy = Q'_yx = amplitude cos(2 pi m . x)`.
    PlaneWave {
        /// Amplitude.
        amplitude: f64,
        /// Integer wavevector `m`.
        wavevector: [i64; 3],
    },
}

/// A perturbation ready to evaluate: `Q'(x)` at any point of the unit box (periodic).
#[derive(Clone, Debug)]
pub struct PerturbationField {
    /// Modes: integer wavevector, traceless symmetric amplitude (components in [`SYM`]
    /// order), phase.
    modes: Vec<([f64; 3], [f64; 6], f64)>,
}

impl PerturbationField {
    /// The field of `p`.
    pub fn new(p: &Perturbation) -> Self {
        match *p {
            Perturbation::PlaneWave {
                amplitude,
                wavevector,
            } => Self {
                modes: vec![(
                    wavevector.map(|v| v as f64),
                    [0.0, amplitude, 0.0, 0.0, 0.0, 0.0],
                    0.0,
                )],
            },
            Perturbation::Random {
                amplitude,
                mode_min,
                mode_max,
                seed,
            } => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let (lo, hi) = (mode_min as i64, mode_max as i64);
                let mut modes = Vec::new();
                for mx in -hi..=hi {
                    for my in -hi..=hi {
                        for mz in 0..=hi {
                            let m2 = mx * mx + my * my + mz * mz;
                            if m2 < lo * lo
                                || m2 > hi * hi
                                || (mz == 0 && (my < 0 || (my == 0 && mx <= 0)))
                            {
                                continue;
                            }
                            let mut a: [f64; 6] =
                                std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                            let tr = (a[0] + a[3] + a[5]) / 3.0;
                            a[0] -= tr;
                            a[3] -= tr;
                            a[5] -= tr;
                            let phase: f64 = rng.random_range(0.0..2.0 * PI);
                            modes.push(([mx as f64, my as f64, mz as f64], a, phase));
                        }
                    }
                }
                let mut field = Self { modes };
                // Scale on a sampling that does not depend on the run's grid, so every grid (and
                // the particle model) starts from the same function.
                const SAMPLING: usize = 32;
                let peak = (0..SAMPLING.pow(3))
                    .map(|idx| {
                        let x = [
                            idx % SAMPLING,
                            (idx / SAMPLING) % SAMPLING,
                            idx / (SAMPLING * SAMPLING),
                        ]
                        .map(|i| i as f64 / SAMPLING as f64);
                        field.eval(x).iter().fold(0.0f64, |m, v| m.max(v.abs()))
                    })
                    .fold(0.0f64, f64::max)
                    .max(1e-300);
                for (_, a, _) in &mut field.modes {
                    for c in a.iter_mut() {
                        *c *= amplitude / peak;
                    }
                }
                field
            }
        }
    }

    /// `Q'(x)` (components in [`SYM`] order) at `x` in units of the box side.
    pub fn eval(&self, x: [f64; 3]) -> [f64; 6] {
        let mut v = [0.0; 6];
        for (m, a, phase) in &self.modes {
            let s = (2.0 * PI * (m[0] * x[0] + m[1] * x[1] + m[2] * x[2]) + phase).cos();
            for c in 0..6 {
                v[c] += a[c] * s;
            }
        }
        v
    }

    /// `Q = I/3 + Q'` on an `n^3` grid of the unit box (axis 0 fastest).
    pub fn on_grid(&self, n: usize) -> [Vec<f64>; 6] {
        let mut q: [Vec<f64>; 6] = std::array::from_fn(|c| {
            vec![if SYM[c].0 == SYM[c].1 { 1.0 / 3.0 } else { 0.0 }; n * n * n]
        });
        for idx in 0..n * n * n {
            let x = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| i as f64 / n as f64);
            let v = self.eval(x);
            for c in 0..6 {
                q[c][idx] += v[c];
            }
        }
        q
    }

    /// The largest Frobenius norm of `Q'` on a 32^3 sampling: the orientation distribution
    /// `(1 + (15/2) Q' : pp) / 4 pi` stays positive while it is below `2/15`.
    pub fn max_norm(&self) -> f64 {
        const SAMPLING: usize = 32;
        (0..SAMPLING.pow(3))
            .map(|idx| {
                let x = [
                    idx % SAMPLING,
                    (idx / SAMPLING) % SAMPLING,
                    idx / (SAMPLING * SAMPLING),
                ]
                .map(|i| i as f64 / SAMPLING as f64);
                frobenius(&self.eval(x))
            })
            .fold(0.0, f64::max)
    }
}

/// Frobenius norm of a symmetric tensor given by its [`SYM`] components.
pub fn frobenius(q: &[f64; 6]) -> f64 {
    SYM.iter()
        .zip(q)
        .map(|(&(i, j), v)| if i == j { v * v } else { 2.0 * v * v })
        .sum::<f64>()
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_perturbations_are_traceless_and_scaled() {
        let f = PerturbationField::new(&Perturbation::Random {
            amplitude: 0.02,
            mode_min: 1,
            mode_max: 2,
            seed: 3,
        });
        let mut peak: f64 = 0.0;
        for k in 0..500 {
            let x = [k as f64 * 0.013, k as f64 * 0.0071, k as f64 * 0.0037].map(|c| c % 1.0);
            let v = f.eval(x);
            assert!(
                (v[0] + v[3] + v[5]).abs() < 1e-15,
                "trace {}",
                v[0] + v[3] + v[5]
            );
            peak = peak.max(v.iter().fold(0.0f64, |m, c| m.max(c.abs())));
            // Periodic on the unit box.
            let w = f.eval([x[0] + 1.0, x[1] - 2.0, x[2] + 3.0]);
            assert!(v.iter().zip(&w).all(|(a, b)| (a - b).abs() < 1e-12));
        }
        assert!(peak <= 0.02 * (1.0 + 1e-9) && peak > 0.01, "peak {peak}");
    }
}
