//! Opacity masks (Mitsuba's `mask`): a surface of opacity α stops a ray with probability α and
//! lets it through otherwise, so that the expected contribution is α·(the surface) + (1 − α)·(what
//! lies behind) — Mitsuba's mask BSDF α·f + (1 − α)·(pass-through), decided stochastically.
//!
//! The decision is a deterministic hash of the ray (origin, direction) and the primitive hit, so a
//! render stays reproducible bit for bit and needs no random numbers from the integrators (pbrt-v4
//! does the same, `HashFloat(ray.o, ray.d)`). Closest-hit and shadow queries use the same rule.
//!
//! In BDPT and MLT the mask needs no term in the pdfs: a vertex on a masked surface exists with
//! probability α whichever side sampled it (a camera ray, a light ray, or an emitter — emitters
//! cannot be masked), and its BSDF carries the same α, so α cancels in every strategy's
//! contribution and in every ratio of pdfs the MIS weights take; the pass-through probability
//! 1 − α of a segment is a visibility factor that every strategy estimates the same way (a traced
//! ray or a shadow ray through the same surface), unbiased because its expectation is the
//! transmittance. The weights stay a partition of unity because they do not depend on it.

use super::Scene;
use crate::geometry::{Ray, SurfaceInteraction};

/// Most masked surfaces one query passes through before it reports the next hit as opaque (a
/// guard against pathological stacks; 256 coplanar cut-outs are far beyond any real scene).
const MAX_PASSES: usize = 256;

/// A uniform in [0, 1) from the ray and the primitive (SplitMix64 finalizer over their bits).
fn hash_uniform(ray: &Ray, si: &SurfaceInteraction) -> f32 {
    let mut h: u64 = 0x9e37_79b9_7f4a_7c15;
    let words = [
        ray.o.x.to_bits(),
        ray.o.y.to_bits(),
        ray.o.z.to_bits(),
        ray.d.x.to_bits(),
        ray.d.y.to_bits(),
        ray.d.z.to_bits(),
        si.geom_id,
        si.prim_id,
    ];
    for w in words {
        h ^= u64::from(w);
        h = h.wrapping_add(0x9e37_79b9_7f4a_7c15);
        h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h ^= h >> 31;
    }
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Whether the surface at `si`, reached along `ray`, stops it.
fn stops(scene: &Scene, ray: &Ray, si: &SurfaceInteraction) -> bool {
    let alpha = scene.materials[scene.shapes[si.geom_id as usize].material as usize].opacity_at(si.uv);
    alpha >= 1.0 || (alpha > 0.0 && hash_uniform(ray, si) < alpha)
}

/// The ray continuing `ray` past the surface at `si`, up to the same end point.
fn continue_past(ray: &Ray, si: &SurfaceInteraction) -> Ray {
    let mut next = si.spawn(ray.d);
    if ray.t_max.is_finite() {
        let end = ray.o + ray.d * ray.t_max;
        next.t_max = (end - next.o).dot(ray.d) / ray.d.length_squared();
    }
    next
}

/// The first surface along `ray` that stops it, starting from the accelerator's first hit `si`.
pub(super) fn closest_opaque(scene: &Scene, ray: &Ray, mut si: SurfaceInteraction) -> Option<SurfaceInteraction> {
    let mut current = *ray;
    for _ in 0..MAX_PASSES {
        if stops(scene, &current, &si) {
            // `t` is measured along the query's ray, as without masks.
            si.t = (si.p - ray.o).dot(ray.d) / ray.d.length_squared();
            return Some(si);
        }
        current = continue_past(&current, &si);
        if !(current.t_max > 0.0) {
            return None;
        }
        let hit = scene.accel.intersect(&current)?;
        si = scene.surface(&hit);
    }
    si.t = (si.p - ray.o).dot(ray.d) / ray.d.length_squared();
    Some(si)
}

/// Whether a surface along `ray` stops it.
pub(super) fn occluded(scene: &Scene, ray: &Ray) -> bool {
    let Some(hit) = scene.accel.intersect(ray) else { return false };
    let si = scene.surface(&hit);
    closest_opaque(scene, ray, si).is_some()
}
