//! Every row of the bad-input table in `docs/bad_inputs.md` is run here: the input is given to
//! the `motile` binary (in a directory of fixture files) and its error output must contain the
//! message the table shows, with a non-zero exit status. The table is the single source: a row
//! added there is tested, a message changed in the code fails here until the table follows.

use std::path::Path;
use std::process::Command;

/// Files the table's rows refer to.
fn write_fixtures(dir: &Path) {
    let w = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    w("orient.txt", "1 1 1 1 0 0\n4 4 4 0 0.5 0\n");
    w("overlap.txt", "1 1 1 1 0 0\n1.2 1 1 0 1 0\n");
    w("nan.txt", "1 1 1 1 0 0\n4 nan 4 0 0 1\n");
    w("short.txt", "1 1 1 1 0 0\n4 4 4 0 1\n");
    w("outside.txt", "1 1 1 1 0 0\n4 4 40 0 0 1\n");
    w("garbage.h5", "this is not an HDF5 file\n");
    // A particle snapshot cut to half its length.
    let snap = motile_experiments::io::snapshot::ParticleSnapshot {
        time: 0.0,
        step: 0,
        box_length: 10.0,
        positions: vec![[1.0, 1.0, 1.0], [4.0, 4.0, 4.0]],
        orientations: vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        image_counts: vec![[0; 3]; 2],
        forces: None,
        kinematics: None,
    };
    snap.write(&dir.join("box10.h5")).unwrap();
    let path = dir.join("truncated.h5");
    snap.write(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
}

/// Rows of the table: (number, kind, input, expected message).
fn rows(doc: &str) -> Vec<(String, String, String, String)> {
    // A cell is plain text, a code span `x`, or a double-backtick span `` x `` (for text that
    // contains backticks itself).
    let cell = |c: &str| {
        let c = c.trim();
        if let Some(inner) = c.strip_prefix("``").and_then(|c| c.strip_suffix("``")) {
            return inner.trim().to_string();
        }
        c.strip_prefix('`')
            .and_then(|c| c.strip_suffix('`'))
            .unwrap_or(c)
            .to_string()
    };
    doc.lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| #"))
        .map(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split(" | ").collect();
            assert_eq!(cells.len(), 4, "malformed row: {l}");
            (
                cell(cells[0]),
                cell(cells[1]),
                cell(cells[2]).replace("\\n", "\n"),
                cell(cells[3]),
            )
        })
        .collect()
}

#[test]
fn every_bad_input_in_the_table_gets_its_message() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../docs/bad_inputs.md"
    ))
    .expect("docs/bad_inputs.md");
    let rows = rows(&doc);
    assert!(rows.len() >= 25, "the table has only {} rows", rows.len());
    let dir = tempfile::tempdir().unwrap();
    write_fixtures(dir.path());
    let bin = env!("CARGO_BIN_EXE_motile");
    let mut failures = Vec::new();
    for (num, kind, input, expected) in &rows {
        let args: Vec<String> = match kind.as_str() {
            "particle config" | "meanfield config" => {
                let file = format!("case_{num}.toml");
                std::fs::write(dir.path().join(&file), input).unwrap();
                let model = kind.split(' ').next().unwrap();
                vec![
                    model.into(),
                    "run".into(),
                    file,
                    "--out".into(),
                    format!("out_{num}"),
                ]
            }
            "particle dry run" | "meanfield dry run" => {
                let file = format!("case_{num}.toml");
                std::fs::write(dir.path().join(&file), input).unwrap();
                let model = kind.split(' ').next().unwrap();
                vec![model.into(), "run".into(), file, "--dry-run".into()]
            }
            "command line" => input.split_whitespace().map(String::from).collect(),
            other => panic!("row {num}: unknown kind '{other}'"),
        };
        let out = Command::new(bin)
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let wrote = dir.path().join(format!("out_{num}")).exists() || dir.path().join("x").exists();
        if out.status.success() || !stderr.contains(expected.as_str()) || wrote {
            failures.push(format!(
                "row {num} ({kind}: {input:?}): exit {:?}, output directory written: {wrote}, expected `{expected}` in: {stderr}",
                out.status.code()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
