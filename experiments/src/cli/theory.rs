//! `motile theory`: the linear theory of the periodic box (docs/MODEL.md §5b) for a volume
//! fraction and a list of box sides.

use motile_particle::model::linear_theory::{gamma0, growth_rate, lowest_mode, onset_box};
use motile_particle::model::units::DEFAULT_DIAMETER;

/// Arguments of `motile theory`.
#[derive(clap::Args, Debug)]
pub struct TheoryArgs {
    /// Volume fraction nu.
    #[arg(long, default_value_t = 0.625)]
    pub nu: f64,
    /// Box sides L/l, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "25,32,40,50,64,75,87,100,150,175"
    )]
    pub boxes: Vec<f64>,
    /// Rotational diffusion d_r (1/beta), besides none.
    #[arg(long, default_value_t = 0.0)]
    pub rotational_diffusion: f64,
}

/// Print the lowest box mode's growth rate for each box, the onset box and the continuum's
/// rate.
pub fn run(a: TheoryArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        a.nu > 0.0 && a.nu <= 6.0,
        "--nu = {} is outside the allowed range (0, 6]",
        a.nu
    );
    let b = DEFAULT_DIAMETER;
    let continuum = gamma0(a.nu, b) / 5.0;
    let d_r = a.rotational_diffusion.max(0.0);
    println!(
        "Lowest box mode k = 2 pi/L at nu = {}, b = {b} l: growth rate sigma (1/beta; a complex \
         pair beats at 2 Im sigma). The continuum's rate (M3, D = 0): {continuum:.5}.",
        a.nu
    );
    let head = if d_r > 0.0 {
        format!("| L/l | sigma, d_r = 0 | sigma, d_r = {d_r:e} |\n|---|---|---|")
    } else {
        "| L/l | sigma |\n|---|---|".to_string()
    };
    println!("{head}");
    let show = |l: f64, d: f64| {
        growth_rate(a.nu, b, lowest_mode(l), d).map_or("damped".into(), |g| {
            if g.sigma.im.abs() < 1e-12 {
                format!("{:.5}", g.sigma.re)
            } else {
                format!("{:.5} +- {:.5} i", g.sigma.re, g.sigma.im)
            }
        })
    };
    for &l in &a.boxes {
        if d_r > 0.0 {
            println!("| {l} | {} | {} |", show(l, 0.0), show(l, d_r));
        } else {
            println!("| {l} | {} |", show(l, 0.0));
        }
    }
    // Without diffusion, then with the given one (if any).
    let rates: &[f64] = if d_r > 0.0 { &[0.0, d_r] } else { &[0.0] };
    for &d in rates {
        match onset_box(a.nu, b, d, (2.0, 1000.0)) {
            Some(l) => println!("onset (d_r = {d}): the lowest mode grows for L/l > {l:.2}"),
            None => println!("onset (d_r = {d}): none found between L/l = 2 and 1000"),
        }
    }
    Ok(())
}
