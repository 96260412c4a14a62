//! Where a particle run's wall time went: its steps with their outputs, the outputs alone, and
//! the CPU stepper's stages (logged at the end of each invocation).

use motile_particle::step::report::{StageTimes, StepReport};

/// Wall seconds of an invocation's steps with their outputs, and of the outputs alone.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WallShares {
    /// The steps with their outputs (checkpoints not included: the run loop writes them).
    pub(crate) total: f64,
    /// The time series' rows: the flow's norms, the lowest modes, the CSV files.
    pub(crate) diagnostics: f64,
    /// Snapshots (HDF5 and VTK) with the downloads and point forces they need.
    pub(crate) snapshots: f64,
    /// The stepper's own stages, summed over the steps taken on the CPU (zero for resident
    /// steps, whose stages run on the device).
    stages: StageTimes,
    /// Seconds in the periodic sums over the same steps (counted within the stages' seconds:
    /// the stages call the sums).
    sum_seconds: f64,
    /// The periodic sums over the same steps.
    sums: usize,
    /// GMRES iterations over the same steps.
    gmres_iterations: usize,
}

impl WallShares {
    /// One line for the log.
    pub(crate) fn describe(&self) -> String {
        let mut line = format!(
            "wall time of the steps with their outputs {:.1} s: stepping {:.1} s, diagnostics {:.1} s (flow norms, lowest modes, time series), snapshots {:.1} s",
            self.total,
            self.total - self.diagnostics - self.snapshots,
            self.diagnostics,
            self.snapshots
        );
        let s = &self.stages;
        if s.as_array().iter().sum::<f64>() > 0.0 {
            line += &format!(
                "; the steps' stages: cells {:.1} s, constraints {:.1} s, free velocities {:.1} s, contacts {:.1} s, update {:.1} s; of these, in the periodic sums {:.1} s ({} sums, {} GMRES iterations)",
                s.cells,
                s.constraints,
                s.free_velocities,
                s.contacts,
                s.update,
                self.sum_seconds,
                self.sums,
                self.gmres_iterations
            );
        }
        line
    }

    /// Add one CPU step's stages.
    pub(crate) fn add_step(&mut self, report: &StepReport) {
        self.stages += &report.seconds;
        self.sum_seconds += report.hydro.seconds_sums;
        self.sums += report.hydro.sums;
        self.gmres_iterations += report.hydro.gmres_iterations;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two steps' stages and sums add up in the log line, and a run without CPU stages (the
    /// resident step's) leaves the stage split out.
    #[test]
    fn the_log_line_sums_the_steps_stages_and_sums() {
        let report = StepReport {
            seconds: StageTimes {
                cells: 0.5,
                constraints: 1.0,
                free_velocities: 2.0,
                contacts: 4.0,
                update: 8.0,
            },
            hydro: motile_particle::hydro::mobility::HydroReport {
                seconds_sums: 3.0,
                sums: 5,
                gmres_iterations: 3,
                ..Default::default()
            },
            ..StepReport::default()
        };
        let mut shares = WallShares {
            total: 40.0,
            diagnostics: 2.0,
            snapshots: 1.0,
            ..WallShares::default()
        };
        assert!(
            !shares.describe().contains("stages"),
            "no CPU steps, no stage split: {}",
            shares.describe()
        );
        shares.add_step(&report);
        shares.add_step(&report);
        let line = shares.describe();
        for part in [
            "stepping 37.0 s",
            "cells 1.0 s",
            "constraints 2.0 s",
            "free velocities 4.0 s",
            "contacts 8.0 s",
            "update 16.0 s",
            "periodic sums 6.0 s (10 sums, 6 GMRES iterations)",
        ] {
            assert!(line.contains(part), "'{part}' missing from: {line}");
        }
    }
}
