//! The particle model of docs/MODEL.md §1-§3: rigid rods in a triply periodic box, periodic
//! neighbour search, steric contacts as a complementarity problem solved by BBPGD, and explicit
//! time stepping with quaternion orientation updates. Hydrodynamics plugs in through
//! [`mobility::Mobility`], one implementation per [`Hydrodynamics`] level: [`LocalDrag`]
//! (`"none"`), [`dipole::Dipole`] (point stresslets, §2) and [`slender::SlenderBody`]
//! (slender-body theory inside GMRES, §1); their periodic flows come from a
//! [`periodic::PeriodicStokes`] sum ([`spectral_ewald::SpectralEwald`], with the direct
//! [`rpy_reference::EwaldReference`] as its slow twin), which honours the tolerance of
//! docs/accuracy.md for every output it returns.
//!
//! State ([`rods::RodSet`]) is plain data; [`step::Stepper`] owns only the mobility, the solver
//! and scratch memory, and returns a [`step::StepReport`] instead of printing.
//!
//! The public surface: the [`prelude`] (what a run needs), the modules of the model's parts
//! (rods and geometry, contacts, mobilities, periodic sums with their slow twins
//! [`rpy_reference`] and the kernels of [`ewald`], GMRES, initial states, units). The fast sum's
//! machinery (cell lists, parameter choice, Gaussian gridding, slab scheduling) is private:
//! it is reached through [`spectral_ewald::SpectralEwald`] and its [`spectral_ewald::EwaldParams`].
#![warn(missing_docs)]
#![warn(unreachable_pub)]

mod cells;
pub mod contact;
pub mod dipole;
pub mod distributed;
pub mod domain;
pub mod ewald;
mod ewald_params;
mod gaussian_grid;
pub mod geometry;
pub mod gmres;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod init;
pub mod level;
pub mod mobility;
pub mod periodic;
mod point_cells;
pub mod rods;
pub mod rpy_reference;
pub mod shared_ewald;
mod slabs;
pub mod slender;
pub mod spectral_ewald;
pub mod step;
pub mod units;

pub use contact::{ContactParams, ContactSolver};
pub use level::Hydrodynamics;
pub use mobility::{LocalDrag, Mobility};
pub use rods::RodSet;
pub use step::{StepError, StepReport, Stepper};

/// What a user of the particle model needs, in one import: `use motile_particle::prelude::*;`.
pub mod prelude {
    pub use crate::contact::ContactParams;
    pub use crate::dipole::Dipole;
    pub use crate::gmres::GmresParams;
    pub use crate::init::{nonoverlapping_with, overlapping_pairs, random_nonoverlapping};
    pub use crate::level::Hydrodynamics;
    pub use crate::mobility::{LocalDrag, Mobility};
    pub use crate::periodic::PeriodicStokes;
    pub use crate::rods::RodSet;
    pub use crate::slender::{SlenderBody, SlenderParams};
    pub use crate::spectral_ewald::SpectralEwald;
    pub use crate::step::{StepError, StepReport, Stepper};
    pub use crate::units;
}
