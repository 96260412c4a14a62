//! `motile fidelity`: the hydrodynamic levels against slender-body theory on pairs of rods.

use crate::campaign::fidelity::{FidelityOptions, fidelity};
use std::path::PathBuf;

/// Arguments of `motile fidelity`.
#[derive(clap::Args, Debug)]
pub struct FidelityArgs {
    /// Pairs per centre distance (random orientations without contact).
    #[arg(long, default_value_t = 40)]
    pub pairs: usize,
    /// Output directory.
    #[arg(long, default_value = "runs/fidelity")]
    pub out: PathBuf,
}

/// Compare the levels on pairs and print the table.
pub fn run(a: FidelityArgs) -> anyhow::Result<()> {
    let opts = FidelityOptions {
        pairs: a.pairs,
        ..FidelityOptions::default()
    };
    let md = fidelity(&opts, &a.out)?;
    println!("{md}");
    println!("wrote {}", a.out.join("pair_fidelity.png").display());
    Ok(())
}
