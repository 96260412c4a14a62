//! How rods move under forces (docs/MODEL.md §1-§2): the [`mobility::Mobility`] trait and its
//! levels (local drag, point stresslets, slender-body theory), and the GMRES solver of the
//! slender-body equation.

pub mod dipole;
pub mod explicit;
pub mod gmres;
// Without the `gpu` feature, `gpu/off.rs`: the device path's traits, saying that nothing runs
// on a device, so that the CPU code names them without `cfg`.
#[cfg_attr(not(feature = "gpu"), path = "gpu/off.rs")]
pub mod gpu;
pub mod mobility;
pub mod report;
pub mod slender;
pub mod sum;
