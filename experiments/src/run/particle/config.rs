//! The particle run's config (`config.toml`): every key with its default and allowed range,
//! validated with messages that name the field; the mobility it selects.

use crate::io::rundir::{parse_run_config_with, range};
use crate::run::memory::CUDA_CONTEXT_BYTES;
pub use crate::run::memory::GpuMemoryNeed;
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::explicit::ExplicitSlender;
use motile_particle::hydro::gmres::GmresParams;
use motile_particle::hydro::mobility::{LocalDrag, Mobility};
use motile_particle::hydro::slender::{SlenderBody, SlenderParams, default_rpy_radius};
use motile_particle::model::level::Hydrodynamics;
use motile_particle::step::contact::ContactParams;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Configuration of a particle run (`config.toml`), every field with its default.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ParticleRunConfig {
    /// Box side L/l. Default 10; allowed [2, 1000].
    pub box_length: f64,
    /// Effective volume fraction nu = N l^3 / L^3 for a random start. Default 0.625 (dilute);
    /// allowed (0, 6] (random sequential addition stalls a little above 5).
    pub volume_fraction: f64,
    /// Number of rods N for a random start; when set it replaces `volume_fraction`
    /// (nu = N / (L/l)^3 must still lie in (0, 6]). Default: unset.
    pub rods: Option<usize>,
    /// Time step, 1/beta. Default 0.002; allowed (0, 0.2]. Larger steps leave larger
    /// overlaps (of order (dt w)^2 l) and need a larger contact.margin.
    pub dt: f64,
    /// End time, 1/beta. Default 2.
    pub t_end: f64,
    /// Random seed of the initial configuration. Default 1.
    pub seed: u64,
    /// Rod diameter b (rod lengths). Default 0.2 (the source paper's l/5); allowed (0, 0.5].
    /// Sets the contact distance and the slender-body coefficient eta = ln(2l/b)/(4 pi mu), so
    /// also zeta = nu/(24 eta) and the time unit of the comparison with the mean-field model.
    pub diameter: f64,
    /// Hydrodynamic coupling: "none" (free swimming with local drag, no flow), "dipole" (point
    /// stresslets moved by the periodic flow, docs/MODEL.md §2: one fast sum per step),
    /// "sbt-explicit" (each rod's isolated-swimmer force density, one fast sum per step) or
    /// "sbt" (slender-body theory, docs/MODEL.md §1: a GMRES solve per step, several fast sums
    /// each). Default "none".
    pub hydrodynamics: Hydrodynamics,
    /// Settings of the hydrodynamic models.
    pub hydro: HydroConfig,
    /// Where the step runs: "cpu" (the worker threads) or "gpu" (a build with `--features
    /// gpu`: the whole step at every level, the rods resident on the device, with the flow's
    /// sums and, at "sbt", GMRES there too). "gpu" needs one process (not MPI ranks). Default
    /// "cpu".
    pub device: crate::run::Device,
    /// How the GPU's sums spread their sources onto the grid ([`GpuSpreader`]): "cells" (the
    /// default), "sorted" or "atomic". Used where `device = "gpu"`, ignored on the CPU; left
    /// out of the resolved config at its default.
    #[serde(skip_serializing_if = "GpuSpreader::is_default")]
    pub gpu_spreader: GpuSpreader,
    /// "random" (isotropic), "perturbation" (orientations drawn from
    /// `Psi = (1 + (15/2) Q'(x) : pp) / 4 pi` with `Q'` from `[perturbation]`: the mean-field
    /// model's initial field, docs/MODEL.md §5), or a file: a particle snapshot (.h5) or a text table
    /// with one rod per line, `x y z px py pz`.
    pub initial: String,
    /// The perturbation of `initial = "perturbation"`.
    pub perturbation: PerturbationConfig,
    /// Time between time-series rows, 1/beta. Default 0.02.
    pub diagnostic_interval: f64,
    /// Time between snapshots, 1/beta. Default 0.2.
    pub snapshot_interval: f64,
    /// Time between checkpoints, 1/beta. Default 0.5.
    pub checkpoint_interval: f64,
    /// Also checkpoint when this much wall-clock time has passed since the last one, seconds.
    /// Default 900; allowed (0, 1e7].
    pub checkpoint_wall_seconds: f64,
    /// Regular checkpoints kept (older ones are deleted). Default 3; allowed [1, 1000].
    pub checkpoints_kept: usize,
    /// Write a VTK PolyData file (.vtp) with each snapshot, and a .pvd index. Default true.
    pub vtk: bool,
    /// Also write `modes.csv`: the flow's complex amplitudes at the three lowest box modes
    /// (`m = (1,0,0), (0,1,0), (0,0,1)`) at every diagnostic time, for fits of the lowest
    /// mode's complex growth rate. Default false (then the key is left out of the resolved
    /// config); needs hydrodynamics.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub lowest_modes: bool,
    /// Contact solver settings.
    pub contact: ContactParams,
}

/// How the GPU's sums spread their sources onto the grid (the library's
/// `motile_particle::ewald::gpu::SpreadMethod`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GpuSpreader {
    /// Output-driven, without atomics: each bin of grid cells sums the points that reach it,
    /// in the same order in every run (the sums repeat bit for bit on a GPU).
    #[default]
    Cells,
    /// The per-point spreader with global atomics, the points in bin order. On the host
    /// emulation of the kernels, where each GPU thread is an OS thread, it is about 100 times
    /// faster than "cells" (0.05 s against 6.5 s for a sum of 1 728 points on 2 cores).
    Sorted,
    /// The per-point spreader with global atomics in the points' own order: the slow twin.
    Atomic,
}

impl GpuSpreader {
    /// Whether this is the default (left out of the resolved config).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

impl Default for ParticleRunConfig {
    fn default() -> Self {
        Self {
            box_length: 10.0,
            volume_fraction: 0.625,
            rods: None,
            dt: 0.002,
            t_end: 2.0,
            seed: 1,
            diameter: motile_particle::model::units::DEFAULT_DIAMETER,
            hydrodynamics: Hydrodynamics::None,
            hydro: HydroConfig::default(),
            device: crate::run::Device::Cpu,
            gpu_spreader: GpuSpreader::Cells,
            initial: "random".into(),
            perturbation: PerturbationConfig::default(),
            diagnostic_interval: 0.02,
            snapshot_interval: 0.2,
            checkpoint_interval: 0.5,
            checkpoint_wall_seconds: 900.0,
            checkpoints_kept: 3,
            vtk: true,
            lowest_modes: false,
            contact: ContactParams::default(),
        }
    }
}

/// A perturbation of the isotropic state (`[perturbation]`), the same keys and function as a
/// mean-field run's initial field (`initial`, `amplitude`, `mode_min`, `mode_max`, `seed`,
/// `wavevector`), on the particle box scaled to the unit box.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PerturbationConfig {
    /// "random" (modes with `|m|` in `[mode_min, mode_max]`, random traceless amplitudes and
    /// phases) or "plane_wave" (`Q'_xy = amplitude cos(2 pi m . x / L)`). Default "random".
    pub kind: String,
    /// Largest component of `Q'`. Default 0.02; allowed (0, 0.1] (the distribution must stay
    /// positive: `|Q'|_F < 2/15` everywhere, checked).
    pub amplitude: f64,
    /// Smallest integer wavenumber. Default 1.
    pub mode_min: usize,
    /// Largest integer wavenumber. Default 2.
    pub mode_max: usize,
    /// Seed of the amplitudes and phases (not of the rods: that is the run's `seed`). Default 1.
    pub seed: u64,
    /// Plane wave's integer wavevector. Default [1, 0, 0].
    pub wavevector: [i64; 3],
}

impl Default for PerturbationConfig {
    fn default() -> Self {
        Self {
            kind: "random".into(),
            amplitude: 0.02,
            mode_min: 1,
            mode_max: 2,
            seed: 1,
            wavevector: [1, 0, 0],
        }
    }
}

impl PerturbationConfig {
    /// The perturbation (the mean-field library's description of it).
    pub fn perturbation(&self) -> motile_meanfield::initial::Perturbation {
        use motile_meanfield::initial::Perturbation;
        if self.kind == "plane_wave" {
            Perturbation::PlaneWave {
                amplitude: self.amplitude,
                wavevector: self.wavevector,
            }
        } else {
            Perturbation::Random {
                amplitude: self.amplitude,
                mode_min: self.mode_min,
                mode_max: self.mode_max,
                seed: self.seed,
            }
        }
    }

    fn validate(&self) -> Result<(), String> {
        if !["random", "plane_wave"].contains(&self.kind.as_str()) {
            return Err(format!(
                "perturbation.kind = \"{}\": allowed \"random\" or \"plane_wave\"",
                self.kind
            ));
        }
        range(
            "perturbation.amplitude",
            self.amplitude,
            0.0,
            0.1,
            true,
            "largest component of Q'",
        )?;
        if self.mode_min < 1 || self.mode_min > self.mode_max || self.mode_max > 16 {
            return Err(format!(
                "perturbation.mode_min = {}, mode_max = {}: need 1 <= mode_min <= mode_max <= 16",
                self.mode_min, self.mode_max
            ));
        }
        if self.kind == "plane_wave" && self.wavevector == [0, 0, 0] {
            return Err("perturbation.wavevector = [0, 0, 0]: a plane wave needs m != 0".into());
        }
        Ok(())
    }
}

/// Settings of the hydrodynamic models (`[hydro]`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct HydroConfig {
    /// Relative tolerance of the periodic RPY / stresslet sums (spectral Ewald): the largest
    /// error of each output over all rods, and its L2 norm, at most this fraction of the
    /// output's (docs/accuracy.md). Default 1e-4; allowed [1e-10, 1e-1]. Smaller costs more
    /// real-space pairs and Fourier modes; force-free (swimming) data cost more than random
    /// forces at the same tolerance, since their flows are weaker than their forces.
    pub sum_tolerance: f64,
    /// Quadrature nodes per rod for "sbt", even (Gauss-Legendre on each half rod). Default 4;
    /// allowed 2..=64. Cost grows linearly; error falls fast (see BENCHMARKS.md).
    pub quadrature_points: usize,
    /// GMRES relative residual tolerance for "sbt". Default 1e-5; allowed [1e-14, 1e-1].
    pub gmres_tolerance: f64,
    /// GMRES iteration cap; a solve that reaches it stops the run. Default 100; allowed
    /// [1, 10000].
    pub gmres_max_iterations: usize,
    /// GMRES restart length. Default 40; allowed [1, 1000].
    pub gmres_restart: usize,
    /// RPY radius a (rod lengths). Default (sqrt 3/2)(b/2) of the run's diameter b (0.0866 at
    /// b = 0.2), filled in when the config is read; allowed (0, 0.5].
    pub rpy_radius: Option<f64>,
}

impl Default for HydroConfig {
    /// The library's defaults ([`SlenderParams`], [`GmresParams`]): one source for each.
    fn default() -> Self {
        let s = SlenderParams::default();
        Self {
            sum_tolerance: 1e-4,
            quadrature_points: s.quadrature_points,
            gmres_tolerance: s.gmres.tol,
            gmres_max_iterations: s.gmres.max_iterations,
            gmres_restart: s.gmres.restart,
            rpy_radius: None,
        }
    }
}

impl HydroConfig {
    /// The slender-body model's settings for rods of diameter `diameter`.
    pub fn slender(&self, diameter: f64) -> SlenderParams {
        SlenderParams {
            diameter,
            quadrature_points: self.quadrature_points,
            rpy_radius: self
                .rpy_radius
                .unwrap_or_else(|| default_rpy_radius(diameter)),
            gmres: GmresParams {
                tol: self.gmres_tolerance,
                restart: self.gmres_restart,
                max_iterations: self.gmres_max_iterations,
            },
        }
    }

    fn validate(&self, diameter: f64) -> Result<(), String> {
        range(
            "hydro.sum_tolerance",
            self.sum_tolerance,
            1e-10,
            1e-1,
            false,
            "relative",
        )?;
        // The slender-body model's own checks, under this table's key names.
        self.slender(diameter).validate().map_err(|e| {
            let key = match e.name.as_str() {
                "gmres.tol" => "gmres_tolerance".to_string(),
                "gmres.restart" => "gmres_restart".to_string(),
                "gmres.max_iterations" => "gmres_max_iterations".to_string(),
                other => other.to_string(),
            };
            e.renamed(&key).in_table("hydro").to_string()
        })?;
        Ok(())
    }
}

impl ParticleRunConfig {
    /// The config with every default that depends on another key filled in (the RPY radius
    /// from the diameter), as `config.toml` records it.
    pub fn resolved(&self) -> Self {
        let mut cfg = self.clone();
        cfg.hydro.rpy_radius = Some(cfg.hydro.slender(cfg.diameter).rpy_radius);
        cfg
    }

    /// Make a relative `initial` file name relative to `base` (the folder of the config file
    /// it came from) instead of the working directory.
    pub fn resolve_paths(&mut self, base: &Path) {
        if !["random", "perturbation"].contains(&self.initial.as_str())
            && Path::new(&self.initial).is_relative()
        {
            let p = base.join(&self.initial);
            self.initial = std::path::absolute(&p)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned();
        }
    }

    /// Check every field; the message names the field, the value, the range and the unit.
    pub fn validate(&self) -> Result<(), String> {
        range(
            "box_length",
            self.box_length,
            2.0,
            1000.0,
            false,
            "rod lengths",
        )?;
        range(
            "volume_fraction",
            self.volume_fraction,
            0.0,
            6.0,
            true,
            "N l^3 / L^3",
        )?;
        range("dt", self.dt, 0.0, 0.2, true, "1/beta")?;
        if self.lowest_modes && !self.hydrodynamics.has_flow() {
            return Err(
                "lowest_modes = true: the modes are those of the flow, and hydrodynamics = \"none\" has none"
                    .into(),
            );
        }
        motile_particle::model::units::check_diameter(self.diameter).map_err(|e| e.to_string())?;
        self.perturbation.validate()?;
        range("t_end", self.t_end, 0.0, 1e9, true, "1/beta")?;
        for (name, v) in [
            ("diagnostic_interval", self.diagnostic_interval),
            ("snapshot_interval", self.snapshot_interval),
            ("checkpoint_interval", self.checkpoint_interval),
        ] {
            range(name, v, self.dt, 1e9, false, "1/beta, at least dt")?;
        }
        range(
            "checkpoint_wall_seconds",
            self.checkpoint_wall_seconds,
            0.0,
            1e7,
            true,
            "seconds of wall-clock time",
        )?;
        range(
            "checkpoints_kept",
            self.checkpoints_kept as f64,
            1.0,
            1000.0,
            false,
            "files",
        )?;
        self.contact
            .validate()
            .map_err(|e| e.in_table("contact").to_string())?;
        self.hydro.validate(self.diameter)?;
        if let Some(n) = self.rods {
            let nu = n as f64 / self.box_length.powi(3);
            if n == 0 || nu > 6.0 {
                return Err(format!(
                    "rods = {n} in a box of L/l = {} gives nu = N l^3/L^3 = {nu}, outside the allowed range (0, 6]",
                    self.box_length
                ));
            }
        }
        if self.contact.margin < 2.5 * self.dt {
            return Err(format!(
                "contact.margin = {} is smaller than the distance two rods close in one step (2 U dt = {}): raise it above {}",
                self.contact.margin,
                2.0 * self.dt,
                2.5 * self.dt
            ));
        }
        // The step resident on the GPU searches neighbours in at least 3 cells of one contact
        // reach per axis.
        let reach = motile_particle::model::units::ROD_LENGTH + self.diameter + self.contact.margin;
        if self.resident() && self.box_length < 3.0 * reach {
            return Err(format!(
                "box_length = {} with device = \"gpu\" and hydrodynamics = \"{}\": the GPU step needs a box of at least 3 contact reaches (3 x (l + b + contact.margin) = {} l); use a larger box or device = \"cpu\"",
                self.box_length,
                self.hydrodynamics.name(),
                3.0 * reach
            ));
        }
        Ok(())
    }

    /// Whether the step runs resident on the GPU: `device = "gpu"`, at every level (the flow
    /// summed on the GPU where the mobility can, [`Self::resident`]'s callers ask it).
    pub(crate) fn resident(&self) -> bool {
        self.device == crate::run::Device::Gpu
    }

    /// Steps between events of an interval.
    pub(crate) fn every(&self, interval: f64) -> u64 {
        ((interval / self.dt).round() as u64).max(1)
    }

    /// Rods: `rods`, or `round(nu L^3)` where it is left out.
    pub fn rod_count(&self) -> usize {
        self.rods
            .unwrap_or((self.volume_fraction * self.box_length.powi(3)).round() as usize)
    }

    /// The GPU memory a resident run of this config needs ([`GpuMemoryNeed`]), from the
    /// measured figures (BENCHMARKS.md, "Memory per rod"): per rod the level's peak (the dipole
    /// step 2 212 bytes at L/l = 100: its buffers 1 817 and the driver's pool 395; `sbt` 6 520
    /// at L/l = 50, its GMRES vectors with it; `sbt-explicit` and `none` not measured, taken as
    /// the dipole step's, which sums as much).
    pub fn gpu_memory(&self) -> GpuMemoryNeed {
        GpuMemoryNeed {
            items: self.rod_count(),
            what: "rods",
            per_item: match self.hydrodynamics {
                Hydrodynamics::Sbt => 6_520.0,
                _ => 2_212.0,
            },
            context: CUDA_CONTEXT_BYTES,
        }
    }

    /// Total steps.
    pub fn total_steps(&self) -> u64 {
        (self.t_end / self.dt).round() as u64
    }
}

/// Parse a `config.toml` (with or without the `[motile]` header table).
pub fn parse_config(text: &str, path: &Path) -> anyhow::Result<ParticleRunConfig> {
    parse_run_config_with(text, path, intervals_from_dt, ParticleRunConfig::validate)
        .map(|c| c.resolved())
}

/// An output interval left to its default is never shorter than the step the config gives
/// (`dt = 0.05` without `diagnostic_interval` writes a row every step, not an error about a
/// key the user never wrote), nor the contact margin below what that step needs.
fn intervals_from_dt(c: &mut ParticleRunConfig, given: &toml::Table) {
    let dt = c.dt;
    for (key, value) in [
        ("diagnostic_interval", &mut c.diagnostic_interval),
        ("snapshot_interval", &mut c.snapshot_interval),
        ("checkpoint_interval", &mut c.checkpoint_interval),
    ] {
        if !given.contains_key(key) && *value < dt {
            *value = dt;
        }
    }
    // The contact margin likewise: at least the 2.5 U dt the validation asks of it (U = 1).
    let margin_given = given
        .get("contact")
        .and_then(|c| c.as_table())
        .is_some_and(|c| c.contains_key("margin"));
    if !margin_given && c.contact.margin < 2.5 * dt {
        c.contact.margin = 2.5 * dt;
    }
}

/// The mobility of one rank's part of a box shared by several: the dipole and slender-body
/// levels' sums are the shared one ([`motile_particle::ewald::shared`]).
pub(crate) fn shared_mobility(cfg: &ParticleRunConfig) -> anyhow::Result<Box<dyn Mobility>> {
    if cfg.device == crate::run::Device::Gpu {
        anyhow::bail!(
            "device = \"gpu\": the GPU sums run in one process, not shared among MPI ranks; run one process with the GPU, or the ranks with device = \"cpu\""
        );
    }
    let h = &cfg.hydro;
    let sum = || SpectralEwald::new(h.sum_tolerance).map(Box::new);
    Ok(match cfg.hydrodynamics {
        Hydrodynamics::Dipole => {
            Box::new(Dipole::new(sum()?, cfg.diameter).shared(h.sum_tolerance)?)
        }
        Hydrodynamics::SbtExplicit => {
            Box::new(ExplicitSlender::new(h.slender(cfg.diameter), sum()?).shared(h.sum_tolerance)?)
        }
        Hydrodynamics::Sbt => {
            Box::new(SlenderBody::new(h.slender(cfg.diameter), sum()?).shared(h.sum_tolerance)?)
        }
        Hydrodynamics::None => Box::new(LocalDrag::new(cfg.diameter)),
    })
}

/// The mobility named by `hydrodynamics` (validated).
pub fn mobility(cfg: &ParticleRunConfig) -> anyhow::Result<Box<dyn Mobility>> {
    let h = &cfg.hydro;
    let sum = || -> anyhow::Result<Box<SpectralEwald>> {
        Ok(Box::new(match cfg.device {
            crate::run::Device::Cpu => SpectralEwald::new(h.sum_tolerance)?,
            crate::run::Device::Gpu => gpu_sum(h.sum_tolerance, cfg.gpu_spreader)?,
        }))
    };
    Ok(match cfg.hydrodynamics {
        Hydrodynamics::Dipole => Box::new(Dipole::new(sum()?, cfg.diameter)),
        Hydrodynamics::SbtExplicit => {
            Box::new(ExplicitSlender::new(h.slender(cfg.diameter), sum()?))
        }
        Hydrodynamics::Sbt => Box::new(SlenderBody::new(h.slender(cfg.diameter), sum()?)),
        Hydrodynamics::None => Box::new(LocalDrag::new(cfg.diameter)),
    })
}

/// The fast sum with its Fourier part on the GPU (`MOTILE_GPU_BACKEND` says which device, CUDA
/// by default): an error, never a CPU fallback, where there is none.
#[cfg(feature = "gpu")]
fn gpu_sum(tol: f64, spreader: GpuSpreader) -> anyhow::Result<SpectralEwald> {
    use motile_particle::ewald::gpu::{GpuFourier, SpreadMethod};
    let mut dev = GpuFourier::open(crate::run::gpu_backend()?)
        .map_err(|e| anyhow::anyhow!("device = \"gpu\": {e}"))?;
    dev.set_spread_method(Some(match spreader {
        GpuSpreader::Cells => SpreadMethod::Cells,
        GpuSpreader::Sorted => SpreadMethod::Sorted,
        GpuSpreader::Atomic => SpreadMethod::Atomic,
    }));
    Ok(SpectralEwald::with_device(tol, dev)?)
}

#[cfg(not(feature = "gpu"))]
fn gpu_sum(_tol: f64, _spreader: GpuSpreader) -> anyhow::Result<SpectralEwald> {
    anyhow::bail!(
        "device = \"gpu\": this motile was built without GPU support; build it with `cargo install --path experiments --features gpu` (CUDA is loaded when a run starts: the build needs nothing but cargo)"
    )
}
