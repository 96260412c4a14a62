//! The GPU back-end against the CPU, side by side in one process (BENCHMARKS.md's GPU tables).
//!
//! ```text
//! cargo run --release -p motile-experiments --features gpu --example gpu_bench -- \
//!     [--device cuda|emulation] [--small] [--cases mf,sum,dipole,explicit,sbt] [--reps 3]
//!     [--cpu-max N] [--sum-sizes 100000,1000000] [--lengths 100,175] [--profile] [--out FILE.csv]
//! cargo run --release -p motile-experiments --features gpu --example gpu_bench -- --model [--small]
//! ```
//!
//! `--model` needs no device: it prints the work model of the particle sums' Fourier part
//! (`motile_particle::ewald::gpu::work_model`: global-memory bytes, atomics and launches per
//! phase, per point and per sum) for each spreading method on the benchmark's cases, and the
//! launches, transforms and host round trips of whole steps (the mean-field step and the
//! particle step resident on the device), counted by the device as they are issued on the
//! host emulation (`motile_gpu::Counters`: the same counts as on CUDA), so the design is
//! judged by counts where no GPU is at hand.
//!
//! Cases (`--small` shrinks every one to seconds, for checking the
//! harness, e.g. on the host emulation):
//! - `mf`: one mean-field step (64^3 warm-up, then 128^3 and 256^3; closure degree 20), the
//!   CPU stepper and the GPU stepper from the same state, with the largest relative difference
//!   of Q between them after the timed steps;
//! - `sum`: one RPY mobility product of 1e5, 1e6, 1e7 random points at tolerances 1e-4 and
//!   1e-8 (points per second; the Fourier part's seconds; the largest difference of the GPU's
//!   velocities from the CPU's relative to the largest velocity), on the GPU with the default
//!   (output-driven) spreader and, below 1e7 points, also with the per-point atomic one, the
//!   shared-memory tiles (at 1e-4) and the global-memory spreader in bin order (rows `gpu
//!   atomic`, `gpu tiles`, `gpu sorted`: the befores of the before/after ratios);
//! - `dipole`: steps of the point-stresslet level at L/l = 100 and 175 (nu = 0.625): the CPU
//!   stepper with the CPU's sums and with the GPU's, and the step resident on the GPU (its
//!   flow summed from the host, `device = "gpu"` runs' step);
//! - `explicit`: the same for the explicit slender-body level at L/l = 50 (`explicit100`, not
//!   in the default cases: at L/l = 100, 2.5e6 quadrature nodes, one timed step per side), at
//!   the settings the `paper-dilute` scene runs it with (sum tolerance 1e-2, 4 nodes per rod);
//! - `sbt`: steps of the slender-body level at L/l = 50 (`sbt100`: also at 100).
//!
//! `--profile` waits for the device after each of its operations and prints (to stderr) each
//! GPU side's time by kernel, transform and transfer (`motile_gpu::profile`), over its untimed
//! and timed runs; the waits slow the GPU rows a little, so profile in a run of its own.
//!
//! `--cpu-max N` leaves out the CPU side of the cases with more than N points, grid points or
//! rods (the
//! device check's time limit: the CPU's 16-thread figures at 1e7 points and L/l = 175 are in
//! BENCHMARKS.md from the H200 run).
//!
//! The CPU runs on the rayon pool (`RAYON_NUM_THREADS`, default all cores). Each row is the
//! median of `--reps` timed runs after one untimed run (one timed run for the largest sizes).
//! Memory: the GPU's bytes in use after the case (every context on the device, so the probe's
//! own small context too) and the process's resident set (VmRSS) after it. The GPU does the
//! particle sums' Fourier part only: their real space, the contacts and everything else stay
//! on the CPU threads, so the particle rows measure that split.

use motile_gpu::Backend;
use motile_meanfield::closure::{BinghamClosure, DEFAULT_DEGREE};
use motile_meanfield::gpu::GpuMeanField;
use motile_meanfield::solver::grid::SpectralGrid;
use motile_meanfield::solver::params::MeanFieldParams;
use motile_meanfield::solver::rhs::MeanFieldRhs;
use motile_meanfield::solver::stepper::{MeanFieldStepper, SBDF2};
use motile_particle::ewald::gpu::{GpuFourier, PointForces, SpreadMethod};
use motile_particle::ewald::periodic::{PeriodicStokes, RpyGeometry};
use motile_particle::ewald::spectral::SpectralEwald;
use motile_particle::hydro::dipole::Dipole;
use motile_particle::hydro::explicit::ExplicitSlender;
use motile_particle::hydro::mobility::Mobility;
use motile_particle::hydro::slender::{SlenderBody, SlenderParams};
use motile_particle::model::init::random_nonoverlapping;
use motile_particle::model::rods::RodSet;
use motile_particle::model::units::DEFAULT_DIAMETER;
use motile_particle::step::contact::ContactParams;
use motile_particle::step::gpu::DeviceStepper;
use motile_particle::step::stepper::Stepper;
use std::time::Instant;

mod gpu_bench_model;
mod shared;
use gpu_bench_model::{counted_table, meanfield_model_table, model_table};
use shared::{arg, list_arg, meanfield_state, median, random_points};

/// One row of the table.
struct Row {
    case: String,
    side: &'static str,
    seconds: f64,
    rate: f64,
    unit: &'static str,
    note: String,
    gpu_bytes: Option<usize>,
    rss_bytes: usize,
}

/// The process's resident set in bytes (Linux), else 0.
fn rss() -> usize {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<usize>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// One RPY product case: `n` random points and forces in a box, timed `reps` times at the
/// sum tolerance `tol`.
struct SumCase {
    n: usize,
    tol: f64,
    geometry: RpyGeometry,
    points: Vec<[f64; 3]>,
    forces: Vec<[f64; 3]>,
    reps: usize,
}

/// The default GPU sum of a case and its resident product.
struct DefaultSum {
    /// Seconds per sum.
    seconds: f64,
    /// Seconds of its Fourier part.
    fourier_seconds: f64,
    /// Its other parts' seconds, as the note writes them.
    split: String,
    /// Device memory in use after it.
    gpu_bytes: Option<usize>,
    /// The velocities.
    velocities: Vec<[f64; 3]>,
    /// Seconds per resident product.
    resident_seconds: f64,
    /// The largest squared difference of the resident product's velocities from `velocities`.
    resident_difference: f64,
}

/// A case's sum with another spreader.
struct SpreaderSum {
    method: SpreadMethod,
    seconds: f64,
    fourier_seconds: f64,
    velocities: Vec<[f64; 3]>,
}

/// The largest squared velocity.
fn largest_squared(u: &[[f64; 3]]) -> f64 {
    u.iter()
        .map(|a| a.iter().map(|c| c * c).sum::<f64>())
        .fold(0.0, f64::max)
}

/// The largest squared difference of two sets of velocities.
fn largest_squared_difference(u: &[[f64; 3]], v: &[[f64; 3]]) -> f64 {
    u.iter()
        .zip(v)
        .map(|(a, b)| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>())
        .fold(0.0, f64::max)
}

/// Seconds of one untimed then `reps` timed calls, the median.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..reps.max(1))
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

struct Bench {
    emulate: bool,
    reps: usize,
    cpu_max: usize,
    profile: bool,
    /// The device's memory in use before any case (the CUDA context, every context on it).
    base_bytes: Option<usize>,
    probe: GpuFourier,
    rows: Vec<Row>,
}

impl Bench {
    fn backend(&self) -> Backend {
        if self.emulate {
            Backend::HostEmulation
        } else {
            Backend::Cuda
        }
    }

    fn fourier(&self) -> GpuFourier {
        GpuFourier::open(self.backend()).expect("the device")
    }

    /// Start a profiled GPU side (`--profile`): clear the totals.
    fn profile_begin(&self) {
        if self.profile {
            motile_gpu::profile::take();
        }
    }

    /// End a profiled GPU side of `runs` runs of `seconds` each: its totals, to stderr.
    fn profile_end(&self, label: &str, runs: usize, seconds: f64) {
        if !self.profile {
            return;
        }
        let p = motile_gpu::profile::take();
        let total: f64 = p.iter().map(|e| e.seconds).sum();
        eprintln!(
            "\nprofile: {label}: device operations {:.4} s per run of {seconds:.4} s ({runs} runs)",
            total / runs as f64
        );
        eprintln!("| operation | calls per run | s per run | share |\n|---|---:|---:|---:|");
        for e in p.iter().take(25) {
            eprintln!(
                "| {} | {:.1} | {:.5} | {:.1}% |",
                e.name,
                e.calls as f64 / runs as f64,
                e.seconds / runs as f64,
                100.0 * e.seconds / total.max(1e-300)
            );
        }
        eprintln!();
    }

    fn gpu_bytes(&self) -> Option<usize> {
        self.probe.memory().ok().flatten().map(|(used, _)| used)
    }

    fn push(
        &mut self,
        case: &str,
        side: &'static str,
        seconds: f64,
        work: f64,
        unit: &'static str,
        note: String,
    ) {
        let row = Row {
            case: case.into(),
            side,
            seconds,
            rate: work / seconds,
            unit,
            note,
            gpu_bytes: if side.starts_with("gpu") {
                self.gpu_bytes()
            } else {
                None
            },
            rss_bytes: rss(),
        };
        eprintln!(
            "{} {}: {:.4} s, {:.4e} {}{}",
            row.case,
            row.side,
            row.seconds,
            row.rate,
            row.unit,
            if row.note.is_empty() {
                String::new()
            } else {
                format!(" ({})", row.note)
            }
        );
        self.rows.push(row);
    }

    fn meanfield(&mut self, n: usize, closure: &BinghamClosure) {
        let grid = SpectralGrid::new(n);
        let params = MeanFieldParams::default();
        let q = meanfield_state(n);
        let mut cpu = MeanFieldStepper::new(&grid, &q, SBDF2);
        // Timed steps after a warm-up step (which has no history: SBDF1, and a fixed point
        // without the warm start), on both sides (the CPU's 256^3 step takes seconds).
        let reps = self.reps;
        let rhs = MeanFieldRhs {
            grid: &grid,
            closure,
            params: &params,
            with_entropy: false,
        };
        let mut gpu = GpuMeanField::open(self.backend(), &rhs, &cpu).expect("the GPU stepper");
        let dt = 0.01;
        self.profile_begin();
        let tg = time(reps, || {
            gpu.step(dt, false).expect("GPU step");
        });
        self.profile_end(&format!("mean-field step {n}^3"), reps + 1, tg);
        let gpu_bytes = self.gpu_bytes();
        let case = format!("mean-field step {n}^3");
        let note = if n.pow(3) <= self.cpu_max {
            let tc = time(reps, || {
                cpu.step(&rhs, dt).expect("CPU step");
            });
            let (_, q_gpu, _, _) = gpu.state().expect("download");
            let scale = cpu
                .q_hat
                .iter()
                .flatten()
                .map(|z| z.norm())
                .fold(1e-300, f64::max);
            let dq = cpu
                .q_hat
                .iter()
                .flatten()
                .zip(q_gpu.iter().flatten())
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max)
                / scale;
            self.push(&case, "cpu", tc, 1.0, "steps/s", String::new());
            format!(
                "Q differs from the CPU's by {dq:.1e} after {} steps",
                reps + 1
            )
        } else {
            "CPU side left out (--cpu-max)".into()
        };
        let note = format!(
            "{note}; cuFFT work areas {:.2} GB",
            motile_gpu::fft_work_bytes() as f64 / 1e9
        );
        self.push(&case, "gpu", tg, 1.0, "steps/s", note);
        if let Some(last) = self.rows.last_mut() {
            last.gpu_bytes = gpu_bytes;
        }
    }

    /// The RPY product of `n` random points at tolerance `tol`: the default spreader, its
    /// resident product and the other spreaders on the device, and the CPU's where it runs.
    fn sum(&mut self, n: usize, tol: f64) {
        let (box_length, points, forces) = random_points(n);
        let case = SumCase {
            n,
            tol,
            geometry: RpyGeometry {
                box_length,
                radius: 0.0866,
                group: 1,
            },
            points,
            forces,
            reps: if n >= 10_000_000 { 1 } else { self.reps },
        };
        let default = self.default_sum(&case);
        // The other spreaders on the same device, for the ratios (the per-point atomic one,
        // the global-memory one in bin order); skipped at 1e7 points (their times there are
        // in BENCHMARKS.md).
        let methods = if n >= 10_000_000 {
            Vec::new()
        } else {
            vec![SpreadMethod::Atomic, SpreadMethod::Sorted]
        };
        let others: Vec<SpreaderSum> = methods
            .into_iter()
            .map(|method| self.spreader_sum(&case, method))
            .collect();
        self.push_sum_rows(&case, default, others);
    }

    /// The default GPU sum, timed, and the resident product (points, forces and velocities on
    /// the device: the product the resident particle step runs) against the same sum of host
    /// values.
    fn default_sum(&mut self, case: &SumCase) -> DefaultSum {
        let (n, tol, reps) = (case.n, case.tol, case.reps);
        let (geo, y, f) = (&case.geometry, &case.points, &case.forces);
        let mut gpu = SpectralEwald::with_device(tol, self.fourier()).expect("tolerance");
        let mut ug = Vec::new();
        self.profile_begin();
        let tg = time(reps, || ug = gpu.rpy(geo, y, f).expect("GPU sum"));
        let label = format!("RPY product, {n} points, tol {tol:.0e}, gpu");
        self.profile_end(&label, reps + 1, tg);
        let tm = gpu.last_timing();
        let split = format!(
            "setup {:.3} s, real space {:.3} s, corrections {:.3} s",
            tm.setup, tm.real, tm.corrections
        );
        let fourier_seconds = tm.fourier;
        let gpu_bytes = self.gpu_bytes();
        let up = |v: Vec<f64>| gpu.upload(&v).expect("upload");
        let (pts, force) = (up(y.as_flattened().to_vec()), up(f.as_flattened().to_vec()));
        let fields = up((0..3).flat_map(|d| f.iter().map(move |v| v[d])).collect());
        let sources = PointForces {
            points: &pts,
            forces: &force,
            fields: &fields,
        };
        let mut ur = None;
        self.profile_begin();
        let tr = time(reps, || {
            ur = Some(gpu.rpy_resident(geo, sources, n).expect("resident GPU sum"))
        });
        self.profile_end(&format!("{label}, resident"), reps + 1, tr);
        let ur = gpu.download(&ur.expect("ran")).expect("download");
        let resident_difference = ur
            .chunks(3)
            .zip(&ug)
            .map(|(a, b)| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>())
            .fold(0.0, f64::max);
        drop((pts, force, fields, gpu));
        DefaultSum {
            seconds: tg,
            fourier_seconds,
            split,
            gpu_bytes,
            velocities: ug,
            resident_seconds: tr,
            resident_difference,
        }
    }

    /// The sum with the spreader `method`, timed.
    fn spreader_sum(&mut self, case: &SumCase, method: SpreadMethod) -> SpreaderSum {
        let (n, tol, reps) = (case.n, case.tol, case.reps);
        let mut fourier = self.fourier();
        fourier.set_spread_method(Some(method));
        let mut sum = SpectralEwald::with_device(tol, fourier).expect("tolerance");
        let mut velocities = Vec::new();
        self.profile_begin();
        let t = time(reps, || {
            velocities = sum
                .rpy(&case.geometry, &case.points, &case.forces)
                .expect("GPU sum (another spreader)")
        });
        let label = format!("RPY product, {n} points, tol {tol:.0e}, gpu {method:?}");
        self.profile_end(&label, reps + 1, t);
        SpreaderSum {
            method,
            seconds: t,
            fourier_seconds: sum.last_timing().fourier,
            velocities,
        }
    }

    /// The case's rows: the CPU's sum (timed here, where it runs), the default GPU sum, its
    /// resident product and the other spreaders, each with its difference from the reference
    /// relative to the largest velocity (of the CPU's where it runs, else the GPU's).
    fn push_sum_rows(&mut self, case: &SumCase, default: DefaultSum, others: Vec<SpreaderSum>) {
        let (n, tol, reps) = (case.n, case.tol, case.reps);
        let title = format!("RPY product, {n} points, tol {tol:.0e}");
        let ug = &default.velocities;
        let mut largest = largest_squared(ug);
        let mut gpu_note = format!(
            "Fourier part {:.3} s, {}",
            default.fourier_seconds, default.split
        );
        if n <= self.cpu_max {
            let mut cpu = SpectralEwald::new(tol).expect("tolerance");
            let mut uc = Vec::new();
            let tc = time(reps, || {
                uc = cpu
                    .rpy(&case.geometry, &case.points, &case.forces)
                    .expect("CPU sum")
            });
            let fourier_cpu = cpu.last_timing().fourier;
            largest = largest_squared(&uc);
            let diff = largest_squared_difference(&uc, ug);
            let note = format!("Fourier part {fourier_cpu:.3} s");
            self.push(&title, "cpu", tc, n as f64, "points/s", note);
            gpu_note.push_str(&format!(
                "; differs from the CPU's by {:.1e}",
                (diff / largest.max(1e-300)).sqrt()
            ));
        } else {
            gpu_note.push_str("; CPU side left out (--cpu-max)");
        }
        self.push(
            &title,
            "gpu",
            default.seconds,
            n as f64,
            "points/s",
            gpu_note,
        );
        if let Some(last) = self.rows.last_mut() {
            last.gpu_bytes = default.gpu_bytes;
        }
        let note = format!(
            "inputs and velocities on the device; differs from the host values' sum by {:.1e}",
            (default.resident_difference / largest.max(1e-300)).sqrt()
        );
        let tr = default.resident_seconds;
        self.push(&title, "gpu resident", tr, n as f64, "points/s", note);
        for other in others {
            let da = largest_squared_difference(&other.velocities, ug);
            let side = match other.method {
                SpreadMethod::Atomic => "gpu atomic",
                SpreadMethod::Sorted => "gpu sorted",
                SpreadMethod::Cells => "gpu cells",
            };
            self.push(
                &title,
                side,
                other.seconds,
                n as f64,
                "points/s",
                format!(
                    "Fourier part {:.3} s; {:?} spreader; differs from the default's by {:.1e}",
                    other.fourier_seconds,
                    other.method,
                    (da / largest.max(1e-300)).sqrt()
                ),
            );
        }
    }

    fn steps(&mut self, level: &str, l: f64) {
        let n = (0.625 * l * l * l).round() as usize;
        let rods: RodSet = random_nonoverlapping(n, l, DEFAULT_DIAMETER, 1, 1_000_000)
            .expect("initial configuration");
        // The explicit level at the `paper-dilute` scene's settings (sum tolerance 1e-2, 4
        // nodes per rod); the others at the configuration's default tolerance, 1e-4.
        let tol = if level == "sbt-explicit" { 1e-2 } else { 1e-4 };
        let make = |sum: SpectralEwald| -> Box<dyn Mobility> {
            match level {
                "dipole" => Box::new(Dipole::new(Box::new(sum), DEFAULT_DIAMETER)),
                "sbt-explicit" => Box::new(ExplicitSlender::new(
                    SlenderParams::default(),
                    Box::new(sum),
                )),
                _ => Box::new(SlenderBody::new(SlenderParams::default(), Box::new(sum))),
            }
        };
        // One timed run per side above a million rods, or a million quadrature nodes.
        let reps = if n > 1_000_000 || (level != "dipole" && n > 125_000) {
            1
        } else {
            self.reps
        };
        let dt = 0.01;
        let run = |mobility: Box<dyn Mobility>| {
            let mut r = rods.clone();
            let mut stepper = Stepper::new(mobility, ContactParams::default());
            // The slender-body level's first step solves exactly; steady steps predict.
            stepper.step(&mut r, dt).expect("first step");
            let mut sums = 0.0;
            let t = time(reps, || {
                sums = stepper.step(&mut r, dt).expect("step").hydro.seconds_sums;
            });
            (t, sums)
        };
        let per_rod = |g: Option<usize>| {
            g.map_or(String::new(), |g| {
                format!("; {:.0} GPU bytes in use per rod", g as f64 / n as f64)
            })
        };
        let case = format!("{level} step, L/l = {l}, {n} rods, sum tol {tol:.0e}");
        let sum = SpectralEwald::with_device(tol, self.fourier()).unwrap();
        self.profile_begin();
        let (tg, sg) = run(make(sum));
        self.profile_end(&format!("{case}, CPU step, GPU sums"), reps + 2, tg);
        let gpu_bytes = self.gpu_bytes();
        if n <= self.cpu_max {
            let (tc, sc) = run(make(SpectralEwald::new(tol).unwrap()));
            self.push(&case, "cpu", tc, 1.0, "steps/s", format!("sums {sc:.3} s"));
        }
        let note = format!("CPU step, GPU sums: sums {sg:.3} s{}", per_rod(gpu_bytes));
        self.push(&case, "gpu", tg, 1.0, "steps/s", note);
        if let Some(last) = self.rows.last_mut() {
            last.gpu_bytes = gpu_bytes;
        }
        // The step resident on the device (`device = "gpu"` runs at this level): the flow
        // summed on the device from the rods there (no round trip), contacts, the move and the
        // projection on the device.
        motile_gpu::reset_peak();
        let mut mobility = make(SpectralEwald::with_device(tol, self.fourier()).unwrap());
        let mut device =
            DeviceStepper::new(self.backend(), &rods, ContactParams::default(), &Vec::new())
                .expect("the device stepper");
        let mut sums = 0.0;
        let mut step = || {
            let r = device
                .step_with_resident_flow(dt, mobility.as_mut())
                .expect("device step");
            sums = r.hydro.seconds_sums;
        };
        self.profile_begin();
        let tr = time(reps, &mut step);
        self.profile_end(&format!("{case}, resident"), reps + 1, tr);
        let bytes = self.gpu_bytes();
        // What the step's own buffers and cuFFT's work areas take, counted by the process
        // (no device needed), beside the device's total in use (context included). The
        // device's memory at the step's peak: what is in use after it, less the buffers kept
        // (the rest is the context, cuFFT and the driver's reservations), plus the buffers'
        // peak.
        let (peak, work) = (motile_gpu::peak_bytes(), motile_gpu::fft_work_bytes());
        let kept = motile_gpu::live_bytes();
        let at_peak = bytes.map_or(String::new(), |b| {
            format!(
                "; the device at the step's peak {:.0} bytes per rod (in use after it, less \
                 the buffers kept, plus their peak)",
                (b.saturating_sub(kept) + peak) as f64 / n as f64
            )
        });
        let note = format!(
            "resident step (flow on the device): sums {sums:.3} s, the rest {:.3} s{}; per rod: \
             buffers at their peak {:.0} bytes, kept after the step {:.0}, cuFFT work areas \
             {:.0}, the context and the driver's pool the rest (in use before any case: {}){at_peak}",
            tr - sums,
            per_rod(bytes),
            peak as f64 / n as f64,
            kept as f64 / n as f64,
            work as f64 / n as f64,
            self.base_bytes
                .map_or("-".into(), |b| format!("{:.2} GB", b as f64 / 1e9))
        );
        self.push(&case, "gpu resident", tr, 1.0, "steps/s", note);
        if let Some(last) = self.rows.last_mut() {
            last.gpu_bytes = bytes;
        }
    }
}

fn main() {
    let small = std::env::args().any(|a| a == "--small");
    if std::env::args().any(|a| a == "--model") {
        model_table(small);
        meanfield_model_table();
        counted_table();
        return;
    }
    let emulate = arg("--device").as_deref() == Some("emulation");
    let cases = arg("--cases").unwrap_or_else(|| "mf,sum,dipole,explicit,sbt".into());
    let reps: usize = arg("--reps").map_or(3, |r| r.parse().expect("--reps"));
    let cpu_max: usize = arg("--cpu-max").map_or(usize::MAX, |r| r.parse().expect("--cpu-max"));
    let profile = std::env::args().any(|a| a == "--profile");
    motile_gpu::profile::enable(profile);
    let probe = GpuFourier::open(if emulate {
        Backend::HostEmulation
    } else {
        Backend::Cuda
    });
    let probe = match probe {
        Ok(p) => p,
        Err(e) => {
            eprintln!("gpu_bench: {e}");
            std::process::exit(2);
        }
    };
    println!(
        "device: {}; CPU: {} threads",
        probe.describe(),
        rayon::current_num_threads()
    );
    let mut b = Bench {
        emulate,
        reps,
        cpu_max,
        profile,
        base_bytes: probe.memory().ok().flatten().map(|(used, _)| used),
        probe,
        rows: Vec::new(),
    };
    let has = |c: &str| cases.split(',').any(|x| x.trim() == c);
    if has("mf") {
        let closure = BinghamClosure::new(DEFAULT_DEGREE).expect("closure tables");
        for n in if small { vec![16] } else { vec![128, 256] } {
            b.meanfield(n, &closure);
        }
    }
    if has("sum") {
        let sizes = if let Some(list) = list_arg("--sum-sizes") {
            list
        } else if small {
            vec![2_000]
        } else {
            vec![100_000, 1_000_000, 10_000_000]
        };
        for n in sizes {
            for tol in [1e-4, 1e-8] {
                b.sum(n, tol);
            }
        }
    }
    if has("dipole") {
        let lengths = if let Some(list) = list_arg("--lengths") {
            list
        } else if small {
            vec![5.0]
        } else {
            vec![100.0, 175.0]
        };
        for l in lengths {
            b.steps("dipole", l);
        }
    }
    if has("explicit") {
        b.steps("sbt-explicit", if small { 5.0 } else { 50.0 });
    }
    if has("explicit100") && !small {
        b.steps("sbt-explicit", 100.0);
    }
    if has("sbt") {
        b.steps("sbt", if small { 4.0 } else { 50.0 });
    }
    if has("sbt100") && !small {
        b.steps("sbt", 100.0);
    }
    println!("| case | side | seconds | rate | GPU bytes in use | RSS | note |");
    println!("|---|---|---:|---:|---:|---:|---|");
    let mut csv = String::from("case,side,seconds,rate,unit,gpu_bytes,rss_bytes,note\n");
    for r in &b.rows {
        println!(
            "| {} | {} | {:.4} | {:.3e} {} | {} | {:.2} GB | {} |",
            r.case,
            r.side,
            r.seconds,
            r.rate,
            r.unit,
            r.gpu_bytes
                .map_or("-".into(), |g| format!("{:.2} GB", g as f64 / 1e9)),
            r.rss_bytes as f64 / 1e9,
            r.note
        );
        csv.push_str(&format!(
            "\"{}\",{},{},{},{},{},{},\"{}\"\n",
            r.case,
            r.side,
            r.seconds,
            r.rate,
            r.unit,
            r.gpu_bytes.map_or(String::new(), |g| g.to_string()),
            r.rss_bytes,
            r.note
        ));
    }
    if let Some(path) = arg("--out") {
        std::fs::write(&path, csv).expect("writing the CSV");
        println!("wrote {path}");
    }
}
