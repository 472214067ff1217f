//! Settings of `integrator = "pmlt"`: the `[integrator]` table's keys with their defaults, and their
//! validation (the bounds are the primary-sample-space family's, `pss::settings`).

use serde::{Deserialize, Serialize};

use crate::integrator::bdpt::MisHeuristic;
use crate::integrator::pss::settings::{MAX_BOOTSTRAP, MAX_CHAINS, MAX_DEPTH};
use crate::integrator::{settings_from_table, RenderError};

/// Settings of path-space MLT.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PmltSettings {
    /// Maximum number of scattering events of a path (vertices − 2), as for the other MLTs (8).
    pub max_depth: u32,
    /// BDPT samples of the bootstrap that estimates b and starts the chains (100,000, as MMLT's
    /// bootstrap per depth).
    pub bootstrap: u64,
    /// Number of independent chains (1000).
    pub chains: u64,
    /// MIS heuristic of the bootstrap's BDPT weights (the start paths are resampled ∝ w·f/p).
    pub mis: MisHeuristic,
    /// Selection weight of the bidirectional mutation (renormalised over the suitable strategies;
    /// the only strategy until issue 14 adds Veach's perturbations).
    pub bidirectional: f64,
    /// Selection weight of the portal perturbation (issue 15; offered only at paths that cross a
    /// `[[portals]]` quad, so it costs nothing in a scene without portals; 0 turns it off).
    pub portal: f64,
}

impl Default for PmltSettings {
    fn default() -> Self {
        PmltSettings {
            max_depth: 8,
            bootstrap: 100_000,
            chains: 1000,
            mis: MisHeuristic::Balance,
            bidirectional: 1.0,
            portal: 1.0,
        }
    }
}

impl PmltSettings {
    /// The settings from an `[integrator]` table, validated: every refusal names the setting and
    /// its valid range.
    pub fn from_params(params: &toml::Table) -> Result<PmltSettings, RenderError> {
        let settings: PmltSettings = settings_from_table("pmlt", params)?;
        let bad = |m: String| Err(RenderError::Settings(format!("pmlt: {m}")));
        if !(1..=MAX_DEPTH).contains(&settings.max_depth) {
            return bad(format!("max_depth = {}: expected 1 ..= {MAX_DEPTH}", settings.max_depth));
        }
        if !(1..=MAX_BOOTSTRAP).contains(&settings.bootstrap) {
            return bad(format!("bootstrap = {}: expected 1 ..= {MAX_BOOTSTRAP} (2^32) paths", settings.bootstrap));
        }
        if !(1..=MAX_CHAINS).contains(&settings.chains) {
            return bad(format!("chains = {}: expected 1 ..= {MAX_CHAINS} (2^24)", settings.chains));
        }
        if settings.mis == MisHeuristic::None {
            return bad("mis must be \"balance\" or \"power\"".to_string());
        }
        if !(settings.bidirectional > 0.0 && settings.bidirectional.is_finite()) {
            return bad(format!(
                "bidirectional = {}: expected a positive weight (the only strategy so far)",
                settings.bidirectional
            ));
        }
        if !(settings.portal >= 0.0 && settings.portal.is_finite()) {
            return bad(format!(
                "portal = {}: expected a weight ≥ 0 (0 turns the portal perturbation off)",
                settings.portal
            ));
        }
        Ok(settings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_and_refusals() {
        let s = PmltSettings::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(s, PmltSettings::default());
        for (bad, needle) in [
            ("max_depth = 0", "max_depth"),
            ("max_depth = 1025", "1024"),
            ("chains = 16777217", "2^24"),
            ("bootstrap = 4294967297", "2^32"),
            ("bootstrap = 0", "bootstrap"),
            ("mis = \"none\"", "mis"),
            ("bidirectional = 0.0", "bidirectional"),
            ("portal = -1.0", "portal"),
            ("large_step_probability = 0.3", "large_step_probability"),
        ] {
            let t: toml::Table = toml::from_str(bad).expect("toml");
            let err = PmltSettings::from_params(&t).err().unwrap_or_else(|| panic!("{bad} accepted")).to_string();
            assert!(err.contains(needle), "{bad}: {err}");
        }
    }
}
