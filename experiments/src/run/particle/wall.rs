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
    /// Seconds in the periodic sums over the same steps.
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
                "; the steps' stages: cells {:.1} s, constraints {:.1} s, free velocities {:.1} s, contacts {:.1} s, update {:.1} s; periodic sums {:.1} s ({} sums, {} GMRES iterations)",
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
        let (s, r) = (&mut self.stages, &report.seconds);
        s.cells += r.cells;
        s.constraints += r.constraints;
        s.free_velocities += r.free_velocities;
        s.contacts += r.contacts;
        s.update += r.update;
        self.sum_seconds += report.hydro.seconds_sums;
        self.sums += report.hydro.sums;
        self.gmres_iterations += report.hydro.gmres_iterations;
    }
}
