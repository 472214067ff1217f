//! Pure light tracing (`integrator = "light"`): light subpaths from the emitters, every vertex
//! connected to the pinhole and splatted where it lands — BDPT's t = 1 techniques alone, each
//! weighted 1 (plus the emitter point itself, s = 1, which BDPT leaves to s = 0).
//!
//! It cannot see what only camera rays find: an environment seen directly or through specular
//! surfaces only, and emitters seen through mirrors or glass (specular chains ending at the
//! pinhole). It is the estimator of choice for caustics seen on diffuse surfaces.
//!
//! Each pass traces, per tile, as many light paths as the tile has pixels times the pass's samples
//! per pixel; the film is divided by the samples per pixel (N_pixels · spp light paths estimate the
//! film-normalised camera importance, pbrt-v4 Sec. 16.3).

use serde::{Deserialize, Serialize};

use super::bdpt::connect::connect_to_camera;
use super::bdpt::{generate_light_subpath, BdptContext, MisHeuristic, Vertex};
use super::driver::{ImageEngine, ImageIntegrator, ImageRender, ImageRun};
use super::{settings_from_table, Plugin, Progress, RenderError, RenderJob};
use crate::sampling::SamplerKind;
use crate::scene::Scene;
use crate::spectrum::is_finite;
use crate::state::Session;

/// Settings of `integrator = "light"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LightTracerSettings {
    /// Maximum number of scattering events of a path.
    pub max_depth: u32,
    /// Russian roulette on the light subpath after this many bounces.
    pub rr_depth: u32,
    /// The numbers light paths read: "independent" (the default) or "sobol" (the Sobol points of
    /// the pixel the path is counted at; `sampling::SamplerKind`). Independent is the default here:
    /// a light path lands anywhere, so stratifying the few paths counted at one pixel bought
    /// nothing measurable (MSE ratio Sobol/independent 0.97–1.12 on the Cornell scenes,
    /// docs/lab/benchmarks-history.md, "Sobol sampling at equal samples") while the Sobol points
    /// cost time.
    pub sampler: SamplerKind,
}

impl Default for LightTracerSettings {
    fn default() -> Self {
        LightTracerSettings { max_depth: 16, rr_depth: 5, sampler: SamplerKind::Independent }
    }
}

/// The light tracer.
#[derive(Clone, Debug)]
pub struct LightTracer {
    pub settings: LightTracerSettings,
}

impl LightTracer {
    pub fn new(settings: LightTracerSettings) -> LightTracer {
        LightTracer { settings }
    }

    /// Builds from an `[integrator]` parameter table.
    pub fn from_params(params: &toml::Table) -> Result<LightTracer, RenderError> {
        let settings: LightTracerSettings = settings_from_table("light", params)?;
        if settings.max_depth == 0 {
            return Err(RenderError::Settings("light: max_depth must be at least 1".into()));
        }
        Ok(LightTracer::new(settings))
    }
}

impl Plugin for LightTracer {
    type Engine = ImageEngine;
    type Settings = LightTracerSettings;

    fn plugin_name(&self) -> &'static str {
        "light"
    }

    fn settings(&self) -> &LightTracerSettings {
        &self.settings
    }
}

impl LightTracer {
    /// The render with its unnormalised film (`Integrator::render` keeps only the output). Each
    /// "sample" of pixel (x, y) is one light path, splatted wherever its connections land.
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<ImageRun, RenderError> {
        self.render_run_session(scene, job, progress, Session::default(), false)
    }
}

impl ImageIntegrator for LightTracer {
    /// [`Self::render_run`] under a session (`crate::state`): resumed, sharded, stopped early;
    /// with `save`, `ImageRun::state` holds the state reached.
    fn render_run_session(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: Session,
        save: bool,
    ) -> Result<ImageRun, RenderError> {
        let render = ImageRender::new(job, scene.camera.width, scene.camera.height, progress)?
            .with_session(session, save)?
            .with_sampler(self.settings.sampler);
        let ctx = BdptContext::new(scene, self.settings.rr_depth as usize, MisHeuristic::None);
        let max_vertices = self.settings.max_depth as usize + 1;
        let (mut run, _) = render.run(
            |_| Vec::<Vertex>::new(),
            |_, _, sampler, slot| {
                if !generate_light_subpath(
                    &ctx,
                    &mut sampler.stream(1),
                    max_vertices,
                    &mut slot.state,
                    &mut slot.counters,
                ) {
                    return;
                }
                for qs in slot.state.iter() {
                    if !qs.connectible(scene) || qs.infinite {
                        continue;
                    }
                    let Some((value, _, raster)) = connect_to_camera(&ctx, qs, &mut slot.counters) else {
                        continue;
                    };
                    if !is_finite(value) {
                        slot.counters.nonfinite_dropped += 1;
                        continue;
                    }
                    slot.film.splat(raster, value);
                }
            },
        );
        if let Some(stats) = run.output.extra_stats.as_object_mut() {
            let spp = stats.get("spp").cloned().unwrap_or_default();
            stats.insert("light_paths_per_pixel".into(), spp);
        }
        Ok(run)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_defaults_and_unknown_keys() {
        let l = LightTracer::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(l.settings, LightTracerSettings::default());
        let bad: toml::Table = toml::from_str("mis = \"balance\"").expect("toml");
        assert!(LightTracer::from_params(&bad).is_err());
    }
}
