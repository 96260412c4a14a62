//! Initial conditions of the mean-field model: perturbations `Q' ` of the isotropic state
//! `Q = I/3` on the unit box (docs/MODEL.md §4), as functions of position, so that the same field can
//! be sampled on any grid and, by the particle model, at rod positions (a particle
//! configuration drawn from `Psi(x, p) = (1 + (15/2) Q'(x) : pp) / 4 pi`, whose second moment is
//! `I/3 + Q'`: the comparison of the two models from one initial condition, docs/MODEL.md §5).

use crate::solver::params::SYM;
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

    #[test]
    fn particle_fields_have_unit_mean_concentration_and_refuse_too_few_rods() {
        use super::{ParticleFieldError, from_particles};
        // 400 rods on a 10-box, all along x: Q = diag(c, 0, 0) with mean c = 1.
        let x: Vec<[f64; 3]> = (0..400)
            .map(|k| {
                let f = k as f64;
                [
                    (f * 0.618_034 % 1.0) * 10.0,
                    (f * 0.414_214 % 1.0) * 10.0,
                    (f * 0.732_051 % 1.0) * 10.0,
                ]
            })
            .collect();
        let p = vec![[1.0, 0.0, 0.0]; 400];
        let q = from_particles(&x, &p, 10.0, 8, 0.15).unwrap();
        let n3 = 512.0;
        let mean_c: f64 = q[0].iter().sum::<f64>() / n3;
        let off: f64 = q[1..].iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
        assert!((mean_c - 1.0).abs() < 1e-9, "mean concentration {mean_c}");
        assert!(off < 1e-12, "components other than Q_xx reach {off:e}");
        // One rod, no smoothing: the band-limited delta has negative lobes.
        let e = from_particles(&x[..1], &p[..1], 10.0, 8, 0.0).unwrap_err();
        assert!(matches!(e, ParticleFieldError::NotPositive { .. }), "{e}");
        assert_eq!(
            from_particles(&[], &[], 10.0, 8, 0.1).unwrap_err(),
            ParticleFieldError::NoRods
        );
    }
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

/// Why a particle configuration gives no mean-field state.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParticleFieldError {
    /// No rods.
    #[error("a particle configuration without rods")]
    NoRods,
    /// The NUFFT refused the points or the modes.
    #[error(transparent)]
    Nufft(#[from] motile_analysis::nufft::NufftError),
    /// The smoothed concentration is not positive somewhere: too few rods for the grid.
    #[error(
        "the smoothed concentration at grid point {index} is {value}: too few rods for this grid and smoothing = {smoothing}; smooth more"
    )]
    NotPositive {
        /// Flat grid index.
        index: usize,
        /// The concentration there.
        value: f64,
        /// The smoothing used.
        smoothing: f64,
    },
}

/// The second-moment field of a particle configuration on the unit box's `n^3` grid
/// (docs/MODEL.md §5-§6): `Q(x) = (1/N) sum_n p_n p_n delta(x - x_n / L)` (so that its mean
/// trace, the concentration, is 1), its Fourier coefficients by a type-1 NUFFT on the modes of
/// the grid's dealiased band (`|m_i| <= n/3`), each multiplied by `exp(-2 pi^2 |m|^2 sigma^2)`
/// (a Gaussian of standard deviation `sigma` = `smoothing` box sides), back to the grid by an
/// FFT. Components in [`SYM`] order.
pub fn from_particles(
    positions: &[[f64; 3]],
    orientations: &[[f64; 3]],
    box_length: f64,
    n: usize,
    smoothing: f64,
) -> Result<[Vec<f64>; 6], ParticleFieldError> {
    use motile_analysis::correlation::Spectrum;
    use motile_analysis::nufft::{NufftPlan, mode_of};
    use num_complex::Complex64;
    let count = positions.len();
    if count == 0 {
        return Err(ParticleFieldError::NoRods);
    }
    let modes = 2 * (n / 3) + 1;
    let mut plan = NufftPlan::new([modes; 3], 1e-10)?;
    plan.set_points(positions, box_length)?;
    let inv = 1.0 / count as f64;
    let fields: Vec<Vec<Complex64>> = SYM
        .iter()
        .map(|&(i, j)| {
            orientations
                .iter()
                .map(|p| Complex64::new(p[i] * p[j] * inv, 0.0))
                .collect()
        })
        .collect();
    let refs: Vec<&[Complex64]> = fields.iter().map(|f| f.as_slice()).collect();
    let mut coef = plan.type1(&refs)?;
    let s2 = 2.0 * PI.powi(2) * smoothing * smoothing;
    for c in &mut coef {
        for (idx, v) in c.iter_mut().enumerate() {
            let m = [idx % modes, (idx / modes) % modes, idx / (modes * modes)]
                .map(|i| mode_of(i, modes) as f64);
            *v *= (-s2 * (m[0] * m[0] + m[1] * m[1] + m[2] * m[2])).exp();
        }
    }
    // On the grid: the band's coefficients placed among n^3 modes.
    let q: [Vec<f64>; 6] = std::array::from_fn(|c| {
        let mut full = vec![Complex64::default(); n * n * n];
        for (idx, v) in coef[c].iter().enumerate() {
            let m = [idx % modes, (idx / modes) % modes, idx / (modes * modes)]
                .map(|i| mode_of(i, modes));
            let k = m.map(|v| (v + (n / 2) as i64) as usize);
            full[(k[2] * n + k[1]) * n + k[0]] = *v;
        }
        Spectrum {
            modes: n,
            box_length: 1.0,
            components: vec![full],
            weights: vec![1.0],
        }
        .to_grid(0)
    });
    if let Some(index) = (0..n * n * n).find(|&i| q[0][i] + q[3][i] + q[5][i] <= 0.0) {
        return Err(ParticleFieldError::NotPositive {
            index,
            value: q[0][index] + q[3][index] + q[5][index],
            smoothing,
        });
    }
    Ok(q)
}
