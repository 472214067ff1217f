//! Rough plastic: a GGX-rough dielectric coating of index η over a Lambertian base. Lobe 0 is the
//! coating's specular reflection, f_s = F(wo·h) D(h) G2 / (4 cos θo cos θi); lobe 1 the base seen
//! through the coating, f_d = ρ/π (1 − F(cos θo)) (1 − F(cos θi)) — light crosses the interface
//! twice, once on the way in and once out (internal reflections are neglected, which only loses
//! energy). Both terms are symmetric in wo and wi, so the BRDF is reciprocal, and
//! ∫ f cos ≤ 1 (checked by quadrature in the tests).

use glam::Vec3;

use super::fresnel::fresnel_dielectric;
use super::microfacet::{half_vector, Ggx};
use crate::spectrum::Rgb;

/// Lobe index of the coating's specular reflection.
pub const SPECULAR: usize = 0;
/// Lobe index of the diffuse base.
pub const DIFFUSE: usize = 1;

/// Selection probabilities [specular, diffuse] ∝ [F(cos θo), (1 − F(cos θo)) · mean ρ]: each
/// lobe's approximate albedo, so the lobe that reflects more is sampled more.
pub fn lobe_probabilities(diffuse: Rgb, ior: f32, wo: Vec3) -> [f32; 2] {
    if wo.z <= 0.0 {
        return [1.0, 0.0];
    }
    let f = fresnel_dielectric(wo.z, ior).reflectance;
    let ws = f;
    let wd = (1.0 - f) * diffuse.max(Rgb::ZERO).element_sum() / 3.0;
    let total = ws + wd;
    if !(total > 0.0) || !total.is_finite() {
        return [1.0, 0.0];
    }
    let ps = ws / total;
    [ps, 1.0 - ps]
}

/// The coating's specular term.
pub fn eval_specular(ggx: &Ggx, ior: f32, wo: Vec3, wi: Vec3) -> Rgb {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    let Some(h) = half_vector(wo, wi) else { return Rgb::ZERO };
    let d = ggx.d(h);
    if d == 0.0 {
        return Rgb::ZERO;
    }
    let f = fresnel_dielectric(wo.dot(h), ior).reflectance;
    Rgb::splat(f * d * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z))
}

/// The base term, attenuated by the coating's transmittance on the way in and out.
pub fn eval_diffuse(diffuse: Rgb, ior: f32, wo: Vec3, wi: Vec3) -> Rgb {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    let to = 1.0 - fresnel_dielectric(wo.z, ior).reflectance;
    let ti = 1.0 - fresnel_dielectric(wi.z, ior).reflectance;
    diffuse * (std::f32::consts::FRAC_1_PI * to * ti)
}
