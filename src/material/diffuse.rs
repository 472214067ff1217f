//! Lambertian reflection: f = ρ/π on the front hemisphere, sampled by the cosine-weighted warp of
//! `crate::sampling` (whose inverse is exact, so the lobe's direction map is a bijection).

use glam::Vec3;

use crate::sampling::{invert_cosine_hemisphere, pdf_cosine_hemisphere, sample_cosine_hemisphere};
use crate::spectrum::Rgb;

/// f(wo, wi) = ρ/π when both directions are above the horizon.
#[inline]
pub fn eval(reflectance: Rgb, wo: Vec3, wi: Vec3) -> Rgb {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    reflectance * std::f32::consts::FRAC_1_PI
}

/// Cosine-weighted direction; `None` on the horizon itself (cos θ = 0 carries no energy).
#[inline(always)]
pub fn sample(wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
    if wo.z <= 0.0 {
        return None;
    }
    let wi = sample_cosine_hemisphere(u);
    (wi.z > 0.0).then_some(wi)
}

/// Solid-angle density of `sample`.
#[inline]
pub fn pdf(wo: Vec3, wi: Vec3) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    pdf_cosine_hemisphere(wi)
}

/// The direction uniforms `sample` maps to `wi`.
pub fn invert(wo: Vec3, wi: Vec3) -> Option<[f32; 2]> {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return None;
    }
    invert_cosine_hemisphere(wi)
}
