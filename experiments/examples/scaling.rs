//! Thread scaling of every hot path, phase by phase (BENCHMARKS.md, "Thread scaling").
//!
//! ```text
//! cargo run --release -p motile-experiments --example scaling -- [--threads 1,2] [--reps 3] [--large] [--only CASE]
//! ```
//!
//! Cases: `mf64` (mean-field step on 64^3, closure degree 20: Q to the
//! grid, closure, fixed point, gradients, explicit terms, update), `mobility` (RPY mobility
//! product of 1e5 points at tolerance 1e-4, new points every call: setup, real space, Fourier,
//! corrections), `sbt` (slender-body step, 9 766 rods at nu = 0.625, L/l = 25: neighbours,
//! assembly, prediction, contacts, solve and update, of which periodic sums), `dipole` (78 125
//! rods at nu = 0.625, L/l = 50), `contact` (78 125 rods at nu = 5, L/l = 25, no flow). With
//! `--large`: `mf128`, and the mobility product of 1e6 points. Each case runs once to warm up,
//! then `--reps` times at each thread count; the table gives the median seconds per phase, the
//! speedup over the first thread count and the parallel efficiency. A phase that does not
//! reach 1.8x on 2 threads is serial somewhere. Results are bit-identical for any thread count
//! (tested elsewhere); only the time changes.

use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::MeanFieldParams;
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::mobility::{LocalDrag, Mobility};
use motile_particle::hydro::slender::{SlenderBody, SlenderParams};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::stepper::Stepper;
use std::time::Instant;

mod shared;
use shared::{arg, list_arg, meanfield_state, median, random_points};

/// One timed run: the phases' seconds, in the case's phase order, the total last.
type Sample = Vec<f64>;

/// A case: its phase names and a closure that runs it once and returns the phases' seconds.
struct Case {
    name: &'static str,
    phases: Vec<&'static str>,
    run: Box<dyn FnMut() -> Sample + Send>,
}

fn meanfield_case(n: usize, closure: &'static BinghamClosure) -> Case {
    let grid: &'static SpectralGrid = Box::leak(Box::new(SpectralGrid::new(n)));
    let params: &'static MeanFieldParams = Box::leak(Box::new(MeanFieldParams::default()));
    let q = meanfield_state(n);
    let mut stepper = MeanFieldStepper::new(grid, &q, SBDF2);
    Case {
        name: if n == 64 { "mf64" } else { "mf128" },
        phases: vec![
            "Q to grid",
            "closure",
            "fixed point",
            "gradients",
            "explicit terms",
            "update",
        ],
        run: Box::new(move || {
            let rhs = MeanFieldRhs {
                grid,
                closure,
                params,
                with_entropy: false,
            };
            let t = Instant::now();
            stepper.step(&rhs, 0.01).expect("mean-field step");
            let total = t.elapsed().as_secs_f64();
            let (r, update) = stepper.last_timing;
            vec![
                r.q_to_grid,
                r.closure,
                r.fixed_point,
                r.gradients,
                r.nonlinear,
                update,
                total,
            ]
        }),
    }
}

fn mobility_case(n: usize) -> Case {
    let (l, y, f) = random_points(n);
    let y2: Vec<[f64; 3]> = y
        .iter()
        .map(|p| p.map(|c| (c + 0.37).rem_euclid(l)))
        .collect();
    let geo = RpyGeometry {
        box_length: l,
        radius: 0.0866,
        group: 1,
    };
    let mut sum = SpectralEwald::new(1e-4).expect("tolerance");
    let mut flip = false;
    Case {
        name: if n == 100_000 {
            "mobility 1e5"
        } else {
            "mobility 1e6"
        },
        phases: vec!["setup", "real space", "Fourier", "corrections"],
        run: Box::new(move || {
            // New points every call, as the first product of a step.
            flip = !flip;
            let pts = if flip { &y2 } else { &y };
            let t = Instant::now();
            sum.rpy(&geo, pts, &f).expect("sum");
            let total = t.elapsed().as_secs_f64();
            let s = sum.last_timing();
            vec![s.setup, s.real, s.fourier, s.corrections, total]
        }),
    }
}

fn step_case(name: &'static str, rods: RodSet, mobility: Box<dyn Mobility>, dt: f64) -> Case {
    let mut rods = rods;
    let mut stepper = Stepper::new(mobility, ContactParams::default());
    // The first step of the slender-body model solves exactly; steady steps predict.
    stepper.step(&mut rods, dt).expect("first step");
    Case {
        name,
        phases: vec![
            "neighbours",
            "assembly",
            "prediction",
            "contacts",
            "solve + update",
            "(periodic sums)",
        ],
        run: Box::new(move || {
            let t = Instant::now();
            let r = stepper.step(&mut rods, dt).expect("step");
            let total = t.elapsed().as_secs_f64();
            let mut v = r.seconds.as_array().to_vec();
            v.push(r.hydro.seconds_sums);
            v.push(total);
            v
        }),
    }
}

fn rods(nu: f64, l: f64) -> RodSet {
    let n = (nu * l * l * l).round() as usize;
    random_nonoverlapping(n, l, DEFAULT_DIAMETER, 1, 1_000_000).expect("initial configuration")
}

fn main() {
    let threads: Vec<usize> = list_arg("--threads").unwrap_or_else(|| vec![1, 2]);
    let reps: usize = arg("--reps").map_or(3, |r| r.parse().expect("--reps"));
    let large = std::env::args().any(|a| a == "--large");
    let only = arg("--only");
    let closure: &'static BinghamClosure = Box::leak(Box::new(
        BinghamClosure::new(DEFAULT_DEGREE).expect("closure tables"),
    ));
    // Cases are built (and rods placed) on a pool of the largest thread count.
    let build = rayon::ThreadPoolBuilder::new()
        .num_threads(*threads.iter().max().unwrap())
        .build()
        .unwrap();
    let mut cases: Vec<Case> = build.install(|| {
        let mut cases = vec![meanfield_case(64, closure), mobility_case(100_000)];
        cases.push(step_case(
            "sbt 9766",
            rods(0.625, 25.0),
            Box::new(SlenderBody::new(
                SlenderParams::default(),
                Box::new(SpectralEwald::new(1e-4).unwrap()),
            )),
            0.01,
        ));
        cases.push(step_case(
            "dipole 78125",
            rods(0.625, 50.0),
            Box::new(Dipole::new(
                Box::new(SpectralEwald::new(1e-4).unwrap()),
                DEFAULT_DIAMETER,
            )),
            0.01,
        ));
        cases.push(step_case(
            "contact 78125",
            rods(5.0, 25.0),
            Box::new(LocalDrag::default()),
            0.002,
        ));
        if large {
            cases.push(meanfield_case(128, closure));
            cases.push(mobility_case(1_000_000));
        }
        cases
            .into_iter()
            .filter(|c| only.as_deref().is_none_or(|o| c.name.starts_with(o)))
            .collect()
    });
    println!(
        "| case | phase | {} | speedup | efficiency |",
        threads
            .iter()
            .map(|t| format!("{t} thr (s)"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---|---|{}---|---|", "---|".repeat(threads.len()));
    for case in &mut cases {
        let mut medians: Vec<Vec<f64>> = Vec::new();
        for &t in &threads {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap();
            let samples: Vec<Sample> = pool.install(|| {
                (case.run)();
                (0..reps).map(|_| (case.run)()).collect()
            });
            let phases = samples[0].len();
            medians.push(
                (0..phases)
                    .map(|k| median(samples.iter().map(|s| s[k]).collect()))
                    .collect(),
            );
        }
        let names: Vec<&str> = case.phases.iter().copied().chain(["whole step"]).collect();
        for (k, name) in names.iter().enumerate() {
            let base = medians[0][k];
            if base == 0.0 {
                continue; // a phase this case does not have (no periodic sums)
            }
            let last = medians[medians.len() - 1][k];
            let speedup = base / last;
            let ratio = *threads.last().unwrap() as f64 / threads[0] as f64;
            println!(
                "| {} | {name} | {} | {speedup:.2} | {:.0}% |",
                case.name,
                medians
                    .iter()
                    .map(|m| format!("{:.4}", m[k]))
                    .collect::<Vec<_>>()
                    .join(" | "),
                100.0 * speedup / ratio
            );
        }
    }
}
