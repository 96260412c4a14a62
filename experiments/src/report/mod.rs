//! What a user sees of finished runs: their analysis (correlations, norms, statistics), the
//! comparison of particle and mean-field runs in one unit system, figures, accuracy audits.

pub mod accuracy;
pub mod analyze;
pub(crate) mod compact;
pub mod compare;
pub(crate) mod compare_figures;
pub mod curves;
pub mod opened_run;
pub(crate) mod pair_structure;
pub mod plot;
pub(crate) mod products;
pub(crate) mod series;
pub mod statistics;
pub mod trajectory_series;
