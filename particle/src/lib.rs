//! The particle model of docs/MODEL.md §1-§3: rigid rods in a triply periodic box, periodic
//! neighbour search, steric contacts as a complementarity problem solved by BBPGD, and explicit
//! time stepping with quaternion orientation updates. Hydrodynamics plugs in through
//! [`hydro::mobility::Mobility`], one implementation per [`model::level::Hydrodynamics`] level:
//! [`hydro::mobility::LocalDrag`] (`"none"`), [`hydro::dipole::Dipole`] (point stresslets, §2),
//! [`hydro::explicit::ExplicitSlender`] (isolated-swimmer densities, one sum per step) and
//! [`hydro::slender::SlenderBody`] (slender-body theory inside GMRES, §1); their periodic
//! flows come from a [`ewald::periodic::PeriodicStokes`] sum
//! ([`ewald::spectral::SpectralEwald`], with the direct [`ewald::reference::EwaldReference`] as
//! its slow twin), which honours the tolerance of docs/accuracy.md for every output it returns.
//!
//! State ([`model::rods::RodSet`]) is plain data; [`step::stepper::Stepper`] owns only the
//! mobility, the solver and scratch memory, and returns a [`step::report::StepReport`] instead
//! of printing.
//!
//! The crate in rooms, one folder per concern (ARCHITECTURE.md), each naming only those listed
//! before it:
//! - [`model`]: rods, vectors and quaternions, units, the hydrodynamic level, initial states,
//!   the cell list of rods;
//! - [`parallel`]: the communication seam, halos, fixed-order reductions, the distributed FFT;
//! - [`ewald`]: the periodic sums, their kernels, the direct reference and the spectral Ewald
//!   method (its machinery: parameters, window, grid, point cells, phased writes; the sum
//!   shared among ranks; the GPU back-end);
//! - [`hydro`]: the mobilities and the GMRES of the slender-body equation;
//! - [`step`]: the stepper, contact constraints and the contact solver, the driver of a box
//!   shared among ranks, the step on a GPU.
//!
//! Inside the crate, code names the module that defines an item, never a re-export, no two
//! files refer to each other in a circle and no folder names one listed after it above
//! (tests/tests/architecture.rs checks all three). The
//! [`prelude`] is what a run needs in one import.
#![warn(missing_docs)]
#![warn(unreachable_pub)]

pub mod ewald;
pub mod hydro;
pub mod model;
pub mod parallel;
pub mod step;

/// What a user of the particle model needs, in one import: `use motile_particle::prelude::*;`.
pub mod prelude {
    pub use crate::ewald::periodic::PeriodicStokes;
    pub use crate::ewald::spectral::SpectralEwald;
    pub use crate::hydro::dipole::Dipole;
    pub use crate::hydro::gmres::GmresParams;
    pub use crate::hydro::mobility::{LocalDrag, Mobility};
    pub use crate::hydro::slender::{SlenderBody, SlenderParams};
    pub use crate::model::init::{nonoverlapping_with, overlapping_pairs, random_nonoverlapping};
    pub use crate::model::level::Hydrodynamics;
    pub use crate::model::rods::RodSet;
    pub use crate::model::units;
    pub use crate::step::contact::ContactParams;
    pub use crate::step::report::{StepError, StepReport};
    pub use crate::step::stepper::Stepper;
}
