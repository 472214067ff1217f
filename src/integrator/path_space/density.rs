//! Generating one vertex from its neighbour, and the density of having done so, side by side: the
//! building blocks of every mutation's `propose` and `transition`. Densities are per unit area at
//! the new vertex (per unit solid angle for a vertex at infinity), in the delta-stripped convention
//! (module docs, "Measure"): at a specular vertex the lobe's selection probability takes the place
//! of the directional density. The samplers are BDPT's (the pinhole over the whole film, emission,
//! BSDF sampling), so these densities are BDPT's `Vertex::pdf` family, except at delta lobes, which
//! BDPT counts as density 0 (it never connects there) and a mutation must count as their mass.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN densities along with zero and negative ones.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::Vec3;

use crate::geometry::{spawn_ray, Ray};
use crate::integrator::bdpt::{Vertex, VertexKind};
use crate::light::{sample_emission_direction, Light};
use crate::material::TransportMode;
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::spectrum::Rgb;
use crate::stats::Counters;

/// Which end of the path a walk grows from: the camera (radiance transport, towards the light) or
/// the emitter (importance transport, towards the camera).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Camera,
    Light,
}

impl Side {
    fn mode(self) -> TransportMode {
        match self {
            Side::Camera => TransportMode::Radiance,
            Side::Light => TransportMode::Importance,
        }
    }
}

/// The first surface along `ray`, as a vertex reached from the walk's previous vertex; for a camera
/// walk that leaves the scene, the environment as a vertex at infinity (if the scene has one).
pub(super) fn trace(scene: &Scene, ray: &Ray, side: Side, counters: &mut Counters) -> Option<Vertex> {
    counters.rays += 1;
    match scene.intersect(ray) {
        Some(si) => Some(Vertex::surface(scene, &si, -ray.d, Rgb::ONE, side.mode())),
        None if side == Side::Camera && scene.environment.is_some() => {
            Some(Vertex::escaped(scene.environment, ray.d, Rgb::ONE, 0.0))
        }
        None => None,
    }
}

/// Samples the vertex that follows `from` on `side`, `prev` being the vertex before `from` on the
/// same side (None at the pinhole and at an emitter point). Returns None when the sample fails or
/// the ray leaves the scene without an environment to meet. The densities are [`density_next`].
///
/// - the pinhole: a raster position uniform over the whole film (BDPT's `FilmRegion::WholeFilm`);
/// - an emitter point (the light vertex kept by a mutation): a cosine-weighted emission direction;
///   a kept environment vertex cannot be continued (its ray's origin on the scene's disk is not
///   part of the vertex), which [`density_next`] reports as density 0;
/// - a surface: its BSDF (a delta lobe by its selection probability).
pub fn sample_next(
    scene: &Scene,
    from: &Vertex,
    prev: Option<&Vertex>,
    side: Side,
    rng: &mut Rng,
    counters: &mut Counters,
) -> Option<Vertex> {
    let ray = match from.kind {
        VertexKind::Camera => {
            let u = [rng.uniform(), rng.uniform()];
            scene.camera.sample_ray(u)
        }
        VertexKind::Light => {
            let Some(Light::Area(area)) = from.light.map(|l| &scene.lights[l as usize]) else { return None };
            if from.infinite {
                return None;
            }
            let dir = sample_emission_direction(from.ng, area.two_sided, [rng.uniform(), rng.uniform()]);
            spawn_ray(from.p, from.p_error, from.ng, dir)
        }
        VertexKind::Surface => {
            let prev = prev?;
            if from.infinite {
                return None;
            }
            let material = from.bsdf(scene);
            let wo = from.frame.to_local(from.dir_to(prev));
            let u = [rng.uniform(), rng.uniform(), rng.uniform()];
            let bs = material.sample(wo, u, side.mode())?;
            if !(bs.pdf > 0.0) {
                return None;
            }
            let wi = from.frame.to_world(bs.wi).normalize();
            spawn_ray(from.p, from.p_error, from.ng, wi)
        }
    };
    trace(scene, &ray, side, counters)
}

/// Area density (solid angle for a vertex at infinity) at `next` of [`sample_next`] producing it
/// from `from` with predecessor `prev` on `side`.
pub fn density_next(scene: &Scene, from: &Vertex, prev: Option<&Vertex>, next: &Vertex, side: Side) -> f64 {
    let _ = side; // BSDF densities do not depend on the transport mode.
    let pdf = match from.kind {
        VertexKind::Camera => scene.camera.pdf_we(from.dir_to(next)).1,
        VertexKind::Light => {
            if from.infinite {
                return 0.0;
            }
            // The emission direction's density, already converted to area at `next`.
            return from.pdf_light(scene, next) as f64;
        }
        VertexKind::Surface => {
            let Some(prev) = prev else { return 0.0 };
            if from.infinite {
                return 0.0;
            }
            let material = from.bsdf(scene);
            let wo = from.frame.to_local(from.dir_to(prev));
            let wi = from.frame.to_local(from.dir_to(next));
            if material.is_specular() {
                material.pdf_delta(wo, wi)
            } else {
                material.pdf(wo, wi, side.mode())
            }
        }
    };
    if !(pdf > 0.0) {
        return 0.0;
    }
    from.convert_density(pdf, next) as f64
}

/// A new emitter vertex for a light walk that starts from scratch (the mutation deleted the light
/// vertex): a light chosen by power and an emitted ray from it, as BDPT's light subpaths start.
/// Returns the vertex and the emitted ray (which the walk's next step follows: for an environment
/// its origin lies on the scene's disk, which the vertex at infinity does not keep).
pub fn sample_emitter(scene: &Scene, rng: &mut Rng) -> Option<(Vertex, Ray)> {
    let distribution = &scene.light_sampler.distribution;
    if distribution.is_empty() || scene.lights.is_empty() {
        return None;
    }
    let (li, pmf, _) = distribution.sample_discrete(rng.uniform());
    if !(pmf > 0.0) || li >= scene.lights.len() {
        return None;
    }
    let u = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
    let es = scene.lights[li].sample_emission(u)?;
    if !(es.pdf_pos > 0.0) || !(es.pdf_dir > 0.0) {
        return None;
    }
    let v = if es.infinite {
        Vertex::environment_light(li as u32, es.dir, Rgb::ONE, 0.0)
    } else {
        Vertex::area_light(li as u32, es.p, es.n, Rgb::ONE, 0.0)
    };
    let ray = if es.infinite { Ray::new(es.p, es.dir) } else { spawn_ray(es.p, v.p_error, es.n, es.dir) };
    Some((v, ray))
}

/// Follows the emitted ray of [`sample_emitter`] to the walk's next vertex.
pub fn trace_emitted(scene: &Scene, ray: &Ray, counters: &mut Counters) -> Option<Vertex> {
    trace(scene, ray, Side::Light, counters)
}

/// Density of [`sample_emitter`] choosing the emitter vertex `v` (area measure on an area light,
/// solid angle for an environment direction): BDPT's `pdf_light_origin`, light selection included.
pub fn density_emitter(scene: &Scene, v: &Vertex) -> f64 {
    // `pdf_light_origin` reads its second argument only for an environment's reference point,
    // which its direction density ignores.
    let reference = Vertex::camera(Vec3::ZERO, Rgb::ONE);
    v.pdf_light_origin(scene, &reference) as f64
}

/// Density at `next` of the emitted ray of [`sample_emitter`] from the new emitter vertex `v`:
/// the direction's density converted to area (area lights) or the ray origin's density on the disk
/// times the cosine at `next` (environments): BDPT's `pdf_light`.
pub fn density_emitted(scene: &Scene, v: &Vertex, next: &Vertex) -> f64 {
    v.pdf_light(scene, next) as f64
}
