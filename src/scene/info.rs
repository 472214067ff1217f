//! What a built scene contains and costs: `Scene::features` for the stats JSON (which optional
//! machinery was built) and `scene_info` for `plexus info`.

use std::collections::BTreeMap;
use std::fmt;

use serde::Serialize;

use super::Scene;
use crate::job::memory::SceneMemory;
use crate::light::Light;
use crate::material::Material;
use crate::sampling::{Distribution1D, Distribution2D};

/// Which optional scene features were built (and therefore paid for).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneFeatures {
    /// Number of emissive meshes.
    pub area_lights: usize,
    pub constant_environment: bool,
    /// The image environment, if any, with the size of its sampling distribution.
    pub image_environment: Option<ImageEnvironmentFeature>,
    /// Whether an environment importance-sampling distribution was allocated.
    pub environment_distribution: bool,
    pub portals: usize,
    /// Diffuse lobes present (diffuse, or the base of a plastic).
    pub diffuse_materials: bool,
    /// Rough (GGX) lobes present (conductor, plastic coating).
    pub glossy_materials: bool,
    /// Delta lobes present (mirror, smooth dielectric).
    pub specular_materials: bool,
    /// Materials used by at least one shape, by kind.
    pub materials_by_kind: BTreeMap<&'static str, usize>,
    pub triangles: usize,
    /// Used materials with a textured colour parameter, with an opacity below 1, and two-sided.
    pub textured_materials: usize,
    pub masked_materials: usize,
    pub two_sided_materials: usize,
    /// Bytes held by texture images (0 without textures: nothing is built).
    pub texture_bytes: usize,
}

/// The image environment's size and its 2D distribution's cell count.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageEnvironmentFeature {
    pub width: usize,
    pub height: usize,
    pub distribution_cells: usize,
}

/// The numbers `plexus info` prints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneInfo {
    pub source: Option<String>,
    pub triangles: usize,
    pub vertices: usize,
    pub meshes: usize,
    pub area_lights: usize,
    /// "constant", "image WxH" or none.
    pub environment: Option<String>,
    pub materials: usize,
    pub materials_by_kind: BTreeMap<&'static str, usize>,
    pub portals: usize,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub resolution: [u32; 2],
    pub accel: String,
    pub memory: MemoryEstimate,
}

/// Estimated bytes held by the built scene (`Scene::memory`, as the render's estimate counts it).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MemoryEstimate {
    pub meshes: usize,
    /// The triangles' corner copies kept for shading (`Scene::keep_corners_if_room`).
    pub corners: usize,
    pub accel: usize,
    /// Held by the accelerator only while it was built (part of loading's peak).
    pub accel_build: usize,
    pub lights: usize,
    /// Texture images (each shared image once).
    pub textures: usize,
    pub total: usize,
}

/// The kind name a material has in scene files.
pub fn material_kind(m: &Material) -> &'static str {
    match m {
        Material::Diffuse { .. } => "diffuse",
        Material::Mirror { .. } => "mirror",
        Material::Dielectric { .. } => "dielectric",
        Material::RoughConductor { .. } => "conductor",
        Material::RoughDielectric { .. } => "dielectric",
        Material::RoughPlastic { .. } => "plastic",
    }
}

impl Scene {
    /// Which features this scene built; only materials some shape uses count.
    pub fn features(&self) -> SceneFeatures {
        let mut area_lights = 0;
        let mut constant_environment = false;
        let mut image_environment = None;
        for l in &self.lights {
            match l {
                Light::Area(_) => area_lights += 1,
                Light::ConstantEnvironment(_) => constant_environment = true,
                Light::ImageEnvironment(e) => {
                    image_environment = Some(ImageEnvironmentFeature {
                        width: e.width,
                        height: e.height,
                        distribution_cells: e.distribution.conditionals.iter().map(Distribution1D::len).sum(),
                    })
                }
            }
        }
        let used = self.used_materials();
        SceneFeatures {
            area_lights,
            constant_environment,
            environment_distribution: image_environment.is_some(),
            image_environment,
            portals: self.portals.len(),
            diffuse_materials: used
                .iter()
                .any(|m| matches!(m, Material::Diffuse { .. } | Material::RoughPlastic { .. })),
            glossy_materials: used.iter().any(|m| {
                matches!(
                    m,
                    Material::RoughConductor { .. } | Material::RoughPlastic { .. } | Material::RoughDielectric { .. }
                )
            }),
            specular_materials: used.iter().any(|m| m.is_specular()),
            materials_by_kind: count_kinds(&used),
            triangles: self.triangle_count(),
            textured_materials: self.used_surfaces().filter(|m| m.is_textured()).count(),
            masked_materials: self.used_surfaces().filter(|m| m.is_masked()).count(),
            two_sided_materials: self.used_surfaces().filter(|m| m.two_sided).count(),
            texture_bytes: self.texture_memory_bytes(),
        }
    }

    fn used_surfaces(&self) -> impl Iterator<Item = &crate::material::SurfaceMaterial> {
        self.materials
            .iter()
            .enumerate()
            .filter(|(i, _)| self.shapes.iter().any(|s| s.material as usize == *i))
            .map(|(_, m)| m)
    }

    fn used_materials(&self) -> Vec<&Material> {
        let mut used = vec![false; self.materials.len()];
        for s in &self.shapes {
            used[s.material as usize] = true;
        }
        self.materials.iter().zip(used).filter(|(_, u)| *u).map(|(m, _)| &m.template).collect()
    }
}

fn count_kinds(ms: &[&Material]) -> BTreeMap<&'static str, usize> {
    let mut out = BTreeMap::new();
    for m in ms {
        *out.entry(material_kind(m)).or_insert(0) += 1;
    }
    out
}

fn distribution_bytes(d: &Distribution1D) -> usize {
    d.func.capacity() * 4 + d.cdf.capacity() * 8
}

fn distribution2d_bytes(d: &Distribution2D) -> usize {
    d.conditionals.iter().map(distribution_bytes).sum::<usize>() + distribution_bytes(&d.marginal)
}

impl Scene {
    /// The bytes this built scene holds, by part: the scene's share of the render memory estimate
    /// (`job::memory`) that `render` checks and `info` prints.
    pub fn memory(&self) -> SceneMemory {
        let meshes: usize = self.meshes.iter().map(|m| m.memory_bytes()).sum();
        let lights: usize = self
            .lights
            .iter()
            .map(|l| match l {
                Light::Area(a) => {
                    distribution_bytes(&a.triangles) + a.normals.capacity() * std::mem::size_of::<glam::Vec3>()
                }
                Light::ConstantEnvironment(_) => 0,
                Light::ImageEnvironment(e) => e.texels.capacity() * 12 + distribution2d_bytes(&e.distribution),
            })
            .sum::<usize>()
            + distribution_bytes(&self.light_sampler.distribution);
        SceneMemory {
            meshes: meshes as u64,
            corners: self.corners.iter().map(|c| (c.capacity() * std::mem::size_of::<[glam::Vec3; 3]>()) as u64).sum(),
            accel: self.accel.memory_bytes() as u64,
            accel_build: self.accel.peak_memory_bytes().saturating_sub(self.accel.memory_bytes()) as u64,
            lights: lights as u64,
            textures: self.texture_memory_bytes() as u64,
        }
    }
}

/// Counts, bounds and estimated memory of a built scene, for `plexus info`.
pub fn scene_info(scene: &Scene) -> SceneInfo {
    let memory = scene.memory();
    let environment = scene.environment_light().map(|(_, l)| match l {
        Light::ImageEnvironment(e) => format!("image {}x{}", e.width, e.height),
        _ => "constant".to_string(),
    });
    SceneInfo {
        source: scene.source.as_ref().map(|p| p.display().to_string()),
        triangles: scene.triangle_count(),
        vertices: scene.meshes.iter().map(|m| m.vertex_count()).sum(),
        meshes: scene.meshes.len(),
        area_lights: scene.lights.iter().filter(|l| matches!(l, Light::Area(_))).count(),
        environment,
        materials: scene.materials.len(),
        materials_by_kind: count_kinds(&scene.materials.iter().map(|m| &m.template).collect::<Vec<_>>()),
        portals: scene.portals.len(),
        bounds_min: scene.bounds.min.to_array(),
        bounds_max: scene.bounds.max.to_array(),
        resolution: [scene.camera.width, scene.camera.height],
        accel: scene.accel.kind().to_string(),
        memory: MemoryEstimate {
            meshes: memory.meshes as usize,
            corners: memory.corners as usize,
            accel: memory.accel as usize,
            accel_build: memory.accel_build as usize,
            lights: memory.lights as usize,
            textures: memory.textures as usize,
            total: memory.total() as usize,
        },
    }
}

impl fmt::Display for SceneInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mib = |b: usize| b as f64 / (1024.0 * 1024.0);
        writeln!(f, "scene:       {}", self.source.as_deref().unwrap_or("(built-in Cornell box)"))?;
        writeln!(f, "triangles:   {} in {} meshes ({} vertices)", self.triangles, self.meshes, self.vertices)?;
        writeln!(
            f,
            "emitters:    {} area light{}, environment: {}",
            self.area_lights,
            if self.area_lights == 1 { "" } else { "s" },
            self.environment.as_deref().unwrap_or("none")
        )?;
        let kinds: Vec<String> = self.materials_by_kind.iter().map(|(k, n)| format!("{n} {k}")).collect();
        writeln!(f, "materials:   {} ({})", self.materials, kinds.join(", "))?;
        writeln!(f, "portals:     {}", self.portals)?;
        let [a, b, c] = self.bounds_min;
        let [x, y, z] = self.bounds_max;
        writeln!(f, "bounds:      [{a}, {b}, {c}] to [{x}, {y}, {z}]")?;
        writeln!(f, "resolution:  {}x{}", self.resolution[0], self.resolution[1])?;
        write!(
            f,
            "memory:      {:.2} MiB for the scene (meshes {:.2} and their corners {:.2}, {} accelerator {:.2} and {:.2} more while built, \
             lights {:.2}, textures {:.2})",
            mib(self.memory.total),
            mib(self.memory.meshes),
            mib(self.memory.corners),
            self.accel,
            mib(self.memory.accel),
            mib(self.memory.accel_build),
            mib(self.memory.lights),
            mib(self.memory.textures)
        )
    }
}
