//! Fresnel reflectance: exact dielectric (real index) and conductor (complex index) formulas for
//! unpolarised light, Snell refraction in the local frame, and the mapping from an artist colour
//! to a conductor's complex index (Gulbrandsen 2014, "Artist Friendly Metallic Fresnel").

use glam::{Vec3, Vec3A};

use crate::spectrum::Rgb;

/// Result of the dielectric Fresnel equations at one interface crossing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FresnelDielectric {
    /// Unpolarised reflectance in [0, 1] (1 under total internal reflection).
    pub reflectance: f32,
    /// Cosine of the transmitted direction, signed: opposite in sign to the incident cosine
    /// (0 under total internal reflection).
    pub cos_t: f32,
    /// Relative index η_t/η_i of the side the transmitted ray enters over the side the incident ray
    /// comes from.
    pub eta_ti: f32,
}

/// Fresnel reflectance of a smooth dielectric interface with index `eta` (inside/outside, inside
/// being −z) for a direction with signed cosine `cos_i` to the +z normal. A negative `cos_i` means
/// the direction is inside, so the relative index becomes 1/`eta`.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> FresnelDielectric {
    let (eta_ti, c) = if cos_i >= 0.0 { (eta, cos_i) } else { (1.0 / eta, -cos_i) };
    let c = c.min(1.0);
    let sin2_t = (1.0 - c * c).max(0.0) / (eta_ti * eta_ti);
    if sin2_t >= 1.0 {
        return FresnelDielectric { reflectance: 1.0, cos_t: 0.0, eta_ti };
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    // s- and p-polarised amplitude ratios; the unpolarised reflectance is their mean square.
    let rs = (c - eta_ti * cos_t) / (c + eta_ti * cos_t);
    let rp = (eta_ti * c - cos_t) / (eta_ti * c + cos_t);
    let reflectance = (0.5 * (rs * rs + rp * rp)).clamp(0.0, 1.0);
    FresnelDielectric { reflectance, cos_t: if cos_i >= 0.0 { -cos_t } else { cos_t }, eta_ti }
}

/// Mirror reflection of `w` about the +z normal of the local frame.
#[inline]
pub fn reflect_z(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Refraction of `w` (pointing away from the surface) through the +z interface, given the
/// `FresnelDielectric` of `w.z`: Snell's law keeps the tangential component scaled by 1/η_ti and
/// flips sides. `None` under total internal reflection.
#[inline]
pub fn refract_z(w: Vec3, fr: &FresnelDielectric) -> Option<Vec3> {
    if fr.cos_t == 0.0 {
        return None;
    }
    let inv = 1.0 / fr.eta_ti;
    Some(Vec3::new(-w.x * inv, -w.y * inv, fr.cos_t))
}

/// Unpolarised Fresnel reflectance of a conductor with complex index `eta + i k` (relative to the
/// outside medium) at incident cosine `cos_i` in [0, 1], per RGB channel, the three channels at
/// once (SSE lanes).
///
/// The exact equations in real form: with t0 = η² − k² − sin²θ and |a + ib|² = √(t0² + 4η²k²) the
/// squared modulus of n² − sin²θ, a = Re √(n² − sin²θ) = √((|a+ib|² + t0)/2), and
/// R_s = (|a+ib|² + cos² − 2a cos) / (|a+ib|² + cos² + 2a cos),
/// R_p = R_s (cos² |a+ib|² + sin⁴ − 2a cos sin²) / (cos² |a+ib|² + sin⁴ + 2a cos sin²)
/// (Born and Wolf; pbrt-v3's `FrConductor` form). The step that cancels in f32, |a+ib|² + t0 for
/// a metal (t0 < 0 when k > η), is taken as 4η²k² / (|a+ib|² − t0) there, and t0 is formed from
/// cos², so every channel keeps a few ulps of relative accuracy in f32 (`tests_precision`).
#[inline]
pub fn fresnel_conductor(cos_i: f32, eta: Rgb, k: Rgb) -> Rgb {
    let c = cos_i.clamp(0.0, 1.0);
    let c2 = c * c;
    let sin2 = (1.0 - c2).max(0.0);
    let (eta, k) = (Vec3A::from(eta), Vec3A::from(k));
    let eta2 = eta * eta;
    let four_eta2_k2 = 4.0 * eta2 * (k * k);
    // t0 as (η² − k² − 1) + cos²: sin² = 1 − cos² rounds cos² away near grazing incidence.
    let t0 = (eta2 - k * k - Vec3A::ONE) + Vec3A::splat(c2);
    let a2b2 = sqrt_lanes(t0 * t0 + four_eta2_k2);
    let cancel = t0.cmplt(Vec3A::ZERO);
    let two_a2 = Vec3A::select(cancel, four_eta2_k2 / (a2b2 - t0), a2b2 + t0);
    let a = sqrt_lanes((0.5 * two_a2).max(Vec3A::ZERO));
    let t1 = a2b2 + Vec3A::splat(c2);
    let t2 = (2.0 * c) * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + Vec3A::splat(sin2 * sin2);
    let t4 = t2 * sin2;
    // t3 + t4 = 0 only at normal incidence with η = k = 0, where R_p = R_s.
    let sum = t3 + t4;
    let rp = rs * Vec3A::select(sum.cmpgt(Vec3A::ZERO), (t3 - t4) / sum, Vec3A::ONE);
    let r: Vec3A = 0.5 * (rs + rp);
    // Non-finite only for η = k = 0 at grazing incidence (0/0): a perfect reflector by continuity.
    let r = Vec3A::select(r.is_finite_mask(), r.clamp(Vec3A::ZERO, Vec3A::ONE), Vec3A::ONE);
    Rgb::from(r)
}

/// Square root of each lane (glam 0.29's `Vec3A` has none): one `sqrtps` where SSE is there.
#[inline]
fn sqrt_lanes(v: Vec3A) -> Vec3A {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE is part of the x86_64 baseline; `Vec3A` is an `__m128` on this target.
        unsafe { Vec3A::from(std::arch::x86_64::_mm_sqrt_ps(v.into())) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec3A::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt())
    }
}

/// Largest reflectivity the colour mapping accepts: at r = 1 the index would be infinite.
const MAX_COLOUR_REFLECTIVITY: f32 = 0.9999;

/// Complex index (η, k) per channel whose normal-incidence reflectance is `reflectivity` and whose
/// grazing behaviour follows `edge_tint` (Gulbrandsen 2014, Eqs. for n(r, g) and k(r, n)).
/// Channels are clamped to [0, 0.9999] for `reflectivity` and [0, 1] for `edge_tint`; non-finite
/// values count as 0.
pub fn conductor_index_from_colours(reflectivity: Rgb, edge_tint: Rgb) -> (Rgb, Rgb) {
    let channel = |r: f32, g: f32| -> (f32, f32) {
        let r = if r.is_finite() { r.clamp(0.0, MAX_COLOUR_REFLECTIVITY) } else { 0.0 };
        let g = if g.is_finite() { g.clamp(0.0, 1.0) } else { 0.0 };
        let sr = r.sqrt();
        let n_min = (1.0 - r) / (1.0 + r);
        let n_max = (1.0 + sr) / (1.0 - sr);
        let n = g * n_min + (1.0 - g) * n_max;
        let k2 = (r * (n + 1.0) * (n + 1.0) - (n - 1.0) * (n - 1.0)) / (1.0 - r);
        (n, k2.max(0.0).sqrt())
    };
    let (ex, kx) = channel(reflectivity.x, edge_tint.x);
    let (ey, ky) = channel(reflectivity.y, edge_tint.y);
    let (ez, kz) = channel(reflectivity.z, edge_tint.z);
    (Rgb::new(ex, ey, ez), Rgb::new(kx, ky, kz))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `fresnel_conductor` for one channel.
    fn fresnel_conductor_scalar(cos_i: f32, eta: f32, k: f32) -> f32 {
        fresnel_conductor(cos_i, Rgb::splat(eta), Rgb::splat(k)).x
    }

    #[test]
    fn dielectric_fresnel_known_values() {
        // Normal incidence: ((η-1)/(η+1))² = 0.04 for η = 1.5, from either side.
        assert!((fresnel_dielectric(1.0, 1.5).reflectance - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(-1.0, 1.5).reflectance - 0.04).abs() < 1e-6);
        // Brewster's angle tan θ = η: the p-polarised part vanishes, R = rs²/2.
        let theta_b = 1.5f32.atan();
        let fr = fresnel_dielectric(theta_b.cos(), 1.5);
        let cos_t = -fr.cos_t;
        let rs = (theta_b.cos() - 1.5 * cos_t) / (theta_b.cos() + 1.5 * cos_t);
        assert!((fr.reflectance - 0.5 * rs * rs).abs() < 1e-6);
        // Total internal reflection from inside beyond the critical angle asin(1/1.5) ≈ 41.8°.
        let c = 45f32.to_radians().cos();
        assert_eq!(fresnel_dielectric(-c, 1.5).reflectance, 1.0);
        // Grazing: R → 1.
        assert!(fresnel_dielectric(1e-4, 1.5).reflectance > 0.999);
        // η = 1: no interface.
        assert!(fresnel_dielectric(0.3, 1.0).reflectance < 1e-7);
    }

    #[test]
    fn refraction_obeys_snell_and_is_unit() {
        for &(wz, eta) in &[(0.8f32, 1.5f32), (-0.9, 1.5), (0.05, 1.33), (-0.99, 2.4)] {
            let w = Vec3::new((1.0 - wz * wz).sqrt(), 0.0, wz);
            let fr = fresnel_dielectric(wz, eta);
            let t = refract_z(w, &fr).expect("no TIR for these angles");
            assert!((t.length() - 1.0).abs() < 1e-5, "{t:?}");
            assert!(t.z * w.z < 0.0);
            // n_i sin θi = n_t sin θt with sines taken as tangential lengths.
            let sin_i = (w.x * w.x + w.y * w.y).sqrt();
            let sin_t = (t.x * t.x + t.y * t.y).sqrt();
            assert!((sin_i - fr.eta_ti * sin_t).abs() < 1e-5);
        }
    }

    #[test]
    fn conductor_fresnel_reduces_to_dielectric_for_zero_k() {
        for &c in &[1.0f32, 0.7, 0.3, 0.01] {
            let a = fresnel_conductor_scalar(c, 1.5, 0.0);
            let b = fresnel_dielectric(c, 1.5).reflectance;
            assert!((a - b).abs() < 1e-5, "cos {c}: {a} vs {b}");
        }
        // Normal incidence: ((η-1)² + k²)/((η+1)² + k²); gold-like red channel η=0.18, k=3.42.
        let expect = ((0.18f32 - 1.0).powi(2) + 3.42f32.powi(2)) / ((1.18f32).powi(2) + 3.42f32.powi(2));
        assert!((fresnel_conductor_scalar(1.0, 0.18, 3.42) - expect).abs() < 1e-5);
        // Grazing: 1.
        assert!(fresnel_conductor_scalar(0.0, 0.18, 3.42) > 0.9999);
    }

    #[test]
    fn colour_mapping_reproduces_normal_reflectance() {
        let r = Rgb::new(0.95, 0.64, 0.0);
        for g in [Rgb::ZERO, Rgb::splat(0.5), Rgb::ONE, r] {
            let (eta, k) = conductor_index_from_colours(r, g);
            let f = fresnel_conductor(1.0, eta, k);
            assert!((f - r).abs().max_element() < 1e-4, "edge {g:?}: {f:?}");
            assert!(eta.is_finite() && k.is_finite());
        }
        // Out-of-range and non-finite colours are clamped, never NaN.
        let (eta, k) = conductor_index_from_colours(Rgb::new(2.0, -1.0, f32::NAN), Rgb::splat(0.5));
        assert!(eta.is_finite() && k.is_finite());
    }
}
