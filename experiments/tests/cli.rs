//! The `motile` binary: its help lists the commands, and bad input fails with a message that
//! names the file or the field and the allowed range.

#[test]
fn cli_help_and_errors_name_what_is_wrong() {
    let bin = env!("CARGO_BIN_EXE_motile");
    let out = std::process::Command::new(bin)
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && help.contains("analyze") && help.contains("demo"),
        "{help}"
    );
    let out = std::process::Command::new(bin)
        .args(["analyze", "/nonexistent/run"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "analyze of a missing directory must fail"
    );
    assert!(
        err.contains("/nonexistent/run") && err.contains("no config.toml"),
        "{err}"
    );
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(bin)
        .args(["analyze", dir.path().to_str().unwrap(), "--tolerance", "5"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("tolerance = 5e0 is outside the allowed range [1e-12, 1e-1]"),
        "{err}"
    );
}

/// `--dry-run` needs no `--out`, and a relative file name in a config (`initial` of a particle
/// run, `snapshot` of a mean-field run) is read from the config file's folder, not from the
/// working directory: the resolved config names the absolute path.
#[test]
fn dry_run_needs_no_out_and_relative_initial_paths_follow_the_config_file() {
    let bin = env!("CARGO_BIN_EXE_motile");
    let dir = tempfile::tempdir().unwrap();
    let cfgs = dir.path().join("configs");
    std::fs::create_dir(&cfgs).unwrap();
    std::fs::write(cfgs.join("rods.txt"), "1 1 1 1 0 0\n4 4 4 0 1 0\n").unwrap();
    std::fs::write(
        cfgs.join("run.toml"),
        "initial = \"rods.txt\"\nbox_length = 8\nt_end = 0.02\ndt = 0.01\nvtk = false\n",
    )
    .unwrap();
    // Run from another folder.
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let out = std::process::Command::new(bin)
        .args(["particle", "run", "../configs/run.toml", "--dry-run"])
        .current_dir(&elsewhere)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let expected = std::path::absolute(elsewhere.join("../configs/rods.txt")).unwrap();
    assert!(
        out.status.success() && text.contains(&format!("initial = \"{}\"", expected.display())),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = std::process::Command::new(bin)
        .args(["particle", "run", "../configs/run.toml", "--out", "run"])
        .current_dir(&elsewhere)
        .output()
        .unwrap();
    assert!(
        out.status.success() && elsewhere.join("run/snapshots").exists(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = std::process::Command::new(bin)
        .args(["meanfield", "run", "--dry-run"])
        .output()
        .unwrap();
    assert!(
        out.status.success() && String::from_utf8_lossy(&out.stdout).contains("grid = 32"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = std::process::Command::new(bin)
        .args(["particle", "run"])
        .output()
        .unwrap();
    assert!(
        !out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--out"),
        "a run without --out must say it needs one"
    );
}

/// The help texts name what the code has: every hydrodynamic level (from the enum), the GPU
/// running the whole step; `motile scenes` puts each scene on one line and indents the rest.
#[test]
fn help_names_the_levels_and_the_scenes_listing_is_tidy() {
    let bin = env!("CARGO_BIN_EXE_motile");
    let text = |args: &[&str]| {
        let out = std::process::Command::new(bin).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let help = text(&["particle", "run", "--help"]);
    for name in motile_particle::model::level::Hydrodynamics::names() {
        assert!(help.contains(&format!("\"{name}\"")), "{name}: {help}");
    }
    assert!(
        help.contains("the whole step on one NVIDIA GPU") && !help.contains("Fourier part"),
        "{help}"
    );
    let help = text(&["compare", "--help"]);
    assert!(
        help.contains("nine figures") && help.contains("\"sbt-explicit\""),
        "{help}"
    );
    let scenes = text(&["scenes"]);
    let builtin = motile_experiments::campaign::scene::BUILTIN;
    let heads: Vec<&str> = scenes
        .lines()
        .filter(|l| !l.is_empty() && !l.starts_with(' '))
        .collect();
    assert_eq!(heads.len(), builtin.len(), "{scenes}");
    for ((name, _), head) in builtin.iter().zip(&heads) {
        assert!(head.starts_with(&format!("{name} (version ")), "{head}");
    }
    // The cost paragraphs are reflowed: every indented line (runs, costs) fits in 96 characters.
    assert!(
        scenes
            .lines()
            .filter(|l| l.starts_with(' '))
            .all(|l| l.chars().count() <= 96),
        "{scenes}"
    );
}
