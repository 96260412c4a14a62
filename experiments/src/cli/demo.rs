//! `motile demo`: the main job.

use crate::campaign::demo::{DemoConfig, DemoSummary, free_swimmers, meanfield_bound_line};
use crate::campaign::scene::{load_scene, run_scene};
use crate::cli::{print_table, progress, wrap};
use std::path::{Path, PathBuf};

/// Width of the closing lines' figure list.
const WIDTH: usize = 96;

/// Arguments of `motile demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Output directory.
    #[arg(long, default_value = "runs/demo")]
    pub out: PathBuf,
    /// Box side L/l of the free swimmers (part 2) [default: 16].
    #[arg(long)]
    pub box_length: Option<f64>,
    /// Random seed of the free swimmers (part 2) [default: 1].
    #[arg(long)]
    pub seed: Option<u64>,
}

/// Part 1: the demo scene (experiments/scenes/demo.toml), both models above the instability,
/// compared in mean-field units (docs/MODEL.md section 5); part 2: free swimmers against exact
/// values. The checks live in [`crate::campaign::demo`].
pub fn run(a: DemoArgs) -> anyhow::Result<()> {
    let s = load_scene("demo")?;
    let report = run_scene(&s, &a.out, &[], progress(), &mut |line| println!("{line}"))?;
    println!("{}", meanfield_bound_line(&a.out)?);
    println!("{}", report.markdown);
    for line in DemoSummary::of_scene(&a.out, &report)?.lines() {
        println!("{line}");
    }
    let out = a.out.join("free_swimmers");
    let mut cfg = DemoConfig::default();
    cfg.box_length = a.box_length.unwrap_or(cfg.box_length);
    cfg.seed = a.seed.unwrap_or(cfg.seed);
    let t0 = std::time::Instant::now();
    let (table, checks) = free_swimmers(&out, &cfg)?;
    println!(
        "\nPart 2, free swimmers: {} rods at nu = {} in a box of L/l = {}, swimming without \
         hydrodynamics or contacts to t = {}/beta, so the analysis has exact answers. Their \
         analysis time series ({}; t in 1/beta):",
        cfg.rods(),
        cfg.volume_fraction,
        cfg.box_length,
        cfg.t_end,
        out.join("analysis").display()
    );
    print_table(&table);
    for line in checks {
        println!("{line}");
    }
    println!(
        "part 2 wrote {} in {:.1} s",
        out.display(),
        t0.elapsed().as_secs_f64()
    );
    println!("\n{}", results(&a.out, report.compare.is_some())?);
    Ok(())
}

/// The closing lines: where the demo's figures, summary, scene report and runs are (the figures
/// as the comparison folder holds them).
fn results(out: &Path, compared: bool) -> anyhow::Result<String> {
    let compare = out.join("compare");
    let mut lines = vec![format!("Results in {}:", out.display())];
    if compared {
        let mut charts: Vec<String> = std::fs::read_dir(&compare)?
            .filter_map(|e| {
                let p = e.ok()?.path();
                let stem = p.file_stem()?.to_string_lossy().into_owned();
                (p.extension()? == "png").then_some(stem)
            })
            .collect();
        charts.sort();
        lines.push(wrap(
            &format!(
                "{} ({} charts, each .png and .svg): {}",
                compare.display(),
                charts.len(),
                charts.join(", ")
            ),
            WIDTH,
            "  figures:       ",
            "                 ",
        ));
        lines.push(format!(
            "  summary:       {} (growth rates beside the theory, saturated norms)",
            compare.join("summary.md").display()
        ));
    }
    lines.push(format!(
        "  scene report:  {}",
        out.join("scene.md").display()
    ));
    lines.push(format!(
        "  runs:          {}, {}, {}",
        out.join("particle").display(),
        out.join("meanfield").display(),
        out.join("free_swimmers").display()
    ));
    Ok(lines.join("\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closing_lines_name_the_figures_the_summary_and_the_scene_report() {
        let dir = tempfile::tempdir().unwrap();
        let compare = dir.path().join("compare");
        std::fs::create_dir(&compare).unwrap();
        for f in [
            "velocity_norm.png",
            "velocity_norm.svg",
            "msd.png",
            "summary.md",
        ] {
            std::fs::write(compare.join(f), "").unwrap();
        }
        let text = results(dir.path(), true).unwrap();
        let c = compare.display().to_string();
        // The chart names as one list (the line may wrap).
        let flat = text.replace("\n                 ", " ");
        assert!(
            text.contains(&format!("figures:       {c} (2 charts"))
                && flat.contains(": msd, velocity_norm\n")
                && text.contains(&format!("summary:       {c}/summary.md"))
                && text.contains(&format!(
                    "scene report:  {}",
                    dir.path().join("scene.md").display()
                )),
            "{text}"
        );
        assert!(!results(dir.path(), false).unwrap().contains("figures"));
    }
}
