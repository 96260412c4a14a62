//! The mean-field model of MODEL.md §4: pseudo-spectral IMEX solver for the orientation tensor
//! Q with the Bingham closure. Not implemented yet (issue "Mean-field solver"); the crate exists
//! so the workspace has its final shape and the dependency direction
//! `analysis <- meanfield <- experiments` is fixed.
#![warn(missing_docs)]
