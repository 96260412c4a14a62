//! A run config as a scene resolves it: a particle or a mean-field run.

use crate::run::Device;
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

    /// Where the run's steps run (`device`).
    pub fn device(&self) -> Device {
        match self {
            RunConfig::Particle(c) => c.device,
            RunConfig::MeanField(c) => c.device,
        }
    }

    /// Run the steps on `device` (`motile run --device`).
    pub fn set_device(&mut self, device: Device) {
        match self {
            RunConfig::Particle(c) => c.device = device,
            RunConfig::MeanField(c) => c.device = device,
        }
    }

    /// One line describing the run's size (and the GPU, where it runs there).
    pub fn describe(&self) -> String {
        match self {
            RunConfig::Particle(c) => {
                format!(
                    "particle, {} rods, L/l = {}, nu = {}, {}, dt = {}, t_end = {}",
                    c.rod_count(),
                    c.box_length,
                    c.volume_fraction,
                    c.hydrodynamics,
                    c.dt,
                    c.t_end
                ) + on_gpu(c.device)
            }
            RunConfig::MeanField(c) => {
                format!(
                    "mean-field, {}^3, zeta = {}, D = {}, t_end = {}",
                    c.grid, c.zeta, c.diffusion, c.t_end
                ) + on_gpu(c.device)
            }
        }
    }
}

/// ", on the GPU" for a run there, nothing on the CPU.
fn on_gpu(device: Device) -> &'static str {
    match device {
        Device::Gpu => ", on the GPU",
        Device::Cpu => "",
    }
}
