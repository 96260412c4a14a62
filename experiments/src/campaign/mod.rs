//! Campaigns: sets of runs and what they measure. Scenes (named, versioned sets of runs), the
//! README's demo, studies of accuracy against cost, stability and onset maps, cost estimates.

pub mod demo;
pub mod estimate;
pub mod fidelity;
pub mod mutation;
pub mod onset;
pub mod run_config;
pub mod scene;
pub mod stability;
pub mod study;
