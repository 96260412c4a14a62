//! `motile demo`: the main job.

use crate::campaign::demo::{DemoConfig, DemoSummary, free_swimmers, meanfield_bound_line};
use crate::campaign::scene::{load_scene, run_scene};
use crate::cli::{print_table, progress};
use std::path::PathBuf;

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
    for line in DemoSummary::read(&a.out)?.lines() {
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
        "wrote {} in {:.1} s",
        out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
