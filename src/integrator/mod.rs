//! Light-transport algorithms. Each integrator is a settings struct (serde, defaults from the
//! papers), a per-thread kernel and a driver; all of them render a `Scene` into an `Image` and
//! report `Counters`. None of them knows which accelerator answers its rays.

pub mod bdpt;
pub mod driver;
pub mod ensemble;
pub mod light_tracing;
pub mod memory_estimate;
pub mod path_space;
pub mod pss;
pub mod pt;
pub mod registry;

use thiserror::Error;

use crate::scene::Scene;
use crate::state::{RenderState, Session, SessionOutput, StateError};

// The job layer's types are what every integrator takes and returns; they are named here too so
// that an integrator's imports come from one place.
pub use crate::job::{
    check_budget, check_threads, Budget, LimitError, NoProgress, Progress, RenderJob, RenderOutput, MAX_SECONDS,
    MAX_THREADS, MAX_TOTAL_SAMPLES,
};

/// Why a render could not run.
#[derive(Debug, Error)]
pub enum RenderError {
    #[error("invalid integrator setting: {0}")]
    Settings(String),
    #[error("could not create the thread pool: {0}")]
    ThreadPool(String),
    #[error("a {width}×{height} film has more than 2^32 pixels, more than a render can address")]
    FilmTooLarge { width: u32, height: u32 },
    /// A name no row of the registry has; `known` lists the names that are.
    #[error("unknown integrator '{name}': expected one of {known}")]
    UnknownIntegrator { name: String, known: String },
    /// A budget, count or memory need beyond what a render can do (`check_budget`, `memory`).
    #[error("{0}")]
    Limit(String),
    /// A checkpoint, resume, shard or merge asked of an integrator that cannot do it, or a state
    /// that does not fit the render.
    #[error(transparent)]
    State(#[from] StateError),
}

impl From<LimitError> for RenderError {
    fn from(e: LimitError) -> RenderError {
        RenderError::Limit(e.0)
    }
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

/// An integrator as its module writes it: the name users select it by, its settings and the engine
/// that runs it. Every `Plugin` is an [`Integrator`] through the one implementation below, so an
/// integrator module writes its algorithm and one `Plugin` block, no `Integrator` glue: image
/// integrators (pt, bdpt, light) run on [`driver::ImageEngine`] through
/// [`driver::ImageIntegrator`], the Markov chain integrators (pssmlt, mmlt, rjmlt, pmlt, emlt) on
/// [`driver::ChainEngine`] through [`driver::ChainIntegrator`].
pub trait Plugin: Send + Sync {
    /// How renders of this integrator run: checkpoints, resume, shards and merges included.
    type Engine: Engine<Self>;
    /// The settings in effect (reported in the stats JSON).
    type Settings: serde::Serialize;
    /// The name users select it by (`integrator = "pt"`): its registry row's.
    fn plugin_name(&self) -> &'static str;
    fn settings(&self) -> &Self::Settings;
}

/// Runs renders of integrators of type `I` under sessions: what `Integrator::run_session`,
/// `output_of_state` and `merge_parts` do for every integrator of one kind.
pub trait Engine<I: ?Sized> {
    fn run_session(
        integrator: &I,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(RenderOutput, Option<RenderState>), RenderError>;
    fn output_of_state(integrator: &I, state: &RenderState) -> Result<RenderOutput, RenderError>;
    fn merge_parts(parts: &[&[u8]]) -> Result<Vec<u8>, RenderError>;
}

impl<P: Plugin> Integrator for P {
    fn name(&self) -> &'static str {
        self.plugin_name()
    }

    fn settings_json(&self) -> serde_json::Value {
        serde_json::to_value(self.settings()).unwrap_or(serde_json::Value::Null)
    }

    fn run_session(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(RenderOutput, Option<RenderState>), RenderError> {
        P::Engine::run_session(self, scene, job, progress, session, save)
    }

    fn output_of_state(&self, state: &RenderState) -> Result<RenderOutput, RenderError> {
        P::Engine::output_of_state(self, state)
    }

    fn merge_parts(&self, parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        P::Engine::merge_parts(parts)
    }
}

/// The names `create` accepts, in the order `plexus render --help` lists them (the registry's).
pub use registry::NAMES as INTEGRATOR_NAMES;

/// The integrator called `name`, configured from `params` (the scene's `[integrator]` table merged
/// with `--set` overrides; unknown keys are errors): its row of the `registry` builds it.
pub fn create(name: &str, params: &toml::Table) -> Result<Box<dyn Integrator>, RenderError> {
    (registry::lookup(name)?.create)(params)
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
