//! What a render cost and what it did: counters every integrator reports, serialised next to the
//! image as JSON.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// Proposals and acceptances of one mutation strategy (or one path length, or one technique).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct AcceptanceCount {
    pub proposed: u64,
    pub accepted: f64,
}

impl AcceptanceCount {
    pub fn rate(&self) -> f64 {
        if self.proposed == 0 {
            0.0
        } else {
            self.accepted / self.proposed as f64
        }
    }
    pub fn merge(&mut self, o: &AcceptanceCount) {
        self.proposed += o.proposed;
        self.accepted += o.accepted;
    }
}

/// Counters one worker accumulates without synchronisation; merged at the end of a render.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Counters {
    /// Closest-hit queries.
    pub rays: u64,
    /// Occlusion (shadow) queries.
    pub shadow_rays: u64,
    /// Camera samples (path tracer, BDPT) or Markov chain iterations (MCMC).
    pub samples: u64,
    /// Contributions dropped because they were NaN or infinite.
    pub nonfinite_dropped: u64,
    /// Per-strategy acceptance (MCMC); keys are strategy names.
    pub strategies: BTreeMap<String, AcceptanceCount>,
    /// Set by a path-space strategy whose `propose` rejects early, to name the cause (a `'static`
    /// label); the chain's step takes it into that strategy's `early_rejections`. Never saved or
    /// merged: it lives between one `propose` and its step.
    #[serde(skip)]
    pub early_rejection: Option<&'static str>,
}

impl Counters {
    pub fn merge(&mut self, o: &Counters) {
        self.rays += o.rays;
        self.shadow_rays += o.shadow_rays;
        self.samples += o.samples;
        self.nonfinite_dropped += o.nonfinite_dropped;
        for (k, v) in &o.strategies {
            self.strategies.entry(k.clone()).or_default().merge(v);
        }
    }
    pub fn total_rays(&self) -> u64 {
        self.rays + self.shadow_rays
    }
}
