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

#[cfg(test)]
mod tests {
    #[test]
    fn eta_is_the_model_value() {
        assert!(
            (super::eta() - 0.183234).abs() < 1e-6,
            "eta = {}",
            super::eta()
        );
    }
}
