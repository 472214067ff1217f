//! The memory a render needs, and the memory the process may use: one estimate, computed with
//! checked arithmetic, so that a scene, film or Markov chain setup that would not fit is refused
//! with its size instead of aborting on allocation. `plexus info` prints the same
//! estimate.
//!
//! Its parts:
//! - **the scene** (`SceneMemory`), measured on the built scene: mesh arrays, the accelerator
//!   (Embree's own allocations through its memory monitor, or the in-house BVH's nodes and
//!   triangles), lights (distributions, environment texels) and textures;
//! - **the render**, the buffers that grow with the budget's dimensions (see `driver`'s render
//!   model): the film's unnormalised sums (3 × f64 per pixel; MLT stacks one W × H layer per path
//!   depth), the normalised output image (3 × f32 per pixel), one pass of splat buffers (16 bytes a
//!   contribution, at least one per pixel sample of the pass), and for MLT the bootstrap's targets
//!   (one f32 plus one f64 of the discrete distribution per bootstrap path and depth) and the
//!   chains' sub-chains (path-space MLT: the chains' paths; ensemble MLT: its 2 × `ensemble_size`
//!   chains' paths in each of its `pairs` pairs, one film layer per pair, and per pair the view
//!   of its fixed ensemble that the guided strategies read: Y's vertex places and the tree).
//!
//! The estimate is a lower bound: it omits scratch state, so a render it refuses certainly would
//! not have fitted. The scene is already built when the estimate is checked (mesh readers bound
//! their allocations by the file sizes, `input_file`), so its bytes are part of what the process
//! holds: see `available_memory`.

use super::pss::settings::{MltSettings, MltVariant};
use super::RenderError;

/// Bytes of one film pixel: the accumulator's three f64 sums.
const FILM_PIXEL_BYTES: u64 = 3 * 8;
/// Bytes of one output pixel: three f32.
const IMAGE_PIXEL_BYTES: u64 = 3 * 4;
/// Bytes of one recorded contribution in a unit's splat buffer (pixel index and RGB, `SplatBuffer`).
const SPLAT_BYTES: u64 = 16;
/// A pass holds at least this many pixel samples (`driver::MIN_SAMPLES_PER_PASS`).
const MIN_SAMPLES_PER_PASS: u64 = 1 << 16;
/// Bytes per bootstrap path and depth: its f32 target and the f64 CDF entry of the distribution the
/// chains start from.
const BOOTSTRAP_PATH_BYTES: u64 = 4 + 8;
/// Bytes of one MLT sub-chain, at least: its sampler (primary samples of a path with their backups)
/// and its current path's contribution, per path vertex (`max_depth + 2` vertices, two subpaths).
const SUBCHAIN_BYTES_PER_VERTEX: u64 = 2 * 64;

/// Bytes the built scene holds, by part.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SceneMemory {
    pub meshes: u64,
    /// The triangles' corner copies the scene keeps for shading (`Scene::keep_corners_if_room`),
    /// made after the accelerator's build: they and `accel_build` are never held at once.
    pub corners: u64,
    pub accel: u64,
    /// Bytes the accelerator held only while it was built, on top of `accel` (`Accel::
    /// peak_memory_bytes` minus `memory_bytes`): part of the process's peak, freed before rendering.
    pub accel_build: u64,
    /// Light distributions and environment texels.
    pub lights: u64,
    /// Image textures' texels (each shared image once; `Scene::texture_memory_bytes`).
    pub textures: u64,
}

impl SceneMemory {
    /// The scene's peak: what it holds while rendering, or while its accelerator was built (the
    /// build's temporaries instead of the corner copies), whichever is more.
    pub fn total(&self) -> u64 {
        self.meshes
            .saturating_add(self.accel)
            .saturating_add(self.accel_build.max(self.corners))
            .saturating_add(self.lights)
            .saturating_add(self.textures)
    }
}

/// Bytes of one vertex of a path-space chain's path (`path_space::PathVertex`).
const PATH_VERTEX_BYTES: u64 = std::mem::size_of::<crate::integrator::path_space::PathVertex>() as u64;

/// Bytes per vertex of a path in an ensemble's view (`ensemble::guide::GuideView`): its place
/// for the similarity weights (a `DVec3`).
const VIEW_PLACE_BYTES: u64 = 3 * 8;
/// Bytes per path of an ensemble's view beyond its places: where its places start (u32) and its
/// index in the tree's signature order (u32, `ensemble::tree::EnsembleTree`).
const VIEW_PATH_BYTES: u64 = 4 + 4;

/// The memory of a render: the scene it renders, its film, pass buffers and integrator state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RenderMemory {
    /// The built scene (zero until `with_scene`).
    pub scene: SceneMemory,
    /// Film sums (all MLT depth layers) and the output image.
    pub film: u64,
    /// One pass of splat buffers.
    pub pass_buffers: u64,
    /// MLT only: bootstrap targets and chains.
    pub chains: u64,
}

impl RenderMemory {
    pub fn total(&self) -> u64 {
        self.scene.total().saturating_add(self.film).saturating_add(self.pass_buffers).saturating_add(self.chains)
    }
    /// This estimate with the scene's bytes.
    pub fn with_scene(self, scene: SceneMemory) -> RenderMemory {
        RenderMemory { scene, ..self }
    }
}

fn too_large(what: &str) -> RenderError {
    RenderError::Limit(format!("the memory of {what} overflows a 64-bit byte count"))
}

fn mul(a: u64, b: u64, what: &str) -> Result<u64, RenderError> {
    a.checked_mul(b).ok_or_else(|| too_large(what))
}

/// The memory `integrator` (with its `params`, already validated by `create`) needs for a
/// `width`×`height` film. Every product is checked; an overflow is itself a refusal.
pub fn render_memory(
    integrator: &str,
    params: &toml::Table,
    width: u32,
    height: u32,
) -> Result<RenderMemory, RenderError> {
    let pixels = mul(width as u64, height as u64, "the film")?;
    let variant = match integrator {
        "pssmlt" => Some(MltVariant::Pssmlt),
        "mmlt" => Some(MltVariant::Mmlt),
        "rjmlt" => Some(MltVariant::Rjmlt),
        _ => None,
    };
    let image = mul(pixels, IMAGE_PIXEL_BYTES, "the output image")?;
    // A pass of the image integrators takes max(1, 2^16 / pixels) samples per pixel; MLT's pass is
    // about one mutation per pixel. Either way at least max(pixels, 2^16) contributions.
    let pass_buffers = mul(pixels.max(MIN_SAMPLES_PER_PASS), SPLAT_BYTES, "a pass's splat buffers")?;
    if integrator == "pmlt" {
        // Path-space MLT: one W × H film; the bootstrap's targets; per chain its current path and
        // a proposal (max_depth + 2 vertices each).
        let settings = crate::integrator::path_space::PmltSettings::from_params(params)?;
        let film = mul(pixels, FILM_PIXEL_BYTES, "the film")?;
        let film = film.checked_add(image).ok_or_else(|| too_large("the film"))?;
        let bootstrap = mul(settings.bootstrap, BOOTSTRAP_PATH_BYTES, "the bootstrap")?;
        let path = mul(settings.max_depth as u64 + 2, PATH_VERTEX_BYTES, "a chain's path")?;
        let chains = mul(mul(settings.chains, 2, "the chains")?, path, "the chains")?;
        let chains = bootstrap.checked_add(chains).ok_or_else(|| too_large("the chains"))?;
        return Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains });
    }
    if integrator == "emlt" {
        // Ensemble MLT: one W × H film layer per pair; the bootstrap's targets; 2 × ensemble_size
        // chains per pair with their current path and a proposal, as pmlt's; and, while a pass
        // runs, per pair the view of Y (ensemble_size paths: their vertex places, place starts and
        // tree order). Y's paths move into the view, so they are not counted twice.
        let settings = crate::integrator::ensemble::settings::EmltSettings::from_params(params)?;
        let layers = mul(pixels, settings.pairs, "the per-pair film")?;
        let film = mul(layers, FILM_PIXEL_BYTES, "the per-pair film")?;
        let film = film.checked_add(image).ok_or_else(|| too_large("the film"))?;
        let bootstrap = mul(settings.bootstrap, BOOTSTRAP_PATH_BYTES, "the bootstrap")?;
        let vertices = settings.max_depth as u64 + 2;
        let path = mul(vertices, PATH_VERTEX_BYTES, "a chain's path")?;
        let chains = mul(mul(settings.ensemble_size, settings.pairs, "the ensembles")?, 2, "the ensembles")?;
        let paths = mul(mul(chains, 2, "the chains")?, path, "the chains")?;
        let view_path = mul(vertices, VIEW_PLACE_BYTES, "a view's path")?
            .checked_add(VIEW_PATH_BYTES)
            .ok_or_else(|| too_large("a view's path"))?;
        let views = mul(mul(settings.ensemble_size, settings.pairs, "the views")?, view_path, "the views")?;
        let chains = [paths, views]
            .iter()
            .try_fold(bootstrap, |a, &b| a.checked_add(b))
            .ok_or_else(|| too_large("the chains"))?;
        return Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains });
    }
    let Some(variant) = variant else {
        let film = mul(pixels, FILM_PIXEL_BYTES, "the film")?;
        let film = film.checked_add(image).ok_or_else(|| too_large("the film"))?;
        return Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains: 0 });
    };
    let settings = MltSettings::from_params(variant, params)?;
    let depths = match variant {
        MltVariant::Pssmlt => 1,
        MltVariant::Mmlt | MltVariant::Rjmlt => settings.max_depth as u64 + 1,
    };
    // MLT's per-depth images are layers of one W × (H·D) film (`driver` docs).
    let film = mul(mul(pixels, depths, "the per-depth film")?, FILM_PIXEL_BYTES, "the per-depth film")?;
    let film = film.checked_add(image).ok_or_else(|| too_large("the film"))?;
    let bootstrap = mul(mul(settings.bootstrap, depths, "the bootstrap")?, BOOTSTRAP_PATH_BYTES, "the bootstrap")?;
    let subchain = mul(settings.max_depth as u64 + 2, SUBCHAIN_BYTES_PER_VERTEX, "a sub-chain")?;
    let chains = mul(mul(settings.chains, depths, "the chains")?, subchain, "the chains")?;
    let chains = bootstrap.checked_add(chains).ok_or_else(|| too_large("the chains"))?;
    Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains })
}

/// The memory this process may use in all, its scene included: the cgroup's `memory.max` when
/// it is set and finite, else the kernel's `MemAvailable` plus `held` (the bytes the process
/// already holds for the scene, which `MemAvailable`, read after the scene was built, no longer
/// counts); the smaller of the two when both are known. `None` when neither can be read (then
/// nothing is refused).
pub fn available_memory(held: u64) -> Option<u64> {
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok().and_then(|s| s.trim().parse::<u64>().ok());
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok().and_then(|text| {
        text.lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))
            .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .and_then(|kib| kib.checked_mul(1024))
            .map(|bytes| bytes.saturating_add(held))
    });
    match (cgroup, meminfo) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Bytes as GiB for messages.
pub fn gib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 30) as f64
}

/// Refuses a render whose estimate exceeds `available` bytes, naming the estimate's parts.
pub fn check_fits(memory: &RenderMemory, width: u32, height: u32, available: Option<u64>) -> Result<(), RenderError> {
    let Some(available) = available else { return Ok(()) };
    if memory.total() > available {
        return Err(RenderError::Limit(format!(
            "a {width}x{height} render needs at least {:.2} GiB (scene {:.2}: meshes {:.2} and their corners {:.2}, \
             accelerator {:.2}, lights {:.2}, textures {:.2}; film {:.2}, pass buffers {:.2}, chains {:.2}) but only {:.2} GiB are \
             available to the process; lower the resolution{}",
            gib(memory.total()),
            gib(memory.scene.total()),
            gib(memory.scene.meshes),
            gib(memory.scene.corners),
            gib(memory.scene.accel),
            gib(memory.scene.lights),
            gib(memory.scene.textures),
            gib(memory.film),
            gib(memory.pass_buffers),
            gib(memory.chains),
            gib(available),
            if memory.chains > 0 { ", max_depth, bootstrap or chains (emlt: ensemble_size or pairs)" } else { "" }
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_maximum_film_is_counted_in_full() {
        // 65536² pixels × (24 + 12) bytes = 144 GiB of film, 64 GiB of pass buffers.
        let m = render_memory("pt", &toml::Table::new(), 65536, 65536).expect("fits in u64");
        assert_eq!(m.film, (1u64 << 32) * 36);
        assert_eq!(m.pass_buffers, (1u64 << 32) * 16);
        assert_eq!(m.total(), 208 << 30);
        assert!(check_fits(&m, 65536, 65536, Some(m.total() - 1)).is_err());
        assert!(check_fits(&m, 65536, 65536, Some(m.total())).is_ok());
        assert!(check_fits(&m, 65536, 65536, None).is_ok());
        // The scene's bytes count too.
        let scene = SceneMemory { meshes: 1, corners: 0, accel: 2, accel_build: 0, lights: 3, textures: 4 };
        let with = m.with_scene(scene);
        assert_eq!(with.total(), m.total() + 10);
        assert!(check_fits(&with, 65536, 65536, Some(m.total())).is_err());
        // The corner copies are made once the build's temporaries are freed: the larger counts.
        let built = SceneMemory { meshes: 10, corners: 5, accel: 20, accel_build: 8, lights: 1, textures: 2 };
        assert_eq!(built.total(), 10 + 20 + 8 + 1 + 2);
        assert_eq!(SceneMemory { corners: 9, ..built }.total(), 10 + 20 + 9 + 1 + 2);
    }

    #[test]
    fn mlt_counts_every_depth_layer_and_the_bootstrap() {
        let params: toml::Table = toml::from_str("max_depth = 7\nbootstrap = 1000\nchains = 10").expect("toml");
        let m = render_memory("mmlt", &params, 10, 10).expect("small");
        assert_eq!(m.film, 100 * 8 * 24 + 100 * 12);
        assert_eq!(m.chains, 1000 * 8 * 12 + 10 * 8 * 9 * 128);
        let pssmlt = render_memory("pssmlt", &params, 10, 10).expect("small");
        assert_eq!(pssmlt.film, 100 * 24 + 100 * 12);
        // pmlt: one film layer, the bootstrap's targets, two paths of max_depth + 2 vertices a chain.
        let pmlt = render_memory("pmlt", &params, 10, 10).expect("small");
        assert_eq!(pmlt.film, 100 * 24 + 100 * 12);
        assert_eq!(pmlt.chains, 1000 * 12 + 10 * 2 * 9 * PATH_VERTEX_BYTES);
        let huge: toml::Table =
            toml::from_str("chains = 16777216\nmax_depth = 1024\nbootstrap = 4294967296").expect("toml");
        assert!(render_memory("pmlt", &huge, 10, 10).expect("counted").total() > 1 << 40);
    }

    /// emlt: a film layer per pair, the bootstrap's targets, 2 × ensemble_size × pairs chains of
    /// two paths each, and per pair the view of Y (places and indices of ensemble_size paths).
    /// Without its branch emlt counted as an image integrator: chains 0.
    #[test]
    fn emlt_counts_its_pairs_chains_and_views() {
        let params: toml::Table =
            toml::from_str("max_depth = 7\nbootstrap = 1000\nensemble_size = 10\npairs = 3").expect("toml");
        let m = render_memory("emlt", &params, 10, 10).expect("small");
        assert_eq!(m.film, 3 * 100 * 24 + 100 * 12);
        let view = 9 * 24 + 8;
        assert_eq!(m.chains, 1000 * 12 + 3 * 2 * 10 * 2 * 9 * PATH_VERTEX_BYTES + 3 * 10 * view);
        let huge: toml::Table = toml::from_str("ensemble_size = 8388608\nmax_depth = 1024").expect("toml");
        let m = render_memory("emlt", &huge, 10, 10).expect("counted");
        assert!(m.chains > 1 << 40, "{m:?}");
        assert!(check_fits(&m, 10, 10, Some(64 << 30)).is_err());
    }
}
