//! Camera and light subpath generation, driven by explicit uniforms read from a
//! `sampling::UniformSource` (an independent `Rng`, a replayed list, or a primary-sample-space chain).
//!
//! # Dimension layout (each subpath reads its own stream)
//!
//! | stream | dimensions |
//! | --- | --- |
//! | camera | `[0, 2)` film position; then per bounce `i` (from 0) the block `[2 + 4i, 6 + 4i)`: BSDF lobe, BSDF direction (2), Russian roulette |
//! | light | `0` light selection, `[1, 6)` emission (position 3, direction 2); then per bounce `i` the block `[6 + 4i, 10 + 4i)` laid out as on the camera stream |
//! | connection | per `s = 1` connection, 4 numbers: light selection, then `Light::sample_li`'s 3 |
//!
//! Every block is read whole whether or not it is used (a specular lobe ignores its direction
//! numbers, Russian roulette before `rr_depth` ignores its number), so vertex `i` of a subpath is
//! always produced by the same coordinates: primary-sample-space MLT can mutate them and
//! reversible-jump MLT can write inverted numbers into them without shifting anything else.
//! `t = 1` connections read nothing (the pinhole has no lens).

// `!(x > 0.0)` is deliberate throughout: it rejects NaN densities along with zero and negative ones.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::{UVec2, Vec2};

use crate::camera::CAMERA_SAMPLE_DIMS;
use crate::light::EMISSION_SAMPLE_DIMS;
use crate::material::{TransportMode, BSDF_SAMPLE_DIMS};
use crate::sampling::UniformSource;
use crate::spectrum::{luminance, Rgb};
use crate::stats::Counters;

use super::vertex::Vertex;
use super::BdptContext;

/// Film dimensions at the start of the camera stream.
pub const CAMERA_FILM_DIMS: usize = CAMERA_SAMPLE_DIMS;
/// Dimensions every bounce reads: the BSDF's, then one for Russian roulette.
pub const BOUNCE_DIMS: usize = BSDF_SAMPLE_DIMS + 1;
/// Dimensions at the start of the light stream: light selection, then emission.
pub const LIGHT_START_DIMS: usize = 1 + EMISSION_SAMPLE_DIMS;
/// Dimensions one `s = 1` connection reads from the connection stream.
pub const CONNECTION_DIMS: usize = 1 + crate::light::LI_SAMPLE_DIMS;

/// Where the camera subpath's film sample lands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilmRegion {
    /// Inside one pixel (BDPT, light tracing estimates per pixel).
    Pixel(UVec2),
    /// Anywhere on the film, uniformly (primary-sample-space MLT).
    WholeFilm,
}

/// Fills `path` with a camera subpath of at most `max_vertices` vertices (the pinhole included)
/// and returns the continuous raster position of its primary ray. The camera vertex has
/// throughput 1: for a pinhole, W_e·cos / (pdf_pos·pdf_dir) = 1 for film positions drawn uniformly
/// (pbrt-v4 Sec. 16.1.1), per pixel or over the whole film alike.
pub fn generate_camera_subpath<S: UniformSource>(
    ctx: &BdptContext,
    region: FilmRegion,
    sampler: &mut S,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    counters: &mut Counters,
) -> Vec2 {
    path.clear();
    let camera = &ctx.scene.camera;
    let u = sampler.next_2d();
    let raster = match region {
        FilmRegion::Pixel(px) => Vec2::new(px.x as f32 + u[0], px.y as f32 + u[1]),
        FilmRegion::WholeFilm => Vec2::new(u[0] * camera.width as f32, u[1] * camera.height as f32),
    };
    if max_vertices == 0 {
        return raster;
    }
    let ray = camera.ray_through(raster);
    path.push(Vertex::camera(ray.o, Rgb::ONE));
    if max_vertices == 1 {
        return raster;
    }
    random_walk(ctx, ray, sampler, Rgb::ONE, max_vertices - 1, TransportMode::Radiance, path, counters);
    raster
}

/// Fills `path` with a light subpath of at most `max_vertices` vertices (the emitter point
/// included). Returns false (and an empty path) when the scene has no emitter or the emission
/// sample failed.
pub fn generate_light_subpath<S: UniformSource>(
    ctx: &BdptContext,
    sampler: &mut S,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    counters: &mut Counters,
) -> bool {
    path.clear();
    let scene = ctx.scene;
    let u_light = sampler.next_1d();
    let u_emit: [f32; EMISSION_SAMPLE_DIMS] = sampler.next_n();
    let distribution = &scene.light_sampler.distribution;
    if max_vertices == 0 || distribution.is_empty() || scene.lights.is_empty() {
        return false;
    }
    let (li, pmf, _) = distribution.sample_discrete(u_light);
    if !(pmf > 0.0) || li >= scene.lights.len() {
        return false;
    }
    let light = &scene.lights[li];
    let Some(es) = light.sample_emission(u_emit) else { return false };
    if !(es.pdf_pos > 0.0) || !(es.pdf_dir > 0.0) || crate::spectrum::is_black(es.radiance) {
        return false;
    }
    let li = li as u32;
    // The vertex's pdf_fwd is set below from the path's geometry (pdf_light_origin) so that it is
    // the same function of the path as in every MIS evaluation; the throughput uses the densities
    // the sample was actually drawn with.
    let v0 = if es.infinite {
        Vertex::environment_light(li, es.dir, es.radiance / (pmf * es.pdf_pos), 0.0)
    } else {
        Vertex::area_light(li, es.p, es.n, es.radiance / (pmf * es.pdf_pos), 0.0)
    };
    path.push(v0);
    let beta = es.radiance * es.n.dot(es.dir).abs() / (pmf * es.pdf_pos * es.pdf_dir);
    if max_vertices == 1 {
        return true;
    }
    let ray = if es.infinite {
        crate::geometry::Ray::new(es.p, es.dir)
    } else {
        crate::geometry::spawn_ray(es.p, path[0].p_error, es.n, es.dir)
    };
    random_walk(ctx, ray, sampler, beta, max_vertices - 1, TransportMode::Importance, path, counters);
    if path.len() > 1 {
        let (v0, rest) = path.split_first_mut().expect("path has two vertices");
        let v1 = &mut rest[0];
        // For an environment the direction density already chose the point's direction; the disk
        // position density converts to area at v1 by the cosine alone (pbrt-v4 Sec. 13.4.2).
        v1.pdf_fwd = v0.pdf_light(scene, v1);
        v0.pdf_fwd = v0.pdf_light_origin(scene, v1);
    }
    true
}

/// Appends `v` (reached from the path's last vertex) and records the densities that involve it:
/// its forward density from the previous vertex and the reverse density of the vertex before that.
/// Both are computed by `Vertex::pdf` from the vertex positions, not from the sampled direction,
/// so that they are the same function of the path as when `path::split_path` rebuilds any other
/// technique's subpaths: the MIS weights of all techniques then sum to one up to rounding even for
/// vertices a fraction of a millimetre apart, where a ray's offset origin bends the direction
/// between the hit points away from the sampled one. A delta vertex has no density either way.
fn push_with_densities(scene: &crate::scene::Scene, path: &mut Vec<Vertex>, mut v: Vertex) {
    let k = path.len();
    let prev = path[k - 1];
    v.pdf_fwd = if prev.delta {
        0.0
    } else if k >= 2 {
        prev.pdf(scene, Some(&path[k - 2]), &v)
    } else {
        prev.pdf(scene, None, &v)
    };
    if k >= 2 {
        path[k - 2].pdf_rev = if prev.delta { 0.0 } else { prev.pdf(scene, Some(&v), &path[k - 2]) };
    }
    path.push(v);
}

/// Extends `path` by following `ray` from its last vertex, scattering at each hit with uniforms
/// from `sampler` (one `BOUNCE_DIMS` block per surface vertex that is extended), until
/// `max_new` vertices have been added, the ray escapes, a BSDF sample fails or Russian roulette
/// stops it.
#[allow(clippy::too_many_arguments)]
fn random_walk<S: UniformSource>(
    ctx: &BdptContext,
    mut ray: crate::geometry::Ray,
    sampler: &mut S,
    mut beta: Rgb,
    max_new: usize,
    mode: TransportMode,
    path: &mut Vec<Vertex>,
    counters: &mut Counters,
) {
    let scene = ctx.scene;
    let start_luminance = luminance(beta).max(f32::MIN_POSITIVE);
    let mut added = 0;
    while added < max_new {
        counters.rays += 1;
        let Some(si) = scene.intersect(&ray) else {
            // Camera rays that escape meet the environment (if any) as a vertex at infinity; light
            // rays that escape carry nothing further.
            if mode == TransportMode::Radiance && scene.environment.is_some() {
                push_with_densities(scene, path, Vertex::escaped(scene.environment, ray.d, beta, 0.0));
            }
            return;
        };
        let v = Vertex::surface(scene, &si, -ray.d, beta, mode);
        push_with_densities(scene, path, v);
        added += 1;
        if added >= max_new {
            return;
        }
        let u: [f32; BOUNCE_DIMS] = sampler.next_n();
        let index = path.len() - 1;
        let v = path[index];
        let material = v.bsdf(scene);
        let wo_l = v.frame.to_local(v.wo);
        let Some(bs) = material.sample(wo_l, [u[0], u[1], u[2]], mode) else { return };
        if !(bs.pdf > 0.0) || crate::spectrum::is_black(bs.f) {
            return;
        }
        let wi = v.frame.to_world(bs.wi).normalize();
        let cos = bs.wi.z.abs();
        beta *= bs.f * (cos / bs.pdf) * super::vertex::shading_correction(mode, v.wo, wi, v.frame.n, v.ng);
        path[index].delta = bs.delta;
        // Russian roulette on the throughput relative to the subpath's start, from `rr_depth`
        // bounces on (the survival probability is not part of the MIS densities, as in pbrt).
        if added >= ctx.rr_depth {
            let survive = (luminance(beta) / start_luminance).min(1.0);
            if !(u[3] < survive) {
                return;
            }
            beta /= survive;
        }
        if !crate::spectrum::is_finite(beta) || crate::spectrum::is_black(beta) {
            return;
        }
        ray = si.spawn(wi);
    }
}
