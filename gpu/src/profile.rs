//! Where a device's time goes, operation by operation: with profiling on
//! (`MOTILE_GPU_PROFILE=1` in the environment, or [`enable`]), every kernel launch, transform
//! and transfer of every [`crate::Device`] in the process waits for the device before and
//! after it, and its wall time is added to its name's total ([`take`]).
//!
//! The waits serialise the host and the device, so a profiled run is slower than an
//! unprofiled one (by a launch's latency per operation, a few microseconds on CUDA): the totals
//! say which kernels and transfers dominate a step and how far each is from its bandwidth
//! floor, not the step's own time. On the host emulation the totals are the emulation's.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

/// 0: not yet read from the environment; 1: off; 2: on.
static STATE: AtomicU8 = AtomicU8::new(0);
static TOTALS: Mutex<BTreeMap<String, (u64, f64)>> = Mutex::new(BTreeMap::new());

/// Turn profiling on or off for every device of the process (overrides `MOTILE_GPU_PROFILE`).
pub fn enable(on: bool) {
    STATE.store(if on { 2 } else { 1 }, Ordering::Relaxed);
}

/// Whether profiling is on: [`enable`]'s setting, else `MOTILE_GPU_PROFILE` set and not `0`.
pub fn enabled() -> bool {
    match STATE.load(Ordering::Relaxed) {
        0 => {
            let on = std::env::var("MOTILE_GPU_PROFILE").is_ok_and(|v| !v.is_empty() && v != "0");
            enable(on);
            on
        }
        s => s == 2,
    }
}

/// One operation's totals since the last [`take`].
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// The kernel's name, or `forward FFT m^3 x b`, `inverse FFT ...`, `upload`, `download`.
    pub name: String,
    /// How many times it ran.
    pub calls: u64,
    /// Wall seconds in all, the waits before and after each call excluded.
    pub seconds: f64,
}

/// The totals gathered since the last call, the largest first; clears them.
pub fn take() -> Vec<Entry> {
    let totals = std::mem::take(&mut *TOTALS.lock().unwrap_or_else(PoisonError::into_inner));
    let mut v: Vec<Entry> = totals
        .into_iter()
        .map(|(name, (calls, seconds))| Entry {
            name,
            calls,
            seconds,
        })
        .collect();
    v.sort_by(|a, b| b.seconds.total_cmp(&a.seconds));
    v
}

/// Run `op` (after `wait`), and with profiling on add its wall time, measured to the end of a
/// second `wait`, to `name`'s total.
pub(crate) fn timed<R, E>(
    name: impl FnOnce() -> String,
    wait: impl Fn() -> Result<(), E>,
    op: impl FnOnce() -> Result<R, E>,
) -> Result<R, E> {
    if !enabled() {
        return op();
    }
    wait()?;
    let t = Instant::now();
    let r = op()?;
    wait()?;
    let s = t.elapsed().as_secs_f64();
    let mut totals = TOTALS.lock().unwrap_or_else(PoisonError::into_inner);
    let e = totals.entry(name()).or_default();
    e.0 += 1;
    e.1 += s;
    Ok(r)
}
