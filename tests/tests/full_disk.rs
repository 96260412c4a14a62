//! A disk that fills during a run or a comparison (docs/faults.md, "A full disk"): every write
//! goes through `write_atomic`, which is made to fail as a full disk would after a chosen
//! number of bytes (part of the file written, then `StorageFull`). At cut points spread over
//! a whole run of each model, and over a comparison's products: the run stops with a message
//! naming the disk and where it resumes, no partial file stands under a final name, every
//! checkpoint left verifies and every snapshot reads, and `motile resume` from what is left
//! ends bit for bit where the uninterrupted run ends.
//!
//! The limit is process-wide, so this file holds one test.

use motile_experiments::io::checkpoint::{newest_first, verify};
use motile_experiments::io::fail_writes_after;
use motile_experiments::io::snapshot::read_snapshot;
use motile_experiments::report::compare::compare;
use motile_experiments::run::meanfield::{self, resume_meanfield, run_meanfield};
use motile_experiments::run::particle::{self, resume_particle, run_particle};
use std::path::{Path, PathBuf};

const PARTICLE: &str = "box_length = 3.0\nrods = 16\ndt = 0.02\nt_end = 0.2\nseed = 3\nhydrodynamics = \"sbt\"\ndiagnostic_interval = 0.02\nsnapshot_interval = 0.04\ncheckpoint_interval = 0.04\n[hydro]\nsum_tolerance = 1e-2\nquadrature_points = 4\n";
const MEANFIELD: &str = "grid = 8\nt_end = 0.6\ndt_max = 0.05\ndiagnostic_interval = 0.1\nsnapshot_interval = 0.2\ncheckpoint_interval = 0.2\n";

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(files(&p));
        } else {
            out.push(p);
        }
    }
    out
}

fn bytes_in(dir: &Path) -> u64 {
    files(dir)
        .iter()
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum()
}

/// No temporary left, every checkpoint verified, every snapshot readable.
fn whole(dir: &Path, cut: u64) {
    for p in files(dir) {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            !name.ends_with(".tmp"),
            "cut {cut}: temporary left: {}",
            p.display()
        );
        if name.starts_with("ckpt_") && name.ends_with(".h5") {
            verify(&p).unwrap_or_else(|e| panic!("cut {cut}: {e}"));
        }
        if name.starts_with("snap_") {
            read_snapshot(&p).unwrap_or_else(|e| panic!("cut {cut}: {e}"));
        }
    }
}

/// Cut a run at `cuts` points: each stops cleanly, and resumes to `reference` where a
/// checkpoint was left. Returns how many cuts stopped the run.
fn cut_runs<T: PartialEq + std::fmt::Debug>(
    model: &str,
    root: &Path,
    total: u64,
    run: impl Fn(&Path) -> anyhow::Result<T>,
    resume: impl Fn(&Path) -> anyhow::Result<T>,
    reference: &T,
) -> usize {
    let mut stopped = 0;
    for k in 0..24 {
        let cut = total * k / 16;
        let dir = root.join(format!("{model}-{k}"));
        fail_writes_after(Some(cut));
        let r = run(&dir);
        fail_writes_after(None);
        let Err(e) = r else { continue };
        stopped += 1;
        let msg = format!("{e:#}");
        assert!(
            msg.contains("No space left on device"),
            "{model}, cut {cut}: {msg}"
        );
        whole(&dir, cut);
        let resumable = newest_first(&dir.join("checkpoints"))
            .into_iter()
            .next()
            .is_some();
        if resumable {
            assert!(
                msg.contains("newest intact checkpoint") && msg.contains("motile resume"),
                "{model}, cut {cut}: {msg}"
            );
            let end = resume(&dir).unwrap_or_else(|e| panic!("{model}, cut {cut}: resume: {e:#}"));
            assert_eq!(
                &end, reference,
                "{model}, cut {cut}: resumed run ends elsewhere"
            );
        }
    }
    stopped
}

#[test]
fn a_full_disk_stops_runs_and_comparisons_cleanly_and_resumable() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let p = particle::parse_config(PARTICLE, Path::new("p.toml")).unwrap();
    let m = meanfield::parse_config(MEANFIELD, Path::new("m.toml")).unwrap();
    // Particle runs end at the same rods (positions and quaternions bit for bit).
    let rods = |s: particle::RunSummary| (s.final_step, s.rods.x, s.rods.q);
    let p_ref = rods(run_particle(&p, &root.join("p-ref"), false).unwrap());
    let p_total = bytes_in(&root.join("p-ref"));
    let stopped = cut_runs(
        "particle",
        root,
        p_total,
        |d| run_particle(&p, d, false).map(rods),
        |d| resume_particle(d, false).map(rods),
        &p_ref,
    );
    assert!(
        stopped >= 12,
        "particle: {stopped} of the cuts stopped the run"
    );
    // Mean-field runs end with the same time series and Q.
    let fields = |s: meanfield::MeanFieldSummary| {
        let rows: Vec<Vec<u64>> = s
            .timeseries
            .rows
            .iter()
            .map(|r| r.iter().map(|v| v.to_bits()).collect())
            .collect();
        (rows, format!("{:?}", s.q_hat))
    };
    let m_ref = fields(run_meanfield(&m, &root.join("m-ref"), false).unwrap());
    let m_total = bytes_in(&root.join("m-ref"));
    let stopped = cut_runs(
        "meanfield",
        root,
        m_total,
        |d| run_meanfield(&m, d, false).map(fields),
        |d| resume_meanfield(d, false).map(fields),
        &m_ref,
    );
    assert!(
        stopped >= 12,
        "meanfield: {stopped} of the cuts stopped the run"
    );
    // A comparison's products: stopped with the disk named, none partial, and whole when run
    // again with room.
    let runs = [root.join("p-ref"), root.join("m-ref")];
    let out = root.join("compare");
    compare(&runs, &root.join("compare-ref")).unwrap();
    let total = bytes_in(&root.join("compare-ref"));
    for k in 1..8 {
        let cut = total * k / 8;
        fail_writes_after(Some(cut));
        let r = compare(&runs, &out);
        fail_writes_after(None);
        let Err(e) = r else {
            panic!("compare, cut {cut}: a comparison that fills the disk stops");
        };
        let msg = format!("{e:#}");
        assert!(
            msg.contains("No space left on device"),
            "compare, cut {cut}: {msg}"
        );
        whole(&out, cut);
    }
    compare(&runs, &out).unwrap();
    let names = |d: &Path| {
        let mut v: Vec<String> = files(d)
            .iter()
            .map(|p| p.strip_prefix(d).unwrap().display().to_string())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names(&out), names(&root.join("compare-ref")));
}
