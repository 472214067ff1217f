//! GGX rough conductor: f = F(wo·h) D(h) G2(wo, wi) / (4 cos θo cos θi) with the exact conductor
//! Fresnel term per channel, sampled by reflecting a visible normal (Heitz 2018).

use glam::Vec3;

use super::fresnel::fresnel_conductor;
use super::microfacet::{Ggx, GgxReflection};
use crate::spectrum::Rgb;

/// The microfacet BRDF; zero unless both directions are above the horizon.
pub fn eval(ggx: &Ggx, eta: Rgb, k: Rgb, wo: Vec3, wi: Vec3) -> Rgb {
    ggx.reflection(wo, wi).map_or(Rgb::ZERO, |r| brdf(&r, eta, k, wo))
}

/// The BRDF and the sampling density at once (they share the half vector, D and Λ(wo)).
#[inline(always)]
pub fn eval_pdf(ggx: &Ggx, eta: Rgb, k: Rgb, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
    // A match, not `map_or`: the generic `map_or` stayed out of line (~1% of the door's time in
    // perf), returning the pair through memory.
    match ggx.reflection(wo, wi) {
        Some(r) => (brdf(&r, eta, k, wo), r.pdf()),
        None => (Rgb::ZERO, 0.0),
    }
}

#[inline(always)]
fn brdf(r: &GgxReflection, eta: Rgb, k: Rgb, wo: Vec3) -> Rgb {
    fresnel_conductor(wo.dot(r.h), eta, k) * r.brdf()
}
