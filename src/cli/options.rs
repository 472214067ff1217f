//! The options every verb that renders a scene takes (`render`, `reference`, `converge`), defined
//! once and flattened into each verb's arguments.

use clap::Args;

use plexus::accel::AccelKind;
use plexus::integrator;

use super::bad_input;

#[derive(Debug, Args)]
pub struct RenderOptions {
    /// Worker threads, at most 1024 (default: the scene's render.threads where the verb reads
    /// it — render and converge —, else all cores).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Ray-query accelerator: embree or bvh.
    #[arg(long, value_name = "embree|bvh")]
    pub accel: Option<AccelKind>,
    /// Integrator setting, as a TOML value (e.g. --set max_depth=8); repeatable. converge applies
    /// it to every integrator.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

impl RenderOptions {
    /// The `--set` overrides, parsed; a malformed one is bad input.
    pub fn overrides(&self) -> anyhow::Result<Vec<(String, toml::Value)>> {
        self.set.iter().map(|s| integrator::parse_set(s)).collect::<Result<Vec<_>, _>>().map_err(bad_input)
    }

    /// Refuses an explicit `--threads` beyond the limits, before anything is loaded.
    pub fn check_threads(&self) -> anyhow::Result<()> {
        if let Some(n) = self.threads {
            plexus::job::check_threads(n, "--threads").map_err(bad_input)?;
        }
        Ok(())
    }

    /// The thread count: `--threads`, else `scene` (the scene's `render.threads`, for the verbs
    /// that read it), else all cores.
    pub fn threads_or(&self, scene: Option<usize>) -> anyhow::Result<usize> {
        match (self.threads, scene) {
            (Some(n), _) => super::resolve_threads(Some(n), "--threads"),
            (None, n) => super::resolve_threads(n, "render.threads"),
        }
    }
}
