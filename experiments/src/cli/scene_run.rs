//! `motile run SCENE` and `motile scenes`.

use crate::campaign::estimate::estimate;
use crate::campaign::scene::{BUILTIN, load_scene, parse_scene, run_scene};
use crate::cli::progress;
use std::path::PathBuf;

/// Arguments of `motile run`.
#[derive(clap::Args, Debug)]
pub struct SceneArgs {
    /// Built-in scene name (demo, dilute, paper-dilute, concentrated, meanfield) or a
    /// scene file.
    pub scene: String,
    /// Output directory [default: runs/SCENE (the scene's name)].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Only these runs of the scene (repeatable).
    #[arg(long)]
    pub only: Vec<String>,
    /// Print the scene's resolved runs and exit.
    #[arg(long)]
    pub dry_run: bool,
    /// With --dry-run: also time a few steps of each run (at a proxy size when large)
    /// and print its estimated cost (scenes that set `estimate` print it before running).
    #[arg(long, requires = "dry_run")]
    pub estimate: bool,
}

/// Run the scene (or, with `--dry-run`, print its runs).
pub fn run(a: SceneArgs) -> anyhow::Result<()> {
    let s = load_scene(&a.scene)?;
    let out = a
        .out
        .unwrap_or_else(|| PathBuf::from("runs").join(&s.info.name));
    if a.dry_run {
        println!(
            "scene {} (version {}) -> {}\n{}\nmodel level: {}\ncost: {}",
            s.info.name,
            s.info.version,
            out.display(),
            s.info.description.trim(),
            s.info.level.trim(),
            s.info.cost
        );
        let scratch = std::env::temp_dir().join(format!("motile-estimate-{}", std::process::id()));
        for (run, cfg) in &s.runs {
            if !a.only.is_empty() && !a.only.contains(run) {
                continue;
            }
            println!("  {run}: {}", cfg.describe());
            if a.estimate {
                let e = estimate(cfg, &scratch)?;
                println!("    estimated cost: {}", e.describe());
            }
        }
        return Ok(());
    }
    let report = run_scene(&s, &out, &a.only, progress(), &mut |line| {
        println!("{line}")
    })?;
    println!("{}", report.markdown);
    println!("wrote {}", out.join("scene.md").display());
    Ok(())
}

/// `motile scenes`: the built-in scenes and their runs.
pub fn list() -> anyhow::Result<()> {
    for (name, text) in BUILTIN {
        let s = parse_scene(text, name)?;
        println!("{name} (version {}): {}", s.info.version, s.info.cost);
        for (run, cfg) in &s.runs {
            println!("    {run}: {}", cfg.describe());
        }
    }
    Ok(())
}
