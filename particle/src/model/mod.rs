//! What the particle model is made of (docs/MODEL.md §1): the rods' state, vectors and
//! quaternions, units and fixed parameters, the hydrodynamic level, initial configurations, and
//! the cell list of rods that both the initial configurations and the contacts search.

pub(crate) mod cells;
pub mod geometry;
pub mod init;
pub mod level;
pub mod linear_theory;
pub mod rods;
pub mod units;
