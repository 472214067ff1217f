//! BSDFs. Every material works in the local shading frame (normal = +z); `wo` and `wi` both point
//! away from the surface. Sampling takes its uniforms explicitly — `u[0]` chooses the lobe,
//! `u[1..3]` the direction — so primary-sample-space MCMC can drive it and `invert` can recover
//! them. A material's lobe probabilities come from one helper that `sample`, `pdf` and `invert`
//! all call, so they cannot drift apart.

mod bsdf;
mod conductor;
mod dielectric;
mod diffuse;
mod fresnel;
pub mod microfacet;
mod plastic;
mod rough_dielectric;
mod specular;
mod surface;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_precision;
#[cfg(test)]
mod tests_sampling;
#[cfg(test)]
mod tests_surface;
#[cfg(test)]
mod tests_transmission;

pub use bsdf::Bsdf;
pub use fresnel::{conductor_index_from_colours, fresnel_conductor, fresnel_dielectric, FresnelDielectric};
pub use microfacet::{Ggx, ALPHA_MIN};
pub use surface::{ColourSlot, Opacity, SurfaceMaterial};

/// Lobe indices (`BsdfSample::lobe`, `BsdfInverse::lobe`) of the two-lobe materials.
pub use dielectric::{REFLECT as DIELECTRIC_REFLECT, REFRACT as DIELECTRIC_REFRACT};
pub use plastic::{Plastic, DIFFUSE as PLASTIC_DIFFUSE, SPECULAR as PLASTIC_SPECULAR};
pub use rough_dielectric::{REFLECT as ROUGH_DIELECTRIC_REFLECT, TRANSMIT as ROUGH_DIELECTRIC_TRANSMIT};

use serde::Serialize;

use crate::sampling::clamp_unit;
use crate::spectrum::Rgb;
use glam::Vec3;

/// Random numbers one BSDF sample consumes: lobe choice, then a 2D direction.
pub const BSDF_SAMPLE_DIMS: usize = 3;

/// Uniforms `Material::invert` consumes to resolve ambiguity (RJMLT Sec. 5 "probabilistic
/// inverses"): γ[0] picks the lobe t by T(t) (Eq. 44), γ[1] places u[0] inside lobe t's selection
/// interval (Eq. 40–41), γ[2], γ[3] fill direction dimensions a delta lobe does not use.
pub const BSDF_INVERT_DIMS: usize = 4;

/// Most lobes any material has (the length of `Material::lobe_probabilities`).
pub const MAX_LOBES: usize = 2;

/// Largest distance between unit vectors at which `invert` (and the delta-lobe bookkeeping)
/// accepts `wi` as a delta lobe's direction (≈ 1e-3 rad): directions rebuilt from vertex positions
/// are off by rounding, never by this much.
pub const DELTA_DIRECTION_TOLERANCE: f32 = 1e-3;

/// Bound on |wi' − wi| · min(cos θd, |cos θi|), wi' the direction the inverted uniforms sample
/// again for a smooth lobe and θd the angle between wo and the half vector; beyond it `invert`
/// reports failure. The two f32 error sources of a round trip are amplified by these cosines: a
/// half vector rebuilt from f32 directions carries ~ε/cos θd (wo + wi cancels at grazing angles),
/// and a direction lifted from an f32 disk point carries ~ε/cos θi near the horizon. Measured
/// worst 1.2e-7 over GGX widths 1e-4…1, incidence up to 89.99°, and the cosine lobe; the bound
/// leaves a factor 8.
pub const INVERT_DIRECTION_TOLERANCE: f32 = 1e-6;

/// Whether radiance (camera paths) or importance (light paths) is being transported; they differ
/// for refraction (the 1/η² radiance scaling) and for shading normals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum TransportMode {
    Radiance,
    Importance,
}

/// A material, with parameters as the scene file gives them (validated).
// RoughPlastic carries its coating's 64-entry transmittance table inline (~300 bytes), which keeps
// Material `Copy`; moving the table behind a pointer or a per-scene cache is the alternative if a
// profile shows the copies (not measured yet).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Material {
    /// Lambertian reflection.
    Diffuse { reflectance: Rgb },
    /// Perfect specular reflection, scaled by `reflectance`.
    Mirror { reflectance: Rgb },
    /// Smooth dielectric interface (glass): Fresnel-weighted specular reflection and refraction.
    /// `ior` is inside/outside; the geometric normal points outside.
    Dielectric { ior: f32 },
    /// GGX microfacet conductor; `alpha` is the GGX width (Mitsuba's `alpha`), `eta`/`k` the
    /// complex index of refraction per channel.
    RoughConductor { alpha: f32, eta: Rgb, k: Rgb },
    /// GGX rough dielectric interface (Walter et al. 2007): rough reflection and transmission,
    /// `ior` inside/outside as for `Dielectric`.
    RoughDielectric { alpha: f32, ior: f32 },
    /// Diffuse base under a GGX-rough dielectric coating (Mitsuba's plastic; a two-lobe mixture).
    RoughPlastic { alpha: f32, plastic: Plastic },
}

/// A direction drawn from a BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled direction, local frame, unit length.
    pub wi: Vec3,
    /// BSDF value f(wo, wi) (for a delta lobe: the lobe's weight divided by |cos θi|, so that
    /// `f * |cos| / pdf` is the throughput as for any other lobe).
    pub f: Rgb,
    /// Solid-angle density of the whole mixture at `wi` (for a delta lobe: the lobe's selection
    /// probability, a discrete mass).
    pub pdf: f32,
    /// Whether `wi` came from a delta lobe.
    pub delta: bool,
    /// Index of the lobe that was chosen (material-specific; see `Material::lobe_count`).
    pub lobe: u8,
    /// Relative index of refraction η_t/η_i crossed by a refraction lobe (the side `wi` enters
    /// over the side `wo` is on); 1 for reflection. In radiance transport `f` carries its 1/η²
    /// (Veach 1997 Sec. 5.2), which a throughput-driven Russian roulette must undo (pbrt-v4's
    /// `BSDFSample::eta` and `etaScale`, Sec. 13.1.5).
    pub eta: f32,
}

/// What `Material::invert` found: the primary samples that `sample` maps to `wi`, and the factors
/// the reversible-jump acceptance needs (RJMLT Eq. 42–44).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfInverse {
    /// Uniforms `u` with `sample(wo, u, mode).wi == wi` (up to rounding).
    pub u: [f32; BSDF_SAMPLE_DIMS],
    /// The lobe t the inverse assumed produced `wi`.
    pub lobe: u8,
    /// Whether lobe t is a delta lobe.
    pub delta: bool,
    /// T(t) of Eq. 44: the probability with which this inverse chose lobe t among the lobes that
    /// could have produced `wi` (1 for single-lobe materials and for the dielectric, whose lobes
    /// never overlap). It enters the acceptance as the ratio of Eq. 43.
    pub lobe_choice_prob: f32,
    /// |J[g⁻¹]| of Eq. 42: α_t times lobe t's density at `wi` — per unit solid angle for a smooth
    /// lobe, a pure discrete mass α_t for a delta lobe (Eq. 40 with b − a = α_t; the unused
    /// direction dimensions have unit Jacobian). For a smooth mixture `jacobian / lobe_choice_prob`
    /// equals `Material::pdf`.
    pub jacobian: f32,
}

// INTERFACE (implementation owned by the sampling/materials work; bodies to be filled in):
impl Material {
    /// f(wo, wi), without the cosine factor; zero for delta lobes and for invalid configurations.
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        if !valid_pair(wo, wi) {
            return Rgb::ZERO;
        }
        match *self {
            Material::Diffuse { reflectance } => diffuse::eval(reflectance, wo, wi),
            Material::Mirror { .. } | Material::Dielectric { .. } => Rgb::ZERO,
            Material::RoughConductor { alpha, eta, k } => conductor::eval(&Ggx::new(alpha), eta, k, wo, wi),
            Material::RoughDielectric { alpha, ior } => rough_dielectric::eval(&Ggx::new(alpha), ior, wo, wi, mode),
            Material::RoughPlastic { alpha, plastic } => {
                plastic::eval_specular(&Ggx::new(alpha), &plastic, wo, wi) + plastic::eval_diffuse(&plastic, wo, wi)
            }
        }
    }
    /// Solid-angle density with which `sample` produces `wi` given `wo` (zero for delta lobes).
    pub fn pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> f32 {
        let _ = mode;
        if !valid_pair(wo, wi) {
            return 0.0;
        }
        let probs = self.lobe_probabilities(wo);
        let mut pdf = 0.0;
        for (t, &p) in probs.iter().enumerate().take(self.lobe_count()) {
            if p > 0.0 && !self.lobe_is_delta(t) {
                pdf += p * self.lobe_pdf(t, wo, wi);
            }
        }
        pdf
    }
    /// `(eval, pdf)` at once, what a light sample weighted by MIS needs: the two share the half
    /// vector, D and Λ of a GGX lobe and the lobe probabilities of a mixture, computed once here
    /// (equal to the separate calls up to rounding; `tests::eval_pdf_is_eval_and_pdf`).
    #[inline(always)]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> (Rgb, f32) {
        if !valid_pair(wo, wi) {
            return (Rgb::ZERO, 0.0);
        }
        self.eval_pdf_valid(wo, wi, mode, None)
    }

    /// `eval_pdf` for a pair that passed `valid_pair`; `probs` are the lobe probabilities at `wo`
    /// when the caller has them already.
    #[inline(always)]
    fn eval_pdf_valid(&self, wo: Vec3, wi: Vec3, mode: TransportMode, probs: Option<[f32; MAX_LOBES]>) -> (Rgb, f32) {
        match *self {
            Material::Diffuse { reflectance } => (diffuse::eval(reflectance, wo, wi), diffuse::pdf(wo, wi)),
            Material::Mirror { .. } | Material::Dielectric { .. } => (Rgb::ZERO, 0.0),
            Material::RoughConductor { alpha, eta, k } => conductor::eval_pdf(&Ggx::new(alpha), eta, k, wo, wi),
            Material::RoughPlastic { alpha, plastic } => {
                let probs = probs.unwrap_or_else(|| plastic::lobe_probabilities(&plastic, wo));
                plastic::eval_pdf(&Ggx::new(alpha), &plastic, probs, wo, wi)
            }
            Material::RoughDielectric { .. } => (self.eval(wo, wi, mode), self.pdf(wo, wi, mode)),
        }
    }
    /// Draws `wi` given `wo` from the uniforms `u` (`u[0]` lobe, `u[1]`,`u[2]` direction).
    #[inline(always)]
    pub fn sample(&self, wo: Vec3, u: [f32; BSDF_SAMPLE_DIMS], mode: TransportMode) -> Option<BsdfSample> {
        if !wo.is_finite() || wo.z == 0.0 {
            return None;
        }
        let probs = self.lobe_probabilities(wo);
        let t = choose_lobe(&probs[..self.lobe_count()], u[0])?;
        let wi = self.sample_lobe(t, wo, [u[1], u[2]])?;
        if !wi.is_finite() || wi.z == 0.0 {
            return None;
        }
        if self.lobe_is_delta(t) {
            let f = self.delta_weight(t, wo, mode) / wi.z.abs();
            let eta = self.lobe_eta(t, wo);
            return Some(BsdfSample { wi, f, pdf: probs[t], delta: true, lobe: t as u8, eta });
        }
        let (f, pdf) = self.eval_pdf_valid(wo, wi, mode, Some(probs));
        if !(pdf > 0.0) || !pdf.is_finite() {
            return None;
        }
        let eta = self.lobe_eta(t, wo);
        Some(BsdfSample { wi, f, pdf, delta: false, lobe: t as u8, eta })
    }
    /// Whether every lobe is a delta (mirror, smooth dielectric): no light-source connection can
    /// be made at such a vertex.
    #[inline]
    pub fn is_specular(&self) -> bool {
        matches!(self, Material::Mirror { .. } | Material::Dielectric { .. })
    }
}

impl Material {
    /// Number of lobes (entries of `lobe_probabilities` in use; `BsdfSample::lobe` indexes them):
    /// Diffuse, Mirror, RoughConductor 1; Dielectric 2 (0 reflection, 1 refraction); RoughPlastic 2
    /// (0 specular coating, 1 diffuse base).
    #[inline]
    pub fn lobe_count(&self) -> usize {
        match self {
            Material::Diffuse { .. } | Material::Mirror { .. } | Material::RoughConductor { .. } => 1,
            Material::Dielectric { .. } | Material::RoughDielectric { .. } | Material::RoughPlastic { .. } => 2,
        }
    }

    /// Selection probabilities α_t of the lobes given `wo` (entries past `lobe_count` are 0). The
    /// single helper behind `sample` (lobe t is chosen when u[0] falls in [α_0 + … + α_{t−1},
    /// α_0 + … + α_t)), `pdf` (the mixture Σ α_t p_t) and `invert` (Eq. 41–44).
    #[inline]
    pub fn lobe_probabilities(&self, wo: Vec3) -> [f32; MAX_LOBES] {
        match *self {
            Material::Diffuse { .. } | Material::Mirror { .. } | Material::RoughConductor { .. } => [1.0, 0.0],
            Material::Dielectric { ior } => dielectric::lobe_probabilities(ior, wo),
            Material::RoughDielectric { ior, .. } => rough_dielectric::lobe_probabilities(ior, wo),
            Material::RoughPlastic { plastic, .. } => plastic::lobe_probabilities(&plastic, wo),
        }
    }

    /// Whether lobe `t` is a delta distribution (a discrete choice of direction).
    #[inline]
    pub fn lobe_is_delta(&self, t: usize) -> bool {
        let _ = t;
        self.is_specular()
    }

    /// Lobe `t`'s direction map (u[1], u[2]) → wi. Delta lobes ignore `u`.
    #[inline(always)]
    fn sample_lobe(&self, t: usize, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        match *self {
            Material::Diffuse { .. } => diffuse::sample(wo, u),
            Material::Mirror { .. } => specular::sample(wo),
            Material::Dielectric { ior } => dielectric::sample(ior, t, wo),
            Material::RoughDielectric { alpha, ior } => rough_dielectric::sample(&Ggx::new(alpha), ior, t, wo, u),
            Material::RoughConductor { alpha, .. } => {
                (wo.z > 0.0).then(|| Ggx::new(alpha).sample_reflection(wo, u)).flatten().map(|(wi, _)| wi)
            }
            Material::RoughPlastic { alpha, .. } => {
                if t == plastic::SPECULAR {
                    (wo.z > 0.0).then(|| Ggx::new(alpha).sample_reflection(wo, u)).flatten().map(|(wi, _)| wi)
                } else {
                    diffuse::sample(wo, u)
                }
            }
        }
    }

    /// Solid-angle density of smooth lobe `t`'s direction map (0 for delta lobes).
    fn lobe_pdf(&self, t: usize, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Material::Diffuse { .. } => diffuse::pdf(wo, wi),
            Material::Mirror { .. } | Material::Dielectric { .. } => 0.0,
            Material::RoughConductor { alpha, .. } => Ggx::new(alpha).pdf_reflection(wo, wi),
            Material::RoughDielectric { alpha, ior } => rough_dielectric::pdf(&Ggx::new(alpha), ior, t, wo, wi),
            Material::RoughPlastic { alpha, .. } => {
                if t == plastic::SPECULAR {
                    Ggx::new(alpha).pdf_reflection(wo, wi)
                } else {
                    diffuse::pdf(wo, wi)
                }
            }
        }
    }

    /// Inverse of smooth lobe `t`'s direction map.
    fn invert_lobe(&self, t: usize, wo: Vec3, wi: Vec3) -> Option<[f32; 2]> {
        match *self {
            Material::Diffuse { .. } => diffuse::invert(wo, wi),
            Material::Mirror { .. } | Material::Dielectric { .. } => None,
            Material::RoughConductor { alpha, .. } => Ggx::new(alpha).invert_reflection(wo, wi),
            Material::RoughDielectric { alpha, ior } => rough_dielectric::invert(&Ggx::new(alpha), ior, t, wo, wi),
            Material::RoughPlastic { alpha, .. } => {
                if t == plastic::SPECULAR {
                    Ggx::new(alpha).invert_reflection(wo, wi)
                } else {
                    diffuse::invert(wo, wi)
                }
            }
        }
    }

    /// Whether `wi` is delta lobe `t`'s direction for `wo`.
    fn delta_matches(&self, t: usize, wo: Vec3, wi: Vec3) -> bool {
        match *self {
            Material::Mirror { .. } => specular::matches(wo, wi),
            Material::Dielectric { ior } => dielectric::matches(ior, t, wo, wi),
            _ => false,
        }
    }

    /// f·|cos θi| of delta lobe `t`.
    #[inline]
    fn delta_weight(&self, t: usize, wo: Vec3, mode: TransportMode) -> Rgb {
        match *self {
            Material::Mirror { reflectance } => specular::weight(reflectance),
            Material::Dielectric { ior } => dielectric::weight(ior, t, wo, mode),
            _ => Rgb::ZERO,
        }
    }

    /// η_t/η_i that lobe `t` crosses from the side of `wo` (1 for every reflection lobe).
    #[inline]
    fn lobe_eta(&self, t: usize, wo: Vec3) -> f32 {
        match *self {
            Material::Dielectric { ior } => dielectric::eta(ior, t, wo),
            Material::RoughDielectric { ior, .. } => rough_dielectric::eta(ior, t, wo),
            _ => 1.0,
        }
    }

    /// Throughput weight f·|cos θi| of the delta lobe that maps `wo` to `wi` (the mirror or
    /// dielectric direction within `DELTA_DIRECTION_TOLERANCE`), zero if none does. Path-space
    /// integrators use it to evaluate a given specular vertex, which `eval` (zero for deltas)
    /// cannot.
    pub fn eval_delta(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        if !valid_pair(wo, wi) {
            return Rgb::ZERO;
        }
        (0..self.lobe_count())
            .find(|&t| self.lobe_is_delta(t) && self.delta_matches(t, wo, wi))
            .map_or(Rgb::ZERO, |t| self.delta_weight(t, wo, mode))
    }

    /// Selection probability α_t of the delta lobe that maps `wo` to `wi` (within
    /// `DELTA_DIRECTION_TOLERANCE`), zero if none does: the discrete mass `sample` reports as the
    /// `pdf` of a delta lobe. Path-space integrators use it as a specular vertex's share of a
    /// transition density (delta-stripped measure, `integrator::path_space`).
    pub fn pdf_delta(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !valid_pair(wo, wi) {
            return 0.0;
        }
        let probs = self.lobe_probabilities(wo);
        (0..self.lobe_count())
            .find(|&t| self.lobe_is_delta(t) && self.delta_matches(t, wo, wi))
            .map_or(0.0, |t| probs[t])
    }

    /// The uniforms `u` that `sample` maps to `wi`, with the lobe choice and Jacobian the
    /// reversible-jump acceptance needs (RJMLT Sec. 6). `gamma` are fresh uniforms for the
    /// ambiguous parts (see `BSDF_INVERT_DIMS`):
    /// - lobe t is drawn with T(t) = α_t |J_t| / Σ_s α_s |J_s| (Eq. 44) using γ[0], where |J_s| is
    ///   lobe s's density at `wi` (a delta lobe counts 1 if `wi` is its direction; delta and smooth
    ///   lobes never share a material);
    /// - u[0] = lo_t + γ[1] (hi_t − lo_t) inside lobe t's selection interval (Eq. 40/41);
    /// - u[1], u[2] invert lobe t's direction map exactly (smooth lobes), or are γ[2], γ[3] for a
    ///   delta lobe, which does not read them (unit Jacobian).
    ///
    /// `None` when no lobe can produce `wi` (wrong hemisphere, not the delta direction, zero
    /// selection probability).
    pub fn invert(
        &self,
        wo: Vec3,
        wi: Vec3,
        mode: TransportMode,
        gamma: [f32; BSDF_INVERT_DIMS],
    ) -> Option<BsdfInverse> {
        let _ = mode;
        if !valid_pair(wo, wi) {
            return None;
        }
        let n = self.lobe_count();
        let probs = self.lobe_probabilities(wo);
        // α_s |J_s| for every lobe (Eq. 42 without the choice).
        let mut weights = [0.0f32; MAX_LOBES];
        for t in 0..n {
            if probs[t] <= 0.0 {
                continue;
            }
            let j = if self.lobe_is_delta(t) {
                if self.delta_matches(t, wo, wi) {
                    1.0
                } else {
                    0.0
                }
            } else {
                self.lobe_pdf(t, wo, wi)
            };
            weights[t] = probs[t] * j;
        }
        let total: f32 = weights[..n].iter().sum();
        if !(total > 0.0) || !total.is_finite() {
            return None;
        }
        let t = choose_by_weight(&weights[..n], total, gamma[0])?;
        let (lo, hi) = lobe_interval(&probs[..n], t)?;
        let u0 = place_in_interval(lo, hi, gamma[1])?;
        let delta = self.lobe_is_delta(t);
        let [u1, u2] = if delta {
            [clamp_unit(gamma[2]), clamp_unit(gamma[3])]
        } else {
            let u = self.invert_lobe(t, wo, wi)?;
            // The paper's caveat (end of Sec. 6.2): where the direction map is ill-conditioned
            // (far tails of a near-mirror GGX lobe, grazing wo) rounding can make the inverse land
            // on uniforms that sample a visibly different direction, or none; report that as "not
            // invertible" rather than return a different path.
            let again = self.sample_lobe(t, wo, u)?;
            if (again - wi).length() * conditioning(wo, wi) > INVERT_DIRECTION_TOLERANCE {
                return None;
            }
            u
        };
        Some(BsdfInverse {
            u: [u0, u1, u2],
            lobe: t as u8,
            delta,
            lobe_choice_prob: weights[t] / total,
            jacobian: weights[t],
        })
    }
}

/// min(cos θd, |cos θi|): the factor by which a round trip's rounding error is amplified (see
/// `INVERT_DIRECTION_TOLERANCE`), floored at 1e-4 so that a degenerate pair cannot accept anything.
pub fn conditioning(wo: Vec3, wi: Vec3) -> f32 {
    (0.5 * (wo + wi).length()).min(wi.z.abs()).max(1e-4)
}

/// Both directions finite and off the horizon plane (cos θ = 0 carries no energy and would divide
/// by zero).
#[inline]
fn valid_pair(wo: Vec3, wi: Vec3) -> bool {
    wo.is_finite() && wi.is_finite() && wo.z != 0.0 && wi.z != 0.0
}

/// Lobe chosen by `u`: the first t with u < α_0 + … + α_t; the last lobe with non-zero
/// probability takes any u left over by rounding of the sum. `None` if all probabilities are 0.
#[inline]
fn choose_lobe(probs: &[f32], u: f32) -> Option<usize> {
    let mut cdf = 0.0f32;
    let mut last = None;
    for (t, &p) in probs.iter().enumerate() {
        if p > 0.0 {
            cdf += p;
            last = Some(t);
            if u < cdf {
                return Some(t);
            }
        }
    }
    last
}

/// The interval of u[0] that `choose_lobe` maps to lobe `t`, computed with the same summation.
fn lobe_interval(probs: &[f32], t: usize) -> Option<(f32, f32)> {
    if probs.get(t).is_none_or(|&p| !(p > 0.0)) {
        return None;
    }
    let lo: f32 = probs[..t].iter().filter(|&&p| p > 0.0).sum();
    let is_last = probs[t + 1..].iter().all(|&p| !(p > 0.0));
    let hi = if is_last { 1.0 } else { lo + probs[t] };
    Some((lo, hi))
}

/// lo + γ (hi − lo), kept inside [lo, hi) despite rounding (Eq. 40); `None` if the interval is
/// empty in f32.
fn place_in_interval(lo: f32, hi: f32, gamma: f32) -> Option<f32> {
    if !(hi > lo) {
        return None;
    }
    let below_hi = f32::from_bits(hi.to_bits() - 1);
    let u = lo + clamp_unit(gamma) * (hi - lo);
    Some(u.clamp(lo, below_hi))
}

/// Index drawn with probability weight/total by `u` (the discrete choice of Eq. 44).
fn choose_by_weight(weights: &[f32], total: f32, u: f32) -> Option<usize> {
    let target = clamp_unit(u) * total;
    let mut cdf = 0.0f32;
    let mut last = None;
    for (t, &w) in weights.iter().enumerate() {
        if w > 0.0 {
            cdf += w;
            last = Some(t);
            if target < cdf {
                return Some(t);
            }
        }
    }
    last
}

impl Material {
    /// A GGX rough conductor whose normal-incidence reflectance is `colour` (per channel, clamped to
    /// [0, 0.9999]); the colour also serves as the edge tint, so the complex index comes from
    /// Gulbrandsen's (2014) mapping with r = g = colour.
    pub fn conductor_from_colour(alpha: f32, colour: Rgb) -> Material {
        Material::conductor_from_colours(alpha, colour, colour)
    }
    /// A GGX rough conductor from a normal-incidence `reflectivity` and a grazing `edge_tint`
    /// (Gulbrandsen 2014): edge tint 0 gives a dielectric-like falloff, 1 the strongest tint.
    pub fn conductor_from_colours(alpha: f32, reflectivity: Rgb, edge_tint: Rgb) -> Material {
        let (eta, k) = conductor_index_from_colours(reflectivity, edge_tint);
        Material::RoughConductor { alpha, eta, k }
    }
}
