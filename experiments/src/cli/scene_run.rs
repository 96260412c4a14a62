//! `motile run SCENE` and `motile scenes`.

use crate::campaign::estimate::{estimate, gpu_estimate};
use crate::campaign::run_config::RunConfig;
use crate::campaign::scene::{BUILTIN, load_scene, parse_scene, run_scene};
use crate::cli::model_run::device_help;
use crate::cli::{progress, wrap};
use crate::run::Device;
use std::path::PathBuf;

/// Arguments of `motile run`.
#[derive(clap::Args, Debug)]
pub struct SceneArgs {
    /// Built-in scene name or a scene file ([`scene_help`]).
    #[arg(help = scene_help())]
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
    /// Where every run's steps run, overriding the scene's `device` (cpu or gpu;
    /// [`device_help`]). A run begun on one device resumes on the other.
    #[arg(long, value_enum, hide_possible_values = true, help = device_help())]
    pub device: Option<Device>,
}

/// Run the scene (or, with `--dry-run`, print its runs).
pub fn run(a: SceneArgs) -> anyhow::Result<()> {
    let mut s = load_scene(&a.scene)?;
    if let Some(d) = a.device {
        for (name, cfg) in &mut s.runs {
            cfg.set_device(d);
            if let RunConfig::Particle(c) = cfg {
                c.validate()
                    .map_err(|e| anyhow::anyhow!("scene {}, run {name}: {e}", s.info.name))?;
            }
        }
    }
    let out = a
        .out
        .unwrap_or_else(|| PathBuf::from("runs").join(&s.info.name));
    if a.dry_run {
        println!(
            "scene {} (version {}) -> {}\n{}\n{}\n{}",
            s.info.name,
            s.info.version,
            out.display(),
            wrap(&s.info.description, WIDTH, "", ""),
            wrap(&s.info.level, WIDTH, "model level: ", "  "),
            wrap(&s.info.cost, WIDTH, "cost: ", "  ")
        );
        println!("runs:");
        let scratch = std::env::temp_dir().join(format!("motile-estimate-{}", std::process::id()));
        for (run, cfg) in &s.runs {
            if !a.only.is_empty() && !a.only.contains(run) {
                continue;
            }
            println!("    {run}: {}", cfg.describe());
            if a.estimate {
                // On the GPU the estimate comes from the measured rates alone: nothing is timed
                // on the CPU of a node whose time is counted.
                if cfg.device() == Device::Gpu {
                    let g = gpu_estimate(cfg);
                    println!("      estimated cost: {}", g.describe());
                } else {
                    let e = estimate(cfg, &scratch)?;
                    println!("      estimated cost: {}", e.describe());
                }
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

/// Width of the text `motile scenes` and `motile run --dry-run` reflow.
const WIDTH: usize = 96;

/// The help of the scene argument: the built-in scenes' names, from [`BUILTIN`].
pub fn scene_help() -> String {
    let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
    format!(
        "Built-in scene name ({}; `motile scenes` lists them) or a scene file",
        names.join(", ")
    )
}

/// A scene's summary: its description up to the end of the first clause (the first ": " or
/// ". "), on one line.
fn summary(description: &str) -> String {
    let flat = description.split_whitespace().collect::<Vec<_>>().join(" ");
    let end = [": ", ". "]
        .iter()
        .filter_map(|p| flat.find(p))
        .min()
        .unwrap_or(flat.len());
    flat[..end].trim_end_matches('.').to_string()
}

/// `motile scenes`: the built-in scenes, each on one line with its summary, then its runs and
/// its cost (reflowed at word boundaries under its label).
pub fn list() -> anyhow::Result<()> {
    for (i, (name, text)) in BUILTIN.iter().enumerate() {
        let s = parse_scene(text, name)?;
        if i > 0 {
            println!();
        }
        println!(
            "{name} (version {}): {}",
            s.info.version,
            summary(&s.info.description)
        );
        let width = s.runs.iter().map(|(r, _)| r.len()).max().unwrap_or(0);
        for (run, cfg) in &s.runs {
            println!("    {run:<width$}  {}", cfg.describe());
        }
        println!("{}", wrap(&s.info.cost, WIDTH, "    cost: ", "          "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summaries_are_the_first_clause() {
        assert_eq!(
            summary("The paper's case: zeta = 0.14."),
            "The paper's case"
        );
        assert_eq!(summary("Two\nlines. More: here"), "Two lines");
        assert_eq!(summary("No clause."), "No clause");
    }
}
