//! The units and fixed parameters of docs/MODEL.md §1: rod length `l = 1`, viscosity `mu = 1`,
//! propulsion rate `beta = 1` (swimming speed `U = beta l = 1`, time unit `1/beta`); the rod
//! diameter `b` is a run parameter (default `l/5`, the source paper's), and with it the
//! slender-body coefficient `eta = ln(2l/b) / (4 pi mu)` and every conversion to the continuum's
//! units, which depend on `eta`.

use motile_analysis::params::{InvalidParameter, check_range};

/// Rod length `l`.
pub const ROD_LENGTH: f64 = 1.0;
/// The default rod diameter `b = l/5` (the source paper's aspect ratio).
pub const DEFAULT_DIAMETER: f64 = 0.2;
/// Viscosity `mu`.
pub const VISCOSITY: f64 = 1.0;
/// Swimming speed `U = beta l`.
pub const SWIM_SPEED: f64 = 1.0;

/// The largest rod diameter allowed, `l/2`: slender-body theory (MODEL P2-P4) is an expansion in
/// `b/l`, and at `b = l/2` its error is already of order one (`eta` falls to `ln 4 / 4 pi`).
pub const MAX_DIAMETER: f64 = 0.5;

/// Check a rod diameter: `b` in `(0, l/2]` (rod lengths).
pub fn check_diameter(diameter: f64) -> Result<(), InvalidParameter> {
    check_range("diameter", diameter, 0.0, MAX_DIAMETER, true, "rod lengths")
}

/// Slender-body coefficient `eta = ln(2 l / b) / (4 pi mu)` of rods of diameter `b`
/// (`ln(10) / (4 pi)` at the default `b = l/5`).
pub fn eta(diameter: f64) -> f64 {
    (2.0 * ROD_LENGTH / diameter).ln() / (4.0 * std::f64::consts::PI * VISCOSITY)
}

/// The continuum model's time unit `mu/|sigma_a|` in particle time units (`1/beta`) at volume
/// fraction `nu` for rods of diameter `b`: `8 eta mu / nu` (docs/MODEL.md §5, U1).
pub fn meanfield_time_unit(nu: f64, diameter: f64) -> f64 {
    8.0 * eta(diameter) * VISCOSITY / nu
}

/// Particle time (`1/beta`) and velocity normalised by `beta L` to the continuum's units at
/// volume fraction `nu` for rods of diameter `b` (docs/MODEL.md §5, U1):
/// `t_mf = t_p nu/(8 eta mu)`, `u_mf = (u_p/(beta L)) 8 eta mu/nu`.
pub fn particle_to_meanfield(t_p: f64, u_p_over_beta_l: f64, nu: f64, diameter: f64) -> (f64, f64) {
    let s = meanfield_time_unit(nu, diameter);
    (t_p / s, u_p_over_beta_l * s)
}

/// The continuum's constraint parameter `zeta = nu / (24 eta mu)` of a suspension of rods of
/// diameter `b` at volume fraction `nu` (docs/MODEL.md §4-§5).
pub fn zeta(nu: f64, diameter: f64) -> f64 {
    nu / (24.0 * eta(diameter) * VISCOSITY)
}

/// The continuum's linear growth rate (docs/MODEL.md M3 with `D = 0`), `(1/5)/(1 + zeta/15)` in
/// its own units.
pub fn continuum_growth_rate(zeta: f64) -> f64 {
    0.2 / (1.0 + zeta / 15.0)
}

#[cfg(test)]
mod tests {
    use super::DEFAULT_DIAMETER as B;

    #[test]
    fn unit_conversions_are_u1() {
        // nu = 0.625: 8 eta = 1.465872, zeta = 0.625 / (24 eta) = 0.14212.
        let (t, u) = super::particle_to_meanfield(10.0, 0.01, 0.625, B);
        assert!((t - 10.0 * 0.625 / 1.465_872).abs() < 1e-5, "{t}");
        assert!((u - 0.01 * 1.465_872 / 0.625).abs() < 1e-7, "{u}");
        assert!((super::zeta(0.625, B) - 0.142_12).abs() < 1e-5);
        assert!((super::continuum_growth_rate(0.0) - 0.2).abs() < 1e-15);
    }

    #[test]
    fn eta_is_the_model_value() {
        let e = super::eta(B);
        assert!((e - 0.183234).abs() < 1e-6, "eta = {e}");
        // Thinner rods: eta = ln(2/b) / 4 pi, e.g. b = l/50: ln(100) / 4 pi = 0.366468.
        let thin = super::eta(0.02);
        assert!((thin - 0.366_468).abs() < 1e-6, "eta(l/50) = {thin}");
    }

    #[test]
    fn diameters_outside_zero_to_half_a_rod_are_refused() {
        for bad in [0.0, -0.1, 0.6, f64::NAN] {
            let e = super::check_diameter(bad).expect_err("refused");
            assert!(e.to_string().contains("diameter"), "{e}");
        }
        for good in [0.01, 0.2, 0.5] {
            super::check_diameter(good).unwrap();
        }
    }
}
