//! The contribution function f(x̄) of a path, from its vertices alone, visibility included: the
//! one function every proposal of every strategy is evaluated with (module docs, "Measure").
//!
//! For x̄ = x_0 (pinhole) … x_{n−1} (emitter), in radiance transport (wo towards the camera, wi
//! towards the light):
//!
//!   f(x̄) = W(x_0→x_1) · Π_{i=1}^{n−2} f_s(x_{i−1}→x_i→x_{i+1}) · Π_{i=0}^{n−2} g(x_i, x_{i+1}) · Le(x_{n−1}→x_{n−2})
//!
//! - W = W_e·cos θ at the pinhole = 1/(A_film cos³θ) = the camera's directional density (pbrt-v4
//!   Sec. 16.1.1: importance 1/(A cos⁴θ) times the cosine at the pinhole), zero off the film;
//! - g(x_i, x_{i+1}) = |n_s(x_i)·ω| · |n_g(x_{i+1})·ω| / d², the shading cosine at the vertex
//!   that scatters (i ≥ 1; the pinhole's cosine is in W) and the geometric cosine at the vertex the
//!   edge reaches (the Jacobian of solid angle to area there): so f is exactly what a path tracer's
//!   throughput estimates (f_s·|n_s·ω_i| per bounce), with shading normals. An edge to the
//!   environment at infinity is measured in solid angle: g = |n_s(x_i)·ω| (the "|cos| at the
//!   finite end");
//! - a specular vertex's f_s is F/|n_s·ω_i| (the lobe's weight over the cosine, `Material::
//!   eval_delta`), so that f_s·g keeps F: the delta-stripped convention;
//! - every edge must be unoccluded (one shadow ray each), the first edge must land on the film,
//!   the last vertex must be an emitter, and only the endpoints may be at infinity.

use glam::{DVec3, Vec2};

use super::vertex::PathVertex;
use super::PathContext;
use crate::integrator::bdpt::mutually_visible;
use crate::material::TransportMode;
use crate::stats::Counters;

/// f(x̄) and the raster position of x̄ (where its first edge meets the film; (−1, −1) when off the
/// film, with f = 0). In f64: f of a long path in a scene modelled in millimetres is far below f32's
/// range (each edge's 1/d² is ~1e-5 in the Cornell box, so a 9-edge path is ~1e-45 before its
/// emission; in f32, with denormals flushed, depths 7 and 8 of the Cornell box had f = 0 and were
/// missing from the image, 1.2% of its light). Only f/f* ever reaches the film.
pub fn evaluate(ctx: &PathContext, path: &[PathVertex], counters: &mut Counters) -> (DVec3, Vec2) {
    let zero = DVec3::ZERO;
    let off = Vec2::splat(-1.0);
    let scene = ctx.scene;
    let n = path.len();
    if n < 2 || n > ctx.max_depth + 2 {
        return (zero, off);
    }
    let camera = &path[0].vertex;
    let first = &path[1].vertex;
    let d0 = camera.dir_to(first);
    let Some(raster) = scene.camera.raster_of(d0) else { return (zero, off) };
    let w = scene.camera.pdf_we(d0).1;
    if !(w > 0.0) {
        return (zero, raster);
    }
    let light = &path[n - 1].vertex;
    if light.light.is_none() {
        return (zero, raster);
    }
    let mut f = DVec3::splat(w as f64);
    // Scattering at the interior vertices, and the edges' g (geometry without the pinhole's cosine).
    for i in 0..n - 1 {
        let a = &path[i].vertex;
        let b = &path[i + 1].vertex;
        if (a.infinite && i > 0) || (b.infinite && i + 2 < n) {
            return (zero, raster);
        }
        let dir = a.dir_to(b);
        let mut g = 1.0f64;
        if !b.infinite {
            let d2 = (b.p - a.p).as_dvec3().length_squared();
            if !(d2 > 0.0) {
                return (zero, raster);
            }
            g /= d2;
            if b.on_surface() {
                g *= b.ng.dot(dir).abs() as f64;
            }
        }
        if i > 0 {
            let prev = &path[i - 1].vertex;
            let wo = a.frame.to_local(a.dir_to(prev));
            let wi = a.frame.to_local(dir);
            let material = a.bsdf(scene);
            let fs = if material.is_specular() {
                let cos = wi.z.abs();
                if !(cos > 0.0) {
                    return (zero, raster);
                }
                material.eval_delta(wo, wi, TransportMode::Radiance) / cos
            } else {
                material.eval(wo, wi, TransportMode::Radiance)
            };
            f *= (fs * wi.z.abs()).as_dvec3();
        }
        f *= g;
        if !(f.max_element() > 0.0) {
            return (zero, raster);
        }
    }
    f *= light.le(scene, &path[n - 2].vertex).as_dvec3();
    if !(f.max_element() > 0.0) {
        return (zero, raster);
    }
    for i in 0..n - 1 {
        counters.shadow_rays += 1;
        if !mutually_visible(scene, &path[i].vertex, &path[i + 1].vertex) {
            return (zero, raster);
        }
    }
    (f, raster)
}
