//! BSDFs. Every material works in the local shading frame (normal = +z); `wo` and `wi` both point
//! away from the surface. Sampling takes its uniforms explicitly — `u[0]` chooses the lobe,
//! `u[1..3]` the direction — so primary-sample-space MCMC can drive it and `invert` can recover
//! them. A material's lobe probabilities come from one helper that `sample`, `pdf` and `invert`
//! all call, so they cannot drift apart.

mod fresnel;

pub use fresnel::{conductor_index_from_colours, fresnel_conductor, fresnel_dielectric, FresnelDielectric};

use serde::Serialize;

use crate::spectrum::Rgb;
use glam::Vec3;

/// Random numbers one BSDF sample consumes: lobe choice, then a 2D direction.
pub const BSDF_SAMPLE_DIMS: usize = 3;

/// Whether radiance (camera paths) or importance (light paths) is being transported; they differ
/// for refraction (the 1/η² radiance scaling) and for shading normals.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}

/// A material, with parameters as the scene file gives them (validated).
#[derive(Clone, Debug, PartialEq, Serialize)]
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
    /// Diffuse base under a GGX-rough dielectric coating of index `ior` (a two-lobe mixture).
    RoughPlastic { diffuse: Rgb, alpha: f32, ior: f32 },
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
}

// INTERFACE (implementation owned by the sampling/materials work; bodies to be filled in):
impl Material {
    /// f(wo, wi), without the cosine factor; zero for delta lobes and for invalid configurations.
    pub fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Rgb {
        let _ = (wo, wi, mode);
        todo!("Material::eval")
    }
    /// Solid-angle density with which `sample` produces `wi` given `wo` (zero for delta lobes).
    pub fn pdf(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> f32 {
        let _ = (wo, wi, mode);
        todo!("Material::pdf")
    }
    /// Draws `wi` given `wo` from the uniforms `u` (`u[0]` lobe, `u[1]`,`u[2]` direction).
    pub fn sample(&self, wo: Vec3, u: [f32; BSDF_SAMPLE_DIMS], mode: TransportMode) -> Option<BsdfSample> {
        let _ = (wo, u, mode);
        todo!("Material::sample")
    }
    /// Whether every lobe is a delta (mirror, smooth dielectric): no light-source connection can
    /// be made at such a vertex.
    pub fn is_specular(&self) -> bool {
        matches!(self, Material::Mirror { .. } | Material::Dielectric { .. })
    }
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
