//! Step-size control of a mean-field run (docs/MODEL.md §4): the next step is
//! `dt = min(dt_max, cfl h / max(|u_x| + |u_y| + |u_z|))` (the CFL condition with the sum over
//! axes, `h` the grid spacing), its growth capped at `max_step_ratio` per step (below
//! `1 + sqrt 2`, the zero-stability limit of variable-step SBDF2). Output times are reached by
//! spreading the remaining time over at most two equal steps, never by a tiny clipped step
//! followed by a large ratio.

use motile_analysis::params::{InvalidParameter, check_range};

/// The controller's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepControl {
    /// Largest step.
    pub dt_max: f64,
    /// CFL number.
    pub cfl: f64,
    /// Largest ratio of consecutive steps.
    pub max_step_ratio: f64,
}

impl Default for StepControl {
    /// `dt_max = 0.05`, CFL number 0.5, steps growing by at most 1.5 per step.
    fn default() -> Self {
        Self {
            dt_max: 0.05,
            cfl: 0.5,
            max_step_ratio: 1.5,
        }
    }
}

impl StepControl {
    /// Check every field (the error names it, its value, the allowed range and the unit).
    pub fn validate(&self) -> Result<(), InvalidParameter> {
        check_range("dt_max", self.dt_max, 0.0, 1.0, true, "mu/|sigma_a|")?;
        check_range("cfl", self.cfl, 0.0, 2.0, true, "dimensionless")?;
        check_range(
            "max_step_ratio",
            self.max_step_ratio,
            1.0,
            2.4,
            true,
            "dimensionless; SBDF2 is zero-stable below 1 + sqrt 2",
        )
    }

    /// The step to take from `t` with the planned step `dt` when the next output is at
    /// `target > t`: `dt`, or the remaining time split into one or two equal steps when at most
    /// two planned steps remain.
    pub fn toward(&self, t: f64, target: f64, dt: f64) -> f64 {
        let remaining = target - t;
        let k = (remaining / dt).ceil().max(1.0);
        if k <= 2.0 { remaining / k } else { dt }
    }

    /// The planned step after a step of `taken` (planned: `dt`; the one before it:
    /// `prev_dt`) whose velocity reached `u_max` (the largest `|u_x| + |u_y| + |u_z|`) on a
    /// grid of spacing `h`. A step shortened to land on an output time does not shrink the
    /// growth cap's base below the steps around it.
    pub fn next(&self, taken: f64, dt: f64, prev_dt: f64, u_max: f64, h: f64) -> f64 {
        let cfl_dt = if u_max > 0.0 {
            self.cfl * h / u_max
        } else {
            self.dt_max
        };
        let base = if taken < dt {
            taken.max(prev_dt.min(dt))
        } else {
            taken
        };
        cfl_dt.min(self.dt_max).min(self.max_step_ratio * base)
    }
}

#[cfg(test)]
mod tests {
    use super::StepControl;

    const C: StepControl = StepControl {
        dt_max: 0.1,
        cfl: 0.5,
        max_step_ratio: 1.5,
    };

    #[test]
    fn output_times_are_reached_in_at_most_two_equal_steps() {
        // Far away: the planned step.
        assert_eq!(C.toward(0.0, 1.0, 0.1), 0.1);
        // 1.5 planned steps left: two equal steps of 0.075.
        let dt = C.toward(0.0, 0.15, 0.1);
        assert!((dt - 0.075).abs() < 1e-15, "{dt}");
        // Less than one step left: exactly the remainder.
        assert_eq!(C.toward(0.95, 1.0, 0.1), 1.0 - 0.95);
    }

    #[test]
    fn next_step_obeys_cfl_cap_and_growth_limit() {
        let h = 1.0 / 32.0;
        // CFL: 0.5 h / u_max.
        let dt = C.next(0.1, 0.1, 0.1, 10.0, h);
        assert!((dt - 0.5 * h / 10.0).abs() < 1e-16, "{dt}");
        // No flow: dt_max, but at most 1.5 times the step taken.
        assert_eq!(C.next(0.1, 0.1, 0.1, 0.0, h), 0.1);
        assert!((C.next(0.02, 0.02, 0.02, 0.0, h) - 0.03).abs() < 1e-16);
        // A step shortened to land on an output (0.001 of a planned 0.04) grows from the
        // planned steps, not from the short one.
        let dt = C.next(0.001, 0.04, 0.04, 0.0, h);
        assert!((dt - 0.06).abs() < 1e-16, "{dt}");
    }
}
