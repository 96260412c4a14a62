//! What a step on one rank of a shared box is given (docs/MODEL.md §3a): the ranks, this rank's
//! halo and its rods' numbers in the whole box. One process: [`crate::parallel::comm::SingleProcess`]
//! with `Halo::none`.

use crate::parallel::comm::Comm;
use crate::parallel::halo::Halo;

/// The ranks a contact problem is shared among, and this rank's copies of their rods (see
/// [`crate::parallel::comm`]); one process: [`crate::parallel::comm::SingleProcess`] with `Halo::none`.
#[derive(Clone, Copy, Debug)]
pub struct Share<'a> {
    /// The ranks.
    pub comm: &'a dyn Comm,
    /// This rank's copies, in the solver's rod numbering.
    pub halo: &'a Halo,
}

/// This rank's part of a box shared by several ranks (see [`crate::parallel::comm`]).
#[derive(Clone, Copy, Debug)]
pub struct Part<'a> {
    /// The ranks.
    pub comm: &'a dyn Comm,
    /// Which local rods are this rank's and which are copies.
    pub halo: &'a Halo,
    /// Each local rod's number in the whole box (empty: the local numbering is the global one).
    pub ids: &'a [u32],
    /// Rods in the whole box.
    pub total: usize,
    /// How far beyond its slab a rank holds copies (zero for one process): the reach of the
    /// shared sums' real-space pairs.
    pub reach: f64,
}
