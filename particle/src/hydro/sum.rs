//! The periodic sum a mobility's flow runs on ([`FlowSum`]): a [`PeriodicStokes`] sum that
//! says whether it can keep its points, values and results on a device, so that a mobility
//! reaches the resident sums without knowing which sum it was given.

use crate::ewald::periodic::PeriodicStokes;
use crate::ewald::reference::EwaldReference;
use crate::ewald::shared::SharedEwald;
use crate::ewald::spectral::SpectralEwald;

/// A periodic sum as a mobility holds it.
pub trait FlowSum: PeriodicStokes {
    /// This sum where its points, values and results can stay on a device (a
    /// [`SpectralEwald`] with a device, whose `*_resident` sums a GPU build offers); `None`
    /// for sums on the CPU.
    fn resident(&mut self) -> Option<&mut SpectralEwald> {
        None
    }
}

impl FlowSum for EwaldReference {}

impl FlowSum for SpectralEwald {
    fn resident(&mut self) -> Option<&mut SpectralEwald> {
        if self.on_device() { Some(self) } else { None }
    }
}

/// The adaptive state of a mobility's sums for checkpoints: its sum shared among ranks where
/// it has one, else its own sum's.
pub(crate) fn adaptive_state(sum: &dyn FlowSum, shared: Option<&SharedEwald>) -> Vec<u32> {
    match shared {
        Some(s) => s.adaptive_state(),
        None => sum.adaptive_state(),
    }
}

/// Restore what [`adaptive_state`] returned.
pub(crate) fn set_adaptive_state(
    sum: &mut dyn FlowSum,
    shared: Option<&mut SharedEwald>,
    state: &[u32],
) {
    match shared {
        Some(s) => s.set_adaptive_state(state),
        None => sum.set_adaptive_state(state),
    }
}
