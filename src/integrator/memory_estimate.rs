//! Each integrator's estimate of the memory its render needs beyond the scene, for a film of the
//! given size (its row in `registry` names its function here): the buffers that grow with the budget's dimensions (see `driver`'s render model).
//! The types, the process's available memory and the check are the job layer's
//! (`crate::job::memory`); `plexus info` prints the same estimate that `render` checks.
//!
//! Its parts: the film's unnormalised sums (3 × f64 per pixel; MLT stacks one W × H layer per path
//! depth), the normalised output image (3 × f32 per pixel), one pass of splat buffers (16 bytes a
//! contribution, at least one per pixel sample of the pass), and for MLT the bootstrap's targets
//! (one f32 plus one f64 of the discrete distribution per bootstrap path and depth) and the
//! chains' sub-chains (path-space MLT: the chains' paths; ensemble MLT: its 2 × `ensemble_size`
//! chains' paths in each of its `pairs` pairs, one film layer per pair, and per pair the view of
//! its fixed ensemble that the guided strategies read: Y's vertex places and the tree). Every
//! product is checked; an overflow is itself a refusal.

use super::pss::mlt_settings::{DirectEmission, MltSettings, MltVariant};
use super::RenderError;
use crate::job::memory::{add, mul, RenderMemory, SceneMemory};

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

/// Bytes of one vertex of a path-space chain's path (`path_space::PathVertex`).
const PATH_VERTEX_BYTES: u64 = std::mem::size_of::<crate::integrator::path_space::PathVertex>() as u64;
/// Bytes per vertex of a path in an ensemble's view (`ensemble::guide::GuideView`): its place
/// for the similarity weights (a `DVec3`).
const VIEW_PLACE_BYTES: u64 = 3 * 8;
/// Bytes per path of an ensemble's view beyond its places: where its places start (u32) and its
/// index in the tree's signature order (u32, `ensemble::tree::EnsembleTree`).
const VIEW_PATH_BYTES: u64 = 4 + 4;

/// The film's sums (`layers` W × H layers of 3 × f64) with the output image, and one pass of splat
/// buffers: what every integrator holds for a `width`×`height` film.
fn film_and_pass(width: u32, height: u32, layers: u64) -> Result<(u64, u64), RenderError> {
    let pixels = mul(width as u64, height as u64, "the film")?;
    let image = mul(pixels, IMAGE_PIXEL_BYTES, "the output image")?;
    let film = mul(mul(pixels, layers, "the per-depth film")?, FILM_PIXEL_BYTES, "the film")?;
    let film = add(film, image, "the film")?;
    // A pass of the image integrators takes max(1, 2^16 / pixels) samples per pixel; MLT's pass is
    // about one mutation per pixel. Either way at least max(pixels, 2^16) contributions.
    let pass_buffers = mul(pixels.max(MIN_SAMPLES_PER_PASS), SPLAT_BYTES, "a pass's splat buffers")?;
    Ok((film, pass_buffers))
}

/// pt, BDPT and light tracing: one film and a pass's splat buffers; their settings change neither.
pub fn image_memory(_params: &toml::Table, width: u32, height: u32) -> Result<RenderMemory, RenderError> {
    let (film, pass_buffers) = film_and_pass(width, height, 1)?;
    Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains: 0 })
}

/// pssmlt, mmlt and rjmlt: one film layer per path depth (mmlt and rjmlt; pssmlt's one), the
/// bootstrap's targets per depth, and per chain and depth a sub-chain.
pub fn mlt_memory(
    variant: MltVariant,
    params: &toml::Table,
    width: u32,
    height: u32,
) -> Result<RenderMemory, RenderError> {
    let settings = MltSettings::from_params(variant, params)?;
    let depths = match variant {
        MltVariant::Pssmlt => 1,
        MltVariant::Mmlt | MltVariant::Rjmlt => settings.max_depth as u64 + 1,
    };
    // MLT's per-depth images are layers of one W × (H·D) film (`driver` docs); pssmlt's camera
    // estimator of depth 0 has a layer of its own.
    let direct_layer = (variant == MltVariant::Pssmlt && settings.direct_emission == DirectEmission::Camera) as u64;
    let (film, pass_buffers) = film_and_pass(width, height, depths + direct_layer)?;
    let bootstrap = mul(mul(settings.bootstrap, depths, "the bootstrap")?, BOOTSTRAP_PATH_BYTES, "the bootstrap")?;
    let subchain = mul(settings.max_depth as u64 + 2, SUBCHAIN_BYTES_PER_VERTEX, "a sub-chain")?;
    let chains = mul(mul(settings.chains, depths, "the chains")?, subchain, "the chains")?;
    let chains = add(bootstrap, chains, "the chains")?;
    Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains })
}

/// Path-space MLT: one W × H film; the bootstrap's targets; per chain its current path and a
/// proposal (max_depth + 2 vertices each).
pub fn pmlt_memory(params: &toml::Table, width: u32, height: u32) -> Result<RenderMemory, RenderError> {
    let settings = crate::integrator::path_space::PmltSettings::from_params(params)?;
    let (film, pass_buffers) = film_and_pass(width, height, 1)?;
    let bootstrap = mul(settings.bootstrap, BOOTSTRAP_PATH_BYTES, "the bootstrap")?;
    let path = mul(settings.max_depth as u64 + 2, PATH_VERTEX_BYTES, "a chain's path")?;
    let chains = mul(mul(settings.chains, 2, "the chains")?, path, "the chains")?;
    let chains = add(bootstrap, chains, "the chains")?;
    Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains })
}

/// Ensemble MLT: one W × H film layer per pair; the bootstrap's targets; 2 × ensemble_size chains
/// per pair with their current path and a proposal, as pmlt's; and, while a pass runs, per pair
/// the view of Y (ensemble_size paths: their vertex places, place starts and tree order). Y's
/// paths move into the view, so they are not counted twice.
pub fn emlt_memory(params: &toml::Table, width: u32, height: u32) -> Result<RenderMemory, RenderError> {
    let settings = crate::integrator::ensemble::emlt_settings::EmltSettings::from_params(params)?;
    let (film, pass_buffers) = film_and_pass(width, height, settings.pairs)?;
    let bootstrap = mul(settings.bootstrap, BOOTSTRAP_PATH_BYTES, "the bootstrap")?;
    let vertices = settings.max_depth as u64 + 2;
    let path = mul(vertices, PATH_VERTEX_BYTES, "a chain's path")?;
    let chains = mul(mul(settings.ensemble_size, settings.pairs, "the ensembles")?, 2, "the ensembles")?;
    let paths = mul(mul(chains, 2, "the chains")?, path, "the chains")?;
    let view_path = add(mul(vertices, VIEW_PLACE_BYTES, "a view's path")?, VIEW_PATH_BYTES, "a view's path")?;
    let views = mul(mul(settings.ensemble_size, settings.pairs, "the views")?, view_path, "the views")?;
    let chains = add(add(bootstrap, paths, "the chains")?, views, "the chains")?;
    Ok(RenderMemory { scene: SceneMemory::default(), film, pass_buffers, chains })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_maximum_film_is_counted_in_full() {
        // 65536² pixels × (24 + 12) bytes = 144 GiB of film, 64 GiB of pass buffers.
        let m = image_memory(&toml::Table::new(), 65536, 65536).expect("fits in u64");
        assert_eq!(m.film, (1u64 << 32) * 36);
        assert_eq!(m.pass_buffers, (1u64 << 32) * 16);
        assert_eq!(m.total(), 208 << 30);
    }

    #[test]
    fn mlt_counts_every_depth_layer_and_the_bootstrap() {
        let params: toml::Table = toml::from_str("max_depth = 7\nbootstrap = 1000\nchains = 10").expect("toml");
        let m = mlt_memory(MltVariant::Mmlt, &params, 10, 10).expect("small");
        assert_eq!(m.film, 100 * 8 * 24 + 100 * 12);
        assert_eq!(m.chains, 1000 * 8 * 12 + 10 * 8 * 9 * 128);
        // pssmlt: its chains' layer, and by default (`direct_emission = "camera"`) the camera
        // estimator's depth-0 layer beside it; with depth 0 in the chains, the one layer.
        let pssmlt = mlt_memory(MltVariant::Pssmlt, &params, 10, 10).expect("small");
        assert_eq!(pssmlt.film, 100 * 2 * 24 + 100 * 12);
        let mut in_chains = params.clone();
        in_chains.insert("direct_emission".into(), "chains".into());
        let pssmlt = mlt_memory(MltVariant::Pssmlt, &in_chains, 10, 10).expect("small");
        assert_eq!(pssmlt.film, 100 * 24 + 100 * 12);
        // pmlt: one film layer, the bootstrap's targets, two paths of max_depth + 2 vertices a chain.
        let pmlt = pmlt_memory(&params, 10, 10).expect("small");
        assert_eq!(pmlt.film, 100 * 24 + 100 * 12);
        assert_eq!(pmlt.chains, 1000 * 12 + 10 * 2 * 9 * PATH_VERTEX_BYTES);
        let huge: toml::Table =
            toml::from_str("chains = 16777216\nmax_depth = 1024\nbootstrap = 4294967296").expect("toml");
        assert!(pmlt_memory(&huge, 10, 10).expect("counted").total() > 1 << 40);
    }

    #[test]
    fn emlt_counts_its_pairs_chains_and_views() {
        let params: toml::Table =
            toml::from_str("max_depth = 7\nbootstrap = 1000\nensemble_size = 10\npairs = 3").expect("toml");
        let m = emlt_memory(&params, 10, 10).expect("small");
        assert_eq!(m.film, 3 * 100 * 24 + 100 * 12);
        let view = 9 * 24 + 8;
        assert_eq!(m.chains, 1000 * 12 + 3 * 2 * 10 * 2 * 9 * PATH_VERTEX_BYTES + 3 * 10 * view);
        let huge: toml::Table = toml::from_str("ensemble_size = 8388608\nmax_depth = 1024").expect("toml");
        let m = emlt_memory(&huge, 10, 10).expect("counted");
        assert!(m.chains > 1 << 40, "{m:?}");
        assert!(crate::job::memory::check_fits(&m, 10, 10, Some(64 << 30)).is_err());
    }
}
