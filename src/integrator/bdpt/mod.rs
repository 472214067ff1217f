//! Bidirectional path tracing with multiple importance sampling (Veach & Guibas 1995; Veach's
//! thesis ch. 10; the bookkeeping follows pbrt-v4 ch. 13.4), built so that one technique (s, t) can
//! be evaluated on its own: MMLT (Hachisuka et al. 2014, Sec. 4) and RJMLT (Bitterli et al. 2017)
//! drive the same subpath generation with their own primary samples and call the same
//! [`evaluate_technique`] the integrator here sums over.
//!
//! Conventions: a technique (s, t) uses `s` light-subpath vertices (the emitter point first) and
//! `t` camera-subpath vertices (the pinhole first); the full path has s + t vertices and
//! `depth = s + t − 2` scattering events, which `max_depth` bounds exactly as the path tracer's
//! `max_depth` does. The uniforms each vertex consumes are listed in [`subpath`].
//!
//! Image estimate: every pixel sample traces one camera subpath inside the pixel and one light
//! subpath; t ≥ 2 techniques add to the pixel, t = 1 techniques splat where they land, and the
//! film is divided by the samples per pixel (the light tracer's N_pixels · spp light paths estimate
//! the film-normalised importance, pbrt-v4 Sec. 16.3).

pub mod connect;
pub mod mis;
pub mod path;
pub mod subpath;
pub mod vertex;

use std::collections::BTreeMap;

use glam::UVec2;
use serde::{Deserialize, Serialize};

pub use connect::{evaluate_technique, mutually_visible, ConnectScratch, TechniqueSample};
pub use mis::MisHeuristic;
pub use subpath::{
    generate_camera_subpath, generate_light_subpath, FilmRegion, BOUNCE_DIMS, CAMERA_FILM_DIMS, CONNECTION_DIMS,
    LIGHT_START_DIMS,
};
pub use vertex::{Vertex, VertexKind};

use super::driver::{ImageEngine, ImageIntegrator, ImageRender, ImageRun};
use super::{settings_from_table, Plugin, Progress, RenderError, RenderJob};
use crate::film::{Accumulator, SplatBuffer};
use crate::sampling::{PixelSampler, SamplerKind, UniformSource};
use crate::scene::Scene;
use crate::spectrum::is_finite;
use crate::state::Session;
use crate::stats::Counters;

/// What subpath generation and technique evaluation need besides the subpaths: the scene and the
/// settings that change the estimator.
#[derive(Clone, Copy)]
pub struct BdptContext<'a> {
    pub scene: &'a Scene,
    /// Russian roulette starts once a subpath has this many vertices after its first
    /// (`usize::MAX` disables it).
    pub rr_depth: usize,
    pub heuristic: MisHeuristic,
}

impl<'a> BdptContext<'a> {
    pub fn new(scene: &'a Scene, rr_depth: usize, heuristic: MisHeuristic) -> BdptContext<'a> {
        BdptContext { scene, rr_depth, heuristic }
    }
}

/// Settings of `integrator = "bdpt"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BdptSettings {
    /// Maximum number of scattering events of a path (s + t − 2), as for the path tracer.
    pub max_depth: u32,
    /// MIS heuristic: "balance" (default) or "power".
    pub mis: MisHeuristic,
    /// Russian roulette on each subpath after this many bounces.
    pub rr_depth: u32,
    /// Write one image per technique (s, t), weighted and unweighted, as extra layers.
    pub technique_images: bool,
    /// Techniques of paths up to this depth get their own layers; deeper ones are summed into one
    /// `deeper` layer, so the weighted layers always add up to the image (bounds the memory:
    /// two f64 RGB films per technique and worker).
    pub technique_max_depth: u32,
    /// The numbers samples read: "sobol" or "independent" (`sampling::SamplerKind`); the camera,
    /// light and connection subpaths read separate streams.
    pub sampler: SamplerKind,
}

impl Default for BdptSettings {
    fn default() -> Self {
        BdptSettings {
            max_depth: 16,
            mis: MisHeuristic::Balance,
            rr_depth: 5,
            technique_images: false,
            technique_max_depth: 5,
            sampler: SamplerKind::default(),
        }
    }
}

/// Bidirectional path tracing.
#[derive(Clone, Debug)]
pub struct Bdpt {
    pub settings: BdptSettings,
}

/// The per-technique films of one worker slot.
struct TechniqueFilms {
    /// (s, t) → index into `weighted` / `unweighted`; techniques deeper than the limit map to the
    /// last index.
    index: BTreeMap<(usize, usize), usize>,
    names: Vec<String>,
    weighted: Vec<Accumulator>,
    unweighted: Vec<Accumulator>,
}

impl TechniqueFilms {
    fn new(width: usize, height: usize, max_depth: usize) -> TechniqueFilms {
        let mut index = BTreeMap::new();
        let mut names = Vec::new();
        for depth in 0..=max_depth {
            for t in 1..=depth + 2 {
                let s = depth + 2 - t;
                if s == 1 && t == 1 {
                    continue;
                }
                index.insert((s, t), names.len());
                names.push(format!("s{s}t{t}"));
            }
        }
        names.push("deeper".to_string());
        let n = names.len();
        TechniqueFilms {
            index,
            names,
            weighted: vec![Accumulator::new(width, height); n],
            unweighted: vec![Accumulator::new(width, height); n],
        }
    }

    fn slot(&self, s: usize, t: usize) -> usize {
        self.index.get(&(s, t)).copied().unwrap_or(self.names.len() - 1)
    }
}

/// Per-slot scratch of the BDPT kernel.
struct BdptSlot {
    camera: Vec<Vertex>,
    light: Vec<Vertex>,
    scratch: ConnectScratch,
    techniques: Option<TechniqueFilms>,
}

impl Bdpt {
    pub fn new(settings: BdptSettings) -> Bdpt {
        Bdpt { settings }
    }

    /// Builds from an `[integrator]` parameter table.
    pub fn from_params(params: &toml::Table) -> Result<Bdpt, RenderError> {
        let settings: BdptSettings = settings_from_table("bdpt", params)?;
        if settings.max_depth == 0 {
            return Err(RenderError::Settings("bdpt: max_depth must be at least 1".into()));
        }
        if settings.mis == MisHeuristic::None {
            return Err(RenderError::Settings("bdpt: mis must be \"balance\" or \"power\"".into()));
        }
        Ok(Bdpt::new(settings))
    }

    fn context<'a>(&self, scene: &'a Scene) -> BdptContext<'a> {
        BdptContext::new(scene, self.settings.rr_depth as usize, self.settings.mis)
    }

    /// One BDPT sample for pixel `pixel`: traces both subpaths from `sampler` (camera stream 0,
    /// light stream 1, connections stream 2) and adds every
    /// technique's weighted contribution to `film` (t ≥ 2 at the pixel, t = 1 where it lands).
    fn sample_pixel(
        &self,
        ctx: &BdptContext,
        pixel: UVec2,
        sampler: &mut PixelSampler<'_>,
        film: &mut SplatBuffer,
        counters: &mut Counters,
        slot: &mut BdptSlot,
    ) {
        let max_depth = self.settings.max_depth as usize;
        let raster = generate_camera_subpath(
            ctx,
            FilmRegion::Pixel(pixel),
            &mut sampler.stream(0),
            max_depth + 2,
            &mut slot.camera,
            counters,
        );
        generate_light_subpath(ctx, &mut sampler.stream(1), max_depth + 1, &mut slot.light, counters);
        let techniques = &mut slot.techniques;
        connect_all(
            ctx,
            &slot.light,
            &slot.camera,
            raster,
            max_depth,
            &mut sampler.stream(2),
            &mut slot.scratch,
            counters,
            |c, counters| {
                let value = c.weighted();
                if !is_finite(value) || !is_finite(c.contribution) {
                    counters.nonfinite_dropped += 1;
                    return;
                }
                // t ≥ 2 contributions belong to the sampled pixel (c.raster lies inside it).
                let at_pixel = c.t >= 2;
                if at_pixel {
                    film.add(pixel.x as usize, pixel.y as usize, value);
                } else {
                    film.splat(c.raster, value);
                }
                if let Some(tf) = techniques.as_mut() {
                    let i = tf.slot(c.s, c.t);
                    if at_pixel {
                        tf.weighted[i].add(pixel.x as usize, pixel.y as usize, value);
                        tf.unweighted[i].add(pixel.x as usize, pixel.y as usize, c.contribution);
                    } else {
                        tf.weighted[i].splat(c.raster, value);
                        tf.unweighted[i].splat(c.raster, c.contribution);
                    }
                }
            },
        );
    }
}

/// Evaluates every technique (s, t) of BDPT on one pair of subpaths — all s ≤ light.len(),
/// 1 ≤ t ≤ camera.len() with s + t − 2 ≤ max_depth, except (1, 1) — and hands each non-zero one to
/// `sink` (with the counters, for dropping non-finite values). This is BDPT's estimator for one
/// sample and PSSMLT's path contribution (MMLT paper Alg. 1, COMBINE); s = 1 techniques read
/// `CONNECTION_DIMS` numbers each from `connection`, in increasing t.
#[allow(clippy::too_many_arguments)]
pub fn connect_all<S: UniformSource>(
    ctx: &BdptContext,
    light: &[Vertex],
    camera: &[Vertex],
    raster: glam::Vec2,
    max_depth: usize,
    connection: &mut S,
    scratch: &mut ConnectScratch,
    counters: &mut Counters,
    mut sink: impl FnMut(&TechniqueSample, &mut Counters),
) {
    for t in 1..=camera.len() {
        for s in 0..=light.len() {
            let depth = (s + t) as isize - 2;
            if (s == 1 && t == 1) || depth < 0 || depth as usize > max_depth {
                continue;
            }
            if let Some(c) = evaluate_technique(ctx, light, camera, s, t, raster, connection, scratch, counters, None) {
                sink(&c, counters);
            }
        }
    }
}

impl Plugin for Bdpt {
    type Engine = ImageEngine;
    type Settings = BdptSettings;

    fn plugin_name(&self) -> &'static str {
        "bdpt"
    }

    fn settings(&self) -> &BdptSettings {
        &self.settings
    }
}

impl Bdpt {
    /// The render with its unnormalised film (`Integrator::render` keeps only the output), and the
    /// technique layers when `technique_images` is set. (Those layers are per-slot films merged in
    /// slot order, so unlike the image their low bits depend on the thread count.)
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<ImageRun, RenderError> {
        self.render_run_session(scene, job, progress, Session::default(), false)
    }
}

impl ImageIntegrator for Bdpt {
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
        if self.settings.technique_images && (session.resume.is_some() || session.shard.is_some()) {
            // The layers are per-slot films (their low bits depend on the threads), not in a state.
            return Err(crate::state::StateError::Mismatch(
                "bdpt's technique_images layers are not saved in state files: resume or shard without them".into(),
            )
            .into());
        }
        let (width, height) = (scene.camera.width, scene.camera.height);
        let render = ImageRender::new(job, width, height, progress)?
            .with_session(session, save)?
            .with_sampler(self.settings.sampler);
        let ctx = self.context(scene);
        let technique_depth = (self.settings.technique_max_depth.min(self.settings.max_depth)) as usize;
        let (mut run, slot_states) = render.run(
            |_| BdptSlot {
                camera: Vec::new(),
                light: Vec::new(),
                scratch: ConnectScratch::default(),
                techniques: self
                    .settings
                    .technique_images
                    .then(|| TechniqueFilms::new(width as usize, height as usize, technique_depth)),
            },
            |x, y, rng, slot| {
                self.sample_pixel(&ctx, UVec2::new(x, y), rng, &mut slot.film, &mut slot.counters, &mut slot.state)
            },
        );
        let mut technique_names = Vec::new();
        if self.settings.technique_images {
            // Merge the slots' technique films in slot order.
            let mut merged: Option<TechniqueFilms> = None;
            for state in slot_states {
                let Some(tf) = state.techniques else { continue };
                match merged.as_mut() {
                    None => merged = Some(tf),
                    Some(m) => {
                        for (a, b) in m.weighted.iter_mut().zip(&tf.weighted) {
                            a.merge(b);
                        }
                        for (a, b) in m.unweighted.iter_mut().zip(&tf.unweighted) {
                            a.merge(b);
                        }
                    }
                }
            }
            if let Some(m) = merged {
                for (i, name) in m.names.iter().enumerate() {
                    run.output.layers.push((format!("{name}.weighted"), m.weighted[i].to_image(run.scale)));
                    run.output.layers.push((format!("{name}.unweighted"), m.unweighted[i].to_image(run.scale)));
                    technique_names.push(name.clone());
                }
            }
        }
        if let Some(stats) = run.output.extra_stats.as_object_mut() {
            stats.insert("technique_layers".into(), serde_json::json!(technique_names));
        }
        Ok(run)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_defaults_and_validation() {
        let b = Bdpt::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(b.settings, BdptSettings::default());
        assert_eq!(b.settings.max_depth, 16);
        let t: toml::Table = toml::from_str("mis = \"power\"\ntechnique_images = true").expect("toml");
        let b = Bdpt::from_params(&t).expect("valid");
        assert_eq!(b.settings.mis, MisHeuristic::Power);
        assert!(b.settings.technique_images);
        for bad in ["max_depht = 3", "mis = \"nope\"", "max_depth = 0", "mis = \"none\""] {
            let t: toml::Table = toml::from_str(bad).expect("toml");
            assert!(Bdpt::from_params(&t).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn technique_films_cover_every_technique_once() {
        let tf = TechniqueFilms::new(2, 2, 3);
        // depths 0..=3 have 2,3,4,5 techniques, minus (1,1), plus `deeper`.
        assert_eq!(tf.names.len(), 2 + 3 + 4 + 5 - 1 + 1);
        assert_eq!(tf.slot(0, 2), 0);
        assert_eq!(tf.slot(9, 9), tf.names.len() - 1);
    }
}
