//! Smooth dielectric interface: two delta lobes, reflection (lobe 0) and refraction (lobe 1),
//! chosen with the Fresnel reflectance so that the throughput of either is exactly 1 (times the
//! radiance scaling 1/η² for refraction in radiance transport).

use glam::Vec3;

use super::fresnel::{fresnel_dielectric, reflect_z, refract_z};
use super::{TransportMode, DELTA_DIRECTION_TOLERANCE};
use crate::spectrum::Rgb;

/// Lobe index of specular reflection.
pub const REFLECT: usize = 0;
/// Lobe index of specular refraction.
pub const REFRACT: usize = 1;

/// Selection probabilities [F, 1 − F] for `wo` on either side (F = 1 under total internal
/// reflection).
#[inline]
pub fn lobe_probabilities(ior: f32, wo: Vec3) -> [f32; 2] {
    let f = fresnel_dielectric(wo.z, ior).reflectance;
    [f, 1.0 - f]
}

/// The direction of lobe `t`; `None` for refraction under total internal reflection.
#[inline]
pub fn sample(ior: f32, t: usize, wo: Vec3) -> Option<Vec3> {
    if t == REFLECT {
        Some(reflect_z(wo))
    } else {
        refract_z(wo, &fresnel_dielectric(wo.z, ior))
    }
}

/// f·|cos θi| of lobe `t`: F for reflection; (1 − F) for refraction, divided by η_t²/η_i² in
/// radiance transport (radiance is compressed into the smaller solid angle of the denser side;
/// importance is not, Veach 1997 Sec. 5.2).
#[inline]
pub fn weight(ior: f32, t: usize, wo: Vec3, mode: TransportMode) -> Rgb {
    let fr = fresnel_dielectric(wo.z, ior);
    if t == REFLECT {
        return Rgb::splat(fr.reflectance);
    }
    let scale = match mode {
        TransportMode::Radiance => 1.0 / (fr.eta_ti * fr.eta_ti),
        TransportMode::Importance => 1.0,
    };
    Rgb::splat((1.0 - fr.reflectance) * scale)
}

/// η_t/η_i crossed by lobe `t` from the side of `wo`: the `eta_ti` whose square `weight` divides
/// by in radiance transport for refraction; 1 for reflection.
#[inline]
pub fn eta(ior: f32, t: usize, wo: Vec3) -> f32 {
    if t == REFLECT {
        1.0
    } else {
        fresnel_dielectric(wo.z, ior).eta_ti
    }
}

/// Whether `wi` is the direction of lobe `t` for `wo` (within `DELTA_DIRECTION_TOLERANCE`).
pub fn matches(ior: f32, t: usize, wo: Vec3, wi: Vec3) -> bool {
    match sample(ior, t, wo) {
        Some(w) => (w - wi).length() <= DELTA_DIRECTION_TOLERANCE,
        None => false,
    }
}
