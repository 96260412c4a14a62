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
