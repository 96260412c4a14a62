//! Correlation functions (docs/MODEL.md §6).
//!
//! A field `Phi` on the periodic box with Fourier coefficients `Phi~(k)` (so that
//! `Phi(x) = sum_k Phi~(k) exp(i k.x)`) has the autocorrelation
//! `C(x) = (1/|V|) integral Phi(y) Phi(y + x) dy = sum_k |Phi~(k)|^2 exp(i k.x)`, and its
//! spherical average at radius `r` is exactly `Corr(r) = sum_k |Phi~(k)|^2 j0(|k| r)`,
//! `j0(x) = sin(x)/x` (docs/MODEL.md (A2)): evaluated from the retained modes (grouped by `|m|^2`)
//! at any radius, 64 of them in `(0, L/2]` by default. The resolution is that of the modes kept
//! (`L/M` for `M` per axis), not of the sampling. Vector and tensor fields sum their components,
//! so `Corr[Phi](0) = ||Phi||_2^2`, the volume-averaged mean square.
//!
//! Three sources of `Phi~`:
//! - a particle configuration, `Phi~(k) = (1/N) sum_n phi(p_n) exp(-i k.x_n)` by a type-1 NUFFT
//!   ([`particle_coefficients`]), for `c' = c - 1`, polarity `n = [p]` and nematic
//!   `Q = [pp - I/3]` ([`OrderParameter`]);
//! - a field sampled on a uniform grid (the mean-field model), by an FFT
//!   ([`grid_coefficients`]);
//! - point forces, through the Stokes velocity spectrum
//!   `u~(k) = (I - kk/|k|^2)/(mu |V| |k|^2) . sum f w exp(-i k.y)` ([`velocity_spectrum`]).

use crate::fft3::{Direction, Fft3};
use crate::nufft::{NufftError, NufftPlan, mode_of};
use num_complex::Complex64;
use std::f64::consts::PI;

/// Options for correlation functions.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrelationOptions {
    /// Fourier modes per dimension for particle data. Default (`None`): `floor((L/l)/2)`
    /// with `l = 1`, at least 4. More modes resolve shorter distances and cost more.
    pub modes: Option<usize>,
    /// Spacing of the radii at which correlations are evaluated, in units of length. Default
    /// (`None`): `L / 128`, 64 radii in `(0, L/2]`.
    pub shell_width: Option<f64>,
    /// NUFFT tolerance. Default 1e-6: far below the statistical noise of any configuration.
    pub tolerance: f64,
}

impl Default for CorrelationOptions {
    fn default() -> Self {
        Self {
            modes: None,
            shell_width: None,
            tolerance: 1e-6,
        }
    }
}

impl CorrelationOptions {
    /// Mode count for a box of side `box_length` (in rod lengths).
    pub fn modes_for(&self, box_length: f64) -> usize {
        self.modes
            .unwrap_or(((box_length / 2.0).floor() as usize).max(4))
    }
}

/// A radially averaged correlation function.
#[derive(Clone, Debug, PartialEq)]
pub struct RadialCorrelation {
    /// Radii (units of length); the first is 0.
    pub r: Vec<f64>,
    /// Spherical averages of `C` there.
    pub value: Vec<f64>,
    /// Fourier modes per axis behind it (its resolution: `L / modes`).
    pub modes: usize,
}

impl RadialCorrelation {
    /// `C(0)`: the volume-averaged mean square of the field.
    pub fn at_zero(&self) -> f64 {
        self.value[0]
    }
}

/// Order parameters of a particle configuration (docs/MODEL.md §6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderParameter {
    /// Concentration fluctuation `c' = c - 1` (scalar; the k = 0 mode is removed).
    Concentration,
    /// Polarity `n = [p]` (3 components).
    Polarity,
    /// Nematic tensor `Q = [pp - I/3]` (9 components, the 6 independent ones weighted).
    Nematic,
}

impl OrderParameter {
    /// What one rod's value adds to its field's power at every mode, times `N^2` (the `N`
    /// rods' own terms add `self_power / N`): the sum over components, with their weights, of
    /// its squared value: 1 for `c'` and `n`
    /// (`|p| = 1`), 2/3 for `Q` (`|pp - I/3|^2`).
    pub fn self_power(self) -> f64 {
        match self {
            OrderParameter::Concentration | OrderParameter::Polarity => 1.0,
            OrderParameter::Nematic => 2.0 / 3.0,
        }
    }
}

/// The pair part of an order parameter's correlation from its spectrum of `rods` rods
/// ([`particle_coefficients`]): the power without each rod's correlation with itself,
/// `self_power / N` at every mode (the concentration's `k = 0` mode, which the fluctuation
/// removes, stays 0). For the concentration this is `g(r) - 1`, the pair distribution seen at
/// the modes' resolution (`L / modes`); for `n` and `Q` the pair distribution weighted by
/// `p_i.p_j` and `Q_i:Q_j`. Unlike the correlation itself, whose rods' own term scales as
/// `1/N` and dominates at `r = 0`, it does not depend on `N`: boxes of different sizes
/// compare directly, at the same resolution in `l`.
pub fn pair_correlation(
    spec: &Spectrum,
    which: OrderParameter,
    rods: usize,
    shell_width: Option<f64>,
) -> RadialCorrelation {
    let own = which.self_power() / rods.max(1) as f64;
    let zero = zero_mode(spec.modes);
    let power: Vec<f64> = spec
        .power()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if which == OrderParameter::Concentration && i == zero {
                0.0
            } else {
                p - own
            }
        })
        .collect();
    radial_autocorrelation(&power, spec.modes, spec.box_length, shell_width)
}

/// Fourier coefficients of several fields, one mode array each, on a cube of `modes^3`
/// modes (layout of [`crate::nufft`]), with a weight per component (2 for the off-diagonal
/// components of a symmetric tensor, stored once).
#[derive(Clone, Debug)]
pub struct Spectrum {
    /// Modes per dimension.
    pub modes: usize,
    /// Box side.
    pub box_length: f64,
    /// One mode array per component.
    pub components: Vec<Vec<Complex64>>,
    /// Weight of each component in sums over components.
    pub weights: Vec<f64>,
}

impl Spectrum {
    /// Component `c` on the `modes^3` grid `x = L j / modes` (x fastest): the real part of
    /// `sum_k Phi~(k) exp(i k.x)`.
    pub fn to_grid(&self, c: usize) -> Vec<f64> {
        let n = self.modes;
        let mut g = vec![Complex64::default(); n * n * n];
        for (idx, v) in self.components[c].iter().enumerate() {
            let m = [idx % n, (idx / n) % n, idx / (n * n)]
                .map(|i| mode_of(i, n).rem_euclid(n as i64) as usize);
            g[(m[2] * n + m[1]) * n + m[0]] = *v;
        }
        Fft3::new([n; 3]).process(&mut g, Direction::Inverse);
        g.iter().map(|z| z.re).collect()
    }

    /// `sum_components weight |Phi~(k)|^2`, per mode.
    pub fn power(&self) -> Vec<f64> {
        let n = self.modes.pow(3);
        let mut p = vec![0.0; n];
        for (c, w) in self.components.iter().zip(&self.weights) {
            for (pk, ck) in p.iter_mut().zip(c) {
                *pk += w * ck.norm_sqr();
            }
        }
        p
    }

    /// Volume-averaged L2 norm, `sqrt(sum_k power)` (Parseval).
    pub fn l2_norm(&self) -> f64 {
        self.power().iter().sum::<f64>().sqrt()
    }

    /// Radially averaged autocorrelation.
    pub fn correlation(&self, shell_width: Option<f64>) -> RadialCorrelation {
        radial_autocorrelation(&self.power(), self.modes, self.box_length, shell_width)
    }
}

/// Fourier coefficients of an order parameter of a configuration of `N` rods (centres `x`,
/// unit orientations `p`) in a box of side `box_length`: [`ParticleSpectra`] for one parameter.
pub fn particle_coefficients(
    x: &[[f64; 3]],
    p: &[[f64; 3]],
    box_length: f64,
    which: OrderParameter,
    opts: &CorrelationOptions,
) -> Result<Spectrum, NufftError> {
    let mut spectra = ParticleSpectra::new(opts.modes_for(box_length), opts.tolerance)?;
    let mut one = spectra.of(x, p, box_length, &[which])?;
    Ok(one.pop().expect("one spectrum per order parameter"))
}

/// Spectra of order parameters of particle configurations on one NUFFT plan: every requested
/// parameter's components (1 for `c'`, 3 for `n`, 6 for `Q`) are spread in one pass over the
/// rods, so each rod's kernel is evaluated once and the points sorted once per configuration,
/// two real components to a fine grid and transform ([`NufftPlan::type1_real`]), and the
/// plan's buffers serve every configuration that follows (the snapshots of a run).
/// Each spectrum equals [`particle_coefficients`]'s for that parameter to rounding (the component
/// sharing its grid differs).
#[derive(Debug)]
pub struct ParticleSpectra {
    plan: NufftPlan,
    modes: usize,
}

impl ParticleSpectra {
    /// A plan for `modes` Fourier modes per axis at NUFFT tolerance `tolerance`.
    pub fn new(modes: usize, tolerance: f64) -> Result<Self, NufftError> {
        Ok(Self {
            plan: NufftPlan::new([modes; 3], tolerance)?,
            modes,
        })
    }

    /// Modes per axis.
    pub fn modes(&self) -> usize {
        self.modes
    }

    /// The spectra of `which` (in that order) of the rods with centres `x` and unit
    /// orientations `p` in a box of side `box_length`.
    pub fn of(
        &mut self,
        x: &[[f64; 3]],
        p: &[[f64; 3]],
        box_length: f64,
        which: &[OrderParameter],
    ) -> Result<Vec<Spectrum>, NufftError> {
        if p.len() != x.len() {
            return Err(NufftError::Length {
                which: 0,
                got: p.len(),
                expected: x.len(),
            });
        }
        self.plan.set_points(x, box_length)?;
        let inv_n = 1.0 / x.len().max(1) as f64;
        let parts: Vec<(Vec<Vec<f64>>, Vec<f64>)> = which
            .iter()
            .map(|&w| order_parameter_fields(w, p, inv_n))
            .collect();
        let refs: Vec<&[f64]> = parts
            .iter()
            .flat_map(|(fields, _)| fields.iter().map(|f| f.as_slice()))
            .collect();
        let mut components = self.plan.type1_real(&refs)?.into_iter();
        Ok(which
            .iter()
            .zip(parts)
            .map(|(&w, (fields, weights))| {
                let mut comps: Vec<Vec<Complex64>> =
                    components.by_ref().take(fields.len()).collect();
                if w == OrderParameter::Concentration {
                    comps[0][zero_mode(self.modes)] = Complex64::default();
                }
                Spectrum {
                    modes: self.modes,
                    box_length,
                    components: comps,
                    weights,
                }
            })
            .collect())
    }
}

/// The point strengths of an order parameter (each rod's value over `N`), one vector per
/// component, and the components' weights.
fn order_parameter_fields(
    which: OrderParameter,
    p: &[[f64; 3]],
    inv_n: f64,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let field =
        |f: &dyn Fn(&[f64; 3]) -> f64| -> Vec<f64> { p.iter().map(|q| f(q) * inv_n).collect() };
    match which {
        OrderParameter::Concentration => (vec![field(&|_| 1.0)], vec![1.0]),
        OrderParameter::Polarity => ((0..3).map(|d| field(&|q| q[d])).collect(), vec![1.0; 3]),
        OrderParameter::Nematic => SYM_PAIRS
            .iter()
            .map(|&(i, j)| {
                let iso = if i == j { 1.0 / 3.0 } else { 0.0 };
                (
                    field(&|q| q[i] * q[j] - iso),
                    if i == j { 1.0 } else { 2.0 },
                )
            })
            .unzip(),
    }
}

/// Fourier coefficients of a vector field sampled at `N` points (`x`, values `v`), the point
/// field `(1/N) sum_n v_n |V| delta(x - x_n)`: `Phi~(k) = (1/N) sum_n v_n exp(-i k.x_n)` by a
/// type-1 NUFFT at `opts.tolerance`. The polarity of [`particle_coefficients`] (with `v = p`),
/// and the velocity autocorrelation of any code's particles (with `v` their velocities).
pub fn sampled_vector_coefficients(
    x: &[[f64; 3]],
    v: &[[f64; 3]],
    box_length: f64,
    opts: &CorrelationOptions,
) -> Result<Spectrum, NufftError> {
    if v.len() != x.len() {
        return Err(NufftError::Length {
            which: 0,
            got: v.len(),
            expected: x.len(),
        });
    }
    let modes = opts.modes_for(box_length);
    let mut plan = NufftPlan::new([modes; 3], opts.tolerance)?;
    plan.set_points(x, box_length)?;
    let inv_n = 1.0 / x.len().max(1) as f64;
    let fields: Vec<Vec<f64>> = (0..3)
        .map(|d| v.iter().map(|q| q[d] * inv_n).collect())
        .collect();
    let refs: Vec<&[f64]> = fields.iter().map(|f| f.as_slice()).collect();
    Ok(Spectrum {
        modes,
        box_length,
        // Real components two to a transform: two transforms instead of three.
        components: plan.type1_real(&refs)?,
        weights: vec![1.0; 3],
    })
}

/// The independent components of a symmetric 3x3 tensor, in the order of motile's HDF5 files.
pub const SYM_PAIRS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// Index of the `k = 0` mode in a cube of `modes^3`.
pub(crate) fn zero_mode(modes: usize) -> usize {
    let c = modes / 2;
    (c * modes + c) * modes + c
}

/// Fourier coefficients of real fields sampled on a uniform `n^3` grid (axis 0 fastest), with a
/// weight per field; optionally with the mean removed.
pub fn grid_coefficients(
    fields: &[&[f64]],
    weights: &[f64],
    n: usize,
    box_length: f64,
    remove_mean: bool,
) -> Spectrum {
    let fft = Fft3::new([n; 3]);
    let scale = 1.0 / (n * n * n) as f64;
    let components = fields
        .iter()
        .map(|f| {
            assert_eq!(
                f.len(),
                n * n * n,
                "grid field has {} values, expected {n}^3",
                f.len()
            );
            let mut c: Vec<Complex64> = f.iter().map(|&v| Complex64::new(v * scale, 0.0)).collect();
            fft.process(&mut c, Direction::Forward);
            // Reorder from FFT order to centred mode order.
            let mut out = vec![Complex64::default(); n * n * n];
            for (idx, o) in out.iter_mut().enumerate() {
                let m = [idx % n, (idx / n) % n, idx / (n * n)]
                    .map(|i| mode_of(i, n).rem_euclid(n as i64) as usize);
                *o = c[(m[2] * n + m[1]) * n + m[0]];
            }
            if remove_mean {
                out[zero_mode(n)] = Complex64::default();
            }
            out
        })
        .collect();
    Spectrum {
        modes: n,
        box_length,
        components,
        weights: weights.to_vec(),
    }
}

/// Velocity spectrum of point forces `f` at points `y` (docs/MODEL.md §6): the Fourier coefficients
/// of the zero-mean periodic Stokes flow, `modes^3` of them, viscosity `mu`.
pub fn velocity_spectrum(
    y: &[[f64; 3]],
    f: &[[f64; 3]],
    box_length: f64,
    mu: f64,
    modes: usize,
    tolerance: f64,
) -> Result<Spectrum, NufftError> {
    let mut plan = NufftPlan::new([modes; 3], tolerance)?;
    plan.set_points(y, box_length)?;
    // The three real components two to a transform: two spreads instead of three.
    let comps: Vec<Vec<f64>> = (0..3).map(|d| f.iter().map(|v| v[d]).collect()).collect();
    let refs: Vec<&[f64]> = comps.iter().map(|v| v.as_slice()).collect();
    let fk = plan.type1_real(&refs)?;
    let vol = box_length.powi(3);
    let mut u = vec![vec![Complex64::default(); modes.pow(3)]; 3];
    for idx in 0..modes.pow(3) {
        let k = [idx % modes, (idx / modes) % modes, idx / (modes * modes)]
            .map(|i| 2.0 * PI * mode_of(i, modes) as f64 / box_length);
        let k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
        if k2 == 0.0 {
            continue;
        }
        let kf = k[0] * fk[0][idx] + k[1] * fk[1][idx] + k[2] * fk[2][idx];
        let s = 1.0 / (mu * vol * k2);
        for d in 0..3 {
            u[d][idx] = (fk[d][idx] - kf * (k[d] / k2)) * s;
        }
    }
    Ok(Spectrum {
        modes,
        box_length,
        components: u,
        weights: vec![1.0; 3],
    })
}

/// The velocity spectrum (A1) at a few integer wavevectors `m` (`k = 2 pi m / L`) by direct sums,
/// `u~(k) = (I - kk/|k|^2) / (mu |V| |k|^2) . sum_j f_j exp(-i k . y_j)`: the same coefficients
/// [`velocity_spectrum`] returns at those modes, exactly and in `O(N)` per mode (for the lowest
/// box modes at every diagnostic time). `m = 0` gives zeros.
pub fn velocity_modes(
    y: &[[f64; 3]],
    f: &[[f64; 3]],
    box_length: f64,
    mu: f64,
    modes: &[[i64; 3]],
) -> Vec<[Complex64; 3]> {
    let vol = box_length.powi(3);
    modes
        .iter()
        .map(|m| {
            let k = m.map(|c| 2.0 * PI * c as f64 / box_length);
            let k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
            if k2 == 0.0 {
                return [Complex64::default(); 3];
            }
            // Fixed chunks summed in order: the same bits for any thread count.
            let parts = crate::reduce::chunk_partials(y.len(), |chunk| {
                let mut acc = [Complex64::default(); 3];
                for j in chunk {
                    let phase = -(k[0] * y[j][0] + k[1] * y[j][1] + k[2] * y[j][2]);
                    let e = Complex64::new(phase.cos(), phase.sin());
                    for d in 0..3 {
                        acc[d] += e * f[j][d];
                    }
                }
                acc
            });
            let mut fk = [Complex64::default(); 3];
            for p in &parts {
                for d in 0..3 {
                    fk[d] += p[d];
                }
            }
            let kf = k[0] * fk[0] + k[1] * fk[1] + k[2] * fk[2];
            let s = 1.0 / (mu * vol * k2);
            std::array::from_fn(|d| (fk[d] - kf * (k[d] / k2)) * s)
        })
        .collect()
}

/// Spherically averaged inverse transform of a power spectrum on a `modes^3` cube (centred mode
/// order): `Corr(r) = sum_k power(k) j0(|k| r)` at `r = 0, w, 2w, ...` up to `L/2`, `w` the
/// given spacing or `L/128`.
pub fn radial_autocorrelation(
    power: &[f64],
    modes: usize,
    box_length: f64,
    spacing: Option<f64>,
) -> RadialCorrelation {
    let n = modes;
    let w = spacing.unwrap_or(box_length / 128.0);
    assert!(w > 0.0, "radial spacing must be positive, got {w}");
    // Power per integer |m|^2.
    let mut shells = std::collections::BTreeMap::<i64, f64>::new();
    for (idx, p) in power.iter().enumerate() {
        let m = [idx % n, (idx / n) % n, idx / (n * n)].map(|i| mode_of(i, n));
        *shells
            .entry(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
            .or_default() += p;
    }
    let count = ((box_length / 2.0) / w * (1.0 + 1e-12)).floor() as usize + 1;
    let r: Vec<f64> = (0..count).map(|i| i as f64 * w).collect();
    let value = r
        .iter()
        .map(|&r| {
            shells
                .iter()
                .map(|(&m2, &p)| {
                    let x = 2.0 * PI * (m2 as f64).sqrt() * r / box_length;
                    p * if x < 1e-4 {
                        1.0 - x * x / 6.0
                    } else {
                        x.sin() / x
                    }
                })
                .sum()
        })
        .collect();
    RadialCorrelation { r, value, modes: n }
}
