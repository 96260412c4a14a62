//! Analysis shared by both motile models (docs/MODEL.md §5, §6): the non-uniform FFT, correlation
//! functions of particle configurations and of fields on a grid, the velocity spectrum of point
//! forces, volume-averaged norms, correlation lengths, time averages and trajectory statistics.
//!
//! Everything here is pure computation: functions take data and return data. Parallel work runs
//! on the caller's rayon pool and gives bit-identical results for any pool size.
#![warn(missing_docs)]
#![warn(unreachable_pub)]

pub mod correlation;
pub mod fft3;
mod kernel;
pub mod nufft;
pub mod params;
pub mod quadrature;
pub mod reduce;
pub mod stats;

pub use correlation::{CorrelationOptions, OrderParameter, RadialCorrelation, Spectrum};
pub use fft3::{Direction, Fft3, RealFft3};
pub use nufft::{NufftError, NufftPlan};
