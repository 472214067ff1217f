//! Complete paths as vertex lists, and how every technique would have produced the same path.
//!
//! A technique's evaluation leaves its path split between two subpaths; `full_path` joins them in
//! camera-to-light order. `split_path` does the reverse for ANY technique: it rebuilds the two
//! subpaths that technique (s', t') would have generated for the same vertices, with the
//! forward/reverse area densities, delta flags and transport modes the subpath generators would
//! have recorded (throughputs are not rebuilt). `technique_weight` then applies the MIS recurrence
//! from that technique's own point of view. Summing it over the techniques that can produce a path
//! gives 1 exactly when the generators' bookkeeping and the recurrence agree — the test of
//! `tests/images/bdpt.rs` — and RJMLT can use the same functions on a path it has inverted.

use crate::geometry::Frame;
use crate::material::TransportMode;
use crate::scene::Scene;

use super::mis::{density_ratios, weight_from_ratios, ConnectionView, MisHeuristic};
use super::vertex::{Vertex, VertexKind};
use super::TechniqueSample;

/// The complete path of an evaluated technique, camera first, emitter last: camera vertices
/// 0..t (the sampled camera for t = 1) followed by light vertices s−1..0 (the sampled emitter
/// point for s = 1).
pub fn full_path(light: &[Vertex], camera: &[Vertex], technique: &TechniqueSample) -> Vec<Vertex> {
    let (s, t) = (technique.s, technique.t);
    let mut path = Vec::with_capacity(s + t);
    if t == 1 {
        path.push(technique.sampled.unwrap_or(camera[0]));
    } else {
        path.extend_from_slice(&camera[..t]);
    }
    for j in (0..s).rev() {
        if j == 0 && s == 1 && t > 1 {
            path.push(technique.sampled.unwrap_or(light[0]));
        } else {
            path.push(light[j]);
        }
    }
    path
}

/// Whether technique (s', t') with `t_prime` camera vertices can produce `path` at all: its two
/// connection vertices must both be connectible (no delta lobe at either), t' ≥ 1, and the (1, 1)
/// technique is never used.
pub fn technique_can_sample(scene: &Scene, path: &[Vertex], t_prime: usize) -> bool {
    let n = path.len();
    if t_prime == 0 || t_prime > n {
        return false;
    }
    let s_prime = n - t_prime;
    if s_prime == 1 && t_prime == 1 {
        return false;
    }
    if s_prime == 0 {
        return path[n - 1].is_light();
    }
    let pt = &path[t_prime - 1];
    let qs = &path[t_prime];
    let ok = |v: &Vertex, is_light_end: bool| -> bool {
        if is_light_end || v.kind == VertexKind::Camera {
            return true;
        }
        !v.infinite && !scene.materials[v.material as usize].is_specular()
    };
    ok(pt, false) && ok(qs, t_prime == n - 1)
}

/// Rebuilds the light and camera subpaths technique (n − t', t') would have generated for `path`
/// (camera first), with the densities and flags its generators record.
pub fn split_path(scene: &Scene, path: &[Vertex], t_prime: usize) -> (Vec<Vertex>, Vec<Vertex>) {
    let n = path.len();
    let s_prime = n - t_prime;
    let specular = |v: &Vertex| -> bool {
        v.kind == VertexKind::Surface && !v.infinite && scene.materials[v.material as usize].is_specular()
    };
    let mut camera: Vec<Vertex> = Vec::with_capacity(t_prime);
    for i in 0..t_prime {
        let mut v = path[i];
        v.mode = TransportMode::Radiance;
        v.delta = false;
        if i == 0 {
            v.kind = VertexKind::Camera;
        } else {
            if v.kind == VertexKind::Light {
                // The emitter reached by the camera subpath (s' = 0): a surface hit on a light.
                v.kind = VertexKind::Surface;
            }
            v.wo = v.dir_to(&path[i - 1]);
            v.delta = i + 1 < t_prime && specular(&v);
        }
        camera.push(v);
    }
    let mut light: Vec<Vertex> = Vec::with_capacity(s_prime);
    for j in 0..s_prime {
        let mut v = path[n - 1 - j];
        v.mode = TransportMode::Importance;
        v.delta = false;
        if j == 0 {
            v.kind = VertexKind::Light;
            if !v.infinite {
                v.frame = Frame::from_normal(v.ng);
            }
        } else {
            v.wo = v.dir_to(&path[n - j]);
            v.delta = j + 1 < s_prime && specular(&v);
        }
        light.push(v);
    }
    // Forward densities, as the generators record them.
    for i in 1..camera.len() {
        let prev = if i >= 2 { Some(camera[i - 2]) } else { None };
        let pdf = camera[i - 1].pdf(scene, prev.as_ref(), &camera[i]);
        camera[i].pdf_fwd = pdf;
    }
    // Reverse densities inside the camera subpath (the last two are the connection's business).
    for i in 0..camera.len().saturating_sub(2) {
        let next2 = camera[i + 2];
        let pdf = camera[i + 1].pdf(scene, Some(&next2), &camera[i]);
        camera[i].pdf_rev = pdf;
    }
    if !light.is_empty() {
        // The emitter point's density is that of the light subpath's origin towards its next
        // vertex (the camera-side connection vertex when s' = 1).
        let next = if light.len() >= 2 { light[1] } else { *camera.last().expect("t' >= 1") };
        light[0].pdf_fwd = light[0].pdf_light_origin(scene, &next);
    }
    if light.len() >= 2 {
        light[1].pdf_fwd = light[0].pdf_light(scene, &light[1]);
    }
    for j in 2..light.len() {
        let pdf = light[j - 1].pdf(scene, Some(&light[j - 2]), &light[j]);
        light[j].pdf_fwd = pdf;
    }
    for j in 0..light.len().saturating_sub(2) {
        let next2 = light[j + 2];
        let pdf = light[j + 1].pdf(scene, Some(&next2), &light[j]);
        light[j].pdf_rev = pdf;
    }
    (light, camera)
}

/// The MIS weight of technique (s', t') for the subpaths `split_path` rebuilt for it.
pub fn technique_weight(scene: &Scene, heuristic: MisHeuristic, light: &[Vertex], camera: &[Vertex]) -> f32 {
    let (s, t) = (light.len(), camera.len());
    let view = ConnectionView { light, camera, s, t, qs: light.last(), pt: camera.last() };
    let mut ratios = Vec::new();
    density_ratios(scene, &view, &mut ratios);
    weight_from_ratios(heuristic, &ratios)
}
