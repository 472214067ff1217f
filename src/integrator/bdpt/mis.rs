//! Multiple importance sampling weights of the bidirectional techniques (Veach & Guibas 1995;
//! Veach's thesis Sec. 10.3.4), computed with the ratio recurrence over the path as pbrt-v4 does
//! (Sec. 13.4.4): with p_i the density of the technique with i light vertices,
//! r_{i} = p_{i}/p_s is a running product of pdf_rev/pdf_fwd ratios away from the connection.
//!
//! The recurrence runs in f64 and maps zero densities (delta lobes) to 1 so that ratios neither
//! vanish nor divide by zero; techniques that would connect at a delta vertex get weight zero.
//! Delta emitters (point, spot, directional lights) are not handled: the scene builder refuses
//! them (`light::EmitterKind`), and `emitter_is_delta` stops a render that got one anyway.

use serde::{Deserialize, Serialize};

use crate::scene::Scene;

use super::vertex::Vertex;

/// The MIS heuristic (Veach's thesis Sec. 9.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MisHeuristic {
    /// w_i = p_i / Σ_j p_j (provably close to optimal; the MMLT paper uses it throughout).
    #[default]
    Balance,
    /// w_i = p_i² / Σ_j p_j² (exponent β = 2).
    Power,
    /// Every technique weighted 1 (only meaningful when a single technique runs, e.g. light tracing).
    None,
}

impl MisHeuristic {
    #[inline]
    fn h(self, r: f64) -> f64 {
        match self {
            MisHeuristic::Balance | MisHeuristic::None => r,
            MisHeuristic::Power => r * r,
        }
    }
}

#[inline]
fn remap0(f: f32) -> f64 {
    if f != 0.0 {
        f as f64
    } else {
        1.0
    }
}

/// The vertices and densities of the technique (s, t) as they are once connected: the sampled
/// endpoint replacing a subpath's last vertex for s = 1 and t = 1, and the reverse densities at the
/// two vertices on each side of the connection.
pub(crate) struct ConnectionView<'a> {
    pub light: &'a [Vertex],
    pub camera: &'a [Vertex],
    pub s: usize,
    pub t: usize,
    /// Light vertex `s - 1` as connected (the freshly sampled emitter point when s = 1).
    pub qs: Option<&'a Vertex>,
    /// Camera vertex `t - 1` as connected (the freshly sampled camera point when t = 1).
    pub pt: Option<&'a Vertex>,
}

/// Fills `ratios[i]` (for i = 0..=s+t) with p_i / p_s, the density of the technique with i light
/// vertices and s + t − i camera vertices relative to the technique (s, t) that produced the path;
/// zero for techniques that cannot produce it (connection at a delta vertex, t = 0 on a pinhole).
/// `ratios[s]` is 1.
pub(crate) fn density_ratios(scene: &Scene, c: &ConnectionView, ratios: &mut Vec<f64>) {
    let (s, t) = (c.s, c.t);
    ratios.clear();
    ratios.resize(s + t + 1, 0.0);
    ratios[s] = 1.0;
    if s + t == 2 {
        // Only (0, 2) and (1, 1) could produce a length-0 path (an emitter seen directly), and
        // (1, 1) is never used by BDPT.
        return;
    }
    let qs = c.qs;
    let pt = c.pt;
    let qs_minus = if s > 1 { Some(&c.light[s - 2]) } else { None };
    let pt_minus = if t > 1 { Some(&c.camera[t - 2]) } else { None };

    // Reverse densities at the connection (pbrt-v4 BDPT's MISWeight, the ScopedAssignments).
    let pt_rev = match (pt, qs) {
        (Some(pt), Some(qs)) => qs.pdf(scene, qs_minus, pt),
        (Some(pt), None) => match pt_minus {
            Some(pm) => pt.pdf_light_origin(scene, pm),
            None => 0.0,
        },
        _ => 0.0,
    };
    let pt_minus_rev = match (pt, pt_minus) {
        (Some(pt), Some(pm)) => match qs {
            Some(qs) => pt.pdf(scene, Some(qs), pm),
            None => pt.pdf_light(scene, pm),
        },
        _ => 0.0,
    };
    let qs_rev = match (qs, pt) {
        (Some(qs), Some(pt)) => pt.pdf(scene, pt_minus, qs),
        _ => 0.0,
    };
    let qs_minus_rev = match (qs, qs_minus, pt) {
        (Some(qs), Some(qm), Some(pt)) => qs.pdf(scene, Some(pt), qm),
        _ => 0.0,
    };

    // Camera-side accessors with the overrides applied.
    let cam = |i: usize| -> (f32, f32, bool) {
        if i + 1 == t {
            let v = pt.expect("pt exists when t > 0");
            (pt_rev, v.pdf_fwd, false)
        } else if i + 2 == t {
            let v = &c.camera[i];
            (pt_minus_rev, v.pdf_fwd, v.delta)
        } else {
            let v = &c.camera[i];
            (v.pdf_rev, v.pdf_fwd, v.delta)
        }
    };
    let lig = |i: usize| -> (f32, f32, bool) {
        if i + 1 == s {
            let v = qs.expect("qs exists when s > 0");
            (qs_rev, v.pdf_fwd, false)
        } else if i + 2 == s {
            let v = &c.light[i];
            (qs_minus_rev, v.pdf_fwd, v.delta)
        } else {
            let v = &c.light[i];
            (v.pdf_rev, v.pdf_fwd, v.delta)
        }
    };

    // Techniques with fewer camera vertices: moving the connection one vertex towards the camera
    // multiplies the density by pdf_rev/pdf_fwd of the vertex that changes sides.
    let mut r = 1.0f64;
    for i in (1..t).rev() {
        let (rev, fwd, delta) = cam(i);
        r *= remap0(rev) / remap0(fwd);
        let (_, _, delta_prev) = cam(i - 1);
        // Technique with i camera vertices (s + t − i light vertices).
        ratios[s + t - i] = if !delta && !delta_prev { r } else { 0.0 };
    }
    // ratios[s + t] (t = 0) stays zero: rays never hit a pinhole.
    let mut r = 1.0f64;
    for i in (0..s).rev() {
        let (rev, fwd, delta) = lig(i);
        r *= remap0(rev) / remap0(fwd);
        // pbrt-v4 uses IsDeltaLight of the emitter for i = 0 (no camera path hits a delta
        // emitter); the scene builder refuses delta emitters, so it is false here.
        let delta_prev = if i > 0 { lig(i - 1).2 } else { emitter_is_delta(scene, c) };
        ratios[i] = if !delta && !delta_prev { r } else { 0.0 };
    }
}

/// Whether the emitter that starts the light subpath of `c` (s ≥ 1) is a delta emitter. Nothing
/// else here handles one (`Vertex::pdf_light_origin`, the s = 1 connection and the subpath sampler
/// assume area or infinite emitters), which is why the scene builder refuses them; a scene put
/// together without the builder stops here rather than render with wrong weights.
fn emitter_is_delta(scene: &Scene, c: &ConnectionView) -> bool {
    let emitter = if c.s == 1 { c.qs } else { c.light.first() };
    if let Some(kind) = emitter.and_then(|v| v.light).map(|l| scene.lights[l as usize].kind()) {
        assert!(!kind.is_delta(), "BDPT MIS weights do not handle {kind} emitters (the scene builder refuses them)");
    }
    false
}

/// The MIS weight of the technique whose density ratios are `ratios` (with `ratios[s] = 1`).
pub fn weight_from_ratios(heuristic: MisHeuristic, ratios: &[f64]) -> f32 {
    if heuristic == MisHeuristic::None {
        return 1.0;
    }
    let sum: f64 = ratios.iter().map(|&r| heuristic.h(r)).sum();
    (1.0 / sum) as f32
}

/// Every technique's weight for the same path, `w[i]` for the technique with i light vertices
/// (they sum to one; RJMLT's jump distribution, Bitterli et al. 2017 Eq. 33).
pub fn weights_from_ratios(heuristic: MisHeuristic, ratios: &[f64], out: &mut Vec<f32>) {
    out.clear();
    let sum: f64 = ratios.iter().map(|&r| heuristic.h(r)).sum();
    out.extend(ratios.iter().map(|&r| (heuristic.h(r) / sum) as f32));
}
