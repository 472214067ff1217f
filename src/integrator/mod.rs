//! Light-transport algorithms. Each integrator is a settings struct (serde, defaults from the
//! papers), a per-thread kernel and a driver; all of them render a `Scene` into an `Image` and
//! report `Counters`. None of them knows which accelerator answers its rays.

use std::time::Duration;

use serde::Serialize;
use thiserror::Error;

use crate::film::Image;
use crate::scene::Scene;
use crate::stats::Counters;

/// How much work a render may do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Budget {
    /// Samples per pixel (path tracer, BDPT, light tracing) — or, for MCMC integrators, the
    /// number of mutations per pixel.
    SamplesPerPixel(u64),
    /// Wall-clock seconds.
    Seconds(f64),
}

/// Everything about a render that is not the scene: budget, seed, threads.
#[derive(Clone, Debug, Serialize)]
pub struct RenderJob {
    pub budget: Budget,
    pub seed: u64,
    /// Number of worker threads (the result is bit-identical for the same seed and thread count).
    pub threads: usize,
}

/// Reports progress of long work (a progress bar in the CLI, nothing in tests).
pub trait Progress: Sync {
    /// Total units of work, when known in advance (sample budgets).
    fn set_total(&self, total: u64);
    /// `units` more units are done.
    fn advance(&self, units: u64);
    /// A short status line (e.g. an MCMC acceptance rate).
    fn message(&self, msg: &str);
}

/// A `Progress` that ignores everything.
pub struct NoProgress;

impl Progress for NoProgress {
    fn set_total(&self, _: u64) {}
    fn advance(&self, _: u64) {}
    fn message(&self, _: &str) {}
}

/// What a render produced: the image, extra named layers (per-technique images, sample counts),
/// counters, the wall time, and integrator-specific statistics for the JSON report.
#[derive(Debug)]
pub struct RenderOutput {
    pub image: Image,
    pub layers: Vec<(String, Image)>,
    pub counters: Counters,
    pub wall_time: Duration,
    pub extra_stats: serde_json::Value,
}

/// Why a render could not run.
#[derive(Debug, Error)]
pub enum RenderError {
    #[error("invalid integrator setting: {0}")]
    Settings(String),
    #[error("could not create the thread pool: {0}")]
    ThreadPool(String),
}

/// A light-transport algorithm, configured and ready to render any scene.
pub trait Integrator: Send + Sync {
    /// The name users select it by (`integrator = "pt"`).
    fn name(&self) -> &'static str;
    /// The settings in effect, for the stats report.
    fn settings_json(&self) -> serde_json::Value;
    fn render(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<RenderOutput, RenderError>;
}
