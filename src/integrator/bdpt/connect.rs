//! One bidirectional technique (s, t): connect the first `s` vertices of a light subpath with the
//! first `t` vertices of a camera subpath and return the path's unweighted contribution, its MIS
//! weight, where it lands on the film and, on request, every alternative technique's weight for
//! the same path. BDPT sums all techniques; MMLT evaluates one at a time (MMLT paper Sec. 4, "we
//! connect subpaths only at their endpoints"); RJMLT reads the weight vector to choose its jumps.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN densities along with zero and negative ones.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::Vec2;

use crate::sampling::UniformSource;
use crate::scene::Scene;
use crate::spectrum::{is_black, Rgb};
use crate::stats::Counters;

use super::mis::{density_ratios, weight_from_ratios, weights_from_ratios, ConnectionView};
use super::vertex::{geometry_term, Vertex, VertexKind};
use super::BdptContext;

/// The result of evaluating one technique.
#[derive(Clone, Debug)]
pub struct TechniqueSample {
    /// Light subpath vertices used.
    pub s: usize,
    /// Camera subpath vertices used (the pinhole included).
    pub t: usize,
    /// The unweighted contribution C_{s,t} = f(x̄) / p_{s,t}(x̄), visibility included.
    pub contribution: Rgb,
    /// The technique's MIS weight w_{s,t}(x̄) under the context's heuristic.
    pub mis_weight: f32,
    /// Continuous raster position the contribution belongs to (for t = 1, where the light
    /// subpath's end projects; otherwise the camera subpath's film sample).
    pub raster: Vec2,
    /// The sampled endpoint for s = 1 (an emitter point) or t = 1 (the camera), which replaces the
    /// subpath's last vertex in the full path.
    pub sampled: Option<Vertex>,
}

impl TechniqueSample {
    /// `mis_weight · contribution`, what BDPT adds to the image.
    pub fn weighted(&self) -> Rgb {
        self.contribution * self.mis_weight
    }
}

/// Scratch buffers reused between evaluations (no allocation per connection).
#[derive(Clone, Debug, Default)]
pub struct ConnectScratch {
    pub ratios: Vec<f64>,
}

/// Evaluates the technique (s, t) on the given subpaths (`light.len() >= s`, `camera.len() >= t`,
/// t ≥ 1). `raster` is the camera subpath's film position. For s = 1 a fresh point on an emitter
/// is chosen with `CONNECTION_DIMS` numbers from `connection`; for t = 1 the camera is connected
/// deterministically. Returns None when the contribution is zero (including occlusion; shadow rays
/// are counted in `counters`). When `alternatives` is given it receives, at index i, the weight of
/// the technique with i light vertices for the same path (index s is this technique's weight).
#[allow(clippy::too_many_arguments)]
pub fn evaluate_technique<S: UniformSource>(
    ctx: &BdptContext,
    light: &[Vertex],
    camera: &[Vertex],
    s: usize,
    t: usize,
    raster: Vec2,
    connection: &mut S,
    scratch: &mut ConnectScratch,
    counters: &mut Counters,
    alternatives: Option<&mut Vec<f32>>,
) -> Option<TechniqueSample> {
    let scene = ctx.scene;
    if t == 0 || t > camera.len() || s > light.len() {
        return None;
    }
    // An environment reached by a camera ray is only an emitter for s = 0.
    if s > 0 && camera[t - 1].infinite {
        return None;
    }
    let mut raster = raster;
    let mut sampled: Option<Vertex> = None;
    let contribution: Rgb = if s == 0 {
        // The camera subpath hit an emitter on its own.
        let pt = &camera[t - 1];
        if !pt.is_light() || t < 2 {
            return None;
        }
        pt.beta * pt.le(scene, &camera[t - 2])
    } else if t == 1 {
        // Light tracing: connect the light subpath's end to the pinhole.
        let qs = &light[s - 1];
        if !qs.connectible(scene) || qs.infinite {
            return None;
        }
        let (value, cam_vertex, pos) = connect_to_camera(ctx, qs, counters)?;
        raster = pos;
        sampled = Some(cam_vertex);
        value
    } else if s == 1 {
        // Next-event estimation: a fresh point on an emitter, chosen with the connection stream.
        let pt = &camera[t - 1];
        let u_light = connection.next_1d();
        let u_li: [f32; crate::light::LI_SAMPLE_DIMS] = connection.next_n();
        if !pt.connectible(scene) {
            return None;
        }
        let (v, value) = sample_light_point(ctx, pt, u_light, u_li, counters)?;
        sampled = Some(v);
        value
    } else {
        let qs = &light[s - 1];
        let pt = &camera[t - 1];
        if !qs.connectible(scene) || !pt.connectible(scene) || qs.infinite {
            return None;
        }
        let value = qs.beta * qs.f(scene, pt) * pt.f(scene, qs) * pt.beta;
        if is_black(value) {
            return None;
        }
        let g = geometry_term(qs, pt);
        if !(g > 0.0) {
            return None;
        }
        counters.shadow_rays += 1;
        if !mutually_visible(scene, qs, pt) {
            return None;
        }
        value * g
    };
    if is_black(contribution) {
        return None;
    }

    let (qs, pt) = match (s, t) {
        (_, 1) => (Some(&light[s - 1]), sampled.as_ref()),
        (0, _) => (None, Some(&camera[t - 1])),
        (1, _) => (sampled.as_ref(), Some(&camera[t - 1])),
        _ => (Some(&light[s - 1]), Some(&camera[t - 1])),
    };
    let view = ConnectionView { light, camera, s, t, qs, pt };
    density_ratios(scene, &view, &mut scratch.ratios);
    let mis_weight = weight_from_ratios(ctx.heuristic, &scratch.ratios);
    if let Some(out) = alternatives {
        weights_from_ratios(ctx.heuristic, &scratch.ratios, out);
    }
    Some(TechniqueSample { s, t, contribution, mis_weight, raster, sampled })
}

/// Connects a light-subpath vertex to the pinhole (t = 1): returns the unweighted contribution
/// (visibility tested), the camera vertex as sampled, and the raster position. Shared by BDPT's
/// t = 1 techniques and the pure light tracer.
pub(crate) fn connect_to_camera(
    ctx: &BdptContext,
    qs: &Vertex,
    counters: &mut Counters,
) -> Option<(Rgb, Vertex, Vec2)> {
    let scene = ctx.scene;
    let cs = scene.camera.sample_wi(qs.p)?;
    if !(cs.pdf > 0.0) || is_black(cs.importance) {
        return None;
    }
    let cam = Vertex::camera(scene.camera.position, cs.importance / cs.pdf);
    let mut value = if qs.kind == VertexKind::Light {
        // The emitter point itself seen by the camera (pure light tracing's s = 1): the
        // emitted radiance towards the camera over the point's selection and area density.
        let le = qs.le(scene, &cam);
        let pdf_origin = qs.pdf_light_origin(scene, &cam);
        if !(pdf_origin > 0.0) {
            return None;
        }
        le / pdf_origin * cam.beta
    } else {
        qs.beta * qs.f_dir(scene, cs.wi) * cam.beta
    };
    if qs.on_surface() {
        value *= cs.wi.dot(qs.frame.n).abs();
    }
    if is_black(value) {
        return None;
    }
    counters.shadow_rays += 1;
    if !mutually_visible(scene, qs, &cam) {
        return None;
    }
    Some((value, cam, cs.raster))
}

/// Next-event estimation from camera vertex `pt`: chooses an emitter with `u_light` and a point on
/// it with `u_li`; returns the light vertex (pdf_fwd set to its light-subpath density, as the MIS
/// recurrence needs) and the unweighted contribution with visibility tested.
fn sample_light_point(
    ctx: &BdptContext,
    pt: &Vertex,
    u_light: f32,
    u_li: [f32; crate::light::LI_SAMPLE_DIMS],
    counters: &mut Counters,
) -> Option<(Vertex, Rgb)> {
    let scene = ctx.scene;
    let distribution = &scene.light_sampler.distribution;
    if distribution.is_empty() || scene.lights.is_empty() {
        return None;
    }
    let (li, pmf, _) = distribution.sample_discrete(u_light);
    if !(pmf > 0.0) || li >= scene.lights.len() {
        return None;
    }
    let ls = scene.lights[li].sample_li(pt.p, u_li)?;
    if !(ls.pdf > 0.0) || is_black(ls.radiance) {
        return None;
    }
    let beta = ls.radiance / (ls.pdf * pmf);
    let mut v = if ls.infinite {
        Vertex::environment_light(li as u32, -ls.wi, beta, 0.0)
    } else {
        Vertex::area_light(li as u32, ls.p, ls.n, beta, 0.0)
    };
    v.pdf_fwd = v.pdf_light_origin(scene, pt);
    let mut value = pt.beta * pt.f_dir(scene, ls.wi) * v.beta;
    if pt.on_surface() {
        value *= ls.wi.dot(pt.frame.n).abs();
    }
    if is_black(value) {
        return None;
    }
    counters.shadow_rays += 1;
    if !mutually_visible(scene, pt, &v) {
        return None;
    }
    Some((v, value))
}

/// Whether nothing blocks the segment between two vertices (or the ray from `a` towards an
/// environment vertex).
pub fn mutually_visible(scene: &Scene, a: &Vertex, b: &Vertex) -> bool {
    let (a, b) = if a.infinite { (b, a) } else { (a, b) };
    if b.infinite {
        let ray = crate::geometry::spawn_ray(a.p, a.p_error, a.ng, -b.dir);
        return !scene.occluded(&ray);
    }
    let ray = crate::geometry::spawn_ray_to(a.p, a.p_error, a.ng, b.p, b.p_error, b.ng);
    !scene.occluded(&ray)
}
