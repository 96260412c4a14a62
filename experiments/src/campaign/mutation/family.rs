//! The families of files a campaign damages, each with the reader it goes to, and the
//! outcomes a reader can meet a damaged file with.

/// A kind of file and the reader it goes to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Family {
    /// A particle run config, to `motile particle run --dry-run`.
    ParticleConfig,
    /// A mean-field run config, to `motile meanfield run --dry-run`.
    MeanFieldConfig,
    /// A scene file, to `motile run SCENE --dry-run`.
    Scene,
    /// A particle snapshot, as a particle run's `initial` state.
    ParticleSnapshot,
    /// A mean-field snapshot, as a mean-field run's `snapshot` state.
    FieldSnapshot,
    /// A particle checkpoint (with a matching checksum), to `motile resume`.
    ParticleCheckpoint,
    /// A mean-field checkpoint (with a matching checksum), to `motile resume`.
    MeanFieldCheckpoint,
    /// A run's `timeseries.csv`, to `motile compare`/`analyze` opening the run.
    RunDirectory,
    /// A run's `config.toml` (its `[motile]` header and resolved config), likewise.
    RunConfig,
    /// A snapshot in a particle run's directory, to `motile check-accuracy RUN_DIR`.
    RunSnapshot,
    /// A compact run's (`compare/` products, no snapshots) `velocity_correlation.csv`, to
    /// `motile compare` reading it.
    CompactCorrelation,
    /// Its `trajectories.csv` (MSD, orientation correlation), likewise.
    CompactTrajectories,
    /// Its `order_correlations.csv`, likewise.
    CompactOrders,
    /// Its `correlation_lengths.csv`, likewise.
    CompactLengths,
    /// A series table (`series.csv`, as the gallery's), to `motile compare --table`.
    SeriesTable,
}

impl Family {
    /// Every family.
    pub const ALL: [Family; 15] = [
        Family::ParticleConfig,
        Family::MeanFieldConfig,
        Family::Scene,
        Family::ParticleSnapshot,
        Family::FieldSnapshot,
        Family::ParticleCheckpoint,
        Family::MeanFieldCheckpoint,
        Family::RunDirectory,
        Family::RunConfig,
        Family::RunSnapshot,
        Family::CompactCorrelation,
        Family::CompactTrajectories,
        Family::CompactOrders,
        Family::CompactLengths,
        Family::SeriesTable,
    ];

    /// Its name on the command line and in tables.
    pub fn name(self) -> &'static str {
        match self {
            Family::ParticleConfig => "particle-config",
            Family::MeanFieldConfig => "meanfield-config",
            Family::Scene => "scene",
            Family::ParticleSnapshot => "particle-snapshot",
            Family::FieldSnapshot => "meanfield-snapshot",
            Family::ParticleCheckpoint => "particle-checkpoint",
            Family::MeanFieldCheckpoint => "meanfield-checkpoint",
            Family::RunDirectory => "run-timeseries",
            Family::RunConfig => "run-config",
            Family::RunSnapshot => "run-snapshot",
            Family::CompactCorrelation => "compact-corr-u",
            Family::CompactTrajectories => "compact-trajectories",
            Family::CompactOrders => "compact-orders",
            Family::CompactLengths => "compact-lengths",
            Family::SeriesTable => "series-table",
        }
    }

    /// The reader, as a user reaches it.
    pub fn reader(self) -> &'static str {
        match self {
            Family::ParticleConfig => "`particle run CONFIG --dry-run`",
            Family::MeanFieldConfig => "`meanfield run CONFIG --dry-run`",
            Family::Scene => "`run SCENE.toml --dry-run`",
            Family::ParticleSnapshot => "particle run, `initial = FILE`",
            Family::FieldSnapshot => "meanfield run, `snapshot = FILE`",
            Family::ParticleCheckpoint | Family::MeanFieldCheckpoint => "`resume RUN_DIR`",
            Family::RunDirectory | Family::RunConfig => "`compare`/`analyze` opening the run",
            Family::RunSnapshot => "`check-accuracy RUN_DIR --snapshot 1`",
            Family::CompactCorrelation
            | Family::CompactTrajectories
            | Family::CompactOrders
            | Family::CompactLengths => "`compare` of a compact run (series products)",
            Family::SeriesTable => "`compare --table FILE`",
        }
    }

    /// The compact product a compact family damages.
    pub(super) fn compact_file(self) -> Option<&'static str> {
        match self {
            Family::CompactCorrelation => Some("velocity_correlation.csv"),
            Family::CompactTrajectories => Some("trajectories.csv"),
            Family::CompactOrders => Some("order_correlations.csv"),
            Family::CompactLengths => Some("correlation_lengths.csv"),
            _ => None,
        }
    }

    pub(super) fn is_text(self) -> bool {
        matches!(
            self,
            Family::ParticleConfig
                | Family::MeanFieldConfig
                | Family::Scene
                | Family::RunDirectory
                | Family::RunConfig
                | Family::CompactCorrelation
                | Family::CompactTrajectories
                | Family::CompactOrders
                | Family::CompactLengths
                | Family::SeriesTable
        )
    }
}

/// How a reader met one damaged file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Refused with a message naming the file.
    ClearError,
    /// Accepted, and what it accepted is consistent.
    Accepted,
    /// Refused with a message that does not name the file.
    UnclearError,
    /// Accepted, but what it accepted is inconsistent.
    Inconsistent,
    /// The reader panicked.
    Panic,
    /// The reader did not return within the time limit.
    Hang,
}

impl Outcome {
    /// Every outcome, in table order.
    pub const ALL: [Outcome; 6] = [
        Outcome::ClearError,
        Outcome::Accepted,
        Outcome::UnclearError,
        Outcome::Inconsistent,
        Outcome::Panic,
        Outcome::Hang,
    ];

    /// Its column heading.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::ClearError => "clear error",
            Outcome::Accepted => "accepted, consistent",
            Outcome::UnclearError => "error not naming the file",
            Outcome::Inconsistent => "accepted, inconsistent",
            Outcome::Panic => "panic",
            Outcome::Hang => "hang",
        }
    }

    /// Whether it is a defect.
    pub fn is_defect(self) -> bool {
        !matches!(self, Outcome::ClearError | Outcome::Accepted)
    }
}
