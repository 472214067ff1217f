//! Settings of the Markov chain integrators (`pssmlt`, `mmlt`, `rjmlt`): which method, the
//! `[integrator]` table's keys with the papers' defaults, and their validation.

use serde::{Deserialize, Serialize};

use super::sampler::SmallStep;
use crate::integrator::bdpt::MisHeuristic;
use crate::integrator::{settings_from_table, RenderError};
use crate::sampling::SamplerKind;

/// Which of the three methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MltVariant {
    Pssmlt,
    Mmlt,
    Rjmlt,
}

impl MltVariant {
    pub fn name(self) -> &'static str {
        match self {
            MltVariant::Pssmlt => "pssmlt",
            MltVariant::Mmlt => "mmlt",
            MltVariant::Rjmlt => "rjmlt",
        }
    }
}

/// RJMLT's default probability of a large step (Bitterli et al. 2017, Sec. 7: 10% large steps,
/// 85% small steps, 5% technique jumps).
pub const RJMLT_LARGE_STEP_PROBABILITY: f64 = 0.1;
/// RJMLT's default probability of a technique jump.
pub const RJMLT_JUMP_PROBABILITY: f64 = 0.05;

/// The longest path, in scattering events: 1024. MMLT and RJMLT keep a sub-chain, a b_d and a film
/// layer per depth (`integrator::memory_estimate`), so the depth multiplies the render's memory
/// (`max_depth = 100000` aborted on allocation); and past 1024 bounces even an albedo of 0.99
/// leaves 0.99^1024 ≈ 3·10^-5 of a path's throughput, below what the image can show.
pub const MAX_DEPTH: u32 = 1024;
/// The most bootstrap paths per depth: 2^32. They are all held (target and CDF entry, 12 bytes;
/// 48 GiB per depth at the bound) to start the chains from, and the discrete distribution indexes
/// them with u32-range indices on every platform.
pub const MAX_BOOTSTRAP: u64 = 1 << 32;
/// The most chains: 2^24. Each holds a sub-chain per depth (sampler and current path) for the whole
/// render, and per-chain pooled statistics are kept twice; 2^24 is already thousands of chains per
/// pixel of a 4K film, while `chains = 10^12` aborted on allocation.
pub const MAX_CHAINS: u64 = 1 << 24;

/// Settings of `integrator = "pssmlt"` and `"mmlt"` (defaults: the MMLT paper, Sec. 5).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MltSettings {
    /// Maximum number of scattering events of a path (the paper's L = 8).
    pub max_depth: u32,
    /// Bootstrap samples used to estimate b_d (the paper's N; 100,000). PSSMLT: uniform samples of
    /// its state. MMLT and RJMLT: full BDPT samples, each giving every depth's b_d an estimate
    /// (`pss::mlt::bootstrap_sample`), so N per depth for all depths at once.
    pub bootstrap: u64,
    /// The numbers of the bootstrap's samples: "sobol" (default: one Owen-scrambled Sobol sequence
    /// over the film, lower b_d error at equal samples) or "independent". The chains' large steps
    /// are independent proposals either way.
    pub bootstrap_sampler: SamplerKind,
    /// Number of independent chains (each holds one sub-chain per depth for MMLT).
    pub chains: u64,
    /// Probability of a large step (Kelemen's p_large; 0.3; RJMLT 0.1).
    pub large_step_probability: f64,
    /// RJMLT only: probability of a technique jump (0.05; the rest are small steps).
    pub jump_probability: f64,
    /// The small-step kernel: "gaussian" (width `sigma`) or "exponential" (Kelemen et al. 2002,
    /// |Δ| log-uniform between `small_step_min` and `small_step_max`; see `SmallStep`). Default
    /// "gaussian": see `DEFAULT_SMALL_STEP` for the measurement.
    pub small_step: SmallStepKind,
    /// Gaussian small-step standard deviation in primary sample space (0.01).
    pub sigma: f64,
    /// Exponential small steps: Kelemen's s1 and s2, the smallest and largest |Δ| (the MMLT
    /// paper's 1/1024 and 1/64).
    pub small_step_min: f64,
    pub small_step_max: f64,
    /// Refine b_d with every large step during the render (large steps are uniform samples, so
    /// they are extra bootstrap samples for free), pooled with the bootstrap's estimate by inverse
    /// variance (`mlt::depth_choice::BEstimate`). On by default: the paper notes it is more robust
    /// than the one-off bootstrap, and it costs nothing.
    pub progressive_b: bool,
    /// MIS heuristic of the technique weights: "balance" (default) or "power".
    pub mis: MisHeuristic,
    /// Russian roulette on subpaths after this many bounces (disabled by default: MCMC prefers a
    /// deterministic path length per state).
    pub rr_depth: u32,
    /// MMLT only: write, per technique (s, t), an image of how many iterations that technique was
    /// the chain's state at each pixel (the paper's Fig. 5) as extra layers.
    pub technique_count_layers: bool,
}

impl MltSettings {
    /// The settings of `variant` from its `[integrator]` table, with RJMLT's own defaults for the
    /// step probabilities, validated: every refusal names the setting and the valid range.
    pub fn from_params(variant: MltVariant, params: &toml::Table) -> Result<MltSettings, RenderError> {
        let name = variant.name();
        let mut settings: MltSettings = settings_from_table(name, params)?;
        let bad = |m: &str| Err(RenderError::Settings(format!("{name}: {m}")));
        if variant == MltVariant::Rjmlt {
            if !params.contains_key("large_step_probability") {
                settings.large_step_probability = RJMLT_LARGE_STEP_PROBABILITY;
            }
            if !params.contains_key("jump_probability") {
                settings.jump_probability = RJMLT_JUMP_PROBABILITY;
            }
            if settings.rr_depth != u32::MAX {
                // The roulette number lies in an interval that depends on the path's throughput;
                // the inverse walk treats it as unused.
                return bad("rr_depth is not supported: the technique jumps invert paths without Russian roulette");
            }
        } else if params.contains_key("jump_probability") {
            return bad("jump_probability applies only to rjmlt (technique jumps need inverse sampling)");
        }
        if !(0.0..=1.0).contains(&settings.jump_probability)
            || settings.large_step_probability + settings.jump_probability > 1.0
        {
            return bad("jump_probability must be in [0, 1] and large_step_probability + jump_probability at most 1");
        }
        if !(1..=MAX_DEPTH).contains(&settings.max_depth) {
            return bad(&format!("max_depth = {}: expected 1 ..= {MAX_DEPTH}", settings.max_depth));
        }
        if !(1..=MAX_BOOTSTRAP).contains(&settings.bootstrap) {
            return bad(&format!(
                "bootstrap = {}: expected 1 ..= {MAX_BOOTSTRAP} (2^32) paths per depth",
                settings.bootstrap
            ));
        }
        if !(1..=MAX_CHAINS).contains(&settings.chains) {
            return bad(&format!("chains = {}: expected 1 ..= {MAX_CHAINS} (2^24)", settings.chains));
        }
        if !(0.0..=1.0).contains(&settings.large_step_probability) {
            return bad("large_step_probability must be in [0, 1]");
        }
        if !(settings.sigma > 0.0 && settings.sigma.is_finite()) {
            return bad("sigma must be a positive number");
        }
        if !(settings.small_step_min > 0.0
            && settings.small_step_min < settings.small_step_max
            && settings.small_step_max <= 0.5)
        {
            return bad("small_step_min and small_step_max must satisfy 0 < small_step_min < small_step_max <= 0.5");
        }
        if settings.mis == MisHeuristic::None {
            return bad("mis must be \"balance\" or \"power\"");
        }
        Ok(settings)
    }
}

/// Which small-step kernel (`MltSettings::small_step`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SmallStepKind {
    Gaussian,
    Exponential,
}

/// The default small step stays the Gaussian (σ = 0.01): at equal time the exponential kernel
/// (1/1024, 1/64) measured no better. MMLT, `plexus converge`, 2 threads, max_depth 8, the two
/// kernels interleaved per seed (the machine was shared, so mutation counts varied by up to 1.4×
/// between runs): cornell-glossy at 128×128, 6 s, seeds 300–302, relMSE Gaussian 2.12e-2,
/// 2.02e-2, 2.80e-2 (mean 2.31e-2) vs exponential 1.78e-2, 2.59e-2, 3.29e-2 (mean 2.55e-2);
/// veach-ajar, 8 s, seeds 200–202, Gaussian 0.517, 0.373, 0.633 (mean 0.508) vs exponential
/// 0.507, 0.488, 0.570 (mean 0.522). The differences are within the seed-to-seed spread, the
/// Gaussian's lazy update is O(1) per stale coordinate where the exponential's is O(pending
/// steps), and the tests and benchmarks are calibrated on it.
pub const DEFAULT_SMALL_STEP: SmallStepKind = SmallStepKind::Gaussian;

impl MltSettings {
    /// The small-step kernel with its parameters.
    pub fn small_step(&self) -> SmallStep {
        match self.small_step {
            SmallStepKind::Gaussian => SmallStep::Gaussian { sigma: self.sigma },
            SmallStepKind::Exponential => SmallStep::Exponential { s1: self.small_step_min, s2: self.small_step_max },
        }
    }
}

impl Default for MltSettings {
    fn default() -> Self {
        MltSettings {
            max_depth: 8,
            bootstrap: 100_000,
            bootstrap_sampler: SamplerKind::Sobol,
            chains: 1000,
            large_step_probability: 0.3,
            jump_probability: 0.0,
            small_step: DEFAULT_SMALL_STEP,
            sigma: 0.01,
            small_step_min: 1.0 / 1024.0,
            small_step_max: 1.0 / 64.0,
            progressive_b: true,
            mis: MisHeuristic::Balance,
            rr_depth: u32::MAX,
            technique_count_layers: false,
        }
    }
}
