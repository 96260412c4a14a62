//! The `motile` commands, one module each: its arguments (parsed by clap in `main.rs`) and the
//! function that runs it and prints what a user reads. `main.rs` only parses and dispatches.

pub mod analyze;
pub mod check_accuracy;
pub mod compare;
pub mod demo;
pub mod fidelity;
pub mod model_run;
pub mod resume;
pub mod scene_run;
pub mod stability;
pub mod study;
pub mod theory;

use crate::io::rundir::TimeSeries;
use motile_particle::model::level::Hydrodynamics;

/// Whether progress bars are shown (stderr is a terminal).
pub(crate) fn progress() -> bool {
    std::io::IsTerminal::is_terminal(&std::io::stderr())
}

/// A time series as aligned text, its column names first.
pub(crate) fn print_table(ts: &TimeSeries) {
    println!("{}", ts.columns.join("  "));
    for r in &ts.rows {
        let cells: Vec<String> = r.iter().map(|v| format!("{v:.4e}")).collect();
        println!("{}", cells.join("  "));
    }
}

/// The hydrodynamic levels `keep` accepts, named from [`Hydrodynamics::ALL`] as a help text
/// lists them: `"none", "dipole", "sbt-explicit" or "sbt"`.
pub fn levels(keep: impl Fn(Hydrodynamics) -> bool) -> String {
    let names: Vec<String> = Hydrodynamics::ALL
        .into_iter()
        .filter(|h| keep(*h))
        .map(|h| format!("\"{h}\""))
        .collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.concat(),
    }
}

/// `text` reflowed at word boundaries into lines of at most `width` characters (a longer word
/// gets a line of its own), the first line after `first`, the others after `indent`; blank
/// lines in `text` separate paragraphs, other line breaks are spaces, and an `=` keeps the words
/// either side of it on its line.
pub(crate) fn wrap(text: &str, width: usize, first: &str, indent: &str) -> String {
    let mut out = String::new();
    let mut line = first.to_string();
    let mut empty = true;
    for (i, paragraph) in text.trim().split("\n\n").enumerate() {
        if i > 0 {
            out.push_str(line.trim_end());
            out.push_str("\n\n");
            line = indent.to_string();
            empty = true;
        }
        // "t = 29" stays on one line: an "=" binds the words either side of it.
        let mut words: Vec<String> = Vec::new();
        let mut bind = false;
        for w in paragraph.split_whitespace() {
            match words.last_mut() {
                Some(last) if bind || w == "=" => {
                    last.push(' ');
                    last.push_str(w);
                }
                _ => words.push(w.to_string()),
            }
            bind = w == "=";
        }
        for word in &words {
            if !empty && line.chars().count() + 1 + word.chars().count() > width {
                out.push_str(&line);
                out.push('\n');
                line = indent.to_string();
                empty = true;
            }
            if !empty {
                line.push(' ');
            }
            line.push_str(word);
            empty = false;
        }
    }
    out.push_str(line.trim_end());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_listed_from_the_enum() {
        assert_eq!(
            levels(|_| true),
            "\"none\", \"dipole\", \"sbt-explicit\" or \"sbt\""
        );
        assert_eq!(levels(|h| h == Hydrodynamics::Sbt), "\"sbt\"");
    }

    #[test]
    fn wrap_breaks_at_words_and_keeps_paragraphs() {
        let w = wrap("one two\nthree four five\n\nsix", 14, "  a: ", "     ");
        assert_eq!(w, "  a: one two\n     three\n     four five\n\n     six");
        assert!(w.lines().all(|l| l.chars().count() <= 14), "{w}");
        assert_eq!(wrap("to t = 29 at x", 8, "", ""), "to\nt = 29\nat x");
    }
}
