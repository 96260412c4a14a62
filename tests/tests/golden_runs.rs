//! Golden outputs of the run loop: a small slender-body particle run (125 rods with contacts,
//! a perturbed start, snapshots, VTK and checkpoints every 5 of its 10 steps) and a mean-field
//! run (8^3, adaptive steps, outputs at t = 0.25/0.5 to t = 1) write exactly the files whose
//! hashes are recorded here (every file but the log, the particle time series without its
//! wall-clock column), fresh and when resumed from mid-run checkpoints kept in
//! tests/data/golden/{particle,meanfield} (each run's directory as it stood just after its
//! mid-run checkpoint, written by an earlier format of the config: without the `diameter` and
//! `device` keys). A change that moves any bit of these outputs fails here; one that must,
//! records the new hashes and says why in its commit.
//!
//! The hashes were recorded on x86_64 with AVX2 and FMA (rustfft and the compiler's vector
//! code choose their kernels at run time); on a machine with other vector units the test
//! says so and skips instead of comparing bits. They do not depend on the thread count
//! (checked at 1 and 2 threads).

use motile_experiments::io::snapshot::{Snapshot, read_snapshot};
use motile_experiments::run::meanfield::{
    parse_config as mf_config, resume_meanfield, run_meanfield,
};
use motile_experiments::run::particle::{parse_config as p_config, resume_particle, run_particle};
use motile_tests::copy_dir;
use std::path::{Path, PathBuf};

/// `(file, FNV-1a 64)` of every file of the particle run, log excluded.
const PARTICLE: [(&str, u64); 15] = [
    ("checkpoints/ckpt_000000000.h5", 0x985f5bded1fb6157),
    ("checkpoints/ckpt_000000000.h5.crc32", 0x2b658351817da369),
    ("checkpoints/ckpt_000000005.h5", 0xcccf7b38318a2669),
    ("checkpoints/ckpt_000000005.h5.crc32", 0x3cda81625abe5f6b),
    ("checkpoints/ckpt_000000010.h5", 0x9c87ae422a951ba1),
    ("checkpoints/ckpt_000000010.h5.crc32", 0x7669886986b75dfb),
    ("config.toml", 0xb2125f156bf0e2a1),
    ("rods.pvd", 0xdd3f77050fe4c5f7),
    ("snapshots/snap_000000.h5", 0x2241a2383dfbf66e),
    ("snapshots/snap_000001.h5", 0x4ce5e9bb9b90d02c),
    ("snapshots/snap_000002.h5", 0x52af1969a1f1d499),
    ("timeseries.csv", 0xc481a4accc671a43),
    ("vtk/rods_000000.vtp", 0x8748c0f8b5e80b72),
    ("vtk/rods_000001.vtp", 0x5743968c092134b2),
    ("vtk/rods_000002.vtp", 0x9bf88dc555aacd8e),
];
/// config.toml of the particle run in the format of tests/data/golden (no `diameter` key): a
/// run resumed from there keeps that file, and every other file it writes is the fresh run's.
const PARTICLE_CONFIG_BEFORE_DIAMETER: u64 = 0xcb6a1b2e4109c3c8;
/// The same for the mean-field run (config.toml with the `device` key).
const MEANFIELD: [(&str, u64); 11] = [
    ("checkpoints/ckpt_000000000.h5", 0xcdb7d5dc7454c81e),
    ("checkpoints/ckpt_000000000.h5.crc32", 0x9127b0be6ebe020e),
    ("checkpoints/ckpt_000000008.h5", 0x42895eac6073b21b),
    ("checkpoints/ckpt_000000008.h5.crc32", 0xe3874945bf56aa59),
    ("checkpoints/ckpt_000000014.h5", 0xe06fe6d5a1d58fda),
    ("checkpoints/ckpt_000000014.h5.crc32", 0x487e1e1f719b1555),
    ("config.toml", 0xd783a7dbd4f40036),
    ("snapshots/snap_000000.h5", 0x9016fa14d5cc472e),
    ("snapshots/snap_000001.h5", 0x55a9c4d61ddad531),
    ("snapshots/snap_000002.h5", 0x385cf1232eb37875),
    ("timeseries.csv", 0x59dd35dea4559cf9),
];

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/golden")
}

fn fnv(bytes: &[u8]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

fn files(dir: &Path, base: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            files(&p, base, out);
        } else if p.file_name().unwrap() != "run.log" {
            out.push(p.strip_prefix(base).unwrap().to_path_buf());
        }
    }
}

/// Hash of every file under `dir` but run.log; in timeseries.csv the wall-clock column
/// (steps_per_second) is blanked.
fn digest(dir: &Path) -> Vec<(String, u64)> {
    let mut list = Vec::new();
    files(dir, dir, &mut list);
    list.sort();
    list.iter()
        .map(|rel| {
            let bytes = std::fs::read(dir.join(rel)).unwrap();
            let bytes = if rel == Path::new("timeseries.csv") {
                let text = String::from_utf8(bytes).unwrap();
                let mut lines = text.lines();
                let header = lines.next().unwrap();
                let clock = header
                    .split(',')
                    .position(|c| c.starts_with("steps_per_second"));
                let mut kept = vec![header.to_string()];
                for line in lines {
                    let mut cells: Vec<&str> = line.split(',').collect();
                    if let Some(k) = clock {
                        cells[k] = "";
                    }
                    kept.push(cells.join(","));
                }
                kept.join("\n").into_bytes()
            } else {
                bytes
            };
            (rel.display().to_string(), fnv(&bytes))
        })
        .collect()
}

fn same_cpu_as_recorded() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return true;
        }
    }
    eprintln!(
        "golden_runs: skipped: the hashes were recorded on x86_64 with AVX2 and FMA, this CPU differs (other FFT kernels, other bits)"
    );
    false
}

fn check(name: &str, got: &[(String, u64)], want: &[(&str, u64)]) {
    // MOTILE_PRINT_GOLDEN=1 prints the hashes (to record new ones after a deliberate change);
    // the comparison below runs either way.
    if std::env::var("MOTILE_PRINT_GOLDEN").as_deref() == Ok("1") {
        for (f, h) in got {
            println!("    (\"{f}\", 0x{h:016x}),");
        }
    }
    let want: Vec<(String, u64)> = want.iter().map(|(f, h)| (f.to_string(), *h)).collect();
    assert_eq!(
        got, want,
        "{name}: the run's files differ from the golden run's (left: now, right: recorded)"
    );
}

#[test]
fn particle_run_writes_the_golden_files_fresh_and_resumed_from_an_old_checkpoint() {
    if !same_cpu_as_recorded() {
        return;
    }
    let cfg_path = data().join("particle.toml");
    let cfg = p_config(&std::fs::read_to_string(&cfg_path).unwrap(), &cfg_path).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let fresh = tmp.path().join("fresh");
    run_particle(&cfg, &fresh, false).unwrap();
    check("particle, fresh", &digest(&fresh), &PARTICLE);
    let resumed = tmp.path().join("resumed");
    copy_dir(&data().join("particle"), &resumed);
    let s = resume_particle(&resumed, false).unwrap();
    assert_eq!(s.steps, 5, "resumed from step 5 of 10");
    // The fixture's own checkpoints and snapshots (written before format versions) are left
    // as they were; the resumed run's new ones are the fresh run's.
    let old = PARTICLE.map(|(f, h)| {
        let fixture = data().join("particle").join(f);
        let kept = (f.ends_with(".h5") || f.ends_with(".crc32")) && fixture.exists();
        let h = if f == "config.toml" {
            PARTICLE_CONFIG_BEFORE_DIAMETER
        } else if kept {
            fnv(&std::fs::read(&fixture).unwrap())
        } else {
            h
        };
        (f, h)
    });
    check("particle, resumed", &digest(&resumed), &old);
}

/// Largest difference between two runs' time series, per column relative to the column's
/// largest value, over the rows both have (every column but the wall clock and the solver
/// residuals).
fn series_difference(a: &Path, b: &Path) -> (f64, String) {
    let read = |p: &Path| {
        let text = std::fs::read_to_string(p.join("timeseries.csv")).unwrap();
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let rows: Vec<Vec<f64>> = lines
            .map(|l| {
                l.split(',')
                    .map(|c| c.parse().unwrap_or(f64::NAN))
                    .collect()
            })
            .collect();
        (header, rows)
    };
    let ((ha, ra), (hb, rb)) = (read(a), read(b));
    assert_eq!(ha, hb, "columns");
    assert_eq!(ra.len(), rb.len(), "rows");
    let mut worst = (0.0f64, String::new());
    for (c, name) in ha.iter().enumerate() {
        // The wall clock, and the residuals, which are round-off and fixed-point tolerance
        // themselves (their digits are not the run's); the fixed point's iteration counts,
        // which the old checkpoint's rows recorded from the old warm start (one iteration
        // more per step, to the same tolerance).
        if name.starts_with("steps_per_second")
            || name.contains("residual")
            || name.starts_with("fixed_point_iterations")
        {
            continue;
        }
        let scale = ra.iter().map(|r| r[c].abs()).fold(1e-300, f64::max);
        for (x, y) in ra.iter().zip(&rb) {
            let d = (x[c] - y[c]).abs() / scale;
            if d > worst.0 {
                worst = (d, name.clone());
            }
        }
    }
    worst
}

/// The mean-field run's files are pinned fresh. Resumed from the mid-run checkpoint in
/// tests/data/golden/meanfield (written with another round-off: before the closed-form
/// eigen-decomposition and the fixed point's warm start), the run reads it and ends where the
/// fresh run ends: its time series agrees with the fresh one to 1e-10 of each column's scale,
/// the last snapshot's Q to 1e-12 (measured 9.5e-13 and 3.3e-15; the iteration counts of the
/// checkpoint's rows are not compared).
#[test]
fn meanfield_run_writes_the_golden_files_fresh_and_resumed_from_an_old_checkpoint() {
    if !same_cpu_as_recorded() {
        return;
    }
    let cfg_path = data().join("meanfield.toml");
    let cfg = mf_config(&std::fs::read_to_string(&cfg_path).unwrap(), &cfg_path).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let fresh = tmp.path().join("fresh");
    run_meanfield(&cfg, &fresh, false).unwrap();
    check("mean-field, fresh", &digest(&fresh), &MEANFIELD);
    let resumed = tmp.path().join("resumed");
    copy_dir(&data().join("meanfield"), &resumed);
    let s = resume_meanfield(&resumed, false).unwrap();
    assert_eq!(s.steps, 6, "resumed from step 8 of 14");
    let (worst, column) = series_difference(&fresh, &resumed);
    eprintln!(
        "mean-field resumed from the old checkpoint: time series within {worst:.2e} ({column})"
    );
    assert!(
        worst <= 1e-10,
        "resumed from the old checkpoint, the time series differs from the fresh run's by {worst:.2e} of its scale in {column}"
    );
    let q = |dir: &Path| match read_snapshot(&dir.join("snapshots/snap_000002.h5")).unwrap() {
        Snapshot::Field(f) => f.q,
        _ => panic!("a mean-field snapshot"),
    };
    let (qa, qb) = (q(&fresh), q(&resumed));
    let dq = (0..6)
        .flat_map(|c| qa[c].iter().zip(&qb[c]).map(|(a, b)| (a - b).abs()))
        .fold(0.0, f64::max);
    eprintln!("last snapshot's Q within {dq:.2e}");
    assert!(dq <= 1e-12, "last snapshot's Q differs by {dq:.2e}");
}
