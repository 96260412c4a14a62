//! The shape of the source tree (ARCHITECTURE.md): inside every crate, no two files refer to
//! each other in a circle, folders refer to each other in one direction only (each crate's
//! [`LAYERS`], bottom up), every source file is named in ARCHITECTURE.md, and no file is over
//! 800 lines.
//!
//! A file refers to another when it names a path into it: `use crate::a::b::X`, an inline
//! `crate::a::f()`, `super::X`, or `child::f()` for a module it declares. Paths resolve to the
//! file of the longest module prefix they name, so a re-export in a `mod.rs` counts as that
//! `mod.rs`: inside a crate, code names the module that defines an item, and re-exports are
//! for the crate's users. Comments are ignored; test modules inside a file count.
//!
//! The same check from the command line: `cargo test --release -p motile-tests --test
//! architecture -- --nocapture` prints every file's edges with `MOTILE_PRINT_EDGES=1`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The library and binary crates whose sources are checked.
const CRATES: [&str; 5] = ["analysis", "gpu", "particle", "meanfield", "experiments"];
const MAX_LINES: usize = 800;

/// Each crate's folders from the bottom up: a file in one of them names files of its own
/// folder, of the folders below it and at the crate's root, never of a folder above. Every
/// folder of a crate's `src` is listed (a new folder must be placed).
const LAYERS: [(&str, &[&str]); 5] = [
    ("analysis", &[]),
    ("gpu", &[]),
    ("particle", &["model", "parallel", "ewald", "hydro", "step"]),
    ("meanfield", &["solver", "gpu"]),
    ("experiments", &["io", "run", "report", "campaign", "cli"]),
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a source file (`lib.rs`/`main.rs` the root, `a/mod.rs` and `a.rs` are
/// `a`), relative to `src`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

/// The source with comments removed and the contents of string literals and brace
/// characters blanked (so that braces count only as code).
fn strip_comments(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = String::with_capacity(s.len());
    let mut i = 0;
    while i < b.len() {
        let rest = &s[i..];
        if rest.starts_with("//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if rest.starts_with("/*") {
            i = s[i + 2..].find("*/").map_or(b.len(), |e| i + 2 + e + 2);
        } else if rest.starts_with("'{'") || rest.starts_with("'}'") || rest.starts_with("'\"'") {
            out.push_str("' '");
            i += 3;
        } else if let Some(hashes) = raw_string_start(rest)
            .filter(|_| i == 0 || !is_ident(s[..i].chars().next_back().unwrap()))
        {
            let close = format!("\"{}", "#".repeat(hashes));
            let body = i + 2 + hashes;
            let end = s[body..]
                .find(&close)
                .map_or(b.len(), |e| body + e + close.len());
            out.push_str("\"\"");
            i = end;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            out.push_str("\"\"");
            i += 1;
        } else {
            let c = rest.chars().next().unwrap();
            out.push(c);
            i += c.len_utf8();
        }
    }
    out
}

/// `Some(number of #)` where `s` starts a raw string literal `r#"`.
fn raw_string_start(s: &str) -> Option<usize> {
    let t = s.strip_prefix('r')?;
    let hashes = t.len() - t.trim_start_matches('#').len();
    t[hashes..].starts_with('"').then_some(hashes)
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// Every path a `use` tree names, written out in full (`a::{b, c::d}` gives `a::b`, `a::c::d`).
fn expand_use(tree: &str, prefix: &str, out: &mut Vec<String>) {
    let tree = tree.trim();
    if let Some(open) = tree.find('{') {
        let head = tree[..open].trim().trim_end_matches("::");
        let close = tree.rfind('}').unwrap();
        let inner = &tree[open + 1..close];
        let base = join(prefix, head);
        let mut depth = 0;
        let mut start = 0;
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand_use(&inner[start..i], &base, out);
                    start = i + 1;
                }
                _ => {}
            }
        }
        expand_use(&inner[start..], &base, out);
    } else if !tree.is_empty() {
        let path = tree.split(" as ").next().unwrap().trim();
        out.push(join(prefix, path));
    }
}

fn join(a: &str, b: &str) -> String {
    match (a.is_empty(), b.is_empty()) {
        (true, _) => b.to_string(),
        (_, true) => a.to_string(),
        _ => format!("{a}::{b}"),
    }
}

/// For every byte of `code`, how many inline modules (`mod name { .. }`) enclose it.
fn inline_depths(code: &str) -> Vec<usize> {
    let mut depths = Vec::with_capacity(code.len());
    let mut braces = 0usize;
    let mut opened: Vec<usize> = Vec::new();
    for (i, c) in code.char_indices() {
        match c {
            '{' => {
                braces += 1;
                let head = code[..i].trim_end();
                let name_start = head
                    .char_indices()
                    .rev()
                    .find(|&(_, c)| !is_ident(c))
                    .map_or(0, |(k, c)| k + c.len_utf8());
                if head[..name_start].trim_end().ends_with("mod") {
                    opened.push(braces);
                }
            }
            '}' => {
                if opened.last() == Some(&braces) {
                    opened.pop();
                }
                braces = braces.saturating_sub(1);
            }
            _ => {}
        }
        depths.extend(std::iter::repeat_n(opened.len(), c.len_utf8()));
    }
    depths
}

/// The paths a file names, each with the number of inline modules around it: its `use` trees
/// in full, and every other `crate::`/`super::` path and `child::` path of a declared child
/// module.
fn paths_named(code: &str) -> (Vec<(String, usize)>, Vec<String>) {
    let depth = inline_depths(code);
    let mut paths = Vec::new();
    let mut children = Vec::new();
    // Names a `use` brought in (a module among them: `use crate::a::b;` then `b::f()`).
    // Keyed by the inline-module depth of the `use` (an inline module sees only its own).
    let mut imported: BTreeMap<(String, usize), String> = BTreeMap::new();
    let mut rest = String::with_capacity(code.len());
    let mut rest_depth = Vec::with_capacity(code.len());
    // `use` statements, whole.
    let mut i = 0;
    while i < code.len() {
        let at_word = i == 0 || !is_ident(code[..i].chars().next_back().unwrap());
        if at_word && code[i..].starts_with("use ") {
            let end = code[i..].find(';').map_or(code.len(), |e| i + e);
            let mut tree = Vec::new();
            expand_use(&code[i + 4..end], "", &mut tree);
            for p in &tree {
                let name = p.rsplit("::").next().unwrap_or(p);
                if name != "*" && name != "self" {
                    imported.insert((name.to_string(), depth[i]), p.clone());
                }
            }
            paths.extend(tree.into_iter().map(|p| (p, depth[i])));
            i = end + 1;
            continue;
        }
        let c = code[i..].chars().next().unwrap();
        rest.push(c);
        rest_depth.push(depth[i]);
        i += c.len_utf8();
    }
    // `mod name;` declarations (children in their own files).
    for line in rest.lines() {
        let t = line.trim();
        let t = t.strip_prefix("pub(crate) ").unwrap_or(t);
        let t = t.strip_prefix("pub(super) ").unwrap_or(t);
        let t = t.strip_prefix("pub ").unwrap_or(t);
        if let Some(name) = t.strip_prefix("mod ").and_then(|n| n.strip_suffix(';')) {
            children.push(name.trim().to_string());
        }
    }
    // Inline paths.
    let chars: Vec<char> = rest.chars().collect();
    let mut k = 0;
    while k < chars.len() {
        // `$crate::` in a macro is the crate's root as its users see it: not a file's reference.
        if is_ident(chars[k])
            && (k == 0 || (!is_ident(chars[k - 1]) && chars[k - 1] != ':' && chars[k - 1] != '$'))
        {
            let mut e = k;
            let mut path = String::new();
            loop {
                let s = e;
                while e < chars.len() && is_ident(chars[e]) {
                    e += 1;
                }
                path.extend(&chars[s..e]);
                if e + 2 < chars.len()
                    && chars[e] == ':'
                    && chars[e + 1] == ':'
                    && is_ident(chars[e + 2])
                {
                    path.push_str("::");
                    e += 2;
                } else {
                    break;
                }
            }
            let first = path.split("::").next().unwrap();
            if path.contains("::")
                && (first == "crate" || first == "super" || children.iter().any(|c| c == first))
            {
                paths.push((path, rest_depth[k]));
            } else if path.contains("::")
                && let Some(full) = imported.get(&(first.to_string(), rest_depth[k]))
                && (full.starts_with("crate::") || full.starts_with("super::"))
            {
                // Through an imported name: its full path, then the rest.
                paths.push((format!("{full}{}", &path[first.len()..]), rest_depth[k]));
            }
            k = e.max(k + 1);
        } else {
            k += 1;
        }
    }
    (paths, children)
}

/// The absolute module path of `path` named in module `here` (`None` for other crates).
/// `inline` is the number of inline modules around the path: its first `super`s stay in the
/// file.
fn absolute(
    here: &[String],
    (path, inline): (&str, usize),
    children: &[String],
) -> Option<Vec<String>> {
    let segs: Vec<&str> = path.split("::").collect();
    let mut base: Vec<String>;
    let mut rest = &segs[..];
    match segs[0] {
        "crate" => {
            base = Vec::new();
            rest = &segs[1..];
        }
        "super" | "self" => {
            base = here.to_vec();
            let mut inline = inline;
            while let Some(s) = rest.first() {
                match *s {
                    "super" if inline > 0 => inline -= 1,
                    "super" => {
                        base.pop();
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        s if inline == 0 && children.iter().any(|c| c == s) => base = here.to_vec(),
        _ => return None,
    }
    base.extend(rest.iter().map(|s| s.to_string()));
    Some(base)
}

struct CrateGraph {
    files: BTreeMap<Vec<String>, PathBuf>,
    edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
}

fn graph(krate: &str) -> CrateGraph {
    let src = root().join(krate).join("src");
    let mut list = Vec::new();
    rust_files(&src, &mut list);
    // A binary's main.rs is a root of its own: skip it as a module of the library.
    let files: BTreeMap<Vec<String>, PathBuf> = list
        .iter()
        .filter(|p| p.file_name().unwrap() != "main.rs")
        .map(|p| (module_of(&src, p), p.clone()))
        .collect();
    let mut edges = BTreeMap::new();
    for (module, file) in &files {
        let code = strip_comments(&std::fs::read_to_string(file).unwrap());
        let (paths, children) = paths_named(&code);
        if std::env::var_os("MOTILE_PRINT_PATHS").is_some_and(|f| file.ends_with(f)) {
            println!("{}: {paths:?}", file.display());
        }
        let mut to = BTreeSet::new();
        for (p, inline) in paths {
            let Some(abs) = absolute(module, (&p, inline), &children) else {
                continue;
            };
            // The file of the longest module prefix.
            let target = (0..=abs.len())
                .rev()
                .map(|n| abs[..n].to_vec())
                .find(|m| files.contains_key(m))
                .unwrap();
            if &target != module {
                to.insert(target);
            }
        }
        edges.insert(module.clone(), to);
    }
    CrateGraph { files, edges }
}

/// Strongly connected components with more than one file (Tarjan).
fn cycles(g: &CrateGraph) -> Vec<Vec<Vec<String>>> {
    struct T<'a> {
        g: &'a CrateGraph,
        index: BTreeMap<Vec<String>, usize>,
        low: BTreeMap<Vec<String>, usize>,
        stack: Vec<Vec<String>>,
        on: BTreeSet<Vec<String>>,
        next: usize,
        out: Vec<Vec<Vec<String>>>,
    }
    fn visit(t: &mut T, v: &Vec<String>) {
        t.index.insert(v.clone(), t.next);
        t.low.insert(v.clone(), t.next);
        t.next += 1;
        t.stack.push(v.clone());
        t.on.insert(v.clone());
        for w in t.g.edges[v].clone() {
            if !t.index.contains_key(&w) {
                visit(t, &w);
                let l = t.low[&w].min(t.low[v]);
                t.low.insert(v.clone(), l);
            } else if t.on.contains(&w) {
                let l = t.index[&w].min(t.low[v]);
                t.low.insert(v.clone(), l);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = t.stack.pop().unwrap();
                t.on.remove(&w);
                let done = &w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in g.files.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

fn name(m: &[String]) -> String {
    if m.is_empty() {
        "crate".into()
    } else {
        m.join("::")
    }
}

#[test]
fn no_two_files_of_a_crate_refer_to_each_other_in_a_circle() {
    let mut found = Vec::new();
    for krate in CRATES {
        let g = graph(krate);
        if std::env::var_os("MOTILE_PRINT_EDGES").is_some() {
            for (m, to) in &g.edges {
                let to: Vec<String> = to.iter().map(|t| name(t)).collect();
                println!("{krate}: {} -> {}", name(m), to.join(", "));
            }
        }
        for comp in cycles(&g) {
            let names: Vec<String> = comp.iter().map(|m| name(m)).collect();
            found.push(format!("{krate}: {}", names.join(" <-> ")));
        }
    }
    assert!(
        found.is_empty(),
        "files that refer to each other in a circle:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_checker_finds_a_circle_and_follows_use_trees() {
    let mut paths = Vec::new();
    expand_use("crate::{a::{B, c::D}, e as f}", "", &mut paths);
    assert_eq!(paths, ["crate::a::B", "crate::a::c::D", "crate::e"]);
    let code =
        "mod child;\nfn f() { crate::x::y(); child::g(); super::Z; }\n// crate::comment::gone\n";
    let (paths, children) = paths_named(&strip_comments(code));
    assert_eq!(children, ["child"]);
    let names: Vec<&str> = paths.iter().map(|(p, _)| p.as_str()).collect();
    assert_eq!(names, ["crate::x::y", "child::g", "super::Z"]);
    // `super` inside an inline module stays in the file.
    let code = "mod tests {\n use super::*;\n fn f() { let s = \"{\"; super::super::X; }\n}\n";
    let (paths, _) = paths_named(&strip_comments(code));
    let here = vec!["a".to_string(), "b".to_string()];
    let resolved: Vec<_> = paths
        .iter()
        .map(|(p, d)| absolute(&here, (p, *d), &[]).unwrap())
        .collect();
    assert_eq!(resolved, [vec!["a", "b", "*"], vec!["a", "X"]]);
    // A two-file circle is found.
    let m = |s: &str| vec![s.to_string()];
    let files = [m("a"), m("b"), m("c")]
        .into_iter()
        .map(|k| (k, PathBuf::new()))
        .collect();
    let edges = [
        (m("a"), BTreeSet::from([m("b")])),
        (m("b"), BTreeSet::from([m("a")])),
        (m("c"), BTreeSet::from([m("a")])),
    ]
    .into_iter()
    .collect();
    let found = cycles(&CrateGraph { files, edges });
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].len(), 2);
}

#[test]
fn no_source_file_is_over_800_lines() {
    let mut long = Vec::new();
    for krate in CRATES.iter().chain(&["tests"]) {
        let mut list = Vec::new();
        rust_files(&root().join(krate), &mut list);
        for f in list {
            let n = std::fs::read_to_string(&f).unwrap().lines().count();
            if n > MAX_LINES {
                long.push(format!("{} ({n} lines)", f.display()));
            }
        }
    }
    assert!(
        long.is_empty(),
        "files over {MAX_LINES} lines:\n{}",
        long.join("\n")
    );
}

/// The references from a folder to a folder above it in `layers` (bottom up), as
/// `"from -> to"`; a file's folder is the first part of its module path (files at the root
/// have none).
fn upward_references(g: &CrateGraph, layers: &[&str]) -> Vec<String> {
    let rank = |m: &[String]| -> Option<usize> {
        (m.len() > 1).then(|| {
            layers
                .iter()
                .position(|l| *l == m[0])
                .unwrap_or_else(|| panic!("folder {} is not in LAYERS", m[0]))
        })
    };
    let mut found = Vec::new();
    for (from, to) in &g.edges {
        let Some(a) = rank(from) else { continue };
        for t in to {
            if rank(t).is_some_and(|b| b > a) {
                found.push(format!("{} -> {}", name(from), name(t)));
            }
        }
    }
    found
}

#[test]
fn folders_refer_to_each_other_in_one_direction() {
    let mut found = Vec::new();
    for (krate, layers) in LAYERS {
        let g = graph(krate);
        let folders: BTreeSet<&str> = g
            .files
            .keys()
            .filter(|m| m.len() > 1)
            .map(|m| m[0].as_str())
            .collect();
        let listed: BTreeSet<&str> = layers.iter().copied().collect();
        assert_eq!(
            folders, listed,
            "{krate}: the folders of src against LAYERS"
        );
        found.extend(
            upward_references(&g, layers)
                .into_iter()
                .map(|e| format!("{krate}: {e}")),
        );
    }
    assert!(
        found.is_empty(),
        "folders that refer to a folder above them (ARCHITECTURE.md's layers):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_layering_check_finds_an_upward_reference() {
    let m = |s: &[&str]| s.iter().map(|p| p.to_string()).collect::<Vec<_>>();
    let files = [m(&["low", "a"]), m(&["high", "b"]), m(&["c"])]
        .into_iter()
        .map(|k| (k, PathBuf::new()))
        .collect();
    let edges = [
        (
            m(&["low", "a"]),
            BTreeSet::from([m(&["high", "b"]), m(&["c"])]),
        ),
        (m(&["high", "b"]), BTreeSet::from([m(&["low", "a"])])),
        (m(&["c"]), BTreeSet::from([m(&["high", "b"])])),
    ]
    .into_iter()
    .collect();
    let found = upward_references(&CrateGraph { files, edges }, &["low", "high"]);
    assert_eq!(found, ["low::a -> high::b"]);
}

#[test]
fn every_source_file_is_named_in_architecture_md() {
    let map = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let named = |word: &str| {
        map.match_indices(word).any(|(i, _)| {
            let before = map[..i].chars().next_back();
            let after = map[i + word.len()..].chars().next();
            !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
                && !after.is_some_and(|c| c.is_alphanumeric() || c == '_')
        })
    };
    let mut missing = Vec::new();
    for krate in CRATES {
        let src = root().join(krate).join("src");
        let mut list = Vec::new();
        rust_files(&src, &mut list);
        for f in list {
            let stem = f.file_stem().unwrap().to_string_lossy().into_owned();
            // A folder's mod.rs is named by its folder; lib.rs and main.rs by their crate.
            let word = match stem.as_str() {
                "lib" | "main" => continue,
                "mod" => f
                    .parent()
                    .unwrap()
                    .file_name()
                    .unwrap()
                    .to_string_lossy()
                    .into_owned(),
                _ => stem,
            };
            if !named(&word) {
                missing.push(f.strip_prefix(root()).unwrap().display().to_string());
            }
        }
    }
    assert!(
        missing.is_empty(),
        "source files ARCHITECTURE.md does not name:\n{}",
        missing.join("\n")
    );
}
