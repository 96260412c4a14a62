//! Times full particle steps with hydrodynamics and prints the split by stage:
//! `hydro_step --model sbt|dipole [--box L] [--nu NU] [--steps S] [--tol T] [--threads N]`.
//! Defaults: sbt at nu = 0.625, L/l = 25 (9 766 rods), tolerance 1e-4.

use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::mobility::Mobility;
use motile_particle::hydro::slender::{SlenderBody, SlenderParams};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::stepper::Stepper;
use std::time::Instant;

fn arg(name: &str, default: &str) -> String {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
        .unwrap_or_else(|| default.to_string())
}

fn main() {
    let model = arg("--model", "sbt");
    let l: f64 = arg("--box", "25").parse().unwrap();
    let nu: f64 = arg("--nu", "0.625").parse().unwrap();
    let steps: usize = arg("--steps", "5").parse().unwrap();
    let tol: f64 = arg("--tol", "1e-4").parse().unwrap();
    let threads: usize = arg("--threads", "2").parse().unwrap();
    let n = (nu * l * l * l).round() as usize;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut rods = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 1, 1_000_000).expect("initial configuration");
        let sum = Box::new(SpectralEwald::new(tol).unwrap());
        let mob: Box<dyn Mobility> = match model.as_str() {
            "dipole" => Box::new(Dipole::new(sum, DEFAULT_DIAMETER)),
            _ => Box::new(SlenderBody::new(SlenderParams::default(), sum)),
        };
        let mut s = Stepper::new(mob, ContactParams::default());
        println!("{model}: {n} rods, nu = {nu}, L/l = {l}, tol {tol:e}, {threads} threads");
        for k in 0..steps {
            let t = Instant::now();
            let r = s.step(&mut rods, 0.002).expect("step");
            let wall = t.elapsed().as_secs_f64();
            let h = &r.hydro;
            println!(
                "step {k}: {wall:.3} s | neighbours {:.3} assembly {:.3} prediction {:.3} contacts {:.3} solve + update {:.3} | sums {} in {:.3} s, level {}, estimate {:.2} tol | GMRES {} ({:.1e}) | {} active contacts",
                r.seconds.cells, r.seconds.constraints, r.seconds.free_velocities, r.seconds.contacts, r.seconds.update,
                h.sums, h.seconds_sums, h.sum_level, h.sum_error_ratio, h.gmres_iterations, h.gmres_residual, r.contact.active
            );
        }
    });
}
