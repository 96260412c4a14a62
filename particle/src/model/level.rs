//! The hydrodynamic level of a particle run (docs/MODEL.md §1-§2): a closed choice, parsed once
//! and rejected at parse time when unknown (`hydrodynamics = "..."` in a run's configuration).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Which flow the rods feel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Hydrodynamics {
    /// Free swimming with local slender-body drag, no flow ([`crate::hydro::mobility::LocalDrag`]).
    #[default]
    None,
    /// Point stresslets in the periodic flow of all the others (docs/MODEL.md §2, D1-D2).
    Dipole,
    /// Slender-body theory with explicit densities: each rod the force density of an isolated
    /// swimmer, one periodic RPY sum per step, no GMRES (docs/MODEL.md §2a).
    SbtExplicit,
    /// Slender-body theory with the periodic RPY sum inside GMRES (docs/MODEL.md §1, P1-P5).
    Sbt,
}

impl Hydrodynamics {
    /// Every level, in the order of increasing fidelity.
    pub const ALL: [Hydrodynamics; 4] = [Self::None, Self::Dipole, Self::SbtExplicit, Self::Sbt];

    /// The configuration name (`"none"`, `"dipole"`, `"sbt-explicit"`, `"sbt"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Dipole => "dipole",
            Self::SbtExplicit => "sbt-explicit",
            Self::Sbt => "sbt",
        }
    }

    /// Every level's configuration name, in the order of [`Self::ALL`]: the one list that help
    /// texts and messages name the levels from.
    pub fn names() -> [&'static str; 4] {
        Self::ALL.map(Self::name)
    }

    /// The names quoted and separated by commas: `"none", "dipole", "sbt-explicit", "sbt"`.
    pub fn quoted_names() -> String {
        Self::names().map(|n| format!("\"{n}\"")).join(", ")
    }

    /// Whether the level computes a flow (and so force densities, sums, GMRES).
    pub fn has_flow(self) -> bool {
        self != Self::None
    }
}

impl fmt::Display for Hydrodynamics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown level name; the message names the allowed ones.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("hydrodynamics = \"{0}\" is not one of {names}", names = Hydrodynamics::quoted_names())]
pub struct UnknownHydrodynamics(pub String);

impl FromStr for Hydrodynamics {
    type Err = UnknownHydrodynamics;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|h| h.name() == s)
            .ok_or_else(|| UnknownHydrodynamics(s.to_string()))
    }
}

impl TryFrom<String> for Hydrodynamics {
    type Error = UnknownHydrodynamics;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<Hydrodynamics> for String {
    fn from(h: Hydrodynamics) -> Self {
        h.name().to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_refused_with_the_allowed_ones() {
        for h in Hydrodynamics::ALL {
            assert_eq!(h.name().parse::<Hydrodynamics>(), Ok(h));
        }
        let e = "stokesian".parse::<Hydrodynamics>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "hydrodynamics = \"stokesian\" is not one of \"none\", \"dipole\", \"sbt-explicit\", \"sbt\""
        );
    }
}
