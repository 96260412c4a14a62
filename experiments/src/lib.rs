//! The `motile` command line's library: what users and future back-ends touch. Physics lives in
//! the model crates (`motile-particle`, `motile-meanfield`, `motile-analysis`); this crate
//! drives them and decides what to show and where to write it. Its folders:
//!
//! - [`run`]: the run loop, written once ([`run::RunModel`], [`run::start`], [`run::resume`]),
//!   its adapters for the particle and mean-field models, and typed failures;
//! - [`io`]: run directories, verified checkpoints, HDF5 snapshots, VTK files, atomic writes;
//! - [`report`]: analysis of finished runs, comparison of runs, figures, accuracy audits;
//! - [`campaign`]: scenes (named sets of runs), the demo, studies of accuracy against cost,
//!   stability and onset maps, cost estimates;
//! - [`cli`]: the `motile` commands, one module each (`main.rs` only parses and dispatches).
#![warn(missing_docs)]

pub mod campaign;
pub mod cli;
pub mod io;
pub mod report;
pub mod run;
