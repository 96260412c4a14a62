//! The units and fixed parameters of docs/MODEL.md §1: rod length `l = 1`, diameter `b = l/5`,
//! viscosity `mu = 1`, propulsion rate `beta = 1` (swimming speed `U = beta l = 1`, time unit
//! `1/beta`), slender-body coefficient `eta = ln(2l/b) / (4 pi mu)`.

/// Rod length `l`.
pub const ROD_LENGTH: f64 = 1.0;
/// Rod diameter `b = l/5`.
pub const DIAMETER: f64 = 0.2;
/// Viscosity `mu`.
pub const VISCOSITY: f64 = 1.0;
/// Swimming speed `U = beta l`.
pub const SWIM_SPEED: f64 = 1.0;

/// Slender-body coefficient `eta = ln(2 l / b) / (4 pi mu) = ln(10) / (4 pi)`.
pub fn eta() -> f64 {
    (2.0 * ROD_LENGTH / DIAMETER).ln() / (4.0 * std::f64::consts::PI * VISCOSITY)
}

/// The continuum model's time unit `mu/|sigma_a|` in particle time units (`1/beta`) at volume
/// fraction `nu`: `8 eta mu / nu` (docs/MODEL.md §5, U1).
pub fn meanfield_time_unit(nu: f64) -> f64 {
    8.0 * eta() * VISCOSITY / nu
}

/// Particle time (`1/beta`) and velocity normalised by `beta L` to the continuum's units at
/// volume fraction `nu` (docs/MODEL.md §5, U1): `t_mf = t_p nu/(8 eta mu)`,
/// `u_mf = (u_p/(beta L)) 8 eta mu/nu`.
pub fn particle_to_meanfield(t_p: f64, u_p_over_beta_l: f64, nu: f64) -> (f64, f64) {
    let s = meanfield_time_unit(nu);
    (t_p / s, u_p_over_beta_l * s)
}

/// The continuum's constraint parameter `zeta = nu / (24 eta mu)` of a particle suspension at
/// volume fraction `nu` (docs/MODEL.md §4-§5).
pub fn zeta(nu: f64) -> f64 {
    nu / (24.0 * eta() * VISCOSITY)
}

/// The continuum's linear growth rate (docs/MODEL.md M3 with `D = 0`), `(1/5)/(1 + zeta/15)` in
/// its own units.
pub fn continuum_growth_rate(zeta: f64) -> f64 {
    0.2 / (1.0 + zeta / 15.0)
}

#[cfg(test)]
mod tests {
    #[test]
    fn unit_conversions_are_u1() {
        // nu = 0.625: 8 eta = 1.465872, zeta = 0.625 / (24 eta) = 0.14212.
        let (t, u) = super::particle_to_meanfield(10.0, 0.01, 0.625);
        assert!((t - 10.0 * 0.625 / 1.465_872).abs() < 1e-5, "{t}");
        assert!((u - 0.01 * 1.465_872 / 0.625).abs() < 1e-7, "{u}");
        assert!((super::zeta(0.625) - 0.142_12).abs() < 1e-5);
        assert!((super::continuum_growth_rate(0.0) - 0.2).abs() < 1e-15);
    }

    #[test]
    fn eta_is_the_model_value() {
        assert!(
            (super::eta() - 0.183234).abs() < 1e-6,
            "eta = {}",
            super::eta()
        );
    }
}
