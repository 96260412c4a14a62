//! A run config as a scene resolves it: a particle or a mean-field run.

use crate::run::meanfield::MeanFieldRunConfig;
use crate::run::particle::ParticleRunConfig;

/// A run config resolved from a scene.
#[derive(Clone, Debug, PartialEq)]
pub enum RunConfig {
    /// A particle run.
    Particle(ParticleRunConfig),
    /// A mean-field run.
    MeanField(MeanFieldRunConfig),
}

impl RunConfig {
    /// Model name as in run directories.
    pub fn model(&self) -> &'static str {
        match self {
            RunConfig::Particle(_) => "particle",
            RunConfig::MeanField(_) => "meanfield",
        }
    }

    /// One line describing the run's size.
    pub fn describe(&self) -> String {
        match self {
            RunConfig::Particle(c) => format!(
                "particle, {} rods, L/l = {}, nu = {}, {}, dt = {}, t_end = {}",
                c.rods
                    .unwrap_or((c.volume_fraction * c.box_length.powi(3)).round() as usize),
                c.box_length,
                c.volume_fraction,
                c.hydrodynamics,
                c.dt,
                c.t_end
            ),
            RunConfig::MeanField(c) => format!(
                "mean-field, {}^3, zeta = {}, D = {}, t_end = {}",
                c.grid, c.zeta, c.diffusion, c.t_end
            ),
        }
    }
}
