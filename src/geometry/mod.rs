//! Rays, hits, surface interactions, shading frames and robust ray spawning.
//!
//! Everything here is `f32`, like Embree. Robustness at the extremes (scenes scaled by 1e-3 or 1e4,
//! translated by 1e5) comes from carrying a conservative bound on the floating-point error of every
//! hit point and offsetting spawned rays by that bound, never by a fixed epsilon.

mod frame;
mod interaction;
mod mesh;
mod ray;

pub use frame::Frame;
pub use interaction::SurfaceInteraction;
pub use mesh::{triangle_area, triangle_is_degenerate, triangle_normal, MeshError, TriangleMesh};
pub use ray::{offset_ray_origin, spawn_ray, spawn_ray_to, Aabb, Hit, Ray};

/// γ(n) = nε/(1−nε) with ε the unit roundoff: the standard bound on accumulated rounding error
/// of n floating-point operations (Higham; used the same way by pbrt).
#[inline]
pub fn gamma(n: i32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n as f32 * e) / (1.0 - n as f32 * e)
}
