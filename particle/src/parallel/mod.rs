//! One box shared by several ranks (docs/MODEL.md §3a): the communication seam
//! ([`comm::Comm`], with threads as ranks for tests), the halo of copies, what a step on one
//! rank is given, reductions in a fixed order, the distributed FFT of the shared grid and the
//! distributed driver.

pub mod comm;
pub mod distributed;
pub mod halo;
pub mod part;
pub(crate) mod reduce;
pub mod slab_fft;
