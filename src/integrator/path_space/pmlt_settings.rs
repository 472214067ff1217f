//! Settings of `integrator = "pmlt"`: the `[integrator]` table's keys with their defaults, and their
//! validation (the bounds are the primary-sample-space family's, `pss::mlt_settings`).

use serde::{Deserialize, Serialize};

use super::reciprocal_kernel::RasterKernel;
use crate::integrator::bdpt::MisHeuristic;
use crate::integrator::pss::mlt_settings::{MAX_BOOTSTRAP, MAX_CHAINS, MAX_DEPTH};
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
    /// Selection weight of the bidirectional mutation (1; renormalised over the suitable
    /// strategies, `strategy` module docs). Positive: it is what makes the chain ergodic.
    pub bidirectional: f64,
    /// Selection weights of the perturbations (2 each; 0 turns one off). A perturbation's weight
    /// is shared equally among the perturbations suitable at the path, so the defaults give the
    /// bidirectional mutation 1/3 and the suitable perturbations 2/3 between them (the ensemble
    /// paper's setting).
    pub lens: f64,
    pub caustic: f64,
    pub multi_chain: f64,
    /// Selection weight of the portal perturbation (2 like the other perturbations, with
    /// which it shares its weight; offered only at paths that cross a `[[portals]]` quad, so it
    /// costs nothing in a scene without portals; 0 turns it off).
    pub portal: f64,
    /// The lens perturbation's offset range [r_1, r_2] in pixels (`kernel::RasterKernel`), which
    /// also sets the caustic perturbation's angular range (`caustic::CausticKernel::from_lens`).
    /// Unset (the default): Veach's range for the film, r_1 = 0.1 px and r_2 the radius of a disc
    /// of 5% of the image (`RasterKernel::veach`). Both set: that range, 0 < r_1 < r_2, for
    /// instance the portal paper's Fig. 4 configuration, which ran the lens and portal kernels
    /// over the same relative range.
    pub lens_r1: Option<f64>,
    pub lens_r2: Option<f64>,
}

impl Default for PmltSettings {
    fn default() -> Self {
        PmltSettings {
            max_depth: 8,
            bootstrap: 100_000,
            chains: 1000,
            mis: MisHeuristic::Balance,
            bidirectional: 1.0,
            lens: 2.0,
            caustic: 2.0,
            multi_chain: 2.0,
            portal: 2.0,
            lens_r1: None,
            lens_r2: None,
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
                "bidirectional = {}: expected a positive weight (it makes the chain ergodic)",
                settings.bidirectional
            ));
        }
        for (name, w) in [
            ("lens", settings.lens),
            ("caustic", settings.caustic),
            ("multi_chain", settings.multi_chain),
            ("portal", settings.portal),
        ] {
            if !(w >= 0.0 && w.is_finite()) {
                return bad(format!("{name} = {w}: expected a weight >= 0 (0 turns the perturbation off)"));
            }
        }
        match (settings.lens_r1, settings.lens_r2) {
            (None, None) => {}
            (Some(r1), Some(r2)) if r1 > 0.0 && r1 < r2 && r2.is_finite() => {}
            (r1, r2) => {
                let show = |r: Option<f64>| r.map_or("unset".to_string(), |r| r.to_string());
                return bad(format!(
                    "lens_r1 = {}, lens_r2 = {}: expected both unset (Veach's range) or 0 < lens_r1 < lens_r2, \
                     finite, in pixels",
                    show(r1),
                    show(r2)
                ));
            }
        }
        Ok(settings)
    }

    /// The lens perturbation's kernel for a `width` × `height` film: the set range, else Veach's.
    pub fn lens_kernel(&self, width: u32, height: u32) -> RasterKernel {
        match (self.lens_r1, self.lens_r2) {
            (Some(r1), Some(r2)) => RasterKernel { r1, r2 },
            _ => RasterKernel::veach(width, height),
        }
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
            ("lens = -1.0", "lens"),
            ("caustic = nan", "caustic"),
            ("multi_chain = inf", "multi_chain"),
            ("portal = -1.0", "portal"),
            ("large_step_probability = 0.3", "large_step_probability"),
            ("lens_r1 = 0.5", "lens_r2"),
            ("lens_r2 = 4.0", "lens_r1"),
            ("lens_r1 = 4.0\nlens_r2 = 0.5", "lens_r1"),
            ("lens_r1 = 0.0\nlens_r2 = 0.5", "lens_r1"),
            ("lens_r1 = 0.5\nlens_r2 = inf", "lens_r2"),
        ] {
            let t: toml::Table = toml::from_str(bad).expect("toml");
            let err = PmltSettings::from_params(&t).err().unwrap_or_else(|| panic!("{bad} accepted")).to_string();
            assert!(err.contains(needle), "{bad}: {err}");
        }
    }

    /// The lens kernel's range: Veach's for the film when unset, the setting's when set.
    #[test]
    fn lens_kernel_range() {
        let s = PmltSettings::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(s.lens_kernel(64, 48), RasterKernel::veach(64, 48));
        let t: toml::Table = toml::from_str("lens_r1 = 0.25\nlens_r2 = 4.0").expect("toml");
        let s = PmltSettings::from_params(&t).expect("a range");
        assert_eq!(s.lens_kernel(64, 48), RasterKernel { r1: 0.25, r2: 4.0 });
    }
}
