//! GGX rough dielectric interface (Walter et al. 2007, "Microfacet Models for Refraction through
//! Rough Surfaces"): two smooth lobes, reflection (lobe 0) and transmission (lobe 1).
//!
//! Everything is computed in the frame where `wo` is above the surface: when `wo.z < 0` both
//! directions are mirrored through the tangent plane and the relative index becomes 1/`ior`, so η
//! below is always η_t/η_i, the index of the side `wi` enters over the side `wo` is on.
//!
//! - Reflection: h = (wo + wi)/|wo + wi|, f_r = F(wo·h) D(h) G2 / (4 |cos θo| |cos θi|) (Eq. 20).
//! - Transmission: h = −(wo + η wi)/|wo + η wi| turned to the +z side (Eq. 16),
//!   f_t = (1 − F(wo·h)) D(h) G2 |wi·h| |wo·h| / (|cos θo| |cos θi| (wi·h + wo·h/η)²), the
//!   importance form; radiance transport divides it by η² (Eq. 21 with η_o = 1; Veach 1997
//!   Sec. 5.2), so in radiance mode f(wo→wi)/η_o² = f(wi→wo)/η_i².
//!
//! Sampling does not follow Walter's "choose the lobe after the microfacet normal": the lobe is
//! chosen first from `u[0]` (the renderer's layout, which RJMLT's inverse needs) with probability
//! F(|cos θo|) clamped to [`LOBE_MIN`, 1 − `LOBE_MIN`], then a visible normal is drawn (Heitz 2018)
//! and wo is reflected or refracted about it. The clamp keeps both lobes' densities positive
//! wherever f is (under macroscopic total internal reflection, F = 1, rough microfacets still
//! transmit). A refraction that meets total internal reflection at its microfacet, or lands on
//! the wrong side, fails: the pdf integrates to the sampler's success probability.

use glam::{DVec3, Vec3};

use super::fresnel::fresnel_dielectric;
use super::microfacet::{half_vector, Ggx};
use super::TransportMode;
use crate::spectrum::Rgb;

/// Lobe index of rough reflection.
pub const REFLECT: usize = 0;
/// Lobe index of rough transmission.
pub const TRANSMIT: usize = 1;

/// Least selection probability of either lobe (see the module doc).
pub const LOBE_MIN: f32 = 0.1;

/// (wo, wi, η) mirrored so that wo is above the surface. η is formed in f64: 1/ior rounded to f32
/// would move cos θt at a grazing microfacet by percents (sin²θt ≈ 1 there).
fn oriented(ior: f32, wo: Vec3, wi: Vec3) -> (Vec3, Vec3, f64) {
    if wo.z >= 0.0 {
        (wo, wi, f64::from(ior))
    } else {
        (flip(wo), flip(wi), 1.0 / f64::from(ior))
    }
}

fn flip(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

/// Selection probabilities [reflect, transmit].
pub fn lobe_probabilities(ior: f32, wo: Vec3) -> [f32; 2] {
    let f = fresnel_dielectric(wo.z, ior).reflectance;
    let pr = f.clamp(LOBE_MIN, 1.0 - LOBE_MIN);
    [pr, 1.0 - pr]
}

/// η_t/η_i crossed by lobe `t` from the side of `wo`.
pub fn eta(ior: f32, t: usize, wo: Vec3) -> f32 {
    if t == REFLECT {
        1.0
    } else if wo.z >= 0.0 {
        ior
    } else {
        1.0 / ior
    }
}

/// The transmission half vector of (wo, wi) with wo above, wi below: −(wo + η wi) normalised and
/// turned to +z; `None` when degenerate or when wo and wi are not on the microfacet's two sides.
///
/// The directions are renormalised in f64 first: at a microfacet near the critical angle,
/// cos θt = √(1 − η² sin²θ) cancels almost completely, and the ~6e-8 length error of an f32 unit
/// vector moves it by percents (and breaks reciprocity by as much).
fn transmission_half(wo: Vec3, wi: Vec3, eta: f64) -> Option<DVec3> {
    let (wo, wi) = (wo.as_dvec3().normalize_or_zero(), wi.as_dvec3().normalize_or_zero());
    let h = (wo + eta * wi).normalize_or_zero();
    if h == DVec3::ZERO {
        return None;
    }
    let h = if h.z < 0.0 { -h } else { h };
    let (cos_o, cos_i) = (wo.dot(h), wi.dot(h));
    (cos_o > 0.0 && cos_i < 0.0).then_some(h)
}

/// 1 − F at a microfacet for a direction with cosine `c` > 0 on the side of relative index
/// η = η_t/η_i, in f64: near grazing microfacets F → 1 and 1 − F in f32 keeps only a digit or two
/// (enough to break reciprocity by several percent there); both crossing directions give the
/// same value, as they must.
fn fresnel_transmittance(c: f64, eta: f64) -> f64 {
    let c = c.min(1.0);
    let sin2_t = (1.0 - c * c).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 0.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (c - eta * cos_t) / (c + eta * cos_t);
    let rp = (eta * c - cos_t) / (eta * c + cos_t);
    (1.0 - 0.5 * (rs * rs + rp * rp)).clamp(0.0, 1.0)
}

/// f(wo, wi) of both lobes (only one is non-zero for any pair).
pub fn eval(ggx: &Ggx, ior: f32, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
    let (wo, wi, eta) = oriented(ior, wo, wi);
    if wi.z > 0.0 {
        let Some(h) = half_vector(wo, wi) else { return Rgb::ZERO };
        let d = ggx.d(h);
        if d == 0.0 || wo.dot(h) <= 0.0 {
            return Rgb::ZERO;
        }
        let f = fresnel_dielectric(wo.dot(h), eta as f32).reflectance;
        return Rgb::splat(f * d * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z));
    }
    let Some(hd) = transmission_half(wo, wi, eta) else { return Rgb::ZERO };
    let h = hd.as_vec3();
    let d = f64::from(ggx.d(h));
    if d == 0.0 {
        return Rgb::ZERO;
    }
    let (wod, wid) = (wo.as_dvec3().normalize(), wi.as_dvec3().normalize());
    let (cos_oh, cos_ih) = (wod.dot(hd), wid.dot(hd));
    let t = fresnel_transmittance(cos_oh, eta);
    let denom = (cos_ih + cos_oh / eta).powi(2) * wod.z * (-wid.z);
    if !(denom > 0.0) {
        return Rgb::ZERO;
    }
    let mut f = t * d * f64::from(ggx.g2(wo, wi)) * (cos_ih * cos_oh).abs() / denom;
    if mode == TransportMode::Radiance {
        f /= eta * eta;
    }
    Rgb::splat(f as f32)
}

/// Lobe `t`'s direction from the visible normal drawn with `u`.
pub fn sample(ggx: &Ggx, ior: f32, t: usize, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
    let flipped = wo.z < 0.0;
    let (wo, _, eta) = oriented(ior, wo, Vec3::Z);
    if t == REFLECT {
        let (wi, _) = ggx.sample_reflection(wo, u)?;
        return Some(if flipped { flip(wi) } else { wi });
    }
    let h = ggx.sample_visible(wo, u).as_dvec3();
    let w = wo.as_dvec3();
    let cos_i = w.dot(h);
    let e = eta;
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (e * e);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let wi = (-w / e + (cos_i / e - cos_t) * h).normalize_or_zero().as_vec3();
    if !(wi.z < 0.0) || !wi.is_finite() {
        return None;
    }
    Some(if flipped { flip(wi) } else { wi })
}

/// Solid-angle density of lobe `t`'s direction map at `wi`.
pub fn pdf(ggx: &Ggx, ior: f32, t: usize, wo: Vec3, wi: Vec3) -> f32 {
    let (wo, wi, eta) = oriented(ior, wo, wi);
    if t == REFLECT {
        return ggx.pdf_reflection(wo, wi);
    }
    if wi.z >= 0.0 {
        return 0.0;
    }
    let Some(hd) = transmission_half(wo, wi, eta) else { return 0.0 };
    let (cos_oh, cos_ih) = (wo.as_dvec3().normalize().dot(hd), wi.as_dvec3().normalize().dot(hd));
    // dh/dwi = |wi·h| / (wi·h + wo·h/η)² (Walter Eq. 17, with the η normalisation of pbrt-v4).
    let dh_dwi = cos_ih.abs() / (cos_ih + cos_oh / eta).powi(2);
    (f64::from(ggx.pdf_visible(wo, hd.as_vec3())) * dh_dwi) as f32
}

/// The direction uniforms lobe `t` maps to `wi`.
pub fn invert(ggx: &Ggx, ior: f32, t: usize, wo: Vec3, wi: Vec3) -> Option<[f32; 2]> {
    let (wo, wi, eta) = oriented(ior, wo, wi);
    if t == REFLECT {
        return ggx.invert_reflection(wo, wi);
    }
    if wi.z >= 0.0 {
        return None;
    }
    let hd = transmission_half(wo, wi, eta)?;
    ggx.invert_visible(wo, hd.as_vec3())
}
