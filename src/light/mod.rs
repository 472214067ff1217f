//! Emitters: area emission on meshes, constant and image environments, and light selection.
//! Each sampling routine has its pdf and its inverse beside it, with the uniforms it consumes passed
//! explicitly.
//!
//! # Dimension layout
//! - `sample_li` (`LI_SAMPLE_DIMS` = 3): area light: `u[0]` the triangle (by area, discrete),
//!   `u[1..3]` the point in it; environment: `u[0]` unused, `u[1..3]` the direction.
//! - `sample_emission` (`EMISSION_SAMPLE_DIMS` = 5): area light: `u[0..3]` the point as above,
//!   `u[3..5]` the cosine-weighted direction (two-sided: `u[3]` < ½ front, ≥ ½ back); environment:
//!   `u[0]` unused, `u[1..3]` the direction towards the environment, `u[3..5]` the ray's origin on
//!   the disk perpendicular to it.
//! - light selection (`LightSampler`) takes its own single uniform.
//! - the path tracer's light sample (`sample_li_point`, `li_from_point`, density `pdf_li_nee`)
//!   takes `sample_li`'s 3 uniforms; near a rectangle light it samples by solid angle with
//!   `u[1..3]` (`spherical_rectangle`) and has no inverse (nothing inverts pt's paths).
//!
//! Inverses take, for each ambiguous dimension (a discrete choice's interval, RJMLT Eq. 40, or an
//! unused dimension), a fresh uniform `gamma` and return `None` for a point the sampler cannot
//! produce (off the emitter, behind a one-sided emitter, in a texel of zero density).

// `!(x > 0.0)` is deliberate throughout: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod area;
mod environment;
pub mod spherical_rectangle;
pub mod sunsky;

pub use area::{
    invert_emission_direction, invert_mesh_point, invert_triangle_point, pdf_emission_direction, pdf_mesh_point,
    sample_emission_direction, sample_mesh_point, sample_triangle_point, triangle_barycentrics, triangle_normal,
    MeshPoint,
};
pub use environment::{direction_to_equirect, equirect_to_direction, Environment};

use std::sync::Arc;

use glam::Vec3;

use crate::geometry::{spawn_ray, spawn_ray_to, Ray, TriangleMesh};
use crate::sampling::Distribution1D;
use crate::spectrum::Rgb;

/// Uniforms consumed by `Light::sample_li` (triangle choice, then 2D position or direction).
pub const LI_SAMPLE_DIMS: usize = 3;
/// Uniforms consumed by `Light::sample_emission` (3 for the position, 2 for the direction).
pub const EMISSION_SAMPLE_DIMS: usize = 5;

/// An emitter.
#[derive(Debug)]
pub enum Light {
    Area(AreaLight),
    ConstantEnvironment(ConstantEnvironment),
    ImageEnvironment(ImageEnvironment),
}

/// How an emitter's emission is spread over positions and directions (pbrt-v4's `LightType`).
/// Delta emitters (a point or spot light: one position; a directional light: one direction) have
/// no density a ray can hit, so every technique that finds emission by hitting it has density 0,
/// and estimators and MIS weights must treat them apart. The bidirectional MIS weights
/// (integrator/bdpt/mis.rs) do not yet, so the scene builder refuses them (docs/scene-format.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitterKind {
    /// Emission from surfaces with area (`Light::Area`).
    Area,
    /// Emission from infinity over a solid angle (the environments).
    Infinite,
    /// Emission from a single point (point and spot lights).
    DeltaPosition,
    /// Emission in a single direction (directional lights).
    DeltaDirection,
}

impl EmitterKind {
    /// Whether the emitter is concentrated on a single position or direction.
    pub fn is_delta(self) -> bool {
        matches!(self, EmitterKind::DeltaPosition | EmitterKind::DeltaDirection)
    }
}

impl std::fmt::Display for EmitterKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            EmitterKind::Area => "area",
            EmitterKind::Infinite => "infinite (environment)",
            EmitterKind::DeltaPosition => "delta-position (point or spot)",
            EmitterKind::DeltaDirection => "delta-direction (directional)",
        })
    }
}

/// Emission `radiance` from every triangle of one mesh, on the side the geometric normal points to
/// (or both sides when `two_sided`).
#[derive(Debug)]
pub struct AreaLight {
    pub mesh: Arc<TriangleMesh>,
    /// Index of the mesh in `Scene::meshes` (its `geom_id`).
    pub geom_id: u32,
    pub radiance: Rgb,
    pub two_sided: bool,
    /// Triangle choice proportional to area.
    pub triangles: Distribution1D,
    /// Unit geometric normal of each triangle (`area::triangle_normal`), kept for light sampling.
    pub normals: Vec<Vec3>,
    pub area: f32,
    /// The rectangle the mesh is, when it is one (two triangles): the path tracer samples it by
    /// solid angle from nearby points (`AreaLight::sample_li_nee`).
    pub rectangle: Option<spherical_rectangle::Rectangle>,
}

/// Radiance arriving equally from every direction at infinity.
#[derive(Debug)]
pub struct ConstantEnvironment {
    pub radiance: Rgb,
    /// Centre and radius of a sphere bounding the scene (for emission sampling).
    pub scene_center: Vec3,
    pub scene_radius: f32,
}

/// Radiance at infinity from an equirectangular (latitude-longitude) image, importance-sampled
/// with a 2D piecewise-constant distribution over its pixels.
#[derive(Debug)]
pub struct ImageEnvironment {
    pub width: usize,
    pub height: usize,
    /// Row-major texels, row 0 at the top (+y, θ = 0).
    pub texels: Vec<Rgb>,
    pub scale: f32,
    /// Rotation of the map: world-to-map transform.
    pub to_local: glam::Mat3,
    pub distribution: crate::sampling::Distribution2D,
    pub scene_center: Vec3,
    pub scene_radius: f32,
}

/// What `Light::sample_li_point` draws before the reference point is known.
#[derive(Clone, Copy, Debug)]
pub enum LiPoint {
    /// The point on an area light (`None` when the light cannot produce one).
    Area(Option<MeshPoint>),
    /// The uniforms, for a light whose sample needs the reference point throughout.
    Deferred([f32; LI_SAMPLE_DIMS]),
}

/// A point on an emitter seen from a reference point, as next-event estimation needs it.
#[derive(Clone, Copy, Debug)]
pub struct LightLiSample {
    /// Unit direction from the reference point towards the light.
    pub wi: Vec3,
    /// The point on the light (for an environment: a point far outside the scene along `wi`).
    pub p: Vec3,
    /// Conservative absolute error bound of `p`, per axis (zero for environments).
    pub p_error: Vec3,
    /// Unit normal at the light point (zero for environments).
    pub n: Vec3,
    /// Emitted radiance towards the reference point.
    pub radiance: Rgb,
    /// Solid-angle density at the reference point (not including light selection).
    pub pdf: f32,
    /// Whether the light is at infinity (shadow ray unbounded).
    pub infinite: bool,
}

impl LightLiSample {
    /// The shadow ray from the reference point (`p`, error bound `p_error`, geometric normal `ng`)
    /// to this light sample. Both ends are offset by their error bounds (`spawn_ray_to`): a light
    /// point computed in f32 lies up to its bound off the emitter's plane, and un-offset it lies
    /// behind the emitter half the time, so that a shadow ray arriving at a grazing angle hits the
    /// emitter itself before its end. Far from the origin (the room of tests/images/extremes.rs
    /// translated by 1e5: bound ≈ 0.04 units) that darkened walls that see the light at grazing
    /// angles by about 1%.
    #[inline]
    pub fn shadow_ray_from(&self, p: Vec3, p_error: Vec3, ng: Vec3) -> Ray {
        if self.infinite {
            spawn_ray(p, p_error, ng, self.wi)
        } else {
            spawn_ray_to(p, p_error, ng, self.p, self.p_error, self.n)
        }
    }
}

/// What `Light::invert_li` found: the uniforms `sample_li` maps to the emitter point (or, for an
/// environment, the direction) and |J| of that inverse (RJMLT Eq. 39–40): uniforms per unit area
/// of the emitter point (area lights: the triangle's interval, Eq. 40, times the uniform-triangle
/// warp's 1/area), per unit solid angle of the direction (environments; the unused `u[0]` adds 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiInverse {
    pub u: [f32; LI_SAMPLE_DIMS],
    pub jacobian: f32,
}

/// What `Light::invert_emission` found: the uniforms of the emitted ray and the Jacobians of the
/// two halves of the inverse. Area lights: `jacobian_pos` per unit area of the point (as for
/// `LiInverse`), `jacobian_dir` per unit solid angle of the direction. Environments:
/// `jacobian_dir` per unit solid angle of the direction towards the environment, `jacobian_pos`
/// per unit area of the origin on the disk perpendicular to it (the unused `u[0]` adds 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionInverse {
    pub u: [f32; EMISSION_SAMPLE_DIMS],
    pub jacobian_pos: f32,
    pub jacobian_dir: f32,
}

/// A ray leaving an emitter, as light tracing and BDPT start light subpaths.
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample {
    pub p: Vec3,
    /// Unit normal at `p` (for an environment: the direction `dir`, the disk's normal).
    pub n: Vec3,
    pub dir: Vec3,
    pub radiance: Rgb,
    /// Area density of `p` (for an environment: density on the disk perpendicular to `dir`).
    pub pdf_pos: f32,
    /// Solid-angle density of `dir`.
    pub pdf_dir: f32,
    pub infinite: bool,
}

// INTERFACE (implementation owned by the sampling/materials/lights work):
impl Light {
    /// Samples a direction towards this light from `reference` with uniforms `u` (area lights: a
    /// point by area, the density BDPT's weights and the inverses are written in).
    pub fn sample_li(&self, reference: Vec3, u: [f32; LI_SAMPLE_DIMS]) -> Option<LightLiSample> {
        match self {
            Light::Area(l) => l.sample_li(reference, u),
            Light::ConstantEnvironment(l) => l.sample_li(reference, u),
            Light::ImageEnvironment(l) => l.sample_li(reference, u),
        }
    }
    /// The path tracer's light sample (next-event estimation), in two halves: this one, which does
    /// not depend on the reference point, is the point on an area light sampled by area (pt draws
    /// it while the shading point's vertices are still loading), or the uniforms, kept for later,
    /// for an environment. [`Self::li_from_point`] completes it, sampling a rectangle light seen
    /// from nearby by solid angle instead (`AreaLight::sample_li_nee`); [`Self::pdf_li_nee`] is its
    /// density.
    #[inline(always)]
    pub fn sample_li_point(&self, u: [f32; LI_SAMPLE_DIMS]) -> LiPoint {
        match self {
            Light::Area(l) => LiPoint::Area(l.sample_point(u)),
            Light::ConstantEnvironment(_) | Light::ImageEnvironment(_) => LiPoint::Deferred(u),
        }
    }
    /// The path tracer's light sample from its reference-independent half `point`, drawn by this
    /// light's [`Self::sample_li_point`] from the uniforms `u`, which a rectangle light seen from
    /// nearby samples by solid angle instead (`u` is passed again rather than kept in `point`: the
    /// caller has it, and `point` stays as small as the path tracer's loop had it).
    #[inline(always)]
    pub fn li_from_point(&self, reference: Vec3, point: &LiPoint, u: [f32; LI_SAMPLE_DIMS]) -> Option<LightLiSample> {
        match (self, point) {
            (Light::Area(l), LiPoint::Area(q)) if l.rectangle.is_some() => {
                l.li_from_rectangle_point(reference, q.as_ref(), u)
            }
            (Light::Area(l), LiPoint::Area(q)) => l.li_from_point(reference, q.as_ref()?),
            (Light::ConstantEnvironment(l), LiPoint::Deferred(u)) => l.sample_li(reference, *u),
            (Light::ImageEnvironment(l), LiPoint::Deferred(u)) => l.sample_li(reference, *u),
            // A point drawn by another kind of light: a caller's bug (pt draws the point and
            // completes it with the same light): asserted in debug builds, no light sample otherwise.
            _ => {
                debug_assert!(false, "li_from_point: the point was drawn by another kind of light");
                None
            }
        }
    }
    /// Solid-angle density at `reference` of `sample_li` choosing the point `p_light` with normal
    /// `n_light` (area lights). For environments pass the direction as `wi` and ignore p/n.
    pub fn pdf_li(&self, reference: Vec3, wi: Vec3, p_light: Vec3, n_light: Vec3) -> f32 {
        match self {
            Light::Area(l) => l.pdf_li(reference, wi, p_light, n_light),
            Light::ConstantEnvironment(l) => l.pdf_direction(wi),
            Light::ImageEnvironment(l) => l.pdf_direction(wi),
        }
    }
    /// Solid-angle density at `reference` of the path tracer's light sample
    /// ([`Self::sample_li_point`], [`Self::li_from_point`]) producing the point `p_light`.
    pub fn pdf_li_nee(&self, reference: Vec3, wi: Vec3, p_light: Vec3, n_light: Vec3) -> f32 {
        match self {
            Light::Area(l) => l.pdf_li_nee(reference, wi, p_light, n_light),
            _ => self.pdf_li(reference, wi, p_light, n_light),
        }
    }
    /// Inverse of `sample_li`: the uniforms that make `sample_li` choose the point `p_light` on
    /// triangle `prim` (area lights) or the direction `wi` (environments; `prim`/`p_light`
    /// ignored). `gamma` is a fresh uniform for the ambiguous `u[0]`. `None` when the sampler cannot
    /// produce that point or direction.
    pub fn invert_li(&self, wi: Vec3, prim: u32, p_light: Vec3, gamma: f32) -> Option<LiInverse> {
        match self {
            Light::Area(l) => l.invert_li(prim, p_light, gamma),
            Light::ConstantEnvironment(l) => l.invert_li(wi, gamma),
            Light::ImageEnvironment(l) => l.invert_li(wi, gamma),
        }
    }
    /// Radiance an area light emits from a point with geometric normal `n` in direction `w`.
    pub fn emitted(&self, n: Vec3, w: Vec3) -> Rgb {
        match self {
            Light::Area(l) => l.emitted(n, w),
            _ => Rgb::ZERO,
        }
    }
    /// Radiance an environment sends along `-dir` (i.e. seen when looking in direction `dir`).
    pub fn environment_radiance(&self, dir: Vec3) -> Rgb {
        match self {
            Light::Area(_) => Rgb::ZERO,
            Light::ConstantEnvironment(l) => l.radiance,
            Light::ImageEnvironment(l) => l.radiance(dir),
        }
    }
    /// Samples an emitted ray with uniforms `u` (3 for position, 2 for direction).
    pub fn sample_emission(&self, u: [f32; EMISSION_SAMPLE_DIMS]) -> Option<EmissionSample> {
        match self {
            Light::Area(l) => l.sample_emission(u),
            Light::ConstantEnvironment(l) => l.sample_emission(u),
            Light::ImageEnvironment(l) => l.sample_emission(u),
        }
    }
    /// Densities `(pdf_pos, pdf_dir)` of `sample_emission` producing the ray from `p` (normal `n`)
    /// in direction `dir`.
    pub fn pdf_emission(&self, p: Vec3, n: Vec3, dir: Vec3) -> (f32, f32) {
        let _ = p;
        match self {
            Light::Area(l) => l.pdf_emission(n, dir),
            Light::ConstantEnvironment(l) => l.pdf_emission(dir),
            Light::ImageEnvironment(l) => l.pdf_emission(dir),
        }
    }
    /// Inverse of `sample_emission` for the ray leaving `p` along `dir`: for an area light `p` lies
    /// on triangle `prim`; for an environment `p` is any point on the ray (e.g. the first surface it
    /// reaches), projected onto the emission disk, and `prim` is ignored. `gamma` is a fresh uniform
    /// for the ambiguous `u[0]`.
    pub fn invert_emission(&self, prim: u32, p: Vec3, dir: Vec3, gamma: f32) -> Option<EmissionInverse> {
        match self {
            Light::Area(l) => l.invert_emission(prim, p, dir, gamma),
            Light::ConstantEnvironment(l) => l.invert_emission(p, dir, gamma),
            Light::ImageEnvironment(l) => l.invert_emission(p, dir, gamma),
        }
    }
    /// Total emitted power (luminance-weighted flux), for light selection.
    pub fn power(&self) -> f32 {
        let p = match self {
            Light::Area(l) => l.power(),
            Light::ConstantEnvironment(l) => l.power(),
            Light::ImageEnvironment(l) => l.power(),
        };
        if p.is_finite() {
            p.max(0.0)
        } else {
            0.0
        }
    }
    pub fn is_environment(&self) -> bool {
        !matches!(self, Light::Area(_))
    }
    /// The emitter's kind. The match lists every variant on purpose: a new emitter must say here
    /// whether it is a delta emitter, which the scene builder then refuses.
    pub fn kind(&self) -> EmitterKind {
        match self {
            Light::Area(_) => EmitterKind::Area,
            Light::ConstantEnvironment(_) | Light::ImageEnvironment(_) => EmitterKind::Infinite,
        }
    }
}

/// Chooses a light proportionally to its power (one uniform), with pdf and inverse beside it.
#[derive(Debug)]
pub struct LightSampler {
    pub distribution: Distribution1D,
}

impl LightSampler {
    /// Selection proportional to each light's power; all-zero power gives uniform selection.
    pub fn new(lights: &[Light]) -> LightSampler {
        let power: Vec<f32> = lights.iter().map(|l| l.power()).collect();
        LightSampler { distribution: Distribution1D::new(&power) }
    }
    /// `(index, pmf, u remapped into [0,1) inside the index's interval)`; pmf 0 when there are no
    /// lights.
    pub fn sample(&self, u: f32) -> (usize, f32, f32) {
        self.distribution.sample_discrete(u)
    }
    /// Probability of choosing light `index`.
    pub fn pmf(&self, index: usize) -> f32 {
        self.distribution.pdf_discrete(index)
    }
    /// Probabilistic inverse of `sample` (RJMLT Eq. 40): a u that selects `index`, uniform in its
    /// interval as `gamma` is uniform, and the Jacobian of that inverse, the interval's length
    /// pmf(index). `None` for a light of zero probability.
    pub fn invert(&self, index: usize, gamma: f32) -> Option<(f32, f32)> {
        let u = self.distribution.invert_discrete(index, gamma)?;
        Some((u, self.distribution.pdf_discrete(index)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;
    use crate::sampling::Rng;

    fn triangle() -> Arc<TriangleMesh> {
        Arc::new(TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]], None, None).unwrap())
    }

    #[test]
    fn light_sampler_by_power_with_inverse() {
        let bounds = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
        let lights = vec![
            Light::Area(AreaLight::new(triangle(), 0, Rgb::ONE, false)),
            Light::Area(AreaLight::new(triangle(), 1, Rgb::splat(2.0), true)),
            Light::ConstantEnvironment(ConstantEnvironment::new(Rgb::ZERO, bounds)),
        ];
        // Power: L·A·π per side; luminance of white is 1.
        let p0 = std::f32::consts::PI * 0.5;
        assert!((lights[0].power() - p0).abs() < 1e-4 * p0);
        assert!((lights[1].power() - 4.0 * p0).abs() < 1e-4 * p0);
        assert_eq!(lights[2].power(), 0.0);
        let s = LightSampler::new(&lights);
        assert!((s.pmf(0) - 0.2).abs() < 1e-6 && (s.pmf(1) - 0.8).abs() < 1e-6 && s.pmf(2) == 0.0);
        let mut rng = Rng::new(12, 0);
        for _ in 0..1000 {
            let (i, pmf, r) = s.sample(rng.uniform());
            assert!(i < 2 && pmf > 0.0 && (0.0..1.0).contains(&r));
            let g = rng.uniform();
            let (u, jacobian) = s.invert(i, g).unwrap();
            assert_eq!(jacobian, pmf);
            let (j, _, r2) = s.sample(u);
            assert_eq!(i, j);
            assert!((r2 - g).abs() < 1e-4);
        }
        assert_eq!(s.invert(2, 0.5), None);
        // No power anywhere: uniform choice.
        let dark = LightSampler::new(&lights[2..]);
        assert_eq!(dark.pmf(0), 1.0);
    }

    #[test]
    fn dispatch_inverts_li_and_emission_for_every_kind() {
        let bounds = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
        let texels: Vec<Rgb> = (0..32).map(|i| Rgb::splat(0.1 + (i % 5) as f32)).collect();
        let lights = [
            Light::Area(AreaLight::new(triangle(), 0, Rgb::ONE, true)),
            Light::ConstantEnvironment(ConstantEnvironment::new(Rgb::ONE, bounds)),
            Light::ImageEnvironment(ImageEnvironment::new(8, 4, texels, 2.0, glam::Mat3::IDENTITY, bounds)),
        ];
        let reference = Vec3::new(0.2, 0.3, 2.0);
        let mut rng = Rng::new(13, 0);
        for light in &lights {
            for _ in 0..500 {
                let u = [rng.uniform(), rng.uniform(), rng.uniform()];
                let Some(s) = light.sample_li(reference, u) else { continue };
                let pdf = light.pdf_li(reference, s.wi, s.p, s.n);
                assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf, "{pdf} vs {}", s.pdf);
                let v = light.invert_li(s.wi, 0, s.p, 0.5).unwrap().u;
                let again = light.sample_li(reference, v).unwrap();
                assert!(again.wi.dot(s.wi) > 1.0 - 1e-6);
                let ue = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
                let Some(e) = light.sample_emission(ue) else { continue };
                let ve = light.invert_emission(0, e.p, e.dir, 0.5).unwrap().u;
                let e2 = light.sample_emission(ve).unwrap();
                assert!(e2.dir.dot(e.dir) > 1.0 - 1e-6 && (e2.p - e.p).length() < 1e-4);
            }
        }
        assert!(!lights[0].is_environment() && lights[2].is_environment());
    }
}
