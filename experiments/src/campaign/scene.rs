//! Scenes: named, versioned TOML files (`experiments/scenes/*.toml`, built into the binary) that
//! list the runs of one study, particle and mean-field, with the model level each uses and why.
//! `motile run <scene> --out DIR` runs them into `DIR/<run name>`, analyses each and compares
//! them all in `DIR/compare`. Running a scene again resumes what is unfinished and skips what
//! is done; a run directory whose config differs from the scene's is refused, not overwritten.
//!
//! A scene file:
//!
//! ```toml
//! [scene]
//! name = "demo"
//! version = 1
//! description = "what it shows"
//! level = "the model level and why it is enough"
//! cost = "what it takes on 2 cores"
//!
//! [[run]]
//! name = "particle"
//! model = "particle"        # or "meanfield"
//! [run.config]              # a run config (every key optional, as in `motile particle run`)
//! box_length = 8.0
//! ```

use crate::campaign::estimate;
use crate::campaign::run_config::RunConfig;
use crate::io::rundir::{RunDir, read_run_config};
use crate::io::write_atomic;
use crate::report::analyze::{AnalyzeOptions, analyze_run};
use crate::report::compare::{self, CompareReport};
use crate::run::meanfield::{self, MeanFieldRunConfig};
use crate::run::particle::{self, ParticleRunConfig};
use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The scenes shipped with motile: `(name, TOML text)`.
pub const BUILTIN: [(&str, &str); 6] = [
    ("demo", include_str!("../../scenes/demo.toml")),
    ("dilute", include_str!("../../scenes/dilute.toml")),
    (
        "paper-dilute",
        include_str!("../../scenes/paper-dilute.toml"),
    ),
    (
        "concentrated",
        include_str!("../../scenes/concentrated.toml"),
    ),
    (
        "paper-concentrated",
        include_str!("../../scenes/paper-concentrated.toml"),
    ),
    ("meanfield", include_str!("../../scenes/meanfield.toml")),
];

/// A scene file.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// What the scene is.
    pub scene: SceneInfo,
    /// Its runs, in order.
    pub run: Vec<SceneRun>,
}

/// The `[scene]` table.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SceneInfo {
    /// Name (the file's stem for built-in scenes).
    pub name: String,
    /// Version: bumped when a run's settings change, so results say which scene made them.
    pub version: u32,
    /// What it shows.
    pub description: String,
    /// The model level it uses and why that level is enough for it.
    pub level: String,
    /// What it costs on the reference machine (2 cores).
    pub cost: String,
    /// Time a few steps of each run and print its estimated cost before it starts
    /// ([`crate::campaign::estimate`]). Default false.
    #[serde(default)]
    pub estimate: bool,
}

/// One `[[run]]` entry.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SceneRun {
    /// Run directory name under the scene's output.
    pub name: String,
    /// "particle" or "meanfield".
    pub model: String,
    /// The run's config (keys as in `motile particle run` / `motile meanfield run`).
    #[serde(default)]
    pub config: toml::Table,
}

/// A scene ready to run: its description and resolved runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The `[scene]` table.
    pub info: SceneInfo,
    /// `(name, config)` of each run.
    pub runs: Vec<(String, RunConfig)>,
    /// The scene file's text (written next to the results).
    pub text: String,
}

/// Parse and validate a scene; `origin` names it in messages.
pub fn parse_scene(text: &str, origin: &str) -> anyhow::Result<Scene> {
    let file: SceneFile =
        toml::from_str(text).map_err(|e| anyhow::anyhow!("scene {origin}: {e}"))?;
    if file.run.is_empty() {
        bail!("scene {origin}: no [[run]] entries");
    }
    let mut runs = Vec::new();
    for (k, r) in file.run.iter().enumerate() {
        let where_ = format!("scene {origin}, run {} (\"{}\")", k + 1, r.name);
        if r.name.is_empty()
            || !r
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            bail!(
                "{where_}: name must be non-empty ASCII letters, digits, '_' or '-' (it names a directory)"
            );
        }
        if runs.iter().any(|(n, _)| n == &r.name) {
            bail!("{where_}: name used twice");
        }
        let text = toml::to_string(&r.config)?;
        let label = PathBuf::from(where_.clone());
        let cfg = match r.model.as_str() {
            "particle" => RunConfig::Particle(particle::parse_config(&text, &label)?),
            "meanfield" => RunConfig::MeanField(meanfield::parse_config(&text, &label)?),
            other => {
                bail!("{where_}: model = \"{other}\" is not one of \"particle\", \"meanfield\"")
            }
        };
        runs.push((r.name.clone(), cfg));
    }
    Ok(Scene {
        info: file.scene,
        runs,
        text: text.to_string(),
    })
}

/// A built-in scene by name, or a scene file by path.
pub fn load_scene(name_or_path: &str) -> anyhow::Result<Scene> {
    if let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
        return parse_scene(text, name_or_path);
    }
    let path = Path::new(name_or_path);
    if !path.exists() {
        let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
        bail!(
            "no scene \"{name_or_path}\": not a built-in scene ({}) and no such file",
            names.join(", ")
        );
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    parse_scene(&text, &path.display().to_string())
}

/// What happened to one run of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOutcome {
    /// Run name.
    pub name: String,
    /// Its size, in words.
    pub describe: String,
    /// "ran", "resumed" or "done already".
    pub action: &'static str,
    /// Steps taken now.
    pub steps: u64,
    /// Wall seconds now (run and analysis).
    pub seconds: f64,
}

/// What a scene did.
#[derive(Clone, Debug)]
pub struct SceneReport {
    /// Each run.
    pub runs: Vec<RunOutcome>,
    /// The comparison of all runs (absent when no run has a flow to compare).
    pub compare: Option<CompareReport>,
    /// Markdown summary (also in `OUT/scene.md`).
    pub markdown: String,
}

/// Whether a run directory already holds this config (same model and resolved settings).
fn existing(dir: &Path, cfg: &RunConfig) -> anyhow::Result<bool> {
    if !dir.join("config.toml").exists() {
        return Ok(false);
    }
    // The model first: another model's config would not parse as this one's.
    let model = RunDir::open(dir)?.header()?.model;
    // The device is not a setting of the physics: a run begun on a GPU resumes on the CPU.
    let same = model == cfg.model()
        && match cfg {
            RunConfig::Particle(c) => {
                let mut held: ParticleRunConfig =
                    read_run_config(dir, ParticleRunConfig::validate)?;
                held.device = c.device;
                held.resolved() == c.resolved()
            }
            RunConfig::MeanField(c) => {
                let mut held: MeanFieldRunConfig =
                    read_run_config(dir, MeanFieldRunConfig::validate)?;
                held.device = c.device;
                &held == c
            }
        };
    if !same {
        bail!(
            "{}: holds a {model} run with other settings than the scene's; give another --out or remove it",
            dir.display()
        );
    }
    Ok(true)
}

/// Run (or resume) `scene` into `out`: each run in `out/<name>` (only those in `only`, if
/// given), each analysed, then all compared in `out/compare`. `event` gets a line per stage.
pub fn run_scene(
    scene: &Scene,
    out: &Path,
    only: &[String],
    progress: bool,
    event: &mut dyn FnMut(&str),
) -> anyhow::Result<SceneReport> {
    for name in only {
        if !scene.runs.iter().any(|(n, _)| n == name) {
            let names: Vec<&str> = scene.runs.iter().map(|(n, _)| n.as_str()).collect();
            bail!(
                "scene {} has no run \"{name}\" (runs: {})",
                scene.info.name,
                names.join(", ")
            );
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    write_atomic(&out.join("scene.toml"), scene.text.as_bytes())?;
    if scene.info.estimate {
        for (name, cfg) in &scene.runs {
            if (!only.is_empty() && !only.contains(name)) || existing(&out.join(name), cfg)? {
                continue;
            }
            let line = if cfg.device() == crate::run::Device::Gpu {
                estimate::gpu_estimate(cfg).describe()
            } else {
                estimate::estimate(cfg, &out.join(".estimate"))?.describe()
            };
            event(&format!("estimated cost of {name}: {line}"));
        }
    }
    let mut outcomes = Vec::new();
    for (name, cfg) in &scene.runs {
        if !only.is_empty() && !only.contains(name) {
            continue;
        }
        let dir = out.join(name);
        let resume = existing(&dir, cfg)?;
        event(&format!(
            "{} {name}: {}",
            if resume { "resuming" } else { "running" },
            cfg.describe()
        ));
        let t0 = std::time::Instant::now();
        let steps = match (cfg, resume) {
            (RunConfig::Particle(c), false) => particle::run_particle(c, &dir, progress)?.steps,
            (RunConfig::Particle(_), true) => particle::resume_particle(&dir, progress)?.steps,
            (RunConfig::MeanField(c), false) => meanfield::run_meanfield(c, &dir, progress)?.steps,
            (RunConfig::MeanField(_), true) => meanfield::resume_meanfield(&dir, progress)?.steps,
        };
        analyze_run(&dir, &AnalyzeOptions::default())
            .with_context(|| format!("analysing {}", dir.display()))?;
        let seconds = t0.elapsed().as_secs_f64();
        event(&format!(
            "{name}: {steps} steps, {seconds:.1} s (with analysis)"
        ));
        outcomes.push(RunOutcome {
            name: name.clone(),
            describe: cfg.describe(),
            action: match (resume, steps) {
                (false, _) => "ran",
                (true, 0) => "done already",
                (true, _) => "resumed",
            },
            steps,
            seconds,
        });
    }
    // Compare every run of the scene that is there and has a flow.
    let comparable: Vec<PathBuf> = scene
        .runs
        .iter()
        .filter(|(name, cfg)| {
            out.join(name).join("timeseries.csv").exists()
                && match cfg {
                    RunConfig::Particle(c) => c.hydrodynamics.has_flow(),
                    RunConfig::MeanField(_) => true,
                }
        })
        .map(|(name, _)| out.join(name))
        .collect();
    let cmp = if comparable.is_empty() {
        None
    } else {
        event(&format!(
            "comparing {} run(s) in {}",
            comparable.len(),
            out.join("compare").display()
        ));
        Some(compare::compare(&comparable, &out.join("compare"))?)
    };
    let mut md = format!(
        "# Scene `{}` (version {})\n\n{}\n\n**Model level.** {}\n\n**Cost.** {}\n\n| run | what | this invocation | steps | wall time (s) |\n|---|---|---|---|---|\n",
        scene.info.name,
        scene.info.version,
        scene.info.description.trim(),
        scene.info.level.trim(),
        scene.info.cost.trim()
    );
    for o in &outcomes {
        writeln!(
            md,
            "| {} | {} | {} | {} | {:.1} |",
            o.name, o.describe, o.action, o.steps, o.seconds
        )
        .expect("string");
    }
    if let Some(c) = &cmp {
        write!(md, "\n## Comparison (`compare/`)\n\n{}", c.table).expect("string");
    }
    write_atomic(&out.join("scene.md"), md.as_bytes())?;
    Ok(SceneReport {
        runs: outcomes,
        compare: cmp,
        markdown: md,
    })
}
