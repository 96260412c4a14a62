//! How rods move under forces (docs/MODEL.md §1-§2): the [`mobility::Mobility`] trait and its
//! levels (local drag, point stresslets, slender-body theory), and the GMRES solver of the
//! slender-body equation.

pub mod dipole;
pub mod explicit;
pub mod gmres;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod mobility;
pub mod slender;
