//! Mutation campaign over the files a user hands motile (docs/faults.md, "Mutation campaigns").
//!
//! ```text
//! cargo run --release -p motile-experiments --example mutation -- [--per-family 10000] [--seed 1] [--time-limit 20] [--only FAMILY] [--scratch DIR]
//! ```
//!
//! Makes a tiny particle run and a tiny mean-field run, then damages their files (configs,
//! scenes, snapshots, checkpoints with matching checksums, the time series) `--per-family`
//! times each, seeded, and feeds each to the reader a user reaches. Prints the outcome table
//! (clear error, accepted and consistent, error not naming the file, accepted inconsistent,
//! panic, hang) and every defect with its mutation; copies of the defective inputs are left
//! in `SCRATCH/findings`. Exits with status 1 if any defect was found.

use motile_experiments::campaign::mutation::{CampaignOptions, Family, run_campaign};
use std::path::PathBuf;
use std::time::Duration;

fn main() -> anyhow::Result<()> {
    let mut opts = CampaignOptions {
        seed: 1,
        per_family: 10_000,
        time_limit: Duration::from_secs(20),
        families: Family::ALL.to_vec(),
        scratch: std::env::temp_dir().join("motile-mutation"),
    };
    let mut only = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || {
            args.next()
                .ok_or_else(|| anyhow::anyhow!("{a} needs a value"))
        };
        match a.as_str() {
            "--seed" => opts.seed = value()?.parse()?,
            "--per-family" => opts.per_family = value()?.parse()?,
            "--time-limit" => opts.time_limit = Duration::from_secs_f64(value()?.parse()?),
            "--scratch" => opts.scratch = PathBuf::from(value()?),
            "--only" => {
                let v = value()?;
                only.push(
                    Family::ALL
                        .into_iter()
                        .find(|f| f.name() == v)
                        .ok_or_else(|| {
                            let names: Vec<_> = Family::ALL.iter().map(|f| f.name()).collect();
                            anyhow::anyhow!("--only {v}: not one of {}", names.join(", "))
                        })?,
                );
            }
            other => anyhow::bail!("unknown argument {other}"),
        }
    }
    if !only.is_empty() {
        opts.families = only;
    }
    std::fs::create_dir_all(&opts.scratch)?;
    eprintln!(
        "mutation campaign: seed {}, {} inputs per family, time limit {:?}, scratch {}",
        opts.seed,
        opts.per_family,
        opts.time_limit,
        opts.scratch.display()
    );
    let report = run_campaign(&opts, |row| {
        eprintln!(
            "{}: {} inputs in {:.0} s, counts {:?}",
            row.family.name(),
            row.counts.iter().sum::<usize>(),
            row.seconds,
            row.counts
        );
    })?;
    println!("{}", report.markdown());
    for f in &report.findings {
        println!("- {f}");
    }
    if !report.findings.is_empty() {
        std::process::exit(1);
    }
    Ok(())
}
