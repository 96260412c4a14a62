//! Injected device failures, for the fault tests of the code around the kernels: a launch that
//! fails as a real device's can (an illegal address, a lost device), on the host emulation as on
//! CUDA, so that what a run does then (stop, say why, keep its last good state) is tested where
//! there is no GPU.
//!
//! `MOTILE_GPU_INJECT_FAILURE = "N"` makes the `N`-th kernel launch of the process (counted
//! from 1 over every device) fail with a driver error; `"N,sticky"` also fails every later
//! operation (launches, transfers, transforms), as CUDA's sticky errors leave a context unusable.
//! [`inject_failure`] sets the same from code. Unset, a launch costs an uncontended lock.

use crate::error::GpuError;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// A device failure to inject.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Injection {
    /// The launch that fails, counted from 1 over the process's launches from the moment the
    /// injection is set.
    pub at_launch: u64,
    /// Whether every later operation fails too (the device unusable after the failure).
    pub sticky: bool,
}

impl Injection {
    /// The injection `text` states (`"N"` or `"N,sticky"`), or an error naming the variable.
    pub fn parse(text: &str) -> Result<Self, GpuError> {
        let bad = || {
            GpuError::Input(format!(
                "MOTILE_GPU_INJECT_FAILURE = {text:?}: expected a launch number from 1, optionally followed by \",sticky\" (e.g. \"120\" or \"120,sticky\")"
            ))
        };
        let (n, rest) = match text.split_once(',') {
            Some((n, rest)) => (n, Some(rest.trim())),
            None => (text, None),
        };
        let at_launch: u64 = n.trim().parse().map_err(|_| bad())?;
        if at_launch == 0 {
            return Err(bad());
        }
        let sticky = match rest {
            None => false,
            Some("sticky") => true,
            Some(_) => return Err(bad()),
        };
        Ok(Self { at_launch, sticky })
    }
}

/// The injection in force, read from the environment on first use.
static PLAN: Mutex<Option<Option<Injection>>> = Mutex::new(None);
/// Launches since the injection was set.
static LAUNCHES: AtomicU64 = AtomicU64::new(0);
/// Whether a sticky failure has happened.
static FAILED: AtomicBool = AtomicBool::new(false);

/// Inject `plan` from now on (`None`: no failure), counting launches afresh; this replaces what
/// `MOTILE_GPU_INJECT_FAILURE` said.
pub fn inject_failure(plan: Option<Injection>) {
    *PLAN
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(plan);
    LAUNCHES.store(0, Ordering::SeqCst);
    FAILED.store(false, Ordering::SeqCst);
}

/// The plan in force (the environment's on first use; a malformed value is an error at every
/// launch, so that a test that meant to inject a failure cannot pass without one).
fn plan() -> Result<Option<Injection>, GpuError> {
    let mut p = PLAN
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if p.is_none() {
        *p = Some(match std::env::var("MOTILE_GPU_INJECT_FAILURE") {
            Err(_) => None,
            Ok(v) if v.trim().is_empty() => None,
            Ok(v) => Some(Injection::parse(&v)?),
        });
    }
    Ok(p.expect("set above"))
}

/// Before launching `kernel`: the injected failure where this is its launch.
pub(crate) fn on_launch(kernel: &str) -> Result<(), GpuError> {
    let Some(plan) = plan()? else {
        return Ok(());
    };
    let n = LAUNCHES.fetch_add(1, Ordering::SeqCst) + 1;
    if n == plan.at_launch {
        FAILED.store(plan.sticky, Ordering::SeqCst);
        return Err(GpuError::Driver(format!(
            "launching {kernel} (launch {n}): an illegal memory access was encountered (injected by MOTILE_GPU_INJECT_FAILURE{})",
            if plan.sticky {
                "; the device is unusable from now on"
            } else {
                ""
            }
        )));
    }
    unusable()
}

/// Before any operation: an error once a sticky failure has happened.
pub(crate) fn unusable() -> Result<(), GpuError> {
    if FAILED.load(Ordering::SeqCst) {
        return Err(GpuError::Driver(
            "the device is unusable after an earlier failure (injected by MOTILE_GPU_INJECT_FAILURE)"
                .into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn injections_parse_and_refuse_by_name() {
        assert_eq!(
            Injection::parse("12").unwrap(),
            Injection {
                at_launch: 12,
                sticky: false
            }
        );
        assert_eq!(
            Injection::parse(" 3 , sticky").unwrap(),
            Injection {
                at_launch: 3,
                sticky: true
            }
        );
        for bad in ["0", "-1", "x", "3,often", "3,sticky,again"] {
            let e = Injection::parse(bad).unwrap_err().to_string();
            assert!(e.contains("MOTILE_GPU_INJECT_FAILURE"), "{bad}: {e}");
        }
    }
}
