//! The integrators by name: one row each, with everything the rest of plexus asks of an integrator
//! before it renders. The command line's help and errors list the rows' names, `create` builds
//! from a row, `render`, `resume` and `reference` check a row's memory estimate
//! (`Row::check_limits`) and `info` prints it, and the session options (checkpoints, resume,
//! shards) are offered by a row's capabilities. Adding an integrator is its module and one row
//! here.
//!
//! A row's settings are the integrator's settings struct: `Row::settings` gives its keys with the
//! values in effect for the parameters (the defaults for an empty table), as the render's JSON
//! reports them; unknown keys are refused with the valid ones (`settings_from_table`).

use super::{bdpt, ensemble, light_tracing, memory_estimate, path_space, pss, pt, Integrator, RenderError};
use crate::job::memory::{available_memory, check_fits, RenderMemory};
use crate::job::{check_budget, Budget};
use crate::scene::Scene;
use pss::mlt_settings::MltVariant;

/// Where an integrator's work units live (`driver`'s render model).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    /// Image-space: tiles and passes of samples per pixel (`driver::ImageRender`).
    Image,
    /// Markov chains: chains as units, mutations per pixel as the budget.
    Chain,
}

/// What an integrator's renders can do beyond running from the start to the end of the budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capabilities {
    pub space: Space,
    /// `--checkpoint`, `--checkpoint-every` and a saved state when interrupted.
    pub checkpoint: bool,
    /// `plexus resume` of such a state.
    pub resume: bool,
    /// `--shard K/N` and `plexus merge`.
    pub shard: bool,
}

impl Capabilities {
    /// Everything the render model offers.
    pub const fn sessions(space: Space) -> Capabilities {
        Capabilities { space, checkpoint: true, resume: true, shard: true }
    }
    /// A render that keeps no state: from the start to the end of its budget only.
    pub const fn whole_renders(space: Space) -> Capabilities {
        Capabilities { space, checkpoint: false, resume: false, shard: false }
    }
    /// Whether any session option (checkpoint, resume, shard) works.
    pub fn any_session(&self) -> bool {
        self.checkpoint || self.resume || self.shard
    }
}

/// One integrator: its name, how to build it from parameters, the memory a render of it needs
/// beyond the scene, and what its renders can do.
#[derive(Clone, Copy)]
pub struct Row {
    /// The name users select it by (`[integrator] type`, `--integrator`).
    pub name: &'static str,
    /// Builds it from the scene's `[integrator]` table merged with `--set` overrides; unknown keys
    /// and invalid values are errors.
    pub create: fn(&toml::Table) -> Result<Box<dyn Integrator>, RenderError>,
    /// Its film, pass buffers and chains for a `width`×`height` film (`integrator::memory_estimate`).
    pub memory: fn(&toml::Table, u32, u32) -> Result<RenderMemory, RenderError>,
    pub capabilities: Capabilities,
}

impl Row {
    /// The settings in effect for `params`, every key with its value (the defaults where `params`
    /// names none): the settings struct as the JSON report gives it.
    pub fn settings(&self, params: &toml::Table) -> Result<serde_json::Value, RenderError> {
        Ok((self.create)(params)?.settings_json())
    }

    /// Every limit a render of this integrator with `params` is checked against before work
    /// starts, as `plexus render`, `resume` and `reference` check it: the budget (`option` names its
    /// source) for the scene's film, and the row's memory estimate with the built scene's bytes
    /// against what the process may use. Returns the estimate.
    pub fn check_limits(
        &self,
        scene: &Scene,
        params: &toml::Table,
        budget: Budget,
        option: &str,
    ) -> Result<RenderMemory, RenderError> {
        self.check_limits_within(scene, params, budget, option, available_memory(scene.memory().total()))
    }

    /// [`Row::check_limits`] against `available` bytes instead of the process's (`None`: no bound).
    pub fn check_limits_within(
        &self,
        scene: &Scene,
        params: &toml::Table,
        budget: Budget,
        option: &str,
        available: Option<u64>,
    ) -> Result<RenderMemory, RenderError> {
        let (width, height) = (scene.camera.width, scene.camera.height);
        check_budget(budget, width, height, option)?;
        let needed = (self.memory)(params, width, height)?.with_scene(scene.memory());
        check_fits(&needed, width, height, available)?;
        Ok(needed)
    }
}

impl std::fmt::Debug for Row {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Row").field("name", &self.name).field("capabilities", &self.capabilities).finish()
    }
}

/// The integrators plexus ships, in the order help texts list them.
pub const INTEGRATORS: &[Row] = &[
    Row {
        name: "pt",
        create: |p| Ok(Box::new(pt::PathTracer::from_params(p)?)),
        memory: memory_estimate::image_memory,
        capabilities: Capabilities::sessions(Space::Image),
    },
    Row {
        name: "bdpt",
        create: |p| Ok(Box::new(bdpt::Bdpt::from_params(p)?)),
        memory: memory_estimate::image_memory,
        capabilities: Capabilities::sessions(Space::Image),
    },
    Row {
        name: "light",
        create: |p| Ok(Box::new(light_tracing::LightTracer::from_params(p)?)),
        memory: memory_estimate::image_memory,
        capabilities: Capabilities::sessions(Space::Image),
    },
    Row {
        name: "pssmlt",
        create: |p| Ok(Box::new(pss::mlt::Mlt::from_params(MltVariant::Pssmlt, p)?)),
        memory: |p, w, h| memory_estimate::mlt_memory(MltVariant::Pssmlt, p, w, h),
        capabilities: Capabilities::sessions(Space::Chain),
    },
    Row {
        name: "mmlt",
        create: |p| Ok(Box::new(pss::mlt::Mlt::from_params(MltVariant::Mmlt, p)?)),
        memory: |p, w, h| memory_estimate::mlt_memory(MltVariant::Mmlt, p, w, h),
        capabilities: Capabilities::sessions(Space::Chain),
    },
    Row {
        name: "rjmlt",
        create: |p| Ok(Box::new(pss::mlt::Mlt::from_params(MltVariant::Rjmlt, p)?)),
        memory: |p, w, h| memory_estimate::mlt_memory(MltVariant::Rjmlt, p, w, h),
        capabilities: Capabilities::sessions(Space::Chain),
    },
    Row {
        name: "pmlt",
        create: |p| Ok(Box::new(path_space::Pmlt::from_params(p)?)),
        memory: memory_estimate::pmlt_memory,
        capabilities: Capabilities::sessions(Space::Chain),
    },
    Row {
        name: "emlt",
        create: |p| Ok(Box::new(ensemble::emlt_render::Emlt::from_params(p)?)),
        memory: memory_estimate::emlt_memory,
        capabilities: Capabilities::sessions(Space::Chain),
    },
];

/// The names of `rows`, in order.
pub fn names_in(rows: &[Row]) -> Vec<&'static str> {
    rows.iter().map(|r| r.name).collect()
}

/// The names of the shipped integrators, in the order help texts list them: the rows' names,
/// read off the table at compile time.
pub const NAMES: &[&str] = &{
    let mut names = [""; INTEGRATORS.len()];
    let mut i = 0;
    while i < names.len() {
        names[i] = INTEGRATORS[i].name;
        i += 1;
    }
    names
};

/// The row of `rows` called `name`; an unknown name is an error listing the known ones.
pub fn find<'a>(rows: &'a [Row], name: &str) -> Result<&'a Row, RenderError> {
    rows.iter()
        .find(|r| r.name == name)
        .ok_or_else(|| RenderError::UnknownIntegrator { name: name.to_string(), known: names_in(rows).join(", ") })
}

/// The shipped integrator called `name`.
pub fn lookup(name: &str) -> Result<&'static Row, RenderError> {
    find(INTEGRATORS, name)
}

/// The memory a render of `integrator` with `params` needs for a `width`×`height` film, the scene
/// not included (`RenderMemory::with_scene` adds it).
pub fn render_memory(
    integrator: &str,
    params: &toml::Table,
    width: u32,
    height: u32,
) -> Result<RenderMemory, RenderError> {
    (lookup(integrator)?.memory)(params, width, height)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_every_row_builds_with_its_defaults() {
        let names = NAMES;
        let unique: std::collections::BTreeSet<_> = names.iter().collect();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        assert_eq!(names_in(INTEGRATORS), NAMES);
        for row in INTEGRATORS {
            let built = (row.create)(&toml::Table::new()).unwrap_or_else(|e| panic!("{}: {e}", row.name));
            assert_eq!(built.name(), row.name, "a row builds the integrator it names");
            // The row's capabilities and the integrator's own answer cannot drift apart.
            assert_eq!(built.supports_sessions(), row.capabilities.any_session(), "{}", row.name);
            assert!(row.settings(&toml::Table::new()).expect("defaults").is_object(), "{}", row.name);
            assert!((row.memory)(&toml::Table::new(), 16, 16).expect("small").film > 0, "{}", row.name);
        }
        let err = lookup("nope").expect_err("unknown name").to_string();
        assert!(err.contains("'nope'") && err.contains(&names.join(", ")), "{err}");
    }
}
