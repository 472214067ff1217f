//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution with the height-correlated Smith
//! masking-shadowing function, and visible-normal sampling (Heitz 2018, "Sampling the GGX
//! Distribution of Visible Normals") with its pdf and its exact inverse.
//!
//! Formulas avoid `1 - z²` cancellation: squared sines are taken as `x² + y²`, so the near-mirror
//! limit (α down to `ALPHA_MIN`) stays finite. The visible-normal warp and its inverse run in f64
//! because both directions of the round trip must agree to ~1e-6 in u.

use glam::{DVec3, Vec3};

use crate::sampling::clamp_unit;

/// Smallest GGX width accepted. Below it D(h) at the peak (1/(π α²) ≈ 3e7 at 1e-4) and the
/// stretched coordinates h.xy/α lose all f32 precision; a near-mirror material is still a smooth
/// (non-delta) lobe of angular width ~1e-4 rad.
pub const ALPHA_MIN: f32 = 1e-4;

/// GGX distribution of width `alpha` (Mitsuba's α: the slope standard deviation scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    /// A distribution with `alpha` clamped to `[ALPHA_MIN, ∞)` (non-finite or negative widths become
    /// `ALPHA_MIN`; validation of user input happens in the scene parser).
    pub fn new(alpha: f32) -> Ggx {
        let alpha = if alpha.is_finite() { alpha.max(ALPHA_MIN) } else { ALPHA_MIN };
        Ggx { alpha }
    }

    /// Normal distribution D(h) for a unit `h` (zero below the horizon):
    /// D = α² / (π (h.x² + h.y² + α² h.z²)²).
    pub fn d(&self, h: Vec3) -> f32 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let denom = h.x * h.x + h.y * h.y + a2 * h.z * h.z;
        if denom <= 0.0 {
            return 0.0;
        }
        a2 / (std::f32::consts::PI * denom * denom)
    }

    /// Smith Λ(w) = (−1 + √(1 + α² tan²θ)) / 2, written as a / (2 (1 + √(1 + a))) to avoid
    /// cancellation for small a = α² tan²θ.
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        let xy2 = w.x * w.x + w.y * w.y;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        let a = self.alpha * self.alpha * xy2 / z2;
        a / (2.0 * (1.0 + (1.0 + a).sqrt()))
    }

    /// Smith masking G1(w) = 1 / (1 + Λ(w)).
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing G2 = 1 / (1 + Λ(wo) + Λ(wi)) (Heitz 2014, Eq. 99); for
    /// reflection only, so both directions are on the same side.
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Stretched view direction and its tangent basis (Heitz 2018, listing lines 1–5), shared by
    /// the sampler and its inverse so they use the same basis.
    fn vndf_basis(&self, wo: Vec3) -> (DVec3, DVec3, DVec3) {
        let a = f64::from(self.alpha);
        let w = wo.as_dvec3();
        let vh = DVec3::new(a * w.x, a * w.y, w.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 { DVec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { DVec3::X };
        let t2 = vh.cross(t1);
        (vh, t1, t2)
    }

    /// A microfacet normal drawn from the distribution of normals visible from `wo` (requires
    /// `wo.z > 0`): D_wo(h) = G1(wo) max(0, wo·h) D(h) / wo.z (Heitz 2018).
    pub fn sample_visible(&self, wo: Vec3, u: [f32; 2]) -> Vec3 {
        self.sample_visible_f64(wo, u).as_vec3()
    }

    fn sample_visible_f64(&self, wo: Vec3, u: [f32; 2]) -> DVec3 {
        let (vh, t1, t2) = self.vndf_basis(wo);
        // Uniform point on the unit disk by the polar map r = √u0, φ = 2πu1 (Heitz's choice), in
        // f64: then 1 − r² = 1 − u0 is exact, which keeps the lift below accurate in the lobe's
        // tails (an f32 disk point loses it near the rim, where a near-mirror lobe's far tail is).
        let r = f64::from(u[0]).sqrt();
        let phi = 2.0 * std::f64::consts::PI * f64::from(u[1]);
        let (p1, p2) = (r * phi.cos(), r * phi.sin());
        // Warp the disk onto the projected visible hemisphere: the half-disk p2 < 0 is squashed
        // by s = (1 + Vh.z)/2 towards the ellipse boundary of the projected hemisphere.
        let s = 0.5 * (1.0 + vh.z);
        let q2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        // Lift onto the hemisphere around Vh, then unstretch.
        let nh = p1 * t1 + q2 * t2 + (1.0 - p1 * p1 - q2 * q2).max(0.0).sqrt() * vh;
        let a = f64::from(self.alpha);
        DVec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
    }

    /// Density of `sample_visible` at the microfacet normal `h` (per solid angle of h).
    pub fn pdf_visible(&self, wo: Vec3, h: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        let cos = wo.dot(h);
        if cos <= 0.0 {
            return 0.0;
        }
        self.g1(wo) * cos * self.d(h) / wo.z
    }

    /// The uniforms that `sample_visible(wo, ·)` maps to `h`, or `None` if `h` is not visible from
    /// `wo` (or `wo` is below the horizon). Exact up to rounding: every step of the warp (polar disk,
    /// squash, lift, unstretch) is a bijection onto the visible hemisphere, except for the polar
    /// map's seam (u[1] = 0 and u[1] → 1 give the same φ, so u[1] is recovered modulo 1) and its
    /// centre (u[0] = 0, where u[1] is undetermined).
    pub fn invert_visible(&self, wo: Vec3, h: Vec3) -> Option<[f32; 2]> {
        self.invert_visible_f64(wo, h.as_dvec3())
    }

    fn invert_visible_f64(&self, wo: Vec3, hd: DVec3) -> Option<[f32; 2]> {
        if wo.z <= 0.0 || hd.z <= 0.0 || wo.as_dvec3().dot(hd) <= 0.0 {
            return None;
        }
        let (vh, t1, t2) = self.vndf_basis(wo);
        let a = f64::from(self.alpha);
        // Undo the unstretch: Ne ∝ (α Nh.x, α Nh.y, Nh.z) ⇒ Nh ∝ (Ne.x/α, Ne.y/α, Ne.z).
        let nh = DVec3::new(hd.x / a, hd.y / a, hd.z).normalize();
        if nh.dot(vh) < 0.0 {
            return None;
        }
        // Project onto the disk spanned by (T1, T2), then undo the squash.
        let p1 = nh.dot(t1).clamp(-1.0, 1.0);
        let q2 = nh.dot(t2);
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (q2 - (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt()) / s;
        let r2 = p1 * p1 + p2 * p2;
        let mut phi = p2.atan2(p1) / (2.0 * std::f64::consts::PI);
        if phi < 0.0 {
            phi += 1.0;
        }
        Some([clamp_unit(r2.min(1.0) as f32), clamp_unit(phi as f32)])
    }

    /// Reflected direction from a visible normal sample, with `None` when it falls below the
    /// horizon (those uniforms produce no direction).
    pub fn sample_reflection(&self, wo: Vec3, u: [f32; 2]) -> Option<(Vec3, Vec3)> {
        let h = self.sample_visible_f64(wo, u);
        let w = wo.as_dvec3();
        let wi = (2.0 * w.dot(h) * h - w).normalize_or_zero().as_vec3();
        if wi.z <= 0.0 || !wi.is_finite() {
            return None;
        }
        Some((wi, h.as_vec3()))
    }

    /// Solid-angle density of `sample_reflection` at `wi`: D_wo(h) / (4 |wo·h|), which simplifies to
    /// G1(wo) D(h) / (4 wo.z).
    pub fn pdf_reflection(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        match half_vector(wo, wi) {
            Some(h) => self.g1(wo) * self.d(h) / (4.0 * wo.z),
            None => 0.0,
        }
    }

    /// The uniforms `sample_reflection(wo, ·)` maps to `wi` (exact: h = (wo + wi)/|wo + wi| is the
    /// only normal that reflects wo into wi).
    pub fn invert_reflection(&self, wo: Vec3, wi: Vec3) -> Option<[f32; 2]> {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return None;
        }
        let h = (wo.as_dvec3() + wi.as_dvec3()).normalize_or_zero();
        if h == DVec3::ZERO {
            return None;
        }
        self.invert_visible_f64(wo, h)
    }
}

/// Reflection half vector, `None` when `wo` and `wi` are opposite.
pub fn half_vector(wo: Vec3, wi: Vec3) -> Option<Vec3> {
    let h = (wo.as_dvec3() + wi.as_dvec3()).normalize_or_zero();
    if h == DVec3::ZERO {
        None
    } else {
        Some(h.as_vec3())
    }
}
