//! What the parts of the model share to run on one box split among several ranks (docs/MODEL.md
//! §3a): the communication seam ([`comm::Comm`], with threads as ranks for tests), the halo of
//! copies, what a step on one rank is given, reductions in a fixed order, the distributed FFT of
//! the shared grid. The driver that steps such a box is [`crate::step::distributed`].

pub mod comm;
pub mod halo;
pub mod part;
pub(crate) mod reduce;
pub mod slab_fft;
