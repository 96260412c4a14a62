//! Periodic Stokes sums (docs/MODEL.md §1-§2, docs/accuracy.md): the [`periodic::PeriodicStokes`]
//! trait, the kernels and their Ewald split, the direct reference sum (the slow twin), the
//! spectral Ewald sum (parameters, Gaussian window and grid, point cells, deterministic phased
//! writes), its version shared among ranks, and (feature `gpu`) its Fourier part and real-space
//! pairs on a device.

// Without the `gpu` feature, `gpu/off.rs`: a device type with no values, so that the sums
// name their device without `cfg`.
#[cfg_attr(not(feature = "gpu"), path = "gpu/off.rs")]
pub mod gpu;
pub(crate) mod grid;
pub mod kernels;
pub mod params;
pub mod periodic;
pub(crate) mod phased_writes;
pub(crate) mod point_cells;
pub mod reference;
pub mod shared;
pub mod spectral;
pub(crate) mod window;
