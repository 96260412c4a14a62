//! Time the stages of one spectral Ewald RPY product: `cargo run --release -p motile-particle
//! --example sum_profile -- [points] [tol] [density] [stresslets|rods]`. Medians over `REPS`
//! calls (default 9) at new points each call, then at the same points; `PAIR_COST` overrides
//! the cost model's constant. Random point forces by default; `rods` puts the points on
//! swimming rods (4 per rod, the force-free density of an isolated pusher), the data the
//! slender-body solves produce, where the accuracy contract asks for finer parameters.

use motile_particle::ewald::params::{EwaldParams, SumOutput};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::model::units::DEFAULT_DIAMETER;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// A random unit vector.
fn direction(rng: &mut ChaCha8Rng) -> [f64; 3] {
    loop {
        let v = [0, 1, 2].map(|_| rng.random_range(-1.0..1.0));
        let n2: f64 = v.iter().map(|c| c * c).sum();
        if n2 > 0.01 && n2 < 1.0 {
            return v.map(|c| c / n2.sqrt());
        }
    }
}

/// The command line: points, tolerance, points per unit volume, and the case.
struct Case {
    n: usize,
    tol: f64,
    l: f64,
    /// `"stresslets"`, `"rods"` (force-free swimming rods) or random point forces.
    kind: String,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(100_000, |s| s.parse().unwrap());
    let tol: f64 = args.get(2).map_or(1e-4, |s| s.parse().unwrap());
    let density: f64 = args.get(3).map_or(2.5, |s| s.parse().unwrap());
    let case = Case {
        n,
        tol,
        l: (n as f64 / density).cbrt(),
        kind: args.get(4).cloned().unwrap_or_default(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let l = case.l;
    let y: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..l)))
        .collect();
    let f: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
        .collect();
    match case.kind.as_str() {
        "stresslets" => profile_stresslets(&case, &y, &f),
        "rods" => {
            let (y, f) = swimming_rods(&case, &mut rng);
            profile_rpy(&case, &y, &f);
        }
        _ => profile_rpy(&case, &y, &f),
    }
}

/// A fixed parameter choice at pair cost `PAIR_COST` (from the environment) for `outputs`.
fn fixed_params(case: &Case, outputs: &[SumOutput]) -> Option<EwaldParams> {
    let c = std::env::var("PAIR_COST").ok()?;
    Some(EwaldParams::choose_for(
        case.tol,
        case.n,
        case.l,
        outputs,
        c.parse().unwrap(),
    ))
}

/// Three stresslet sums of strength 0.85 along the directions of `f`, at `y`.
fn profile_stresslets(case: &Case, y: &[[f64; 3]], f: &[[f64; 3]]) {
    let p: Vec<[f64; 3]> = f
        .iter()
        .map(|v| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|c| c / n)
        })
        .collect();
    let sigma = vec![0.85; case.n];
    let mut s = SpectralEwald::new(case.tol).unwrap();
    let outputs = [SumOutput::StressletVelocity, SumOutput::StressletGradient];
    s.fixed = fixed_params(case, &outputs);
    for rep in 0..3 {
        let t = Instant::now();
        s.stresslets(case.l, y, &p, &sigma).unwrap();
        let r = s.last_report().unwrap();
        println!(
            "stresslets rep {rep}: {:.4} s; {:?}; {:?}; level {} attempts {}",
            t.elapsed().as_secs_f64(),
            s.last_timing(),
            s.last_params().unwrap(),
            r.level,
            r.attempts
        );
    }
}

/// Swimming rods: their nodes (4 per rod, `n / 4` rods) and the isolated pusher's force
/// density there.
fn swimming_rods(case: &Case, rng: &mut ChaCha8Rng) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (s, w) = motile_particle::hydro::slender::half_rod_rule(4, 1.0);
    let c = 1.0 / (2.0 * motile_particle::model::units::eta(DEFAULT_DIAMETER));
    let mut y = Vec::new();
    let mut f = Vec::new();
    for _ in 0..case.n / 4 {
        let p = direction(rng);
        let x: [f64; 3] = [0, 1, 2].map(|_| rng.random_range(0.0..case.l));
        for (sj, wj) in s.iter().zip(&w) {
            y.push([0, 1, 2].map(|d| x[d] + sj * p[d]));
            f.push(p.map(|v| c * sj.signum() * wj * v));
        }
    }
    (y, f)
}

/// `REPS` RPY sums (default 9) at alternating and at the same points, with the medians of
/// their stages.
fn profile_rpy(case: &Case, y: &[[f64; 3]], f: &[[f64; 3]]) {
    let (n, tol, l) = (case.n, case.tol, case.l);
    let rods = case.kind == "rods";
    let geo = RpyGeometry {
        box_length: l,
        radius: 0.0866,
        group: if rods { 4 } else { 1 },
    };
    let mut s = SpectralEwald::new(tol).unwrap();
    s.fixed = fixed_params(case, &[SumOutput::RpyVelocity]);
    let reps: usize = std::env::var("REPS").map_or(9, |r| r.parse().unwrap());
    // A second configuration, so that alternating calls always see new points (a GMRES
    // solve repeats products at the same points, which reuse the prepared points).
    let y2: Vec<[f64; 3]> = y
        .iter()
        .map(|p| p.map(|c| (c + 0.37).rem_euclid(l)))
        .collect();
    for (label, alternate) in [("new points", true), ("same points", false)] {
        let mut rows = Vec::new();
        for rep in 0..reps {
            let pts = if alternate && rep % 2 == 1 {
                &y2[..]
            } else {
                y
            };
            let t = Instant::now();
            s.rpy(&geo, pts, f).unwrap();
            let total = t.elapsed().as_secs_f64();
            let st = s.last_timing();
            let r = s.last_report().unwrap();
            rows.push([
                total,
                st.setup,
                st.real,
                st.fourier,
                st.corrections,
                r.level as f64,
                r.attempts as f64,
            ]);
        }
        // The first call plans and page-faults its buffers: medians of the rest.
        let median = |c: usize| {
            let mut v: Vec<f64> = rows[1..].iter().map(|r| r[c]).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        println!(
            "rpy N {n} tol {tol:e}{}, {label}: median of {} calls {:.4} s (setup {:.4}, real {:.4}, fourier {:.4}, corrections {:.4}, last attempt); first call {:.4} s ({} attempts); level {}; {:?}",
            if rods { " (force-free rods)" } else { "" },
            reps - 1,
            median(0),
            median(1),
            median(2),
            median(3),
            median(4),
            rows[0][0],
            rows[0][6],
            median(5),
            s.last_params().unwrap()
        );
    }
}
