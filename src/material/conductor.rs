//! GGX rough conductor: f = F(wo·h) D(h) G2(wo, wi) / (4 cos θo cos θi) with the exact conductor
//! Fresnel term per channel, sampled by reflecting a visible normal (Heitz 2018).

use glam::Vec3;

use super::fresnel::fresnel_conductor;
use super::microfacet::{half_vector, Ggx};
use crate::spectrum::Rgb;

/// The microfacet BRDF; zero unless both directions are above the horizon.
pub fn eval(ggx: &Ggx, eta: Rgb, k: Rgb, wo: Vec3, wi: Vec3) -> Rgb {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    let Some(h) = half_vector(wo, wi) else { return Rgb::ZERO };
    let d = ggx.d(h);
    if d == 0.0 {
        return Rgb::ZERO;
    }
    let g = ggx.g2(wo, wi);
    fresnel_conductor(wo.dot(h), eta, k) * (d * g / (4.0 * wo.z * wi.z))
}
