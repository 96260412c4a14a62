//! The mean-field model of docs/MODEL.md §4: the orientation tensor Q with the Bingham closure.
//! So far: the Bingham distribution's moments and its inversion ([`bingham`]) and the tabulated
//! fast closure ([`closure`]). The spectral Stokes solve and IMEX stepping are not implemented yet.
#![warn(missing_docs)]

pub mod bessel;
pub mod bingham;
pub mod closure;
pub mod eigen;
pub mod initial;
pub mod solver;
