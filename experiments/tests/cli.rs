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
