//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution with the height-correlated Smith
//! masking-shadowing function, and visible-normal sampling (Heitz 2018, "Sampling the GGX
//! Distribution of Visible Normals") with its pdf and its exact inverse.
//!
//! Formulas avoid `1 - z²` cancellation: squared sines are taken as `x² + y²`, so the near-mirror
//! limit (α down to `ALPHA_MIN`) stays finite. The visible-normal warp runs in f32, arranged so that
//! no step cancels (see `sample_visible`); its inverse, which only the reversible-jump mutations
//! call, runs in f64 so that the round trip agrees to ~1e-6 in u.

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
    #[inline]
    pub fn new(alpha: f32) -> Ggx {
        let alpha = if alpha.is_finite() { alpha.max(ALPHA_MIN) } else { ALPHA_MIN };
        Ggx { alpha }
    }

    /// Normal distribution D(h) for a unit `h` (zero below the horizon):
    /// D = α² / (π (h.x² + h.y² + α² h.z²)²).
    #[inline]
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
    #[inline]
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
    ///
    /// In f32, arranged so that no step cancels (the f64 version this replaces cost a fifth of
    /// the door scene's samples). The delicate steps, each rewritten with an identity:
    /// - the lift's height z = √(1 − p1² − q2²), which in a near-mirror lobe's tails is ~α, and
    ///   formed directly would keep no digit of it. With w = 1 − u0 (exact: the polar map's r² is
    ///   u0, so p1² + p2² = u0) and c = √(1 − p1²) = √(w + p2²), the squash q2 = (1 − s) c + s p2
    ///   gives z² = (c − q2)(c + q2) = s (c − p2) (2 (1 − s) c + s (c + p2)), a product of
    ///   non-negative terms, and (c − p2)(c + p2) = w supplies whichever of c ∓ p2 would cancel;
    /// - 1 − s = (1 − Vh.z)/2 = |Vh.xy|² / (2 (1 + Vh.z)), not 1 minus a rounded s;
    /// - q2 for p2 < 0 as (1 − s)(c + p2) + Vh.z p2, which cancels only as far as Vh.z allows;
    /// - Nh.z = q2 |Vh.xy| + z Vh.z (the tangent T2 has T2.z = |Vh.xy|), which for q2 < 0 cancels
    ///   at the visible hemisphere's horizon: there it is (c Vh.z − q2) s (c + p2) / (z Vh.z −
    ///   q2 |Vh.xy|), from c Vh.z + q2 = s (c + p2) and z² + q2² = c²;
    /// - the azimuth's sine and cosine per quadrant (`sin_cos_turns`).
    ///
    /// What remains is the disk point's own f32 rounding, which near the disk's rim at grazing
    /// incidence moves h by up to ~ε/α (`tests_precision`).
    #[inline(always)]
    pub fn sample_visible(&self, wo: Vec3, u: [f32; 2]) -> Vec3 {
        let (vh, t1, t2) = self.vndf_basis_f32(wo);
        let r = u[0].sqrt();
        let (sin, cos) = sin_cos_turns(u[1]);
        let (p1, p2) = (r * cos, r * sin);
        let w = 1.0 - u[0];
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let s = 0.5 * (1.0 + vh.z);
        let one_minus_s = 0.5 * lensq / (1.0 + vh.z);
        let c = (w + p2 * p2).sqrt();
        let (c_minus, c_plus) = if p2 >= 0.0 {
            let c_plus = c + p2;
            (if c_plus > 0.0 { w / c_plus } else { 0.0 }, c_plus)
        } else {
            let c_minus = c - p2;
            (c_minus, w / c_minus)
        };
        let q2 = if p2 >= 0.0 { one_minus_s * c + s * p2 } else { one_minus_s * c_plus + vh.z * p2 };
        let z = (s * c_minus * (2.0 * one_minus_s * c + s * c_plus)).max(0.0).sqrt();
        // Lift onto the hemisphere around Vh, then unstretch.
        let len_xy = lensq.sqrt();
        let nh_z = if q2 >= 0.0 {
            q2 * len_xy + z * vh.z
        } else {
            let den = z * vh.z - q2 * len_xy;
            if den > 0.0 {
                (c * vh.z - q2) * s * c_plus / den
            } else {
                0.0
            }
        };
        let a = self.alpha;
        let nh_x = p1 * t1.x + q2 * t2.x + z * vh.x;
        let nh_y = p1 * t1.y + q2 * t2.y + z * vh.y;
        Vec3::new(a * nh_x, a * nh_y, nh_z.max(0.0)).normalize()
    }

    /// `vndf_basis` in f32 (the sampler's; the inverse keeps the f64 one).
    #[inline]
    fn vndf_basis_f32(&self, wo: Vec3) -> (Vec3, Vec3, Vec3) {
        let a = self.alpha;
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        (vh, t1, t2)
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
    ///
    /// The reflection itself is taken in f64 (a few products, no transcendental): in f32, wi.z =
    /// 2 (wo·h) h.z − wo.z cancels at grazing incidence, and a round trip through `invert` then
    /// fails four to thirty times as often (α = 1e-3 at 89.9°: 0.11% instead of 0.024%).
    #[inline(always)]
    pub fn sample_reflection(&self, wo: Vec3, u: [f32; 2]) -> Option<(Vec3, Vec3)> {
        let h = self.sample_visible(wo, u);
        let (w, hd) = (wo.as_dvec3(), h.as_dvec3());
        let wi = (2.0 * w.dot(hd) * hd - w).normalize_or_zero().as_vec3();
        if wi.z <= 0.0 || !wi.is_finite() {
            return None;
        }
        Some((wi, h))
    }

    /// Solid-angle density of `sample_reflection` at `wi`: D_wo(h) / (4 |wo·h|), which simplifies to
    /// G1(wo) D(h) / (4 wo.z).
    pub fn pdf_reflection(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.reflection(wo, wi).map_or(0.0, |r| r.pdf())
    }

    /// The terms a reflection pair's BRDF and density share (half vector, D, both Λ), computed
    /// once; `None` unless both directions are above the horizon and D(h) > 0.
    #[inline(always)]
    pub fn reflection(&self, wo: Vec3, wi: Vec3) -> Option<GgxReflection> {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return None;
        }
        let h = half_vector(wo, wi)?;
        let d = self.d(h);
        if d == 0.0 {
            return None;
        }
        Some(GgxReflection { h, d, lambda_o: self.lambda(wo), lambda_i: self.lambda(wi), cos_o: wo.z, cos_i: wi.z })
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

/// What a GGX reflection pair's BRDF and density share (`Ggx::reflection`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxReflection {
    /// The half vector (wo + wi)/|wo + wi|.
    pub h: Vec3,
    /// D(h) > 0.
    pub d: f32,
    pub lambda_o: f32,
    pub lambda_i: f32,
    pub cos_o: f32,
    pub cos_i: f32,
}

impl GgxReflection {
    /// D G2 / (4 cos θo cos θi): the microfacet BRDF without its Fresnel factor (G2
    /// height-correlated, Heitz 2014 Eq. 99).
    #[inline]
    pub fn brdf(&self) -> f32 {
        self.d / ((1.0 + self.lambda_o + self.lambda_i) * (4.0 * self.cos_o * self.cos_i))
    }
    /// Density of `Ggx::sample_reflection`: G1(wo) D(h) / (4 cos θo).
    #[inline]
    pub fn pdf(&self) -> f32 {
        self.d / ((1.0 + self.lambda_o) * (4.0 * self.cos_o))
    }
}

/// (sin 2πt, cos 2πt) for t in [0, 1), reduced to a quadrant first: 4t splits exactly into the
/// quadrant q and a fraction f, and the angle π/2 · f is rounded at π/2's scale (2π t would carry
/// up to 2.4e-7 rad of rounding near t = 1).
#[inline]
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    let x = 4.0 * t;
    let q = x.floor();
    let (s, c) = ((x - q) * std::f32::consts::FRAC_PI_2).sin_cos();
    match (q as i32) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Reflection half vector, `None` when `wo` and `wi` are opposite. In f32: each component of
/// wo + wi is rounded once relative to itself (exactly when the two nearly cancel), so h keeps a
/// few ulps of relative accuracy per component even a near-mirror lobe's width from the normal.
#[inline]
pub fn half_vector(wo: Vec3, wi: Vec3) -> Option<Vec3> {
    let h = (wo + wi).normalize_or_zero();
    if h == Vec3::ZERO {
        None
    } else {
        Some(h)
    }
}
