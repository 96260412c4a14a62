//! The adaptive level of a fast sum (docs/accuracy.md): the internal tolerance an attempt
//! uses, raised when the error estimate misses the bound, lowered after a calm stretch.

use crate::ewald::periodic::SumError;

/// The finest internal tolerance an attempt uses (the windows reach their widest support
/// there; beyond it round-off of the cancelling parts takes over).
pub(crate) const MIN_INTERNAL_TOLERANCE: f64 = 1e-13;

/// Sums in a row that met the contract with ten times room before the level is lowered by one.
const CALM_SUMS: u32 = 50;

/// The adaptive level of a sum (shared by `SpectralEwald` and the sum shared among ranks,
/// `crate::ewald::kernels::shared`): internal tolerance `tol 10^(-level/2)`, raised by the half decades
/// an attempt missed, lowered after [`CALM_SUMS`] sums in a row with ten times room.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Refinement {
    /// Refinement level.
    pub(crate) level: u32,
    /// Sums in a row with ten times room at the current level.
    pub(crate) calm: u32,
}

impl Refinement {
    /// Internal tolerance at the current level.
    pub(crate) fn internal_tolerance(&self, tol: f64) -> f64 {
        (tol * 10f64.powf(-0.5 * self.level as f64)).max(MIN_INTERNAL_TOLERANCE)
    }

    /// The highest level (internal tolerance [`MIN_INTERNAL_TOLERANCE`]).
    pub(crate) fn max_level(tol: f64) -> u32 {
        (2.0 * (tol / MIN_INTERNAL_TOLERANCE).log10())
            .ceil()
            .max(0.0) as u32
    }

    /// After an attempt with worst estimate/bound ratio `ratio`: `true` if it stands (met,
    /// nothing finer to try, or `fixed` parameters), else the level rises by the half decades
    /// missing.
    pub(crate) fn accept(&mut self, tol: f64, ratio: f64, fixed: bool) -> Result<bool, SumError> {
        // An estimate that is not a number is not an error a finer grid reduces: the sum
        // overflowed (inputs far beyond any physical force), and refining would only grow
        // the grid, one level per attempt. (An infinite ratio, a vanishing output under a
        // non-zero estimate, goes to the finest level at once, as before.)
        if ratio.is_nan() {
            return Err(SumError::Input(format!(
                "the sum's error estimate is {ratio} of its tolerance: its forces overflow it"
            )));
        }
        let max = Self::max_level(tol);
        if fixed || ratio <= 1.0 || self.level >= max {
            if ratio <= 0.1 {
                self.calm += 1;
                if self.calm >= CALM_SUMS && self.level > 0 {
                    self.level -= 1;
                    self.calm = 0;
                }
            } else {
                self.calm = 0;
            }
            return Ok(true);
        }
        let steps = (2.0 * ratio.log10()).ceil().max(1.0) as u32;
        self.level = (self.level + steps).min(max);
        self.calm = 0;
        Ok(false)
    }

    /// As a checkpoint keeps it.
    pub(crate) fn state(&self) -> Vec<u32> {
        vec![self.level, self.calm]
    }

    /// Restore what [`Self::state`] returned (ignored if it does not fit).
    pub(crate) fn set_state(&mut self, tol: f64, state: &[u32]) {
        if let [level, calm] = *state {
            self.level = level.min(Self::max_level(tol));
            self.calm = calm;
        }
    }
}

/// Refuse tolerances outside `[1e-10, 1e-1]`.
pub(crate) fn check_tolerance(tol: f64) -> Result<(), SumError> {
    if !(1e-10..=1e-1).contains(&tol) {
        return Err(SumError::Input(format!(
            "fast-sum tolerance {tol:e} outside [1e-10, 1e-1]"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nan_estimate_is_an_error_and_an_infinite_one_goes_to_the_finest_level() {
        let tol = 1e-4;
        let mut r = Refinement::default();
        let e = r.accept(tol, f64::NAN, false).unwrap_err().to_string();
        assert!(e.contains("overflow"), "{e}");
        assert_eq!(r, Refinement::default(), "the level is left as it was");
        assert!(!r.accept(tol, f64::INFINITY, false).unwrap());
        assert_eq!(r.level, Refinement::max_level(tol));
        assert!(
            r.accept(tol, f64::INFINITY, false).unwrap(),
            "nothing finer to try"
        );
        assert!(r.accept(tol, 0.5, false).unwrap());
    }
}
