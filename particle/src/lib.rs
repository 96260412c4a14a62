//! The particle model of MODEL.md §1-§3: rigid rods, periodic neighbour search, contacts,
//! slender-body hydrodynamics. Not implemented yet (issues "Particle engine, part 1/2"); the
//! crate exists so the workspace has its final shape and the dependency direction
//! `analysis <- particle <- experiments` is fixed.
#![warn(missing_docs)]
