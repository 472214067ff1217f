//! From a TOML scene file to a built `Scene`: parse (serde), validate every value with its key
//! path, load and transform meshes, and build only the lights, distributions and accelerator the
//! scene asks for.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use glam::{Mat3, Mat4, Vec3};

use super::desc::{CameraDesc, ColorDesc, EnvironmentDesc, PortalDesc, RenderSettingsDesc, SceneDesc, ShapeDesc};
use super::error::{fmt3, SceneError};
use super::mesh_io::{self, RawMesh};
use super::{shapes, transform, Portal, Scene, ShapeInfo};
use crate::accel::{self, AccelKind};
use crate::camera::Camera;
use crate::geometry::{Aabb, TriangleMesh};
use crate::light::{AreaLight, ConstantEnvironment, EmitterKind, ImageEnvironment, Light, LightSampler};
use crate::spectrum::Rgb;

mod materials;

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

    /// `radiance` (already multiplied by its `scale`), refused when a component exceeds
    /// [`MAX_RADIANCE`].
    fn radiance_in_range(&self, key: &str, radiance: Rgb) -> Result<Rgb, SceneError> {
        if radiance.is_finite() && radiance.max_element() <= MAX_RADIANCE {
            return Ok(radiance);
        }
        Err(self.err(
            key,
            format!(
                "radiance × scale = [{:e}, {:e}, {:e}] exceeds the largest radiance plexus accepts, {MAX_RADIANCE:e}",
                radiance.x, radiance.y, radiance.z
            ),
        ))
    }

    /// Refuses lights whose flux (radiance × area × π, the light sampler's weight) or whose sum
    /// overflows f32: the selection distribution would be NaN. Within the radiance and scale
    /// ranges this takes a bright emitter of a huge area (1e20 × 1e24 units² overflows).
    fn check_light_power(&self, lights: &[Light], infos: &[ShapeInfo]) -> Result<(), SceneError> {
        let mut total = 0.0f64;
        for (index, light) in lights.iter().enumerate() {
            let power = light.power();
            total += power as f64;
            if !(power.is_finite() && total <= f32::MAX as f64) {
                let key = match infos.iter().position(|info| info.light == Some(index as u32)) {
                    Some(geom_id) => format!("shapes[{geom_id}].emission"),
                    None => "environment".to_string(),
                };
                return Err(self.err(
                    key,
                    format!(
                        "the emitted power (radiance × area × π) overflows f32 ({power:e}, all lights {total:e}): \
                         lower the radiance or the scene's scale"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Refuses a delta emitter (point, spot, directional light): the bidirectional MIS weights
    /// (integrator/bdpt/mis.rs) assume every emitter has area or lies at infinity, and would give
    /// its paths wrong weights without any sign in the image's statistics.
    fn refuse_delta_emitter(&self, key: &str, name: &str, kind: EmitterKind) -> Result<(), SceneError> {
        if kind.is_delta() {
            return Err(self.err(
                key,
                format!(
                    "emitter '{name}' is a {kind} light, which plexus does not support: the bidirectional \
                     integrators' MIS weights assume every emitter has area or lies at infinity"
                ),
            ));
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

    /// Splits a transform error "sub.key: message" into the key path and the message.
    fn split_err(&self, prefix: &str, e: &str) -> SceneError {
        match e.split_once(": ") {
            Some((sub, msg)) if !sub.contains(' ') => self.err(format!("{prefix}.{sub}"), msg),
            _ => self.err(prefix, e),
        }
    }

    fn subdivisions(&self, key: &str, v: Option<i64>, default: u32, min: i64, max: i64) -> Result<u32, SceneError> {
        match v {
            None => Ok(default),
            Some(n) if (min..=max).contains(&n) => Ok(n as u32),
            Some(n) => Err(self.err(key, format!("expected an integer in [{min}, {max}], got {n}"))),
        }
    }

    fn environment(&self, env: &EnvironmentDesc, bounds: &Aabb) -> Result<Light, SceneError> {
        let allowed: &[&str] = match env.kind.as_str() {
            "constant" => &["radiance", "scale"],
            "image" => &["file", "scale", "rotate"],
            "sunsky" | "sky" => &["sun_direction", "up", "turbidity", "albedo", "sun_scale", "sky_scale"],
            "sun" => &["sun_direction", "up", "turbidity", "sun_scale"],
            other => {
                return Err(self.err(
                    "environment.type",
                    format!("expected one of: constant, image, sunsky, sun, sky, got '{other}'"),
                ))
            }
        };
        let present = [
            ("radiance", env.radiance.is_some()),
            ("file", env.file.is_some()),
            ("scale", env.scale.is_some()),
            ("rotate", env.rotate.is_some()),
            ("sun_direction", env.sun_direction.is_some()),
            ("up", env.up.is_some()),
            ("turbidity", env.turbidity.is_some()),
            ("albedo", env.albedo.is_some()),
            ("sun_scale", env.sun_scale.is_some()),
            ("sky_scale", env.sky_scale.is_some()),
        ];
        for (k, p) in present {
            if p && !allowed.contains(&k) {
                return Err(self.err(
                    "environment",
                    format!("key '{k}' does not apply to type '{}' (expected: type, {})", env.kind, allowed.join(", ")),
                ));
            }
        }
        if matches!(env.kind.as_str(), "sunsky" | "sun" | "sky") {
            return self.sunsky(env, bounds);
        }
        let scale = env.scale.unwrap_or(1.0);
        if !(scale >= 0.0 && scale.is_finite()) {
            return Err(self.err("environment.scale", format!("expected a finite number ≥ 0, got {scale}")));
        }
        if env.kind == "constant" {
            let c = env.radiance.ok_or_else(|| self.err("environment", "a 'constant' environment needs 'radiance'"))?;
            let radiance = self.color("environment.radiance", c, "every component ≥ 0", |v| v >= 0.0)?;
            let radiance = self.radiance_in_range("environment", radiance * scale)?;
            return Ok(Light::ConstantEnvironment(ConstantEnvironment::new(radiance, *bounds)));
        }
        let file = env
            .file
            .as_deref()
            .ok_or_else(|| self.err("environment", "an 'image' environment needs 'file' (an EXR)"))?;
        let path = self.base_dir.join(file);
        let image = crate::film::exr_io::read_exr(&path).map_err(|e| self.err("environment.file", e.to_string()))?;
        if image.width == 0 || image.height == 0 {
            return Err(self.err("environment.file", format!("image '{}': expected a non-empty image", path.display())));
        }
        if let Some(i) = image.pixels.iter().position(|p| !(p.is_finite() && p.min_element() >= 0.0)) {
            let p = image.pixels[i];
            return Err(self.err(
                "environment.file",
                format!(
                    "image '{}': expected finite texels ≥ 0, got {} at pixel ({}, {})",
                    path.display(),
                    fmt3(p.to_array()),
                    i % image.width,
                    i / image.width
                ),
            ));
        }
        // The brightest texel channel (and where), as the renderer will see it: times `scale`.
        let (brightest, at) = image
            .pixels
            .iter()
            .enumerate()
            .map(|(i, p)| (p.max_element(), i))
            .fold((0.0f32, 0), |best, x| if x.0 > best.0 { x } else { best });
        if brightest as f64 * scale as f64 > MAX_RADIANCE as f64 {
            return Err(self.err(
                "environment.file",
                format!(
                    "image '{}': texel ({}, {}) = {brightest:e} times scale {scale:e} exceeds the largest radiance \
                     plexus accepts, {MAX_RADIANCE:e}",
                    path.display(),
                    at % image.width,
                    at / image.width
                ),
            ));
        }
        let rotation = match &env.rotate {
            Some(r) => transform::rotation_matrix(r).map_err(|e| self.split_err("environment", &e))?,
            None => Mat3::IDENTITY,
        };
        // `rotate` turns the map in the world; lookups need the inverse, world to map.
        let to_local = rotation.transpose();
        Ok(Light::ImageEnvironment(ImageEnvironment::new(
            image.width,
            image.height,
            image.pixels,
            scale,
            to_local,
            *bounds,
        )))
    }

    fn portal(&self, i: usize, p: &PortalDesc) -> Result<Portal, SceneError> {
        let key = format!("portals[{i}]");
        let (corner, edge_u, edge_v) = match (p.corner, p.edge_u, p.edge_v, &p.transform) {
            (Some(c), Some(u), Some(v), None) => (
                self.finite_vec(&format!("{key}.corner"), c)?,
                self.finite_vec(&format!("{key}.edge_u"), u)?,
                self.finite_vec(&format!("{key}.edge_v"), v)?,
            ),
            (None, None, None, Some(t)) => {
                let m = transform::matrix_from_desc(t).map_err(|e| self.split_err(&format!("{key}.transform"), &e))?;
                // The unit quad [-1, 1]² of a `quad` shape, placed by the transform.
                let c = m.transform_point3(Vec3::new(-1.0, -1.0, 0.0));
                (
                    c,
                    m.transform_point3(Vec3::new(1.0, -1.0, 0.0)) - c,
                    m.transform_point3(Vec3::new(-1.0, 1.0, 0.0)) - c,
                )
            }
            _ => {
                return Err(self.err(
                    key,
                    "expected either 'corner', 'edge_u' and 'edge_v', or 'transform' (a unit quad placed by it)",
                ))
            }
        };
        if edge_u.cross(edge_v).length_squared() == 0.0 {
            return Err(self.err(
                key,
                format!(
                    "expected edges spanning a quad of non-zero area, got edge_u = {} and edge_v = {}",
                    fmt3(edge_u.to_array()),
                    fmt3(edge_v.to_array())
                ),
            ));
        }
        Ok(Portal { corner, edge_u, edge_v })
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

    fn finite_vec(&self, key: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
        let v3 = Vec3::from(v);
        if v3.is_finite() {
            Ok(v3)
        } else {
            Err(self.err(key, format!("expected three finite numbers, got {}", fmt3(v))))
        }
    }

    /// A colour whose every component passes `ok` (and is finite).
    fn color(&self, key: &str, c: ColorDesc, what: &str, ok: impl Fn(f32) -> bool) -> Result<Rgb, SceneError> {
        if c.0.iter().all(|&v| v.is_finite() && ok(v)) {
            Ok(Rgb::from(c.0))
        } else {
            Err(self.err(key, format!("expected [r, g, b] with {what}, got {}", fmt3(c.0))))
        }
    }

    fn reflectance(&self, key: &str, c: Option<ColorDesc>, default: f32) -> Result<Rgb, SceneError> {
        match c {
            None => Ok(Rgb::splat(default)),
            Some(c) => self.color(key, c, "every component in [0, 1]", |v| (0.0..=1.0).contains(&v)),
        }
    }

    fn roughness(&self, key: &str, r: Option<f32>) -> Result<f32, SceneError> {
        match r {
            None => Ok(DEFAULT_ROUGHNESS),
            Some(a) if (0.0..=MAX_ROUGHNESS).contains(&a) => Ok(a),
            Some(a) => {
                Err(self.err(key, format!("expected a number in [0, {MAX_ROUGHNESS}] (the GGX alpha), got {a}")))
            }
        }
    }

    fn ior(&self, key: &str, ior: Option<f32>) -> Result<f32, SceneError> {
        match ior {
            None => Ok(DEFAULT_IOR),
            Some(v) if v > 0.0 && v.is_finite() => Ok(v),
            Some(v) => Err(self.err(key, format!("expected a number > 0, got {v}"))),
        }
    }
}

/// The largest GGX α a material may have. At α = 1 the microfacets are already as rough as any
/// measured surface, and far beyond it GGX is a cosine-like lobe that changes no more; past about
/// 1e9 its α⁴ overflows f32 and contributions become non-finite. 100 keeps every rough material
/// plexus renders far from that.
pub const MAX_ROUGHNESS: f32 = 100.0;

/// The smallest scene extent (in scene units) plexus renders correctly; see `Builder::check_scale`.
pub const MIN_EXTENT: f32 = 1e-9;
/// The largest scene extent and coordinate plexus renders correctly; see `Builder::check_scale`.
pub const MAX_EXTENT: f32 = 1e12;

/// The largest radiance component (after `scale`) an emitter or environment texel may have. The
/// integrators multiply radiance by path throughputs (BSDF/pdf ratios, and G·A/pdf factors of
/// sampled light points: A/h² reaches 1e14 for a point 1e-7 of the scene's extent from a light's
/// plane) before the film sums it in f64 and writes the image in f32 (at most 3.4e38): 1e20 leaves
/// those factors 18 decades of headroom. Environment texels of 3e38 (which once rendered black
/// or wrote Inf pixels) are far beyond it.
pub const MAX_RADIANCE: f32 = 1e20;

/// Roughness (GGX alpha) when a conductor or plastic gives none.
pub const DEFAULT_ROUGHNESS: f32 = 0.1;
/// Index of refraction when a dielectric or plastic gives none (glass).
pub const DEFAULT_IOR: f32 = 1.5;

#[cfg(test)]
mod tests {
    use super::*;

    /// No scene syntax makes a delta emitter yet, so the refusal is tested on the kinds: both delta
    /// kinds are refused with a one-line message naming the emitter and the reason, the kinds the
    /// loader builds pass. (Without the check, a delta emitter loads and BDPT weights it wrongly.)
    #[test]
    fn delta_emitters_are_refused_with_the_reason() {
        let builder = Builder { file: "scene.toml", base_dir: Path::new("") };
        for kind in [EmitterKind::DeltaPosition, EmitterKind::DeltaDirection] {
            let err = builder.refuse_delta_emitter("lights[0]", "key light", kind).expect_err("delta refused");
            let msg = err.to_string();
            assert!(matches!(err, SceneError::Invalid { .. }), "{msg}");
            assert!(!msg.contains('\n'), "one line: {msg}");
            for part in ["scene.toml: lights[0]: ", "'key light'", "delta-", "MIS weights"] {
                assert!(msg.contains(part), "{part:?} missing from: {msg}");
            }
        }
        for kind in [EmitterKind::Area, EmitterKind::Infinite] {
            assert!(builder.refuse_delta_emitter("shapes[0].emission", "quad", kind).is_ok());
        }
    }
}
