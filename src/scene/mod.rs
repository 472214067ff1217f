//! Scenes: the TOML schema (serde), validation with precise messages, mesh loading, and the built
//! `Scene` that integrators render.

mod builtin;
pub mod desc;
mod error;
pub mod import;
mod info;
mod load;
pub mod mesh_io;
pub mod procedural;
pub mod shapes;
pub mod transform;

pub use builtin::{builtin_cornell_box, CORNELL_BOX_TOML};
pub use error::SceneError;
pub use info::{material_kind, scene_info, ImageEnvironmentFeature, MemoryEstimate, SceneFeatures, SceneInfo};
pub use load::{
    load_scene, load_scene_str, load_scene_str_with_meshes, LoadedScene, MeshShape, RenderDesc, DEFAULT_IOR,
    DEFAULT_ROUGHNESS, MAX_EXTENT, MAX_RADIANCE, MIN_EXTENT,
};

use std::path::PathBuf;
use std::sync::Arc;

use glam::Vec3;

use crate::accel::Accel;
use crate::camera::Camera;
use crate::geometry::{Aabb, Ray, SurfaceInteraction, TriangleMesh};
use crate::light::{Light, LightSampler};
use crate::material::Material;

/// What each mesh (`geom_id`) is made of.
#[derive(Clone, Debug)]
pub struct ShapeInfo {
    /// Name for messages and `plexus info` (the shape's file or kind).
    pub name: String,
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Index into `Scene::lights` when the shape emits.
    pub light: Option<u32>,
}

/// A portal: a quad through which light is known to enter (used only by path-space mutations;
/// never intersected by ordinary rays). `corner + s·edge_u + t·edge_v` for s, t in [0,1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Portal {
    pub corner: Vec3,
    pub edge_u: Vec3,
    pub edge_v: Vec3,
}

/// A built scene, read-only while rendering and shared by every worker.
pub struct Scene {
    pub camera: Camera,
    /// Meshes, indexed by `geom_id`.
    pub meshes: Vec<Arc<TriangleMesh>>,
    /// Per-mesh material and emission, indexed by `geom_id`.
    pub shapes: Vec<ShapeInfo>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Light selection (by power).
    pub light_sampler: LightSampler,
    /// Index into `lights` of the environment, if the scene has one.
    pub environment: Option<u32>,
    pub portals: Vec<Portal>,
    pub accel: Box<dyn Accel>,
    pub bounds: Aabb,
    /// The scene file this came from (None for the built-in scene).
    pub source: Option<PathBuf>,
}

impl Scene {
    /// The closest surface hit by `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let hit = self.accel.intersect(ray)?;
        Some(SurfaceInteraction::from_hit(&self.meshes[hit.geom_id as usize], &hit))
    }
    /// Whether anything blocks `ray` within its extent.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }
    /// The material of the surface at `si`.
    #[inline]
    pub fn material(&self, si: &SurfaceInteraction) -> &Material {
        &self.materials[self.shapes[si.geom_id as usize].material as usize]
    }
    /// The area light on the surface at `si`, if it emits.
    #[inline]
    pub fn area_light(&self, si: &SurfaceInteraction) -> Option<(u32, &Light)> {
        let l = self.shapes[si.geom_id as usize].light?;
        Some((l, &self.lights[l as usize]))
    }
    /// The environment light, if any.
    pub fn environment_light(&self) -> Option<(u32, &Light)> {
        self.environment.map(|i| (i, &self.lights[i as usize]))
    }
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.triangle_count()).sum()
    }
}
