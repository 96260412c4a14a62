//! `motile check-accuracy RUN_DIR`: audits the fast sums of a particle run against their slow
//! twin (`docs/accuracy.md`). On one snapshot it evaluates the sum the run's config uses
//! (spectral Ewald at `hydro.sum_tolerance`, the RPY sum over the quadrature points for
//! `"sbt"`, the stresslet sum for `"dipole"`) and the direct Ewald sum at `K` sampled targets
//! only, `O(N K)`: the direct sum's splitting parameter is chosen so that its real-space part
//! (every source and image within `6.5/xi`, per target) and its Fourier part (the structure
//! factor over every source, `|k| <= 13 xi`) cost about the same. It reports the measured
//! error of each output (max-relative and relative L2 over the sampled targets) beside the
//! requested tolerance and the sum's own estimate, and of the rod motion the outputs produce
//! (the flow part of (P2)-(P3) for `"sbt"`, Jeffery's rotation for `"dipole"`).

use crate::io::rundir::{RunDir, read_run_config};
use crate::io::snapshot::{ParticleSnapshot, Snapshot, read_snapshot};
use crate::run::particle::ParticleRunConfig;
use anyhow::{Context, bail};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry, SumReport};
use motile_particle::ewald::reference::EwaldReference;
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::stresslet_strength;
use motile_particle::hydro::slender::half_rod_rule;
use motile_particle::model::geometry::{Vec3, cross, dot};
use motile_particle::model::level::Hydrodynamics;
use motile_particle::model::units::ROD_LENGTH;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One audited quantity.
#[derive(Clone, Debug, PartialEq)]
pub struct AuditRow {
    /// What it is.
    pub quantity: String,
    /// `max |fast - direct| / max |direct|` over the sampled targets.
    pub max_relative: f64,
    /// `||fast - direct||_2 / ||direct||_2` over the sampled targets.
    pub l2_relative: f64,
    /// The fast sum's own estimate (max-relative, relative L2), for the sum's outputs.
    pub estimate: Option<(f64, f64)>,
}

/// The result of an audit.
#[derive(Clone, Debug)]
pub struct Audit {
    /// The snapshot audited.
    pub snapshot: PathBuf,
    /// Its time (1/beta).
    pub time: f64,
    /// Sbt or Dipole.
    pub hydrodynamics: Hydrodynamics,
    /// `hydro.sum_tolerance`.
    pub tolerance: f64,
    /// Sampled rods (indices into the snapshot's rods); for `"sbt"` every quadrature point of
    /// each is a target.
    pub rods: Vec<usize>,
    /// Targets of the direct sum.
    pub targets: usize,
    /// Sources (points or stresslets).
    pub sources: usize,
    /// One row per quantity.
    pub rows: Vec<AuditRow>,
    /// The fast sum's report.
    pub report: SumReport,
    /// Wall time of the fast sum (all targets) and of the direct one (sampled targets).
    pub seconds: (f64, f64),
    /// Splitting parameter of the direct sum.
    pub direct_xi: f64,
}

/// Max-relative and relative-L2 error of `fast` against `exact` (rows of equal length).
fn relative_errors(fast: &[Vec<f64>], exact: &[Vec<f64>]) -> (f64, f64) {
    let (mut e2, mut x2, mut emax, mut xmax): (f64, f64, f64, f64) = (0.0, 0.0, 0.0, 0.0);
    for (a, b) in fast.iter().zip(exact) {
        let d: f64 = a.iter().zip(b).map(|(u, v)| (u - v) * (u - v)).sum();
        let n: f64 = b.iter().map(|v| v * v).sum();
        e2 += d;
        x2 += n;
        emax = emax.max(d.sqrt());
        xmax = xmax.max(n.sqrt());
    }
    let ratio = |e: f64, x: f64| if x > 0.0 { e / x } else { e };
    (ratio(emax, xmax), ratio(e2.sqrt(), x2.sqrt()))
}

fn rows3(v: &[Vec3]) -> Vec<Vec<f64>> {
    v.iter().map(|x| x.to_vec()).collect()
}

/// The direct sum's splitting parameter for `k` targets in a box of side `l`: `xi L` balances
/// a real-space part of cost `k N (4 pi/3)(6.5/(xi L))^3` kernel evaluations against a
/// structure factor of `N (4 pi/3)(13 xi L / 2 pi)^3` terms, a kernel evaluation counted as ten
/// terms: `(xi L)^6 = 310 k`, kept within [3, 10].
pub fn direct_xi(k: usize, l: f64) -> f64 {
    (310.0 * k as f64).powf(1.0 / 6.0).clamp(3.0, 10.0) / l
}

/// The snapshot of `run` to audit: number `index`, or the last one.
fn pick_snapshot(
    run: &RunDir,
    index: Option<usize>,
) -> anyhow::Result<(PathBuf, ParticleSnapshot)> {
    let paths = run.snapshot_paths()?;
    if paths.is_empty() {
        bail!("{}: no snapshots to audit", run.path().display());
    }
    let path = match index {
        Some(i) => run.snapshot_path(i),
        None => paths.last().expect("not empty").clone(),
    };
    if !path.exists() {
        bail!(
            "--snapshot {}: {} does not exist; this run has {} snapshots ({} to {})",
            index.unwrap_or(0),
            path.display(),
            paths.len(),
            paths[0].file_name().unwrap_or_default().to_string_lossy(),
            paths[paths.len() - 1]
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
        );
    }
    match read_snapshot(&path)? {
        Snapshot::Particle(s) => Ok((path, s)),
        Snapshot::Field(_) => bail!("{}: not a particle snapshot", path.display()),
    }
}

/// `k` distinct indices out of `n`, reproducibly (seed 1).
fn sample(n: usize, k: usize) -> Vec<usize> {
    let mut all: Vec<usize> = (0..n).collect();
    all.shuffle(&mut ChaCha8Rng::seed_from_u64(1));
    all.truncate(k.min(n));
    all.sort_unstable();
    all
}

/// Audit snapshot `snapshot` (default: the last) of the particle run in `run_dir` on about
/// `targets` sampled targets.
pub fn audit(run_dir: &Path, snapshot: Option<usize>, targets: usize) -> anyhow::Result<Audit> {
    if targets == 0 {
        bail!("--targets 0: the audit needs at least one target");
    }
    let run = RunDir::open(run_dir)?;
    let model = run.header()?.model;
    if model != "particle" {
        bail!(
            "{}: a {model} run; check-accuracy audits the fast sums of particle runs",
            run_dir.display()
        );
    }
    let cfg: ParticleRunConfig = read_run_config(run_dir, ParticleRunConfig::validate)?;
    if !cfg.hydrodynamics.has_flow() {
        bail!(
            "{}: hydrodynamics = \"none\": the run uses no fast sums, there is nothing to audit",
            run_dir.display()
        );
    }
    let (path, snap) = pick_snapshot(&run, snapshot)?;
    let path_shown = path.clone();
    let tol = cfg.hydro.sum_tolerance;
    let l = snap.box_length;
    if (l - cfg.box_length).abs() > 1e-12 * cfg.box_length {
        bail!(
            "{}: a snapshot of a box of side {l} l, the run's config.toml says box_length = {}",
            path.display(),
            cfg.box_length
        );
    }
    let mut fast = SpectralEwald::new(tol)?;
    match cfg.hydrodynamics {
        // Both sum the RPY flow of the snapshot's force densities at the rods' nodes.
        Hydrodynamics::Sbt | Hydrodynamics::SbtExplicit => {
            audit_sbt(&cfg, path, &snap, targets, &mut fast)
        }
        Hydrodynamics::Dipole => audit_dipole(path, &snap, cfg.diameter, targets, &mut fast),
        Hydrodynamics::None => unreachable!("refused above: no flow, no sums"),
    }
    .and_then(|mut a| {
        // Finite forces whose sums overflow (a damaged file): no error can be measured.
        if let Some(r) = a
            .rows
            .iter()
            .find(|r| !(r.max_relative.is_finite() && r.l2_relative.is_finite()))
        {
            bail!(
                "the {} has no finite error (max-relative {}, relative L2 {}): its point forces overflow the sums",
                r.quantity,
                r.max_relative,
                r.l2_relative
            );
        }
        a.tolerance = tol;
        a.direct_xi = direct_xi(a.targets, l);
        Ok(a)
    })
    .with_context(|| format!("auditing {}", path_shown.display()))
}

fn audit_sbt(
    cfg: &ParticleRunConfig,
    path: PathBuf,
    snap: &ParticleSnapshot,
    targets: usize,
    fast: &mut SpectralEwald,
) -> anyhow::Result<Audit> {
    let Some(pf) = &snap.forces else {
        bail!(
            "{}: no force data (datasets force_points, point_forces): the snapshot at t = 0 is \
             written before the first solve, and runs without hydrodynamics write none; choose \
             a later snapshot with --snapshot N",
            path.display()
        );
    };
    let m = cfg.hydro.quadrature_points;
    let n = snap.positions.len();
    if pf.points.len() != n * m {
        bail!(
            "{}: {} force points for {n} rods of {m} quadrature points",
            path.display(),
            pf.points.len()
        );
    }
    let l = snap.box_length;
    let geo = RpyGeometry {
        box_length: l,
        radius: cfg.hydro.slender(cfg.diameter).rpy_radius,
        group: m,
    };
    let t = Instant::now();
    let u = fast.rpy(&geo, &pf.points, &pf.forces)?;
    let t_fast = t.elapsed().as_secs_f64();
    let report = fast.last_report().context("the fast sum reports")?;
    let rods = sample(n, targets.div_ceil(m));
    let idx: Vec<usize> = rods
        .iter()
        .flat_map(|&r| (0..m).map(move |j| r * m + j))
        .collect();
    let t = Instant::now();
    let exact = EwaldReference::with_xi(direct_xi(idx.len(), l))
        .rpy_at(&geo, &pf.points, &pf.forces, &idx)?;
    let t_direct = t.elapsed().as_secs_f64();
    let fast_u: Vec<Vec3> = idx.iter().map(|&i| u[i]).collect();
    // Rod motion from the flow at the nodes, (P2)-(P3) without swimming and contacts.
    let (s, w) = half_rod_rule(m, ROD_LENGTH);
    let motion = |vals: &[Vec3]| -> (Vec<Vec3>, Vec<Vec3>) {
        vals.chunks_exact(m)
            .zip(&rods)
            .map(|(un, &r)| {
                let pts = &pf.points[r * m..(r + 1) * m];
                let d = [0, 1, 2].map(|k| pts[m - 1][k] - pts[0][k]);
                let p = d.map(|c| c / dot(d, d).sqrt());
                let (mut ubar, mut su) = ([0.0; 3], [0.0; 3]);
                for j in 0..m {
                    for k in 0..3 {
                        ubar[k] += w[j] * un[j][k] / ROD_LENGTH;
                        su[k] += w[j] * s[j] * un[j][k];
                    }
                }
                let c = dot(p, su);
                let pdot = [0, 1, 2].map(|k| 12.0 / ROD_LENGTH.powi(3) * (su[k] - c * p[k]));
                (ubar, cross(p, pdot))
            })
            .unzip()
    };
    let (fv, fw) = motion(&fast_u);
    let (ev, ew) = motion(&exact);
    let est = &report.estimates[0];
    let rows = vec![
        row(
            "RPY velocity at the quadrature points",
            relative_errors(&rows3(&fast_u), &rows3(&exact)),
            Some((est.max_relative, est.l2_relative)),
        ),
        row(
            "rod velocity from the flow, [u]_l / l",
            relative_errors(&rows3(&fv), &rows3(&ev)),
            None,
        ),
        row(
            "rod rotation rate from the flow",
            relative_errors(&rows3(&fw), &rows3(&ew)),
            None,
        ),
    ];
    Ok(Audit {
        snapshot: path,
        time: snap.time,
        hydrodynamics: Hydrodynamics::Sbt,
        tolerance: 0.0,
        targets: idx.len(),
        sources: pf.points.len(),
        rods,
        rows,
        report,
        seconds: (t_fast, t_direct),
        direct_xi: 0.0,
    })
}

fn audit_dipole(
    path: PathBuf,
    snap: &ParticleSnapshot,
    diameter: f64,
    targets: usize,
    fast: &mut SpectralEwald,
) -> anyhow::Result<Audit> {
    let (x, p) = (&snap.positions, &snap.orientations);
    let n = x.len();
    let l = snap.box_length;
    let sigma = vec![stresslet_strength(diameter); n];
    let t = Instant::now();
    let field = fast.stresslets(l, x, p, &sigma)?;
    let t_fast = t.elapsed().as_secs_f64();
    let report = fast.last_report().context("the fast sum reports")?;
    let rods = sample(n, targets);
    let t = Instant::now();
    let exact =
        EwaldReference::with_xi(direct_xi(rods.len(), l)).stresslets_at(l, x, p, &sigma, &rods);
    let t_direct = t.elapsed().as_secs_f64();
    let pick_u: Vec<Vec3> = rods.iter().map(|&r| field.u[r]).collect();
    let grads = |g: &[[Vec3; 3]]| -> Vec<Vec<f64>> {
        g.iter()
            .map(|m| m.iter().flatten().copied().collect())
            .collect()
    };
    let pick_g: Vec<[Vec3; 3]> = rods.iter().map(|&r| field.grad[r]).collect();
    // Jeffery's rotation: pdot = (I - pp)(grad u) p, omega = p x pdot.
    let jeffery = |g: &[[Vec3; 3]]| -> Vec<Vec3> {
        g.iter()
            .zip(&rods)
            .map(|(g, &r)| {
                let pn = p[r];
                let gp = [0, 1, 2].map(|i| dot(g[i], pn));
                let c = dot(pn, gp);
                cross(pn, [0, 1, 2].map(|d| gp[d] - c * pn[d]))
            })
            .collect()
    };
    let (eu, eg) = (&report.estimates[0], &report.estimates[1]);
    let rows = vec![
        row(
            "stresslet velocity",
            relative_errors(&rows3(&pick_u), &rows3(&exact.u)),
            Some((eu.max_relative, eu.l2_relative)),
        ),
        row(
            "stresslet velocity gradient",
            relative_errors(&grads(&pick_g), &grads(&exact.grad)),
            Some((eg.max_relative, eg.l2_relative)),
        ),
        row(
            "rod rotation rate (Jeffery)",
            relative_errors(&rows3(&jeffery(&pick_g)), &rows3(&jeffery(&exact.grad))),
            None,
        ),
    ];
    Ok(Audit {
        snapshot: path,
        time: snap.time,
        hydrodynamics: Hydrodynamics::Dipole,
        tolerance: 0.0,
        targets: rods.len(),
        sources: n,
        rods,
        rows,
        report,
        seconds: (t_fast, t_direct),
        direct_xi: 0.0,
    })
}

fn row(
    quantity: &str,
    (max_relative, l2_relative): (f64, f64),
    estimate: Option<(f64, f64)>,
) -> AuditRow {
    AuditRow {
        quantity: quantity.into(),
        max_relative,
        l2_relative,
        estimate,
    }
}

/// The audit as the table `motile check-accuracy` prints.
pub fn render(a: &Audit) -> String {
    let mut s = format!(
        "Fast-sum audit of {} (t = {:.4}, hydrodynamics = \"{}\"): spectral Ewald at \
         hydro.sum_tolerance = {:e} (refinement level {}, {} attempt(s), {:.2} s for all {} \
         sources) against the direct Ewald sum (xi = {:.3}, {:.2} s) at {} sampled targets.\n\n",
        a.snapshot.display(),
        a.time,
        a.hydrodynamics,
        a.tolerance,
        a.report.level,
        a.report.attempts,
        a.seconds.0,
        a.sources,
        a.direct_xi,
        a.seconds.1,
        a.targets
    );
    s += "| quantity | tolerance | measured max-relative | measured relative L2 | sum's estimate (max / L2) | within |\n";
    s += "|---|---|---|---|---|---|\n";
    for r in &a.rows {
        let est = r
            .estimate
            .map_or("-".into(), |(m, l)| format!("{m:.2e} / {l:.2e}"));
        let within = if r.estimate.is_some() {
            if r.max_relative <= a.tolerance && r.l2_relative <= a.tolerance {
                "yes"
            } else {
                "NO"
            }
        } else {
            "(derived)"
        };
        s += &format!(
            "| {} | {:.0e} | {:.2e} ({:.2} tol) | {:.2e} ({:.2} tol) | {est} | {within} |\n",
            r.quantity,
            a.tolerance,
            r.max_relative,
            r.max_relative / a.tolerance,
            r.l2_relative,
            r.l2_relative / a.tolerance
        );
    }
    s += "\nErrors are over the sampled targets, relative to the largest (max) and the L2 norm \
          of the direct values there. The contract (docs/accuracy.md) bounds the sum's outputs; \
          the derived rod motion is a combination of them and usually inherits their accuracy.\n";
    s
}
