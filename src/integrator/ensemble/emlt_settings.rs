//! Settings of `integrator = "emlt"`: the `[integrator]` table's keys, their defaults (the paper's,
//! Sec. 3.4 and 4) and their validation.

use serde::{Deserialize, Serialize};

use super::directional::KAPPA_MAX;
use crate::integrator::bdpt::MisHeuristic;
use crate::integrator::pss::mlt_settings::{MAX_BOOTSTRAP, MAX_CHAINS, MAX_DEPTH};
use crate::integrator::{settings_from_table, RenderError};

/// Which guided kernel the environment perturbation uses (`environment`'s module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EnvironmentKernel {
    #[default]
    Directional,
    Hemispherical,
}

/// Settings of ensemble MLT.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EmltSettings {
    /// Maximum number of scattering events of a path (vertices − 2), as for the other MLTs (8).
    pub max_depth: u32,
    /// BDPT samples of the bootstrap that estimates b and from which both ensembles are resampled
    /// (100,000, as pmlt's).
    pub bootstrap: u64,
    /// Paths in each of the ensembles X and Y (16,384, the paper's Sec. 3.4).
    pub ensemble_size: u64,
    /// K, the independent X/Y ensemble pairs of the render (1): pair k's chains have their own
    /// streams, and its film is its own layer, so a render sharded by pairs (`--shard k/K`)
    /// merges into exactly the K-pair render. The image is the pairs' mean.
    pub pairs: u64,
    /// M, the size of the subset Υ of the complementary ensemble a guided perturbation draws its
    /// guide from (32; `tree` module docs say why: the paper leaves it to its supplement).
    pub subset_size: u32,
    /// MIS heuristic of the bootstrap's BDPT weights.
    pub mis: MisHeuristic,
    /// Selection weight of the bidirectional mutation (1: with the perturbations' 2 shared among
    /// those suitable, it is chosen 1/3 of the time, the paper's Sec. 4).
    pub bidirectional: f64,
    /// Selection weights of the linear guided perturbations (2 each, 0 turns one off).
    pub linear_lens: f64,
    pub linear_caustic: f64,
    pub linear_multi_chain: f64,
    /// α of the linear kernels when Υ is clustered on the film (α_l = 0.5, Sec. 3.4).
    pub alpha_large: f64,
    /// α when Υ is spread over the film (α_s = 0.05).
    pub alpha_small: f64,
    /// c and σ² of the sigmoid weight w_α = 1/(1 + exp(−(b_res − c)/σ²)) (0.1 and 0.02).
    pub alpha_c: f64,
    pub alpha_sigma2: f64,
    /// Selection weight of the anisotropic path perturbation (2; 0 turns it off).
    pub anisotropic_path: f64,
    /// Selection weight of the environment perturbation (2; suitable only for paths that end at
    /// the environment).
    pub environment: f64,
    /// The environment perturbation's kernel: "directional" (vMF, default) or "hemispherical"
    /// (the great arc about a guide).
    pub environment_kernel: EnvironmentKernel,
    /// κ of the von Mises–Fisher fallback of degenerate fits (1e4: about 0.01 rad; the paper says
    /// only "a high concentration").
    pub fallback_concentration: f64,
    /// Which guided perturbations run, for the paper's ablation (Table 1): "linear" (the default:
    /// linear lens, caustic and multi-chain, part 1 of the method, whose agreement with the path
    /// tracer tests/chains/emlt.rs shows on the Cornell, glossy and glass boxes), "all" (the linear ones,
    /// the anisotropic path and the environment perturbation: agreement shown on the three boxes
    /// and the environment scene, tests/chains/emlt_part2.rs) or "anisotropic" (the
    /// anisotropic path perturbation only); the bidirectional mutation always.
    pub perturbations: Perturbations,
}

/// The ablation switch of `EmltSettings::perturbations`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Perturbations {
    All,
    #[default]
    Linear,
    Anisotropic,
}

impl Default for EmltSettings {
    fn default() -> Self {
        EmltSettings {
            max_depth: 8,
            bootstrap: 100_000,
            ensemble_size: 16_384,
            pairs: 1,
            subset_size: 32,
            mis: MisHeuristic::Balance,
            bidirectional: 1.0,
            linear_lens: 2.0,
            linear_caustic: 2.0,
            linear_multi_chain: 2.0,
            alpha_large: 0.5,
            alpha_small: 0.05,
            alpha_c: 0.1,
            alpha_sigma2: 0.02,
            anisotropic_path: 2.0,
            environment: 2.0,
            environment_kernel: EnvironmentKernel::Directional,
            fallback_concentration: 1e4,
            perturbations: Perturbations::Linear,
        }
    }
}

impl EmltSettings {
    /// The settings from an `[integrator]` table, validated: every refusal names the setting and
    /// its valid range.
    pub fn from_params(params: &toml::Table) -> Result<EmltSettings, RenderError> {
        let s: EmltSettings = settings_from_table("emlt", params)?;
        let bad = |m: String| Err(RenderError::Settings(format!("emlt: {m}")));
        if !(1..=MAX_DEPTH).contains(&s.max_depth) {
            return bad(format!("max_depth = {}: expected 1 ..= {MAX_DEPTH}", s.max_depth));
        }
        if !(1..=MAX_BOOTSTRAP).contains(&s.bootstrap) {
            return bad(format!("bootstrap = {}: expected 1 ..= {MAX_BOOTSTRAP} (2^32) paths", s.bootstrap));
        }
        if !(1..=MAX_CHAINS / 2).contains(&s.ensemble_size) {
            return bad(format!("ensemble_size = {}: expected 1 ..= {} (2^23)", s.ensemble_size, MAX_CHAINS / 2));
        }
        // Every pair's 2·|X| chains are chains of the render: together at most `MAX_CHAINS`.
        if !(1..=MAX_CHAINS / (2 * s.ensemble_size)).contains(&s.pairs) {
            return bad(format!(
                "pairs = {}: expected 1 ..= {} (2 × ensemble_size × pairs chains at most 2^24)",
                s.pairs,
                MAX_CHAINS / (2 * s.ensemble_size)
            ));
        }
        if !(2..=4096).contains(&s.subset_size) {
            return bad(format!("subset_size = {}: expected 2 ..= 4096", s.subset_size));
        }
        if s.mis == MisHeuristic::None {
            return bad("mis must be \"balance\" or \"power\"".to_string());
        }
        if !(s.bidirectional > 0.0 && s.bidirectional.is_finite()) {
            return bad(format!(
                "bidirectional = {}: expected a positive weight (it makes the chains ergodic)",
                s.bidirectional
            ));
        }
        for (name, w) in [
            ("linear_lens", s.linear_lens),
            ("linear_caustic", s.linear_caustic),
            ("linear_multi_chain", s.linear_multi_chain),
            ("anisotropic_path", s.anisotropic_path),
            ("environment", s.environment),
        ] {
            if !(w >= 0.0 && w.is_finite()) {
                return bad(format!("{name} = {w}: expected a weight >= 0 (0 turns the perturbation off)"));
            }
        }
        for (name, a) in [("alpha_large", s.alpha_large), ("alpha_small", s.alpha_small)] {
            if !(a > 0.0 && a <= 100.0) {
                return bad(format!("{name} = {a}: expected 0 < α <= 100 (λ in [1/(1+α), 1+α])"));
            }
        }
        if !(0.0..=1.0).contains(&s.alpha_c) {
            return bad(format!("alpha_c = {}: expected 0 ..= 1 (a share of the film)", s.alpha_c));
        }
        if !(s.alpha_sigma2 > 0.0 && s.alpha_sigma2.is_finite()) {
            return bad(format!("alpha_sigma2 = {}: expected a positive number", s.alpha_sigma2));
        }
        if !(s.fallback_concentration > 0.0 && s.fallback_concentration <= KAPPA_MAX) {
            return bad(format!(
                "fallback_concentration = {}: expected 0 < κ <= {KAPPA_MAX:e}",
                s.fallback_concentration
            ));
        }
        Ok(s)
    }

    /// The selection weights of (linear lens, linear caustic, linear multi-chain, anisotropic path,
    /// environment) after the ablation switch `perturbations`.
    pub fn guided_weights(&self) -> [f64; 5] {
        let (linear, anisotropic, all) = match self.perturbations {
            Perturbations::All => (1.0, 1.0, 1.0),
            Perturbations::Linear => (1.0, 0.0, 0.0),
            Perturbations::Anisotropic => (0.0, 1.0, 0.0),
        };
        [
            self.linear_lens * linear,
            self.linear_caustic * linear,
            self.linear_multi_chain * linear,
            self.anisotropic_path * anisotropic,
            self.environment * all,
        ]
    }

    /// α of the linear kernels for a subset Υ spread over `b_res` of the film (Sec. 3.4): the
    /// sigmoid weight w_α = 1/(1 + exp(−(b_res − c)/σ²)) moves α from α_l (Υ clustered: explore
    /// a small region with large stretches) to α_s (Υ spread: small stretches).
    pub fn alpha(&self, b_res: f64) -> f64 {
        let w = 1.0 / (1.0 + (-(b_res - self.alpha_c) / self.alpha_sigma2).exp());
        (1.0 - w) * self.alpha_large + w * self.alpha_small
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_refusals_and_alpha() {
        let s = EmltSettings::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(s, EmltSettings::default());
        for (bad, needle) in [
            ("ensemble_size = 0", "ensemble_size"),
            ("pairs = 0", "pairs"),
            ("ensemble_size = 8388608\npairs = 2", "pairs"),
            ("subset_size = 1", "subset_size"),
            ("bidirectional = 0.0", "bidirectional"),
            ("linear_lens = -1.0", "linear_lens"),
            ("alpha_small = 0.0", "alpha_small"),
            ("alpha_c = 2.0", "alpha_c"),
            ("anisotropic_path = -2.0", "anisotropic_path"),
            ("fallback_concentration = 0.0", "fallback_concentration"),
            ("perturbations = \"some\"", "perturbations"),
            ("environment_kernel = \"cone\"", "environment_kernel"),
            ("chains = 5", "chains"),
        ] {
            let t: toml::Table = toml::from_str(bad).expect("toml");
            let err = EmltSettings::from_params(&t).err().unwrap_or_else(|| panic!("{bad} accepted")).to_string();
            assert!(err.contains(needle), "{bad}: {err}");
        }
        // Clustered Υ: α_l; spread Υ: α_s; at b_res = c halfway.
        assert!((s.alpha(0.0) - 0.5).abs() < 1e-2);
        assert!((s.alpha(1.0) - 0.05).abs() < 1e-12);
        assert!((s.alpha(0.1) - 0.275).abs() < 1e-12);
    }
}
