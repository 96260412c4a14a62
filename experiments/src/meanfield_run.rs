//! `motile meanfield run`: drives the mean-field stepper (MODEL.md §4) and owns the run
//! directory, the time-step control, the output schedule, snapshots and the closure-table cache.
//!
//! Time step: `dt = min(dt_max, cfl h / max(|u_x| + |u_y| + |u_z|))` (the sum over axes), its
//! growth capped at `max_step_ratio` per step (below 1 + sqrt 2, the zero-stability limit of
//! variable-step SBDF2). Output times are reached by spreading the last one or two steps before
//! them evenly, never by a tiny clipped step followed by a large ratio.

use crate::io::write_atomic;
use crate::rundir::{RunDir, TimeSeries};
use crate::snapshot::FieldSnapshot;
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use motile_meanfield::closure::BinghamClosure;
use motile_meanfield::solver::{
    MeanFieldParams, MeanFieldRhs, MeanFieldStepper, SBDF2, SYM, SpectralGrid,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Configuration of a mean-field run (units: box side 1, time mu/|sigma_a|).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MeanFieldRunConfig {
    /// Grid points per dimension (even). Default 32; allowed [8, 256].
    pub grid: usize,
    /// zeta = sigma_b / mu. Default 0.1421 (nu = 0.625); allowed [0, 10].
    pub zeta: f64,
    /// Diffusion D. Default 1e-4; allowed [0, 1].
    pub diffusion: f64,
    /// End time. Default 20.
    pub t_end: f64,
    /// Largest time step. Default 0.05; allowed (0, 1].
    pub dt_max: f64,
    /// CFL number. Default 0.5; allowed (0, 2].
    pub cfl: f64,
    /// Largest ratio of consecutive steps. Default 1.5; allowed (1, 2.4).
    pub max_step_ratio: f64,
    /// "random" (perturbations with wavenumbers |m| in [mode_min, mode_max]) or "plane_wave"
    /// (Q_xy = amplitude cos(2 pi m.x) with m = `wavevector`).
    pub initial: String,
    /// Perturbation amplitude. Default 1e-2; allowed (0, 0.3].
    pub amplitude: f64,
    /// Smallest integer wavenumber of random perturbations. Default 1.
    pub mode_min: usize,
    /// Largest integer wavenumber of random perturbations. Default 4.
    pub mode_max: usize,
    /// Integer wavevector of the plane wave. Default [1, 0, 0].
    pub wavevector: [i64; 3],
    /// Seed of the random perturbations.
    pub seed: u64,
    /// Relative tolerance of the Stokes fixed point. Default 1e-8.
    pub fixed_point_tolerance: f64,
    /// Iteration cap of the fixed point. Default 50.
    pub fixed_point_max_iterations: usize,
    /// Chebyshev degree of the closure tables. Default 80.
    pub closure_degree: usize,
    /// Time between diagnostics rows. Default 0.5.
    pub diagnostic_interval: f64,
    /// Time between snapshots. Default 5.
    pub snapshot_interval: f64,
}

impl Default for MeanFieldRunConfig {
    fn default() -> Self {
        Self {
            grid: 32,
            zeta: 0.1421,
            diffusion: 1e-4,
            t_end: 20.0,
            dt_max: 0.05,
            cfl: 0.5,
            max_step_ratio: 1.5,
            initial: "random".into(),
            amplitude: 1e-2,
            mode_min: 1,
            mode_max: 4,
            wavevector: [1, 0, 0],
            seed: 1,
            fixed_point_tolerance: 1e-8,
            fixed_point_max_iterations: 50,
            closure_degree: 80,
            diagnostic_interval: 0.5,
            snapshot_interval: 5.0,
        }
    }
}

impl MeanFieldRunConfig {
    /// Check every field; the message names the field, the value and the allowed range.
    pub fn validate(&self) -> Result<(), String> {
        let chk = |name: &str, v: f64, lo: f64, hi: f64, open: bool| -> Result<(), String> {
            let ok = v.is_finite() && (if open { v > lo } else { v >= lo }) && v <= hi;
            if ok {
                Ok(())
            } else {
                Err(format!(
                    "{name} = {v} is outside the allowed range {}{lo}, {hi}]",
                    if open { "(" } else { "[" }
                ))
            }
        };
        if !(8..=256).contains(&self.grid) || self.grid % 2 == 1 {
            return Err(format!(
                "grid = {} must be even and in [8, 256] (points per dimension)",
                self.grid
            ));
        }
        chk("zeta", self.zeta, 0.0, 10.0, false)?;
        chk("diffusion", self.diffusion, 0.0, 1.0, false)?;
        chk("t_end", self.t_end, 0.0, 1e6, true)?;
        chk("dt_max", self.dt_max, 0.0, 1.0, true)?;
        chk("cfl", self.cfl, 0.0, 2.0, true)?;
        chk("max_step_ratio", self.max_step_ratio, 1.0, 2.4, true)?;
        chk("amplitude", self.amplitude, 0.0, 0.3, true)?;
        chk(
            "fixed_point_tolerance",
            self.fixed_point_tolerance,
            0.0,
            1e-2,
            true,
        )?;
        chk(
            "diagnostic_interval",
            self.diagnostic_interval,
            0.0,
            1e6,
            true,
        )?;
        chk("snapshot_interval", self.snapshot_interval, 0.0, 1e6, true)?;
        if !(10..=200).contains(&self.closure_degree) {
            return Err(format!(
                "closure_degree = {} is outside the allowed range [10, 200]",
                self.closure_degree
            ));
        }
        if self.initial == "plane_wave" {
            if self
                .wavevector
                .iter()
                .any(|m| 3 * m.unsigned_abs() as usize > self.grid)
                || self.wavevector == [0; 3]
            {
                return Err(format!(
                    "wavevector = {:?}: need a non-zero integer vector with every |m| <= grid/3 = {} (the 2/3 rule keeps |m| <= n/3)",
                    self.wavevector,
                    self.grid / 3
                ));
            }
        } else if self.mode_min < 1
            || self.mode_min > self.mode_max
            || 3 * self.mode_max > self.grid
        {
            return Err(format!(
                "mode_min = {}, mode_max = {}: need 1 <= mode_min <= mode_max <= grid/3 = {} (the 2/3 rule keeps |m| <= n/3)",
                self.mode_min,
                self.mode_max,
                self.grid / 3
            ));
        }
        if !["random", "plane_wave"].contains(&self.initial.as_str()) {
            return Err(format!(
                "initial = \"{}\": allowed \"random\" or \"plane_wave\"",
                self.initial
            ));
        }
        Ok(())
    }
}

/// Parse a mean-field `config.toml` (with or without the `[motile]` header).
pub fn parse_config(text: &str, path: &Path) -> anyhow::Result<MeanFieldRunConfig> {
    let mut table: toml::Table =
        toml::from_str(text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    table.remove("motile");
    let cfg: MeanFieldRunConfig = table
        .try_into()
        .map_err(|e: toml::de::Error| anyhow::anyhow!("{}: {}", path.display(), e.message()))?;
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(cfg)
}

/// Where closure tables are cached: `$MOTILE_CACHE_DIR`, else `~/.cache/motile`.
pub fn cache_dir() -> PathBuf {
    std::env::var_os("MOTILE_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/motile")))
        .unwrap_or_else(|| PathBuf::from(".motile-cache"))
}

/// Closure tables of a degree: loaded from the cache, or built and cached.
pub fn closure_tables(degree: usize) -> anyhow::Result<BinghamClosure> {
    let path = cache_dir().join(format!("bingham_degree{degree}.bin"));
    if let Ok(bytes) = std::fs::read(&path)
        && let Some(c) = BinghamClosure::from_bytes(&bytes, degree)
    {
        return Ok(c);
    }
    let c = BinghamClosure::new(degree)
        .map_err(|e| anyhow::anyhow!("building the closure tables: {e}"))?;
    // A cache that cannot be written is not an error: the tables are rebuilt next time.
    let _ = write_atomic(&path, &c.to_bytes());
    Ok(c)
}

/// Initial Q on the grid.
pub fn initial_state(cfg: &MeanFieldRunConfig) -> [Vec<f64>; 6] {
    let n = cfg.grid;
    let mut q: [Vec<f64>; 6] = std::array::from_fn(|c| {
        vec![if SYM[c].0 == SYM[c].1 { 1.0 / 3.0 } else { 0.0 }; n * n * n]
    });
    let point = |idx: usize| [idx % n, (idx / n) % n, idx / (n * n)].map(|i| i as f64 / n as f64);
    if cfg.initial == "plane_wave" {
        let m = cfg.wavevector.map(|v| v as f64);
        for idx in 0..n * n * n {
            let x = point(idx);
            q[1][idx] +=
                cfg.amplitude * (2.0 * PI * (m[0] * x[0] + m[1] * x[1] + m[2] * x[2])).cos();
        }
        return q;
    }
    // Random traceless perturbations: a sum of modes in the band, each with random traceless
    // symmetric amplitude and phase, normalised so the largest |Q' component| equals amplitude.
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let (lo, hi) = (cfg.mode_min as i64, cfg.mode_max as i64);
    let mut pert: [Vec<f64>; 6] = std::array::from_fn(|_| vec![0.0; n * n * n]);
    for mx in -hi..=hi {
        for my in -hi..=hi {
            for mz in 0..=hi {
                let m2 = mx * mx + my * my + mz * mz;
                if m2 < lo * lo || m2 > hi * hi || (mz == 0 && (my < 0 || (my == 0 && mx <= 0))) {
                    continue;
                }
                let mut a: [f64; 6] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                let tr = (a[0] + a[3] + a[5]) / 3.0;
                a[0] -= tr;
                a[3] -= tr;
                a[5] -= tr;
                let phase: f64 = rng.random_range(0.0..2.0 * PI);
                for idx in 0..n * n * n {
                    let x = point(idx);
                    let s = (2.0 * PI * (mx as f64 * x[0] + my as f64 * x[1] + mz as f64 * x[2])
                        + phase)
                        .cos();
                    for c in 0..6 {
                        pert[c][idx] += a[c] * s;
                    }
                }
            }
        }
    }
    let peak = pert
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-300);
    for c in 0..6 {
        for idx in 0..n * n * n {
            q[c][idx] += cfg.amplitude * pert[c][idx] / peak;
        }
    }
    q
}

/// Columns of a mean-field `timeseries.csv`.
pub const COLUMNS: [&str; 13] = [
    "t [mu/|sigma_a|]",
    "dt [mu/|sigma_a|]",
    "u_l2 [L |sigma_a|/mu]",
    "u_max [L |sigma_a|/mu]",
    "E_l2 [|sigma_a|/mu]",
    "E:Q [|sigma_a|/mu]",
    "fixed_point_iterations [1]",
    "fixed_point_residual [1]",
    "min_eigenvalue [1]",
    "max_eigenvalue [1]",
    "entropy [1]",
    "energy_identity_residual [1]",
    "steps [1]",
];

/// What a run did.
#[derive(Clone, Debug)]
pub struct MeanFieldSummary {
    /// Steps taken.
    pub steps: u64,
    /// Wall seconds.
    pub seconds: f64,
    /// Diagnostics.
    pub timeseries: TimeSeries,
}

/// Run the mean-field model into `out`.
pub fn run_meanfield(
    cfg: &MeanFieldRunConfig,
    out: &Path,
    progress: bool,
) -> anyhow::Result<MeanFieldSummary> {
    cfg.validate().map_err(|e| anyhow::anyhow!("config: {e}"))?;
    let run = RunDir::create(out, "meanfield", cfg.seed, cfg)?;
    let t_tables = Instant::now();
    let closure = closure_tables(cfg.closure_degree)?;
    run.log(&format!(
        "closure tables (degree {}) ready in {:.1} s",
        cfg.closure_degree,
        t_tables.elapsed().as_secs_f64()
    ))?;
    let grid = SpectralGrid::new(cfg.grid);
    let params = MeanFieldParams {
        zeta: cfg.zeta,
        diffusion: cfg.diffusion,
        fixed_point_tolerance: cfg.fixed_point_tolerance,
        fixed_point_max_iterations: cfg.fixed_point_max_iterations,
    };
    let rhs = MeanFieldRhs {
        grid: &grid,
        closure: &closure,
        params: &params,
    };
    let mut stepper = MeanFieldStepper::new(&grid, &initial_state(cfg), SBDF2);
    let mut ts = TimeSeries::new(&COLUMNS);
    let bar = if progress {
        ProgressBar::new(1000)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} t {msg} [{elapsed} < {eta}]").context("template")?,
    );
    let h = 1.0 / cfg.grid as f64;
    let mut dt = cfg.dt_max.min(0.1 * cfg.diagnostic_interval);
    let mut prev_dt = dt;
    let (mut next_diag, mut next_snap, mut snap_index) = (0.0, 0.0, 0usize);
    let mut steps = 0u64;
    let t0 = Instant::now();
    let eps = 1e-9 * cfg.t_end;
    while stepper.t < cfg.t_end - eps {
        let t = stepper.t;
        let at_diag = t >= next_diag - eps;
        let at_snap = t >= next_snap - eps;
        if at_diag {
            next_diag += cfg.diagnostic_interval;
        }
        if at_snap {
            // The velocity of this Q (the stepper's is that of the previous step's state).
            let ev = rhs
                .eval(&stepper.q_hat, &stepper.u_hat)
                .map_err(|e| anyhow::anyhow!("snapshot at t = {t}: {e}"))?;
            let q = ev.q;
            let u: [Vec<f64>; 3] = std::array::from_fn(|i| grid.inverse(&ev.u[i]));
            let snap = FieldSnapshot {
                time: t,
                step: steps,
                box_length: 1.0,
                grid: cfg.grid,
                q,
                u,
            };
            snap.write(&run.snapshot_path(snap_index))?;
            snap_index += 1;
            next_snap += cfg.snapshot_interval;
        }
        // Output time ahead: spread the remaining time over at most two equal steps.
        let target = next_diag.min(next_snap).min(cfg.t_end);
        let remaining = target - t;
        debug_assert!(remaining > 0.0, "output clocks must be ahead of t");
        let k = (remaining / dt).ceil().max(1.0);
        let this_dt = if k <= 2.0 { remaining / k } else { dt };
        let report = match stepper.step(&rhs, this_dt) {
            Ok(r) => r,
            Err(e) => {
                run.log(&format!("step at t = {t} failed: {e}"))?;
                bail!("mean-field step at t = {t:.4} (dt = {this_dt:.3e}) failed: {e}");
            }
        };
        steps += 1;
        if !report.u_l2.is_finite() {
            bail!("mean-field run diverged at t = {t:.4}: ||u|| is not finite");
        }
        if at_diag {
            ts.push(vec![
                t,
                this_dt,
                report.u_l2,
                report.u_max,
                report.e_l2,
                report.e_dot_q,
                report.rhs.iterations as f64,
                report.rhs.residual,
                report.min_eigenvalue,
                report.max_eigenvalue,
                report.entropy,
                report.energy_residual,
                steps as f64,
            ]);
            ts.write(&run.path().join("timeseries.csv"))?;
            bar.set_position((1000.0 * stepper.t / cfg.t_end) as u64);
            bar.set_message(format!(
                "{:.3} / {}, dt {:.2e}, ||u|| {:.3e}",
                stepper.t, cfg.t_end, this_dt, report.u_l2
            ));
        }
        // Next step from the CFL condition, growth capped.
        let cfl_dt = if report.u_max > 0.0 {
            cfg.cfl * h / report.u_max
        } else {
            cfg.dt_max
        };
        let base = if this_dt < dt {
            this_dt.max(prev_dt.min(dt))
        } else {
            this_dt
        };
        prev_dt = this_dt;
        dt = cfl_dt.min(cfg.dt_max).min(cfg.max_step_ratio * base);
    }
    bar.finish();
    let seconds = t0.elapsed().as_secs_f64();
    run.log(&format!(
        "finished at t = {} after {steps} steps in {seconds:.1} s",
        stepper.t
    ))?;
    Ok(MeanFieldSummary {
        steps,
        seconds,
        timeseries: ts,
    })
}
