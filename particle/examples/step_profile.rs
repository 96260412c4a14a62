//! Times the particle step at nu = 5, L/l = 25 (78 125 rods) and prints, per step, the split
//! between neighbour search, constraint assembly, free velocities, contact solve and update,
//! with the solver's iterations: `step_profile [--threads N] [--steps S] [--box L]`.

use motile_particle::hydro::mobility::LocalDrag;
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::stepper::Stepper;
use std::time::Instant;

fn arg(name: &str, default: f64) -> f64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default, |v| v.parse().expect("number"))
}

fn main() {
    let threads = arg("--threads", 2.0) as usize;
    let steps = arg("--steps", 20.0) as usize;
    let l = arg("--box", 25.0);
    let n = (5.0 * l * l * l).round() as usize;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let t = Instant::now();
        let mut rods = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 1, 1_000_000).expect("initial configuration");
        println!("init: {n} rods at nu = 5, L/l = {l}: {:.2} s", t.elapsed().as_secs_f64());
        let mut s = Stepper::new(Box::new(LocalDrag::default()), ContactParams::default());
        let mut total = [0.0; 5];
        let t = Instant::now();
        for k in 0..steps {
            let r = s.step(&mut rods, 0.002).expect("step");
            for (a, b) in total.iter_mut().zip(r.seconds.as_array()) {
                *a += b;
            }
            if k % 5 == 0 || k == steps - 1 {
                println!(
                    "step {k:3}: {} constraints, {} active, {} iterations, residual {:.1e}, max overlap {:.1e}",
                    r.contact.constraints, r.contact.active, r.contact.iterations, r.contact.residual, r.max_overlap
                );
            }
        }
        let wall = t.elapsed().as_secs_f64();
        println!(
            "{threads} threads: {:.2} steps/s ({:.2} us per rod-step); per step: neighbours {:.1} ms, assembly {:.1} ms, free velocities {:.1} ms, contact solve {:.1} ms, update {:.1} ms",
            steps as f64 / wall,
            wall / steps as f64 / n as f64 * 1e6,
            total[0] / steps as f64 * 1e3,
            total[1] / steps as f64 * 1e3,
            total[2] / steps as f64 * 1e3,
            total[3] / steps as f64 * 1e3,
            total[4] / steps as f64 * 1e3
        );
    });
}
