//! The `motile` command line's library: run directories, HDF5 snapshots, analysis of runs,
//! figures. Physics lives in the model crates; this crate decides what to show and where to
//! write it.
#![warn(missing_docs)]

pub mod accuracy;
pub mod analyze;
pub mod checkpoint;
pub mod compare;
pub mod demo;
pub mod estimate;
pub mod failure;
pub mod io;
pub mod meanfield_run;
pub mod onset;
pub mod particle_run;
pub mod plot;
pub mod run;
pub mod rundir;
pub mod scene;
pub mod snapshot;
pub mod stability;
pub mod study;
pub mod vtk;
