//! Scenes: the TOML schema (serde), validation with precise messages, mesh loading, and the built
//! `Scene` that integrators render.

mod builtin;
pub mod desc;
mod error;
pub mod import;
mod info;
mod load;
mod mask;
pub mod mesh_io;
mod ply;
pub mod portal;
pub mod procedural;
mod raw_mesh;
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

use glam::{Vec2, Vec3};

use crate::accel::Accel;
use crate::camera::Camera;
use crate::geometry::{Aabb, Hit, Ray, SurfaceInteraction, TriangleMesh};
use crate::light::{Light, LightSampler};
use crate::material::{Bsdf, SurfaceMaterial};
use crate::prefetch::prefetch;

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
    pub materials: Vec<SurfaceMaterial>,
    /// Whether any shape's material has an opacity below 1 (only then do rays test masks).
    pub masked: bool,
    pub lights: Vec<Light>,
    /// Light selection (by power).
    pub light_sampler: LightSampler,
    /// Index into `lights` of the environment, if the scene has one.
    pub environment: Option<u32>,
    pub portals: Vec<Portal>,
    pub accel: Box<dyn Accel>,
    /// Per mesh (by `geom_id`), each triangle's three positions side by side, or nothing
    /// ([`Self::keep_corners_if_room`]): what a closest hit's shading reads.
    pub corners: Vec<Vec<[Vec3; 3]>>,
    pub bounds: Aabb,
    /// The scene file this came from (None for the built-in scene).
    pub source: Option<PathBuf>,
}

impl Scene {
    /// Keeps each mesh's triangles' corners side by side (`TriangleMesh::corner_copies`, 36 bytes
    /// a triangle) for shading, when all the copies together take at most half the memory left to
    /// the process (`memory::available_memory` minus what the scene holds); otherwise none, and
    /// shading reads the indexed positions. With the copies a closest hit's positions are one
    /// cache miss, asked for as soon as the hit is known ([`Self::hit`]), instead of the index
    /// triple's and then the vertices' one after the other: on a mesh larger than the caches
    /// (`plexus bench`'s 1.2M triangles) the path tracer takes about 9% less time (0.91×, session
    /// 22). Called once the
    /// accelerator is built, so that the copies are never held with its build's temporaries.
    /// Results are bit for bit the same with or without them.
    pub fn keep_corners_if_room(&mut self) {
        let bytes: u64 =
            self.meshes.iter().map(|m| (m.triangle_count() * std::mem::size_of::<[Vec3; 3]>()) as u64).sum();
        let held = self.memory().total();
        let room = crate::job::memory::available_memory(held).map(|a| a.saturating_sub(held));
        if room.is_none_or(|room| bytes <= room / 2) {
            self.corners = self.meshes.iter().map(|m| m.corner_copies()).collect();
        }
    }

    /// The corner copy of triangle `prim` of mesh `geom_id`, where the scene keeps one.
    #[inline(always)]
    fn kept_corners(&self, geom_id: u32, prim: u32) -> Option<&[Vec3; 3]> {
        self.corners.get(geom_id as usize).and_then(|c| c.get(prim as usize))
    }

    /// The positions of triangle `prim` of mesh `geom_id`: from the corner copies where the scene
    /// keeps them, else through the mesh's indices (the same values).
    #[inline(always)]
    pub fn triangle(&self, geom_id: u32, prim: u32) -> [Vec3; 3] {
        match self.kept_corners(geom_id, prim) {
            Some(corners) => *corners,
            None => self.meshes[geom_id as usize].triangle(prim),
        }
    }

    /// The surface at `hit` (`SurfaceInteraction::from_hit`, its positions by [`Self::triangle`]),
    /// whether or not a mask lets rays through it there.
    #[inline(always)]
    pub fn surface(&self, hit: &Hit) -> SurfaceInteraction {
        SurfaceInteraction::from_corners(
            &self.meshes[hit.geom_id as usize],
            self.triangle(hit.geom_id, hit.prim_id),
            hit,
        )
    }

    /// The closest surface hit by `ray` (passing through masked surfaces where they let it,
    /// see `mask`).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let hit = self.hit(ray)?;
        self.interaction(ray, &hit)
    }
    /// The accelerator's closest hit along `ray`, with the load of its triangle's indices started
    /// (`TriangleMesh::prefetch_indices`): [`Self::intersect`] in two halves, so that a caller can
    /// do work that does not need the hit (drawing the vertex's uniforms) before
    /// [`Self::interaction`] reads the triangle. In a masked scene the hit may be a masked-out
    /// surface; `interaction` resolves it.
    /// With corner copies the triangle's positions are asked for instead (and the indices too only
    /// for a mesh with normals or uvs).
    #[inline]
    pub fn hit(&self, ray: &Ray) -> Option<Hit> {
        let hit = self.accel.intersect(ray)?;
        self.prefetch_hit(&hit);
        Some(hit)
    }
    /// The accelerator's closest hits of `rays`, which start close together and point about the
    /// same way (a camera's rays through neighbouring pixels), traced together where it has
    /// packet queries (`Accel::intersect_coherent`, whose rounding may differ from single queries'
    /// on rare rays): `hits[i]` is as `hit(&rays[i])`, but without its cache hint, which a caller
    /// gives with [`Self::prefetch_hit`] just before it uses `hits[i]` (the hints of eight paths
    /// given at once would be stale by the last ones).
    pub fn hits_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.accel.intersect_coherent(rays, hits);
    }
    /// What [`Self::hit`] asks the cache for once the hit is known.
    #[inline(always)]
    pub fn prefetch_hit(&self, hit: &Hit) {
        if let Some(mesh) = self.meshes.get(hit.geom_id as usize) {
            match self.kept_corners(hit.geom_id, hit.prim_id) {
                Some([first, _, last]) => {
                    // 36 bytes: the first and the last position name both lines they can span.
                    prefetch(first);
                    prefetch(last);
                    if mesh.has_vertex_attributes() {
                        mesh.prefetch_indices(hit.prim_id);
                    }
                }
                None => mesh.prefetch_indices(hit.prim_id),
            }
        }
    }
    /// Starts loading the vertex data of `hit`'s triangle (a hint, as `Scene::hit`'s): nothing
    /// more for a mesh with corner copies and no normals or uvs.
    #[inline]
    pub fn prefetch_vertices(&self, hit: &Hit) {
        if let Some(mesh) = self.meshes.get(hit.geom_id as usize) {
            if self.kept_corners(hit.geom_id, hit.prim_id).is_none() || mesh.has_vertex_attributes() {
                mesh.prefetch_vertices(hit.prim_id);
            }
        }
    }
    /// The surface interaction of `hit`, the accelerator's closest hit along `ray`: the first
    /// surface that stops `ray` (masked surfaces let it pass where their mask says).
    #[inline(always)]
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> Option<SurfaceInteraction> {
        let si = self.surface(hit);
        if !self.masked {
            return Some(si);
        }
        mask::closest_opaque(self, ray, si)
    }
    /// Whether anything blocks `ray` within its extent (masked surfaces block it where they
    /// would stop it in `intersect`).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        if !self.masked {
            return self.accel.occluded(ray);
        }
        mask::occluded(self, ray)
    }
    /// The BSDF of the surface at `si` (textures looked up at its uv).
    #[inline(always)]
    pub fn material(&self, si: &SurfaceInteraction) -> Bsdf {
        self.bsdf(self.shapes[si.geom_id as usize].material, si.uv)
    }
    /// The material of the shape `si` lies on, before its textures are looked up
    /// (`SurfaceMaterial::bsdf_at(si.uv)` is [`Self::material`]).
    #[inline(always)]
    pub fn surface_material(&self, si: &SurfaceInteraction) -> &SurfaceMaterial {
        &self.materials[self.shapes[si.geom_id as usize].material as usize]
    }
    /// Whether the BSDF of a hit on shape `geom_id` reads bitmap texels (cache misses worth
    /// starting early: `prefetch_texels`).
    #[inline]
    pub fn reads_texels(&self, geom_id: u32) -> bool {
        self.shapes.get(geom_id as usize).is_some_and(|s| self.materials[s.material as usize].reads_texels())
    }
    /// Starts loading the texels `material(si)` will read (a hint, as `Scene::hit`'s).
    #[inline(always)]
    pub fn prefetch_texels(&self, si: &SurfaceInteraction) {
        self.materials[self.shapes[si.geom_id as usize].material as usize].prefetch_texels(si.uv);
    }
    /// The BSDF of material `material` at surface coordinates `uv`.
    #[inline(always)]
    pub fn bsdf(&self, material: u32, uv: Vec2) -> Bsdf {
        self.materials[material as usize].bsdf_at(uv)
    }
    /// Bytes held by texture images (each shared image counted once).
    pub fn texture_memory_bytes(&self) -> usize {
        let mut seen: Vec<*const crate::texture::TexelImage> = Vec::new();
        let mut bytes = 0;
        for t in self.materials.iter().flat_map(|m| m.textures()) {
            if let Some(img) = t.image() {
                let p = Arc::as_ptr(img);
                if !seen.contains(&p) {
                    seen.push(p);
                    bytes += img.memory_bytes();
                }
            }
        }
        bytes
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
