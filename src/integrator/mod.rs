//! Light-transport algorithms. Each integrator is a settings struct (serde, defaults from the
//! papers), a per-thread kernel and a driver; all of them render a `Scene` into an `Image` and
//! report `Counters`. None of them knows which accelerator answers its rays.

pub mod bdpt;
pub mod driver;
pub mod ensemble;
pub mod light_tracing;
pub mod memory;
pub mod path_space;
pub mod pss;
pub mod pt;

use std::time::Duration;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::film::Image;
use crate::scene::Scene;
use crate::state::{RenderState, Session, SessionOutput, StateError};
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
    /// Number of worker threads. The same seed and thread count give a bit-identical result; for
    /// pt, BDPT and light tracing the film (and so the image) is the same for any thread count
    /// (`driver`'s render model), MLT's not yet (its films are still per-thread state).
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

/// Why a render could not run.
#[derive(Debug, Error)]
pub enum RenderError {
    #[error("invalid integrator setting: {0}")]
    Settings(String),
    #[error("could not create the thread pool: {0}")]
    ThreadPool(String),
    #[error("a {width}×{height} film has more than 2^32 pixels, more than a render can address")]
    FilmTooLarge { width: u32, height: u32 },
    #[error("unknown integrator '{0}': expected one of {names}", names = INTEGRATOR_NAMES.join(", "))]
    UnknownIntegrator(String),
    /// A budget, count or memory need beyond what a render can do (`check_budget`, `memory`).
    #[error("{0}")]
    Limit(String),
    /// A checkpoint, resume, shard or merge asked of an integrator that cannot do it, or a state
    /// that does not fit the render.
    #[error(transparent)]
    State(#[from] StateError),
}

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
pub fn check_budget(budget: Budget, width: u32, height: u32, option: &str) -> Result<(), RenderError> {
    match budget {
        Budget::Seconds(s) => {
            if !(s.is_finite() && s > 0.0 && s <= MAX_SECONDS) {
                return Err(RenderError::Limit(format!(
                    "{option} {s:?}: expected a number of seconds in (0, {MAX_SECONDS}] (30 days)"
                )));
            }
        }
        Budget::SamplesPerPixel(n) => {
            let pixels = width as u64 * height as u64;
            let total = n.checked_mul(pixels).filter(|&t| (1..=MAX_TOTAL_SAMPLES).contains(&t));
            if n == 0 || total.is_none() {
                return Err(RenderError::Limit(format!(
                    "{option} {n}: expected 1 ..= {} for a {width}x{height} film (total samples at most 2^53)",
                    (MAX_TOTAL_SAMPLES / pixels.max(1)).max(1)
                )));
            }
        }
    }
    Ok(())
}

/// Checks a thread count (`option` names its source) against `MAX_THREADS`.
pub fn check_threads(threads: usize, option: &str) -> Result<(), RenderError> {
    if !(1..=MAX_THREADS).contains(&threads) {
        return Err(RenderError::Limit(format!("{option} {threads}: expected 1 ..= {MAX_THREADS} threads")));
    }
    Ok(())
}

/// A light-transport algorithm, configured and ready to render any scene.
pub trait Integrator: Send + Sync {
    /// The name users select it by (`integrator = "pt"`).
    fn name(&self) -> &'static str;
    /// The settings in effect, for the stats report.
    fn settings_json(&self) -> serde_json::Value;

    /// The one render an integrator implements: under `session` (resumed from a
    /// state, as a shard, stopped early, checkpointed), returning the image of everything rendered
    /// and, with `save`, the state reached (`crate::state`). `render` and `render_session` are
    /// this. An integrator that cannot save its units overrides `render` instead and keeps this
    /// default, which refuses.
    fn run_session(
        &self,
        _scene: &Scene,
        _job: &RenderJob,
        _progress: &dyn Progress,
        _session: &Session,
        _save: bool,
    ) -> Result<(RenderOutput, Option<RenderState>), RenderError> {
        Err(self.no_state())
    }

    /// A whole render from the start: `run_session` without a session or a state.
    fn render(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<RenderOutput, RenderError> {
        Ok(self.run_session(scene, job, progress, &Session::default(), false)?.0)
    }

    /// The render under a `Session`, with the state it reached: `run_session` with `save`.
    fn render_session(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
    ) -> Result<SessionOutput, RenderError> {
        let (output, state) = self.run_session(scene, job, progress, session, true)?;
        Ok(SessionOutput { output, state: state.ok_or_else(|| self.no_state())? })
    }

    /// The normalised image, counters and statistics of a state (a resumed render that had
    /// nothing left to do, or merged shards).
    fn output_of_state(&self, _state: &RenderState) -> Result<RenderOutput, RenderError> {
        Err(self.no_state())
    }

    /// Merges the integrator's parts of the states of a render's shards, in shard order.
    fn merge_parts(&self, _parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        Err(self.no_state())
    }

    /// Whether `run_session` is implemented (checkpoints, interrupts with a saved state, resume,
    /// shards). An integrator without it renders only through `render`; the CLI then refuses
    /// the session options with `no_state`'s message.
    fn supports_sessions(&self) -> bool {
        true
    }

    /// The error of the defaults above.
    fn no_state(&self) -> RenderError {
        RenderError::State(StateError::Mismatch(format!(
            "the {} integrator cannot be interrupted and resumed, checkpointed or sharded yet",
            self.name()
        )))
    }
}

/// The names `create` accepts, in the order `plexus render --help` lists them.
pub const INTEGRATOR_NAMES: &[&str] = &["pt", "bdpt", "light", "pssmlt", "mmlt", "rjmlt", "pmlt", "emlt"];

/// The integrator called `name`, configured from `params` (the scene's `[integrator]` table merged
/// with `--set` overrides; unknown keys are errors).
pub fn create(name: &str, params: &toml::Table) -> Result<Box<dyn Integrator>, RenderError> {
    match name {
        "pt" => Ok(Box::new(pt::PathTracer::from_params(params)?)),
        "bdpt" => Ok(Box::new(bdpt::Bdpt::from_params(params)?)),
        "light" => Ok(Box::new(light_tracing::LightTracer::from_params(params)?)),
        "pssmlt" => Ok(Box::new(pss::mlt::Mlt::from_params(pss::settings::MltVariant::Pssmlt, params)?)),
        "mmlt" => Ok(Box::new(pss::mlt::Mlt::from_params(pss::settings::MltVariant::Mmlt, params)?)),
        "rjmlt" => Ok(Box::new(pss::mlt::Mlt::from_params(pss::settings::MltVariant::Rjmlt, params)?)),
        "pmlt" => Ok(Box::new(path_space::Pmlt::from_params(params)?)),
        "emlt" => Ok(Box::new(ensemble::render::Emlt::from_params(params)?)),
        other => Err(RenderError::UnknownIntegrator(other.to_string())),
    }
}

/// Deserialises an integrator's settings struct from its parameter table; the message of an
/// unknown key or a wrong type names the integrator, the key and what was expected.
pub fn settings_from_table<T: serde::de::DeserializeOwned>(
    integrator: &str,
    params: &toml::Table,
) -> Result<T, RenderError> {
    T::deserialize(toml::Value::Table(params.clone())).map_err(|e| {
        let message = e.message().trim_end().replace('`', "'");
        // serde names unknown keys but not the key holding a value of the wrong type. Settings
        // structs default every field, so a one-key table fails exactly when that key is the culprit.
        let culprit = params.iter().find(|(k, v)| {
            let single: toml::Table = std::iter::once(((*k).clone(), (*v).clone())).collect();
            T::deserialize(toml::Value::Table(single)).is_err()
        });
        match culprit {
            Some((k, v)) if !message.contains(k.as_str()) => {
                RenderError::Settings(format!("[integrator] {integrator}: key '{k}' = {v}: {message}"))
            }
            _ => RenderError::Settings(format!("[integrator] {integrator}: {message}")),
        }
    })
}

/// Parses one `--set key=value` override. The value is read as a TOML scalar (`16`, `0.5`,
/// `true`, `"text"`); anything that is not valid TOML is taken as a bare string, so
/// `--set mis=balance` works without quotes.
pub fn parse_set(assignment: &str) -> Result<(String, toml::Value), RenderError> {
    let Some((key, value)) = assignment.split_once('=') else {
        return Err(RenderError::Settings(format!("--set '{assignment}': expected key=value")));
    };
    let key = key.trim();
    if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        return Err(RenderError::Settings(format!(
            "--set '{assignment}': the key must be a plain setting name (letters, digits, '_', '-')"
        )));
    }
    let value = value.trim();
    let parsed = toml::from_str::<toml::Table>(&format!("v = {value}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    Ok((key.to_string(), parsed))
}

/// The scene's integrator parameters with the `--set` overrides applied on top.
pub fn merge_params(scene_params: &toml::Table, overrides: &[(String, toml::Value)]) -> toml::Table {
    let mut params = scene_params.clone();
    for (k, v) in overrides {
        params.insert(k.clone(), v.clone());
    }
    params
}

#[cfg(test)]
mod registry_tests {
    use super::*;

    #[test]
    fn unknown_integrator_lists_the_valid_names() {
        let err = create("nope", &toml::Table::new()).err().expect("unknown name").to_string();
        assert!(err.contains("'nope'") && err.contains("pt"), "{err}");
        for name in INTEGRATOR_NAMES {
            assert!(create(name, &toml::Table::new()).is_ok(), "{name} builds with defaults");
        }
    }

    #[test]
    fn set_values_are_toml_scalars_or_bare_strings() {
        assert_eq!(parse_set("max_depth=8").expect("int").1, toml::Value::Integer(8));
        assert_eq!(parse_set("x = 0.5").expect("float").1, toml::Value::Float(0.5));
        assert_eq!(parse_set("b=true").expect("bool").1, toml::Value::Boolean(true));
        assert_eq!(parse_set("mis=balance").expect("bare").1, toml::Value::String("balance".into()));
        assert_eq!(parse_set("mis=\"power\"").expect("quoted").1, toml::Value::String("power".into()));
        assert!(parse_set("novalue").is_err());
        assert!(parse_set("=3").is_err());
        let merged = merge_params(
            &toml::from_str("max_depth = 3\nrr_depth = 2").expect("toml"),
            &[parse_set("max_depth=9").expect("set")],
        );
        assert_eq!(merged["max_depth"], toml::Value::Integer(9));
        assert_eq!(merged["rr_depth"], toml::Value::Integer(2));
    }
}
