//! Format versions (docs/faults.md, "Versioned formats"): run directories of format version 1
//! committed under tests/data/formats/v1 (a 16-rod `sbt` particle run and an 8^3 mean-field
//! run, each stopped at a mid-run checkpoint) resume to their end and open for comparison; the
//! same files stamped with a newer version are refused by name, with the version. Files written
//! before versions existed (tests/data/golden) are read as version 1 by the golden-run tests.

use motile_experiments::campaign::mutation::mutate::Content;
use motile_experiments::io::checkpoint::write_verified;
use motile_experiments::io::format::FORMAT_VERSION;
use motile_experiments::io::snapshot::read_snapshot;
use motile_experiments::report::opened_run::OpenedRun;
use motile_experiments::run::meanfield::resume_meanfield;
use motile_experiments::run::particle::resume_particle;
use motile_tests::copy_dir;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/formats/v1")
        .join(name)
}

fn only_checkpoint(run: &Path) -> PathBuf {
    let dir = run.join("checkpoints");
    let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "h5"))
        .collect();
    assert_eq!(found.len(), 1, "{}: {found:?}", dir.display());
    found.pop().unwrap()
}

#[test]
fn version_1_run_directories_resume_and_open() {
    assert_eq!(
        FORMAT_VERSION, 1,
        "a new format version needs its fixture here"
    );
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("particle");
    copy_dir(&fixture("particle"), &p);
    let s = resume_particle(&p, false).unwrap();
    assert_eq!((s.steps, s.final_step), (3, 5), "resumed from step 2 of 5");
    let m = tmp.path().join("meanfield");
    copy_dir(&fixture("meanfield"), &m);
    let s = resume_meanfield(&m, false).unwrap();
    let t_last = s.timeseries.rows.last().unwrap()[0];
    assert!(
        (t_last - 0.4).abs() < 1e-12,
        "mean-field resumed to t = {t_last}"
    );
    for run in [&p, &m] {
        let opened = OpenedRun::open(run).unwrap();
        assert_eq!(opened.snapshots().unwrap().len(), 3, "{}", run.display());
    }
}

/// `path`'s HDF5 file with its `format_version` set to `v`.
fn restamp(path: &Path, v: u64) -> Vec<u8> {
    let mut c = Content::read(&std::fs::read(path).unwrap()).unwrap();
    c.set_attr("format_version", hdf5_pure::AttrValue::U64(v));
    c.build().unwrap()
}

#[test]
fn newer_versions_are_refused_with_the_version_and_the_file() {
    let newer = FORMAT_VERSION + 1;
    let phrase = format!("format version {newer}");
    let tmp = tempfile::tempdir().unwrap();
    let check = |what: &str, e: String, file: &str| {
        assert!(
            e.contains(&phrase) && e.contains(file) && e.contains("reads format versions 1 to"),
            "{what}: {e}"
        );
    };
    // The run directory's config.toml.
    let run = tmp.path().join("config");
    copy_dir(&fixture("particle"), &run);
    let cfg = run.join("config.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    let stamped = text.replace("format_version = 1", &format!("format_version = {newer}"));
    assert_ne!(
        text, stamped,
        "the fixture's config.toml names its format version"
    );
    std::fs::write(&cfg, stamped).unwrap();
    check(
        "config.toml, resume",
        format!("{:#}", resume_particle(&run, false).unwrap_err()),
        "config.toml",
    );
    check(
        "config.toml, compare",
        format!("{:#}", OpenedRun::open(&run).unwrap_err()),
        "config.toml",
    );
    // A checkpoint (checksummed: written so, not damaged).
    for model in ["particle", "meanfield"] {
        let run = tmp.path().join(format!("ckpt-{model}"));
        copy_dir(&fixture(model), &run);
        let ckpt = only_checkpoint(&run);
        write_verified(&ckpt, &restamp(&ckpt, newer)).unwrap();
        let e = match model {
            "particle" => resume_particle(&run, false).map(|_| ()),
            _ => resume_meanfield(&run, false).map(|_| ()),
        };
        let name = ckpt.file_name().unwrap().to_string_lossy().into_owned();
        check(
            &format!("{model} checkpoint"),
            format!("{:#}", e.unwrap_err()),
            &name,
        );
    }
    // A snapshot of each model.
    for model in ["particle", "meanfield"] {
        let snap = fixture(model).join("snapshots/snap_000001.h5");
        let path = tmp.path().join(format!("{model}.h5"));
        std::fs::write(&path, restamp(&snap, newer)).unwrap();
        check(
            &format!("{model} snapshot"),
            format!("{:#}", read_snapshot(&path).unwrap_err()),
            &format!("{model}.h5"),
        );
    }
}
