//! The run loop's seam: a third model, free swimmers without interactions (`x(t) = x0 + U p t`,
//! exact), added as nothing but an adapter of `RunModel`, gets the whole loop: config next to
//! the results, time series, checkpoints on schedule, resume from the newest checkpoint, a
//! failed step saved as the last good state with a typed failure, and resume after the cause
//! is fixed.

use motile_experiments::io::checkpoint;
use motile_experiments::io::rundir::TimeSeries;
use motile_experiments::run::failure::{FailureKind, RunFailure};
use motile_experiments::run::{self, RunIo, RunModel, StepFailure};
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct FreeConfig {
    rods: usize,
    dt: f64,
    steps: u64,
    checkpoint_every: u64,
    seed: u64,
    /// A step that fails (to exercise the failure path); absent: none.
    fail_at: Option<u64>,
}

#[derive(Debug)]
struct Free {
    cfg: FreeConfig,
    x: Vec<[f64; 3]>,
    p: Vec<[f64; 3]>,
    step: u64,
}

/// Seeded start: positions and unit orientations from a small LCG.
fn initial(cfg: &FreeConfig) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut s = cfg.seed.wrapping_mul(6364136223846793005).wrapping_add(1);
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut x = Vec::new();
    let mut p = Vec::new();
    for _ in 0..cfg.rods {
        x.push([10.0 * next(), 10.0 * next(), 10.0 * next()]);
        let (z, phi) = (2.0 * next() - 1.0, 2.0 * std::f64::consts::PI * next());
        let r = (1.0 - z * z).sqrt();
        p.push([r * phi.cos(), r * phi.sin(), z]);
    }
    (x, p)
}

fn encode(step: u64, x: &[[f64; 3]]) -> Vec<u8> {
    let mut s = format!("{step}\n");
    for c in x {
        s += &format!(
            "{:016x} {:016x} {:016x}\n",
            c[0].to_bits(),
            c[1].to_bits(),
            c[2].to_bits()
        );
    }
    s.into_bytes()
}

impl RunModel for Free {
    type Config = FreeConfig;
    type Checkpoint = (u64, Vec<[f64; 3]>);
    const MODEL: &'static str = "free";

    fn columns() -> &'static [&'static str] {
        &["t [1/beta]", "mean_x [l]"]
    }
    fn validate(cfg: &FreeConfig) -> Result<(), String> {
        if cfg.dt > 0.0 && cfg.checkpoint_every > 0 {
            Ok(())
        } else {
            Err(format!(
                "dt = {} and checkpoint_every = {}: both must be positive",
                cfg.dt, cfg.checkpoint_every
            ))
        }
    }
    fn seed(cfg: &FreeConfig) -> u64 {
        cfg.seed
    }
    fn new(cfg: &FreeConfig) -> anyhow::Result<Self> {
        let (x, p) = initial(cfg);
        Ok(Free {
            cfg: cfg.clone(),
            x,
            p,
            step: 0,
        })
    }
    fn read_checkpoint(_cfg: &FreeConfig, path: &Path) -> anyhow::Result<Self::Checkpoint> {
        let text = std::fs::read_to_string(path)?;
        let mut lines = text.lines();
        let step = lines.next().unwrap().parse()?;
        let x = lines
            .map(|l| {
                let v: Vec<f64> = l
                    .split(' ')
                    .map(|h| f64::from_bits(u64::from_str_radix(h, 16).unwrap()))
                    .collect();
                [v[0], v[1], v[2]]
            })
            .collect();
        Ok((step, x))
    }
    fn from_checkpoint(
        cfg: &FreeConfig,
        (step, x): Self::Checkpoint,
        _path: &Path,
    ) -> anyhow::Result<Self> {
        let (_, p) = initial(cfg);
        Ok(Free {
            cfg: cfg.clone(),
            x,
            p,
            step,
        })
    }
    fn notes(&mut self) -> Vec<String> {
        vec![format!("free swimmers: {} rods", self.x.len())]
    }
    fn keeps_row(&self, row: &[f64]) -> bool {
        row[0] <= self.time() + 0.5 * self.cfg.dt
    }
    fn steps(&self) -> u64 {
        self.step
    }
    fn time(&self) -> f64 {
        self.step as f64 * self.cfg.dt
    }
    fn finished(&self) -> bool {
        self.step >= self.cfg.steps
    }
    fn progress(&self) -> (&'static str, u64, u64) {
        ("{pos}/{len}", self.cfg.steps, self.step)
    }
    fn checkpoint_policy(&self) -> (usize, f64) {
        (2, 1e6)
    }
    fn begin(&mut self, _io: &mut RunIo) -> anyhow::Result<bool> {
        Ok(true)
    }
    fn checkpoint_due_before_step(&mut self) -> bool {
        false
    }
    fn step(&mut self, io: &mut RunIo) -> Result<(), StepFailure> {
        let step = self.step + 1;
        if self.cfg.fail_at == Some(step) {
            return Err(StepFailure::Step {
                kind: FailureKind::NonFinite,
                step,
                t: self.time(),
                what: format!("step {step} failed on purpose"),
            });
        }
        for (x, p) in self.x.iter_mut().zip(&self.p) {
            for k in 0..3 {
                x[k] += self.cfg.dt * p[k];
            }
        }
        self.step = step;
        let mean = self.x.iter().map(|c| c[0]).sum::<f64>() / self.x.len() as f64;
        io.push_row(vec![self.time(), mean])?;
        Ok(())
    }
    fn checkpoint_due_after_step(&self) -> bool {
        self.step.is_multiple_of(self.cfg.checkpoint_every) || self.step == self.cfg.steps
    }
    fn finish(&mut self, _io: &mut RunIo, _took_steps: bool) -> Result<bool, StepFailure> {
        Ok(false)
    }
    fn write_checkpoint(&self, path: &Path) -> anyhow::Result<()> {
        Ok(checkpoint::write_verified(
            path,
            &encode(self.step, &self.x),
        )?)
    }
    fn write_last_good(&self, path: &Path) -> anyhow::Result<()> {
        // A failed step changes nothing here: the current state is the one before it.
        self.write_checkpoint(path)
    }
}

fn config(fail_at: Option<u64>) -> FreeConfig {
    FreeConfig {
        rods: 50,
        dt: 0.1,
        steps: 20,
        checkpoint_every: 5,
        seed: 3,
        fail_at,
    }
}

/// Largest deviation from the exact `x0 + p t`.
fn error_from_exact(m: &Free) -> f64 {
    let (x0, p) = initial(&m.cfg);
    let t = m.time();
    m.x.iter()
        .zip(x0.iter().zip(&p))
        .flat_map(|(x, (x0, p))| (0..3).map(move |k| (x[k] - (x0[k] + p[k] * t)).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn free_swimmers_run_through_the_same_loop_and_match_the_exact_answer() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let (m, s) = run::start::<Free>(&config(None), &a, false).unwrap();
    assert_eq!((s.steps, m.step), (20, 20));
    let err = error_from_exact(&m);
    assert!(err < 1e-13, "x(t) = x0 + p t missed by {err:e}");
    let ts = TimeSeries::read(&a.join("timeseries.csv")).unwrap();
    assert_eq!(ts.rows.len(), 20, "a row per step");
    // Checkpoints on schedule, the newest two kept.
    let mut ckpts: Vec<String> = std::fs::read_dir(a.join("checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".h5"))
        .collect();
    ckpts.sort();
    assert_eq!(ckpts, ["ckpt_000000015.h5", "ckpt_000000020.h5"]);
    let config_text = std::fs::read_to_string(a.join("config.toml")).unwrap();
    assert!(config_text.contains("model = \"free\""), "{config_text}");

    // Resume from the step-15 checkpoint: the same final state, bit for bit, and the rows
    // after step 15 written once.
    std::fs::remove_file(a.join("checkpoints/ckpt_000000020.h5")).unwrap();
    let (r, s) = run::resume::<Free>(&a, false).unwrap();
    assert_eq!(s.steps, 5);
    assert_eq!(r.x, m.x, "resume is bit-identical");
    let ts = TimeSeries::read(&a.join("timeseries.csv")).unwrap();
    assert_eq!(ts.rows.len(), 20);
}

#[test]
fn a_failed_step_of_any_model_is_saved_typed_and_resumable() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let e = run::start::<Free>(&config(Some(13)), &a, false).unwrap_err();
    let f = RunFailure::of(&e).expect("a typed RunFailure");
    assert_eq!((f.kind, f.step), (FailureKind::NonFinite, 13));
    assert!((f.t - 1.2).abs() < 1e-12, "t = {}", f.t);
    let last_good = a.join("checkpoints").join(checkpoint::LAST_GOOD);
    assert!(
        f.message.contains(&last_good.display().to_string()) && last_good.is_file(),
        "{}",
        f.message
    );
    // Fix the cause (edit the config) and resume: from the last good state, to the exact end.
    let text = std::fs::read_to_string(a.join("config.toml"))
        .unwrap()
        .replace("fail_at = 13\n", "");
    std::fs::write(a.join("config.toml"), text).unwrap();
    let (m, s) = run::resume::<Free>(&a, false).unwrap();
    assert_eq!(s.steps, 8, "from step 12 to 20");
    let err = error_from_exact(&m);
    assert!(err < 1e-13, "missed by {err:e}");
    assert!(
        !last_good.exists(),
        "a newer checkpoint supersedes the last good state"
    );
}
