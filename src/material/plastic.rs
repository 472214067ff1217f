//! Rough plastic, Mitsuba's model (`plastic`/`roughplastic`): a GGX-rough dielectric coating of
//! index η over a Lambertian base. Lobe 0 is the coating's specular reflection,
//! f_s = k_s F(wo·h) D(h) G2 / (4 cos θo cos θi), k_s the `specular` colour; lobe 1 the base seen
//! through the coating, f_d = ρ'/π (1/η²) (1 − F(cos θo)) (1 − F(cos θi)): light crosses the
//! interface on the way in and out, and the light the coating reflects back down (the internal
//! diffuse reflectance F_dr of the inside, a hemispherical average of Fresnel) bounces on the base
//! again. Summing those bounces gives ρ' = ρ / (1 − F_dr) (the `linear` model: the base colour is
//! the colour of the whole series) or ρ' = ρ / (1 − ρ F_dr) (`nonlinear`: each bounce tints again,
//! so the colour saturates). Because 1 − F_dr = (1 − F_dr,ext)/η² (reciprocity of the coating),
//! the linear model with ρ = 1 has albedo exactly 1 − F(cos θo) in its base. Both terms are
//! symmetric in wo and wi, so the BRDF is reciprocal, and ∫ f cos ≤ 1 (checked by quadrature in
//! the tests). Roughness 0 is the narrowest GGX lobe (`ALPHA_MIN`), Mitsuba's smooth coat up to a
//! lobe 1e-4 rad wide.

use glam::Vec3;

use super::fresnel::fresnel_dielectric;
use super::microfacet::{half_vector, Ggx};
use serde::Serialize;

use crate::spectrum::Rgb;

/// Lobe index of the coating's specular reflection.
pub const SPECULAR: usize = 0;
/// Lobe index of the diffuse base.
pub const DIFFUSE: usize = 1;

/// The parameters of one plastic (build it with `Plastic::new`, which precomputes F_dr).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Plastic {
    pub diffuse: Rgb,
    pub specular: Rgb,
    pub ior: f32,
    pub nonlinear: bool,
    /// Internal diffuse reflectance F_dr of the coating (derived from `ior`).
    #[serde(skip)]
    fdr: f32,
}

/// Hemispherical average 2∫₀¹ F(μ) μ dμ of the Fresnel reflectance seen from outside (index `ior`
/// inside), by the midpoint rule on 512 cells in f64 (F is smooth from outside; error < 1e-6).
pub fn diffuse_fresnel_external(ior: f32) -> f32 {
    const N: usize = 512;
    let sum: f64 = (0..N)
        .map(|i| {
            let mu = (i as f64 + 0.5) / N as f64;
            2.0 * mu * f64::from(fresnel_dielectric(mu as f32, ior).reflectance)
        })
        .sum();
    (sum / N as f64) as f32
}

impl Plastic {
    /// A plastic with base colour `diffuse`, coating tint `specular` and coating index `ior`;
    /// F_dr = 1 − (1 − F_dr,ext)/η² (see the module doc) is computed once here.
    pub fn new(diffuse: Rgb, specular: Rgb, ior: f32, nonlinear: bool) -> Plastic {
        let fdr = (1.0 - (1.0 - diffuse_fresnel_external(ior)) / (ior * ior)).clamp(0.0, 1.0);
        Plastic { diffuse, specular, ior, nonlinear, fdr }
    }
    /// The same plastic with another base colour (a texture lookup); F_dr is kept.
    pub fn with_colours(&self, diffuse: Rgb, specular: Rgb) -> Plastic {
        Plastic { diffuse, specular, ..*self }
    }
    /// ρ'/η²: the base colour with its internal bounces, and the 1/η² of radiance entering and
    /// leaving the coating.
    pub fn base(&self) -> Rgb {
        let fdr = self.fdr;
        let rho = self.diffuse.max(Rgb::ZERO);
        let scaled = if self.nonlinear { rho / (Rgb::ONE - rho * fdr) } else { rho / (1.0 - fdr) };
        scaled / (self.ior * self.ior)
    }
}

/// Selection probabilities [specular, diffuse] ∝ [F(cos θo) · mean k_s, (1 − F(cos θo)) · mean ρ']:
/// each lobe's approximate albedo, so the lobe that reflects more is sampled more.
pub fn lobe_probabilities(p: &Plastic, wo: Vec3) -> [f32; 2] {
    if wo.z <= 0.0 {
        return [1.0, 0.0];
    }
    let f = fresnel_dielectric(wo.z, p.ior).reflectance;
    let ws = f * p.specular.max(Rgb::ZERO).element_sum() / 3.0;
    let wd = (1.0 - f) * (p.base() * (p.ior * p.ior)).element_sum() / 3.0;
    let total = ws + wd;
    if !(total > 0.0) || !total.is_finite() {
        return [1.0, 0.0];
    }
    let ps = ws / total;
    [ps, 1.0 - ps]
}

/// The coating's specular term.
pub fn eval_specular(ggx: &Ggx, p: &Plastic, wo: Vec3, wi: Vec3) -> Rgb {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    let Some(h) = half_vector(wo, wi) else { return Rgb::ZERO };
    let d = ggx.d(h);
    if d == 0.0 {
        return Rgb::ZERO;
    }
    let f = fresnel_dielectric(wo.dot(h), p.ior).reflectance;
    p.specular * (f * d * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z))
}

/// The base term, attenuated by the coating's transmittance on the way in and out.
pub fn eval_diffuse(p: &Plastic, wo: Vec3, wi: Vec3) -> Rgb {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Rgb::ZERO;
    }
    let to = 1.0 - fresnel_dielectric(wo.z, p.ior).reflectance;
    let ti = 1.0 - fresnel_dielectric(wi.z, p.ior).reflectance;
    p.base() * (std::f32::consts::FRAC_1_PI * to * ti)
}
