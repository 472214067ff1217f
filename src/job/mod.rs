//! What a render is asked to do and how it reports back, below every part that renders: the
//! budget and the job (`Budget`, `RenderJob`), the limits a job is checked against before any work
//! (`MAX_SECONDS`, `MAX_THREADS`, `MAX_TOTAL_SAMPLES`, [`check_budget`], [`check_threads`]), the
//! memory the process holds and may use ([`memory`]), what can stop a run ([`RunControl`]), how
//! it reports progress ([`Progress`]) and what it produced ([`RenderOutput`]).
//!
//! It sits below `scene`, `state` and `integrator` so that imports run one way: the scene loader
//! checks its `[render]` table against the same limits, a state file records a `Budget`, and the
//! integrators render a `RenderJob` under a `state::Session`, without any of them naming a layer
//! above it. It names only `film` and `stats` (an output's image and counters).

pub mod memory;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::film::Image;
use crate::stats::Counters;

/// How much work a render may do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
    /// Number of worker threads. The film (and so the image) depends on the seed and the work
    /// units only, not on the thread count (`integrator::driver`'s render model: splats are applied
    /// in unit order): tiles for pt, BDPT and light tracing, chains for the Markov chain methods.
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
    /// Seconds between preview images during a render (`plexus render --preview-every`); `None`
    /// (the default) for no previews, which then cost nothing.
    fn preview_interval(&self) -> Option<f64> {
        None
    }
    /// Receives the render's current normalised image, between passes, at most every
    /// `preview_interval` seconds.
    fn preview(&self, _image: &Image) {}
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

/// What can end a run before its budget, and how often it offers checkpoints: both only at pass
/// boundaries (`integrator::driver`), so what is saved is a state the render model can resume from.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunControl<'a> {
    /// Set (by a signal handler) to stop at the next pass boundary.
    pub stop: Option<&'a AtomicBool>,
    /// Stop when the schedule reaches this pass (`passes_done` ≥ it): a deterministic stand-in for
    /// a signal, for tests of interrupt and resume.
    pub stop_at_pass: Option<u64>,
    /// Offer a checkpoint at a pass boundary once at least this long has passed since the run
    /// started or the last one.
    pub checkpoint_every: Option<Duration>,
}

impl RunControl<'_> {
    /// Whether a run that has completed `passes_done` passes should stop now.
    pub fn stop_requested(&self, passes_done: u64) -> bool {
        self.stop.is_some_and(|f| f.load(Ordering::SeqCst)) || self.stop_at_pass.is_some_and(|n| passes_done >= n)
    }
}

/// A budget, count or memory need beyond what a render can do; the message names the option, the
/// value and the bound. (`integrator::RenderError::Limit` carries it on.)
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{0}")]
pub struct LimitError(pub String);

/// The longest time budget: 30 days. Longer is a typo or a hang (`--time 1e20` once panicked in
/// `Duration::from_secs_f64`); a render that long would be checkpointed and resumed instead.
pub const MAX_SECONDS: f64 = 30.0 * 86_400.0;

/// The largest total sample budget, samples per pixel × pixels (mutations for MCMC): 2^53. Up to
/// there every count is exact in the f64 the normalisation and the JSON report use, and the u64
/// counters (samples, rays ≈ a few per sample) cannot overflow; at the 10^7–10^8 samples per second
/// this machine class does, 2^53 is already years of rendering, so the bound refuses only typos.
pub const MAX_TOTAL_SAMPLES: u64 = 1 << 53;

/// The most worker threads: 1024. Each thread is a worker slot with its own counters and scratch
/// state (MLT: a slot state per thread), and a pass waits for every slot, so far more threads than
/// cores only costs memory and start-up (`--threads 2000` never finished). Refused rather than
/// clamped: for MLT the image depends on the thread count, so a silent clamp would render another
/// image than the one asked for.
pub const MAX_THREADS: usize = 1024;

/// Checks a budget against the limits before any work: a time budget positive, finite and at most
/// `MAX_SECONDS`; a sample budget at least 1 and, times the film's pixels, at most
/// `MAX_TOTAL_SAMPLES`. `option` names where the budget came from (`--spp`, `render.spp`) for the
/// message.
pub fn check_budget(budget: Budget, width: u32, height: u32, option: &str) -> Result<(), LimitError> {
    match budget {
        Budget::Seconds(s) => {
            if !(s.is_finite() && s > 0.0 && s <= MAX_SECONDS) {
                return Err(LimitError(format!(
                    "{option} {s:?}: expected a number of seconds in (0, {MAX_SECONDS}] (30 days)"
                )));
            }
        }
        Budget::SamplesPerPixel(n) => {
            let pixels = width as u64 * height as u64;
            let total = n.checked_mul(pixels).filter(|&t| (1..=MAX_TOTAL_SAMPLES).contains(&t));
            if n == 0 || total.is_none() {
                return Err(LimitError(format!(
                    "{option} {n}: expected 1 ..= {} for a {width}x{height} film (total samples at most 2^53)",
                    (MAX_TOTAL_SAMPLES / pixels.max(1)).max(1)
                )));
            }
        }
    }
    Ok(())
}

/// Checks a thread count (`option` names its source) against `MAX_THREADS`.
pub fn check_threads(threads: usize, option: &str) -> Result<(), LimitError> {
    if !(1..=MAX_THREADS).contains(&threads) {
        return Err(LimitError(format!("{option} {threads}: expected 1 ..= {MAX_THREADS} threads")));
    }
    Ok(())
}
