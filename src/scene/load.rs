//! From a TOML scene file to a built `Scene`: parse (serde), validate every value with its key
//! path, load and transform meshes, and build only the lights, distributions and accelerator the
//! scene asks for.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};

use super::desc::{CameraDesc, RenderSettingsDesc, SceneDesc, ShapeDesc};
use super::error::{fmt3, SceneError};
use super::mesh_io::{self, RawMesh};
use super::{shapes, transform, Scene, ShapeInfo};
use crate::accel::{self, AccelKind};
use crate::camera::Camera;
use crate::geometry::{Aabb, TriangleMesh};
use crate::light::{AreaLight, Light, LightSampler};
use crate::spectrum::Rgb;

mod lights;
mod materials;
mod values;

pub use values::{DEFAULT_IOR, DEFAULT_ROUGHNESS, MAX_EXTENT, MAX_RADIANCE, MIN_EXTENT};

/// A built scene together with the render settings its file asked for.
pub struct LoadedScene {
    pub scene: Scene,
    pub render: RenderDesc,
}

/// The `[integrator]` and `[render]` tables, validated (integrator parameters are checked later
/// by the integrator's own settings struct).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderDesc {
    /// Integrator name; "pt" when the file names none.
    pub integrator: String,
    /// The `[integrator]` table without `type`.
    pub integrator_params: toml::Table,
    pub spp: Option<u64>,
    /// Time budget in seconds.
    pub time: Option<f64>,
    pub seed: u64,
    pub threads: Option<usize>,
    /// Output images, relative to the current directory.
    pub outputs: Vec<PathBuf>,
    pub accel: AccelKind,
}

/// Loads and builds the scene in `path`; mesh and image files are relative to its directory.
/// `accel` overrides the file's `[render] accel`.
pub fn load_scene(path: &Path, accel: Option<AccelKind>) -> Result<LoadedScene, SceneError> {
    let name = path.display().to_string();
    let text = crate::input_file::read_regular_text(path, crate::input_file::MAX_SCENE_TEXT_BYTES)
        .map_err(|reason| SceneError::Read { file: name.clone(), reason })?;
    let base = path.parent().unwrap_or(Path::new(""));
    let mut loaded = load_scene_str(&text, base, &name, accel)?;
    loaded.scene.source = Some(path.to_path_buf());
    Ok(loaded)
}

/// Loads a scene from TOML text; `base_dir` resolves relative mesh and image paths and `name`
/// stands for the file in messages.
pub fn load_scene_str(
    toml_text: &str,
    base_dir: &Path,
    name: &str,
    accel: Option<AccelKind>,
) -> Result<LoadedScene, SceneError> {
    load_scene_str_with_meshes(toml_text, base_dir, name, accel, Vec::new())
}

/// A mesh made in memory (procedurally, say) that joins a scene beside its file's `[[shapes]]`.
/// It does not emit; its material is named as a shape's would be.
#[derive(Clone, Debug)]
pub struct MeshShape {
    /// Name for messages and `plexus info`.
    pub name: String,
    pub mesh: Arc<TriangleMesh>,
    /// A key of the file's `[materials]`.
    pub material: String,
}

/// `load_scene_str` with `meshes` appended after the file's shapes (so their `geom_id`s follow
/// the file's): bounds, lights and the accelerator are built over all of them, once, exactly as
/// for a scene file. A mesh's unknown material is reported at key `meshes[k].material`.
pub fn load_scene_str_with_meshes(
    toml_text: &str,
    base_dir: &Path,
    name: &str,
    accel: Option<AccelKind>,
    meshes: Vec<MeshShape>,
) -> Result<LoadedScene, SceneError> {
    let desc: SceneDesc = toml::from_str(toml_text).map_err(|e| SceneError::from_toml(name, toml_text, &e))?;
    Builder { file: name, base_dir }.build(desc, meshes, accel)
}

struct Builder<'a> {
    file: &'a str,
    base_dir: &'a Path,
}

/// One mesh on its way into the scene.
struct BuiltShape {
    mesh: Arc<TriangleMesh>,
    info: ShapeInfo,
    emission: Option<(Rgb, bool)>,
}

impl Builder<'_> {
    fn err(&self, key: impl Into<String>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid { file: self.file.to_string(), key: key.into(), message: message.into() }
    }

    fn build(
        &self,
        desc: SceneDesc,
        in_memory: Vec<MeshShape>,
        accel_override: Option<AccelKind>,
    ) -> Result<LoadedScene, SceneError> {
        let camera = self.camera(&desc.camera)?;
        let (materials, material_index) = self.materials(&desc.materials)?;
        if desc.shapes.is_empty() {
            return Err(self.err("shapes", "expected at least one [[shapes]] entry, found none"));
        }
        let mut built = Vec::with_capacity(desc.shapes.len() + in_memory.len());
        for (i, s) in desc.shapes.iter().enumerate() {
            built.push(self.shape(i, s, &material_index)?);
        }
        for (k, m) in in_memory.into_iter().enumerate() {
            let material = self.material_index(&format!("meshes[{k}].material"), &m.material, &material_index)?;
            built.push(BuiltShape {
                mesh: m.mesh,
                info: ShapeInfo { name: m.name, material, light: None },
                emission: None,
            });
        }
        let render = self.render(desc.integrator, desc.render.unwrap_or_default(), accel_override)?;

        let mut bounds = Aabb::EMPTY;
        for s in &built {
            bounds = bounds.union(&s.mesh.bounds());
        }
        self.check_scale(&bounds, camera.position)?;

        let mut meshes = Vec::with_capacity(built.len());
        let mut infos = Vec::with_capacity(built.len());
        let mut lights = Vec::new();
        for (geom_id, s) in built.into_iter().enumerate() {
            let mut info = s.info;
            if let Some((radiance, two_sided)) = s.emission {
                if materials[info.material as usize].is_masked() {
                    return Err(self.err(
                        format!("shapes[{geom_id}]"),
                        "an emitting shape cannot have a material with 'opacity' below 1 (a masked emitter \
                         would need the mask in the emission pdfs)",
                    ));
                }
                info.light = Some(lights.len() as u32);
                lights.push(Light::Area(AreaLight::new(s.mesh.clone(), geom_id as u32, radiance, two_sided)));
            }
            meshes.push(s.mesh);
            infos.push(info);
        }
        let environment = match &desc.environment {
            Some(env) => {
                lights.push(self.environment(env, &bounds)?);
                Some(lights.len() as u32 - 1)
            }
            None => None,
        };
        for (index, light) in lights.iter().enumerate() {
            let (key, name) = match infos.iter().position(|info| info.light == Some(index as u32)) {
                Some(geom_id) => (format!("shapes[{geom_id}].emission"), infos[geom_id].name.clone()),
                None => ("environment".to_string(), "the environment".to_string()),
            };
            self.refuse_delta_emitter(&key, &name, light.kind())?;
        }
        self.check_light_power(&lights, &infos)?;
        if lights.is_empty() {
            return Err(self.err(
                "shapes",
                "expected at least one emitter (a shape with 'emission' or an [environment]), found none",
            ));
        }
        let portals = desc.portals.iter().enumerate().map(|(i, p)| self.portal(i, p)).collect::<Result<Vec<_>, _>>()?;

        let light_sampler = LightSampler::new(&lights);
        let accel = accel::build(render.accel, &meshes).map_err(|e| SceneError::Accel {
            file: self.file.to_string(),
            accel: render.accel.to_string(),
            message: e.to_string(),
        })?;
        let masked = infos.iter().any(|info| materials[info.material as usize].is_masked());
        let mut scene = Scene {
            camera,
            meshes,
            shapes: infos,
            materials,
            masked,
            lights,
            light_sampler,
            environment,
            portals,
            accel,
            corners: Vec::new(),
            bounds,
            source: None,
        };
        scene.keep_corners_if_room();
        Ok(LoadedScene { scene, render })
    }

    /// Refuses a scene outside the validated scale range [`MIN_EXTENT`, `MAX_EXTENT`]: its
    /// extent (the largest side of the box holding every shape and the camera) and its largest
    /// coordinate. Inside the range every integrator renders the same image at every scale
    /// (tests/images/extremes.rs renders the edges); outside it f32 quantities that grow as the square or
    /// cube of a length (the light pdf's distance² / area, the accelerators' intersection
    /// determinants) overflow or flush to zero and the image silently darkens (measured at 5.6e13
    /// units: 0.5× with either accelerator; at 5.6e-13 with Embree: 0.5×).
    fn check_scale(&self, shapes: &Aabb, camera: Vec3) -> Result<(), SceneError> {
        let mut all = *shapes;
        all.grow(camera);
        let extent = all.extent().max_element();
        let largest = all.min.abs().max(all.max.abs()).max_element();
        let range = format!(
            "plexus renders scenes spanning {MIN_EXTENT:e} to {MAX_EXTENT:e} units with coordinates up to \
             {MAX_EXTENT:e} correctly: scale the scene into that range"
        );
        if !(MIN_EXTENT..=MAX_EXTENT).contains(&extent) {
            return Err(self.err("shapes", format!("the scene (shapes and camera) spans {extent:e} units; {range}")));
        }
        if largest > MAX_EXTENT {
            return Err(self.err("shapes", format!("the scene reaches coordinate {largest:e}; {range}")));
        }
        Ok(())
    }

    fn camera(&self, c: &CameraDesc) -> Result<Camera, SceneError> {
        let position = self.finite_vec("camera.position", c.position)?;
        let look_at = self.finite_vec("camera.look_at", c.look_at)?;
        let up = self.finite_vec("camera.up", c.up)?;
        let forward = look_at - position;
        if forward.length_squared() == 0.0 {
            return Err(self.err(
                "camera.look_at",
                format!("expected a point other than camera.position, got {}", fmt3(c.look_at)),
            ));
        }
        if forward.normalize().cross(up).length_squared() < 1e-12 {
            return Err(self.err(
                "camera.up",
                format!("expected a direction not parallel to the view direction, got {}", fmt3(c.up)),
            ));
        }
        if !(c.fov > 0.0 && c.fov < 180.0) {
            return Err(self.err(
                "camera.fov",
                format!("expected a vertical field of view in degrees in (0, 180), got {}", c.fov),
            ));
        }
        let [w, h] = c.resolution;
        const MAX: i64 = 1 << 16;
        if !(1..=MAX).contains(&w) || !(1..=MAX).contains(&h) {
            return Err(self.err(
                "camera.resolution",
                format!("expected two positive integers [width, height] (at most {MAX}), got [{w}, {h}]"),
            ));
        }
        Ok(Camera::new(position, look_at, up, c.fov, w as u32, h as u32))
    }

    fn shape(&self, i: usize, s: &ShapeDesc, materials: &BTreeMap<String, u32>) -> Result<BuiltShape, SceneError> {
        let key = |k: &str| format!("shapes[{i}].{k}");
        let material = self.material_index(&key("material"), &s.material, materials)?;
        let takes_file = matches!(s.kind.as_str(), "obj" | "ply");
        if takes_file != s.file.is_some() {
            return Err(if takes_file {
                self.err(key("file"), format!("a '{}' shape needs 'file' (a path relative to the scene file)", s.kind))
            } else {
                self.err(key("file"), format!("only 'obj' and 'ply' shapes take a file, not '{}'", s.kind))
            });
        }
        if s.subdivisions.is_some() && !matches!(s.kind.as_str(), "disk" | "sphere") {
            return Err(self.err(
                key("subdivisions"),
                format!("only 'disk' and 'sphere' shapes take subdivisions, not '{}'", s.kind),
            ));
        }
        let (mut raw, name) = match s.kind.as_str() {
            "obj" | "ply" => {
                let file = s.file.as_deref().unwrap_or_default();
                let path = self.base_dir.join(file);
                let read = if s.kind == "obj" { mesh_io::load_obj(&path) } else { mesh_io::load_ply(&path) };
                let raw = read.map_err(|e| self.err(key("file"), format!("mesh '{}': {e}", path.display())))?;
                (raw, file.to_string())
            }
            "quad" => (shapes::quad(), "quad".to_string()),
            "box" => (shapes::cube(), "box".to_string()),
            "disk" => (
                shapes::disk(self.subdivisions(
                    &key("subdivisions"),
                    s.subdivisions,
                    shapes::DISK_DEFAULT_SEGMENTS,
                    3,
                    1 << 20,
                )?),
                "disk".to_string(),
            ),
            "sphere" => (
                shapes::sphere(self.subdivisions(
                    &key("subdivisions"),
                    s.subdivisions,
                    shapes::SPHERE_DEFAULT_RINGS,
                    2,
                    2048,
                )?),
                "sphere".to_string(),
            ),
            other => {
                return Err(
                    self.err(key("type"), format!("expected one of: obj, ply, quad, box, disk, sphere, got '{other}'"))
                )
            }
        };
        if let Some(t) = &s.transform {
            let m: Mat4 = transform::matrix_from_desc(t).map_err(|e| self.split_err(&key("transform"), &e))?;
            transform::apply(&mut raw, &m);
        }
        if s.face_normals == Some(true) {
            raw.normals = None;
        }
        if s.flip_normals == Some(true) {
            transform::flip_orientation(&mut raw);
        }
        let RawMesh { positions, indices, normals, uvs } = raw;
        let mesh = TriangleMesh::new(positions, indices, normals, uvs).map_err(|e| match &s.file {
            Some(f) => self.err(key("file"), format!("mesh '{}': {e}", self.base_dir.join(f).display())),
            None => self.err(format!("shapes[{i}]"), format!("the {} shape: {e}", s.kind)),
        })?;
        let emission = match &s.emission {
            Some(e) => {
                let radiance =
                    self.color(&key("emission.radiance"), e.radiance, "every component ≥ 0", |v| v >= 0.0)?;
                if !(e.scale >= 0.0 && e.scale.is_finite()) {
                    return Err(
                        self.err(key("emission.scale"), format!("expected a finite number ≥ 0, got {}", e.scale))
                    );
                }
                Some((self.radiance_in_range(&key("emission"), radiance * e.scale)?, e.two_sided))
            }
            None => None,
        };
        Ok(BuiltShape { mesh: Arc::new(mesh), info: ShapeInfo { name, material, light: None }, emission })
    }

    /// The index of material `name`, or an error at `key` listing the defined ones.
    fn material_index(&self, key: &str, name: &str, materials: &BTreeMap<String, u32>) -> Result<u32, SceneError> {
        materials.get(name).copied().ok_or_else(|| {
            let known: Vec<&str> = materials.keys().map(String::as_str).collect();
            self.err(
                key,
                format!(
                    "unknown material '{name}' (defined: {})",
                    if known.is_empty() { "none".to_string() } else { known.join(", ") }
                ),
            )
        })
    }

    fn render(
        &self,
        integrator: Option<toml::Table>,
        r: RenderSettingsDesc,
        accel_override: Option<AccelKind>,
    ) -> Result<RenderDesc, SceneError> {
        let mut params = integrator.unwrap_or_default();
        let integrator = match params.remove("type") {
            None => "pt".to_string(),
            Some(toml::Value::String(s)) => s,
            Some(other) => {
                return Err(self.err("integrator.type", format!("expected a string (an integrator name), got {other}")))
            }
        };
        let spp = match r.spp {
            None => None,
            Some(n) if n > 0 => Some(n as u64),
            Some(n) => return Err(self.err("render.spp", format!("expected an integer > 0, got {n}"))),
        };
        let time = match r.time {
            None => None,
            Some(t) if t > 0.0 && t <= crate::job::MAX_SECONDS => Some(t),
            Some(t) => {
                return Err(self.err(
                    "render.time",
                    format!("expected a number of seconds in (0, {}] (30 days), got {t:?}", crate::job::MAX_SECONDS),
                ))
            }
        };
        if spp.is_some() && time.is_some() {
            return Err(self.err("render", "expected either 'spp' or 'time' as the budget, not both"));
        }
        let seed = match r.seed {
            None => 0,
            Some(s) if s >= 0 => s as u64,
            Some(s) => return Err(self.err("render.seed", format!("expected an integer ≥ 0, got {s}"))),
        };
        let threads = match r.threads {
            None => None,
            Some(n) if (1..=crate::job::MAX_THREADS as i64).contains(&n) => Some(n as usize),
            Some(n) => {
                return Err(self.err(
                    "render.threads",
                    format!("expected an integer in 1 ..= {}, got {n}", crate::job::MAX_THREADS),
                ))
            }
        };
        // A scene file may name its images, but only below the directory the render runs in: a
        // downloaded scene must not make plexus write (or replace) a file anywhere else.
        let mut outputs = Vec::with_capacity(r.output.len());
        for o in r.output {
            let path = PathBuf::from(&o);
            let escapes = path.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir));
            if o.is_empty() || escapes {
                return Err(self.err(
                    "render.output",
                    format!(
                        "expected paths below the current directory (relative, without '..'), got {}; \
                         give other places with --out",
                        toml::Value::String(o)
                    ),
                ));
            }
            outputs.push(path);
        }
        Ok(RenderDesc {
            integrator,
            integrator_params: params,
            spp,
            time,
            seed,
            threads,
            outputs,
            accel: accel_override.or(r.accel).unwrap_or_default(),
        })
    }
}
