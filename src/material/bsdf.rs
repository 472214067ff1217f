//! The BSDF at one surface point: a `Material` whose textured parameters have been looked up, and
//! the two-sided rule (Mitsuba's `twosided`): when `wo` is below the shading frame's horizon, both
//! directions are mirrored through the tangent plane (z → −z) before the material sees them and
//! the sampled direction is mirrored back, so the back side behaves exactly as the front. The
//! mirror is an isometry of the sphere, so densities, Jacobians and the inverse's uniforms carry
//! over unchanged, and every integrator (pt, the BDPT family, RJMLT's inverses) gets the rule by
//! calling these methods. Transmissive materials are never two-sided (the loader refuses them, as
//! Mitsuba does): their two sides are different media.

use glam::Vec3;

use super::{BsdfInverse, BsdfSample, Material, TransportMode, BSDF_INVERT_DIMS, BSDF_SAMPLE_DIMS, MAX_LOBES};
use crate::spectrum::Rgb;

/// A material at a surface point (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bsdf {
    pub material: Material,
    pub two_sided: bool,
}

#[inline]
fn mirror(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

impl From<Material> for Bsdf {
    fn from(material: Material) -> Bsdf {
        Bsdf { material, two_sided: false }
    }
}

impl Bsdf {
    /// Whether the pair is evaluated mirrored (two-sided and `wo` on the back).
    #[inline]
    fn flips(&self, wo: Vec3) -> bool {
        self.two_sided && wo.z < 0.0
    }
    /// (wo, wi) as the material sees them.
    #[inline]
    fn oriented(&self, wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
        if self.flips(wo) {
            (mirror(wo), mirror(wi))
        } else {
            (wo, wi)
        }
    }

    /// `Material::eval` under the side rule.
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        let (wo, wi) = self.oriented(wo, wi);
        self.material.eval(wo, wi, mode)
    }
    /// `Material::pdf` under the side rule.
    pub fn pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> f32 {
        let (wo, wi) = self.oriented(wo, wi);
        self.material.pdf(wo, wi, mode)
    }
    /// `Material::eval_pdf` under the side rule.
    #[inline(always)]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> (Rgb, f32) {
        let (wo, wi) = self.oriented(wo, wi);
        self.material.eval_pdf(wo, wi, mode)
    }
    /// `Material::sample` under the side rule.
    #[inline(always)]
    pub fn sample(&self, wo: Vec3, u: [f32; BSDF_SAMPLE_DIMS], mode: TransportMode) -> Option<BsdfSample> {
        if self.flips(wo) {
            let mut s = self.material.sample(mirror(wo), u, mode)?;
            s.wi = mirror(s.wi);
            Some(s)
        } else {
            self.material.sample(wo, u, mode)
        }
    }
    /// `Material::eval_delta` under the side rule.
    pub fn eval_delta(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        let (wo, wi) = self.oriented(wo, wi);
        self.material.eval_delta(wo, wi, mode)
    }
    /// `Material::pdf_delta` under the side rule.
    pub fn pdf_delta(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (wo, wi) = self.oriented(wo, wi);
        self.material.pdf_delta(wo, wi)
    }
    /// `Material::invert` under the side rule (the uniforms are those `sample` uses).
    pub fn invert(
        &self,
        wo: Vec3,
        wi: Vec3,
        mode: TransportMode,
        gamma: [f32; BSDF_INVERT_DIMS],
    ) -> Option<BsdfInverse> {
        let (wo, wi) = self.oriented(wo, wi);
        self.material.invert(wo, wi, mode, gamma)
    }
    /// `Material::lobe_probabilities` under the side rule.
    pub fn lobe_probabilities(&self, wo: Vec3) -> [f32; MAX_LOBES] {
        let (wo, _) = self.oriented(wo, wo);
        self.material.lobe_probabilities(wo)
    }
    #[inline]
    pub fn is_specular(&self) -> bool {
        self.material.is_specular()
    }
}
