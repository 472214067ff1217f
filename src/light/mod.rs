//! Emitters: area emission on meshes, constant and image environments, and light selection.
//! Each sampling routine has its pdf beside it, with the uniforms it consumes passed explicitly.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::geometry::TriangleMesh;
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
    pub area: f32,
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

/// A point on an emitter seen from a reference point, as next-event estimation needs it.
#[derive(Clone, Copy, Debug)]
pub struct LightLiSample {
    /// Unit direction from the reference point towards the light.
    pub wi: Vec3,
    /// The point on the light (for an environment: a point far outside the scene along `wi`).
    pub p: Vec3,
    /// Unit normal at the light point (zero for environments).
    pub n: Vec3,
    /// Emitted radiance towards the reference point.
    pub radiance: Rgb,
    /// Solid-angle density at the reference point (not including light selection).
    pub pdf: f32,
    /// Whether the light is at infinity (shadow ray unbounded).
    pub infinite: bool,
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
    /// Samples a direction towards this light from `reference` with uniforms `u`.
    pub fn sample_li(&self, reference: Vec3, u: [f32; LI_SAMPLE_DIMS]) -> Option<LightLiSample> {
        let _ = (reference, u);
        todo!("Light::sample_li")
    }
    /// Solid-angle density at `reference` of `sample_li` choosing the point `p_light` with normal
    /// `n_light` (area lights). For environments pass the direction as `wi` and ignore p/n.
    pub fn pdf_li(&self, reference: Vec3, wi: Vec3, p_light: Vec3, n_light: Vec3) -> f32 {
        let _ = (reference, wi, p_light, n_light);
        todo!("Light::pdf_li")
    }
    /// Radiance an area light emits from a point with geometric normal `n` in direction `w`.
    pub fn emitted(&self, n: Vec3, w: Vec3) -> Rgb {
        let _ = (n, w);
        todo!("Light::emitted")
    }
    /// Radiance an environment sends along `-dir` (i.e. seen when looking in direction `dir`).
    pub fn environment_radiance(&self, dir: Vec3) -> Rgb {
        let _ = dir;
        todo!("Light::environment_radiance")
    }
    /// Samples an emitted ray with uniforms `u` (3 for position, 2 for direction).
    pub fn sample_emission(&self, u: [f32; EMISSION_SAMPLE_DIMS]) -> Option<EmissionSample> {
        let _ = u;
        todo!("Light::sample_emission")
    }
    /// Densities `(pdf_pos, pdf_dir)` of `sample_emission` producing the ray from `p` (normal `n`)
    /// in direction `dir`.
    pub fn pdf_emission(&self, p: Vec3, n: Vec3, dir: Vec3) -> (f32, f32) {
        let _ = (p, n, dir);
        todo!("Light::pdf_emission")
    }
    /// Total emitted power (luminance-weighted flux), for light selection.
    pub fn power(&self) -> f32 {
        todo!("Light::power")
    }
    pub fn is_environment(&self) -> bool {
        !matches!(self, Light::Area(_))
    }
}

/// Chooses a light proportionally to its power (one uniform), with pdf and inverse beside it.
#[derive(Debug)]
pub struct LightSampler {
    pub distribution: Distribution1D,
}

impl AreaLight {
    /// An area light over every triangle of `mesh` (the scene's mesh `geom_id`), triangles chosen
    /// by area.
    pub fn new(mesh: Arc<TriangleMesh>, geom_id: u32, radiance: Rgb, two_sided: bool) -> AreaLight {
        let areas: Vec<f32> = (0..mesh.triangle_count() as u32).map(|i| mesh.triangle_area(i)).collect();
        let area = areas.iter().map(|&a| a as f64).sum::<f64>() as f32;
        AreaLight { triangles: Distribution1D::new(&areas), mesh, geom_id, radiance, two_sided, area }
    }
}

impl ConstantEnvironment {
    /// A constant environment around a scene bounded by `scene_bounds`.
    pub fn new(radiance: Rgb, scene_bounds: crate::geometry::Aabb) -> ConstantEnvironment {
        let (scene_center, scene_radius) = scene_bounds.bounding_sphere();
        ConstantEnvironment { radiance, scene_center, scene_radius: scene_radius.max(1e-3) }
    }
}

impl ImageEnvironment {
    /// An equirectangular environment of `width`×`height` row-major texels (row 0 at +y), scaled by
    /// `scale`, with `to_local` the world-to-map rotation. Texels are importance-sampled in
    /// proportion to luminance × sin θ (the equirectangular map's area distortion).
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        scale: f32,
        to_local: glam::Mat3,
        scene_bounds: crate::geometry::Aabb,
    ) -> ImageEnvironment {
        let mut weights = vec![0.0f32; width * height];
        for v in 0..height {
            let sin_theta = (std::f32::consts::PI * (v as f32 + 0.5) / height as f32).sin();
            for u in 0..width {
                let t = texels.get(v * width + u).copied().unwrap_or(Rgb::ZERO);
                weights[v * width + u] = crate::spectrum::luminance(t).max(0.0) * sin_theta;
            }
        }
        let distribution = crate::sampling::Distribution2D::new(&weights, width, height);
        let (scene_center, scene_radius) = scene_bounds.bounding_sphere();
        ImageEnvironment {
            width,
            height,
            texels,
            scale,
            to_local,
            distribution,
            scene_center,
            scene_radius: scene_radius.max(1e-3),
        }
    }
}

impl LightSampler {
    /// Selection proportional to each light's power; all-zero power gives uniform selection.
    pub fn new(lights: &[Light]) -> LightSampler {
        let power: Vec<f32> = lights.iter().map(|l| l.power()).collect();
        LightSampler { distribution: Distribution1D::new(&power) }
    }
}

/// Unused import guard for Vec2 until implementations land.
#[allow(dead_code)]
fn _uses(_: Vec2) {}
