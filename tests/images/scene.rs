//! Scene loading: every shipped scene loads (on both accelerators where it matters), and every
//! kind of bad input gets its one-line message naming the file, the line or key, the value and
//! what was expected.

use std::fs;
use std::path::{Path, PathBuf};

use plexus::accel::AccelKind;
use plexus::scene::{builtin_cornell_box, load_scene, load_scene_str, scene_info, LoadedScene, SceneError};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// A fresh directory for one test's files.
fn temp_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("plexus-scene-test-{name}-")).tempdir().expect("create temp dir")
}

/// A minimal valid scene: one diffuse quad lit by a quad light, plus `extra` TOML appended.
fn scene_text(extra: &str) -> String {
    format!(
        r#"[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
fov = 40
resolution = [32, 24]

[materials.white]
type = "diffuse"
reflectance = 0.5

[[shapes]]
type = "quad"
material = "white"

[[shapes]]
type = "quad"
material = "white"
emission = {{ radiance = [1, 1, 1] }}
transform = {{ translate = [0, 0, 2], rotate = {{ axis = [1, 0, 0], angle = 180 }} }}
{extra}"#
    )
}

/// Writes `text` as `dir/scene.toml` and loads it, expecting failure.
fn load_err(dir: &Path, text: &str) -> (String, String) {
    let path = dir.join("scene.toml");
    fs::write(&path, text).unwrap();
    let file = path.display().to_string();
    match load_scene(&path, Some(AccelKind::Bvh)) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.contains('\n'), "message must be one line: {msg}");
            (file, msg)
        }
    }
}

fn load_ok(path: &Path) -> LoadedScene {
    load_scene(path, Some(AccelKind::Bvh)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn minimal_scene_loads_with_defaults() {
    let tmp = temp_dir("minimal");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("scene.toml");
    fs::write(&path, scene_text("")).unwrap();
    let loaded = load_ok(&path);
    assert_eq!(loaded.render.integrator, "pt");
    assert_eq!(loaded.render.seed, 0);
    assert_eq!(loaded.render.spp, None);
    assert_eq!(loaded.render.accel, AccelKind::Bvh);
    let s = &loaded.scene;
    assert_eq!(s.meshes.len(), 2);
    assert_eq!(s.lights.len(), 1);
    assert_eq!(s.shapes[1].light, Some(0));
    assert_eq!(s.shapes[0].light, None);
    assert_eq!((s.camera.width, s.camera.height), (32, 24));
    assert_eq!(s.source.as_deref(), Some(path.as_path()));
    // The light quad was turned upside down and lifted: it faces -z at z = 2.
    let [a, b, c] = s.meshes[1].triangle(0);
    let n = (b - a).cross(c - a).normalize();
    assert!((n.z + 1.0).abs() < 1e-6 && (a.z - 2.0).abs() < 1e-6, "{n} {a}");
    let f = s.features();
    assert_eq!(f.area_lights, 1);
    assert!(!f.environment_distribution && !f.constant_environment && f.image_environment.is_none());
    assert_eq!(f.portals, 0);
    assert!(f.diffuse_materials && !f.glossy_materials && !f.specular_materials);
    assert_eq!(f.triangles, 4);
}

#[test]
fn render_and_integrator_tables() {
    let tmp = temp_dir("render");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("scene.toml");
    let extra = r#"
[integrator]
type = "bdpt"
max_depth = 12

[render]
time = 2.5
seed = 7
threads = 2
accel = "embree"
output = ["out/a.exr", "b.png"]
"#;
    fs::write(&path, scene_text(extra)).unwrap();
    // The argument overrides the file's accelerator.
    let r = load_ok(&path).render;
    assert_eq!(r.integrator, "bdpt");
    assert_eq!(r.integrator_params.get("max_depth").and_then(|v| v.as_integer()), Some(12));
    assert!(!r.integrator_params.contains_key("type"));
    assert_eq!((r.spp, r.time, r.seed, r.threads), (None, Some(2.5), 7, Some(2)));
    assert_eq!(r.outputs, vec![PathBuf::from("out/a.exr"), PathBuf::from("b.png")]);
    assert_eq!(r.accel, AccelKind::Bvh);
}

#[test]
fn builtin_is_the_shipped_cornell_box() {
    let builtin = builtin_cornell_box(Some(AccelKind::Bvh)).unwrap_or_else(|e| panic!("{e}"));
    let shipped = load_ok(&scenes_dir().join("cornell-box.toml"));
    assert_eq!(builtin.scene.triangle_count(), shipped.scene.triangle_count());
    assert_eq!(builtin.scene.materials, shipped.scene.materials);
    assert_eq!(builtin.render, shipped.render);
    assert!(builtin.scene.source.is_none());
    // Walls, blocks and light: 5 quads + 2 boxes + 1 light quad.
    assert_eq!(builtin.scene.triangle_count(), 5 * 2 + 2 * 12 + 2);
    let b = builtin.scene.bounds;
    assert!(b.min.abs_diff_eq(glam::Vec3::new(0.0, 0.0, 0.0), 0.01), "{:?}", b.min);
    assert!(b.max.abs_diff_eq(glam::Vec3::new(556.0, 548.8, 559.2), 0.01), "{:?}", b.max);
}

#[test]
fn every_shipped_scene_loads() {
    let mut names: Vec<PathBuf> = fs::read_dir(scenes_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    names.sort();
    for required in ["cornell-box", "cornell-glossy", "cornell-glass", "environment", "furnace", "veach-ajar"] {
        assert!(names.iter().any(|p| p.file_stem().unwrap() == required), "scenes/{required}.toml is missing");
    }
    for path in &names {
        let loaded = load_ok(path);
        let info = scene_info(&loaded.scene);
        assert!(info.triangles > 0 && !loaded.scene.lights.is_empty(), "{}", path.display());
        let (w, h) = (loaded.scene.camera.width, loaded.scene.camera.height);
        assert!(w * h <= 320 * 240, "{}: keep shipped scenes small for tests ({w}x{h})", path.display());
        // The human-readable summary names every section on its own line.
        let text = info.to_string();
        for k in ["triangles:", "emitters:", "materials:", "portals:", "bounds:", "memory:"] {
            assert!(text.contains(k), "{text}");
        }
    }
}

#[test]
fn shipped_scene_features() {
    let f = load_ok(&scenes_dir().join("cornell-glossy.toml")).scene.features();
    assert!(f.glossy_materials && !f.specular_materials);
    let f = load_ok(&scenes_dir().join("cornell-glass.toml")).scene.features();
    assert!(f.specular_materials);
    assert_eq!(f.materials_by_kind.get("dielectric"), Some(&1));
    let env = load_ok(&scenes_dir().join("environment.toml")).scene;
    let f = env.features();
    let img = f.image_environment.as_ref().expect("environment.toml has an image environment");
    assert!(f.environment_distribution);
    assert_eq!(img.distribution_cells, img.width * img.height);
    assert_eq!(env.environment.map(|i| env.lights[i as usize].is_environment()), Some(true));
    let f = load_ok(&scenes_dir().join("furnace.toml")).scene.features();
    assert!(!f.environment_distribution && f.area_lights == 1);
}

#[test]
fn accelerator_choice() {
    let path = scenes_dir().join("cornell-box.toml");
    for kind in [AccelKind::Embree, AccelKind::Bvh] {
        let s = load_scene(&path, Some(kind)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(s.scene.accel.kind(), kind);
        assert_eq!(scene_info(&s.scene).accel, kind.to_string());
    }
}

#[test]
fn meshes_from_files_with_transforms() {
    let tmp = temp_dir("meshes");
    let dir = tmp.path().to_path_buf();
    fs::write(dir.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
    fs::write(
        dir.join("tri.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    let extra = r#"
[[shapes]]
type = "obj"
file = "tri.obj"
material = "white"
transform = { scale = [2, 2, -1], translate = [10, 0, 0] }

[[shapes]]
type = "ply"
file = "tri.ply"
material = "white"
transform = { matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -3], [0, 0, 0, 1]] }
"#;
    let path = dir.join("scene.toml");
    fs::write(&path, scene_text(extra)).unwrap();
    let s = load_ok(&path).scene;
    assert_eq!(s.meshes[2].triangle_count(), 2, "the OBJ quad is split into two triangles");
    assert_eq!(s.shapes[2].name, "tri.obj");
    let b = s.meshes[2].bounds();
    assert_eq!((b.min.x, b.max.x, b.max.y), (10.0, 12.0, 2.0));
    // Mirrored through z = 0: the side that faced +z now faces -z, and the winding is reversed
    // so that the geometric normal agrees (as it keeps a closed mesh's normals pointing outwards).
    let [a, bb, c] = s.meshes[2].triangle(0);
    assert!((bb - a).cross(c - a).z < 0.0);
    assert_eq!(s.meshes[3].triangle(0)[0], glam::Vec3::new(0.0, 0.0, -3.0));
}

#[test]
fn portals_are_kept() {
    let tmp = temp_dir("portals");
    let dir = tmp.path().to_path_buf();
    let extra = r#"
[[portals]]
corner = [0, 0, 0]
edge_u = [1, 0, 0]
edge_v = [0, 1, 0]

[[portals]]
transform = { scale = 2, translate = [0, 0, 4] }
"#;
    let path = dir.join("scene.toml");
    fs::write(&path, scene_text(extra)).unwrap();
    let s = load_ok(&path).scene;
    assert_eq!(s.portals.len(), 2);
    assert_eq!(s.portals[1].corner, glam::Vec3::new(-2.0, -2.0, 4.0));
    assert_eq!(s.portals[1].edge_u, glam::Vec3::new(4.0, 0.0, 0.0));
    assert_eq!(s.features().portals, 2);
    // Portals are not geometry: only the two quads are intersectable.
    assert_eq!(s.meshes.len(), 2);
}

// ---- bad input: each message is one line naming the file, the line or key, the value and what
// was expected.

#[test]
fn malformed_toml() {
    let tmp = temp_dir("malformed");
    let dir = tmp.path().to_path_buf();
    let (file, msg) = load_err(&dir, "[camera\nposition = [0, 0, 0]\n");
    assert!(msg.starts_with(&format!("{file}: line 1: ")), "{msg}");
}

#[test]
fn unknown_key_names_line_table_and_expected_keys() {
    let tmp = temp_dir("unknown");
    let dir = tmp.path().to_path_buf();
    let text = scene_text("\n[[shapes]]\ntype = \"quad\"\nmaterial = \"white\"\ncolour = [1, 0, 0]\n");
    let line = text.lines().position(|l| l.starts_with("colour")).unwrap() + 1;
    let (file, msg) = load_err(&dir, &text);
    assert_eq!(
        msg,
        format!(
            "{file}: line {line}: unknown key 'colour' in [[shapes]] (expected one of: type, file, material, \
             emission, transform, subdivisions, face_normals, flip_normals)"
        )
    );
    // Inside an inline table.
    let text = scene_text("\n[[shapes]]\ntype = \"quad\"\nmaterial = \"white\"\nemission = { colour = 1 }\n");
    let line = text.lines().position(|l| l.starts_with("emission = { colour")).unwrap() + 1;
    let (file, msg) = load_err(&dir, &text);
    assert_eq!(
        msg,
        format!(
            "{file}: line {line}: unknown key 'colour' in 'emission' of [[shapes]] (expected one of: radiance, \
             scale, two_sided)"
        )
    );
    // A key of another material type.
    let text = scene_text("\n[materials.red]\ntype = \"diffuse\"\nior = 1.5\n");
    let (file, msg) = load_err(&dir, &text);
    assert_eq!(
        msg,
        format!("{file}: materials.red: key 'ior' does not apply to type 'diffuse' (expected: type, reflectance, two_sided, opacity)")
    );
}

#[test]
fn wrong_type_names_line_and_key() {
    let tmp = temp_dir("wrongtype");
    let dir = tmp.path().to_path_buf();
    let text = scene_text("").replace("fov = 40", "fov = \"wide\"");
    let (file, msg) = load_err(&dir, &text);
    assert!(msg.starts_with(&format!("{file}: line 4: key 'fov' in [camera]: invalid type: string \"wide\"")), "{msg}");
}

#[test]
fn missing_mesh_file() {
    let tmp = temp_dir("missingmesh");
    let dir = tmp.path().to_path_buf();
    let (file, msg) = load_err(
        &dir,
        &scene_text("\n[[shapes]]\ntype = \"obj\"\nfile = \"meshes/nowhere.obj\"\nmaterial = \"white\"\n"),
    );
    let mesh = dir.join("meshes/nowhere.obj");
    assert!(msg.starts_with(&format!("{file}: shapes[2].file: mesh '{}': ", mesh.display())), "{msg}");
    assert!(msg.contains("No such file"), "{msg}");
}

#[test]
fn nan_vertex_in_obj() {
    let tmp = temp_dir("nanobj");
    let dir = tmp.path().to_path_buf();
    fs::write(dir.join("bad.obj"), "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let (file, msg) =
        load_err(&dir, &scene_text("\n[[shapes]]\ntype = \"obj\"\nfile = \"bad.obj\"\nmaterial = \"white\"\n"));
    assert_eq!(
        msg,
        format!(
            "{file}: shapes[2].file: mesh '{}': vertex 1 has a non-finite coordinate ([NaN, 0.0, 0.0])",
            dir.join("bad.obj").display()
        )
    );
}

#[test]
fn out_of_range_index_in_ply() {
    let tmp = temp_dir("badply");
    let dir = tmp.path().to_path_buf();
    fs::write(
        dir.join("bad.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
    )
    .unwrap();
    let (file, msg) =
        load_err(&dir, &scene_text("\n[[shapes]]\ntype = \"ply\"\nfile = \"bad.ply\"\nmaterial = \"white\"\n"));
    assert_eq!(
        msg,
        format!(
            "{file}: shapes[2].file: mesh '{}': triangle 0 refers to vertex 7, but the mesh has only 3 vertices",
            dir.join("bad.ply").display()
        )
    );
}

#[test]
fn non_positive_resolution() {
    let tmp = temp_dir("resolution");
    let dir = tmp.path().to_path_buf();
    for bad in ["[0, 24]", "[32, -5]"] {
        let (file, msg) = load_err(&dir, &scene_text("").replace("[32, 24]", bad));
        assert_eq!(
            msg,
            format!(
                "{file}: camera.resolution: expected two positive integers [width, height] (at most 65536), got {bad}"
            )
        );
    }
}

#[test]
fn negative_roughness() {
    let tmp = temp_dir("roughness");
    let dir = tmp.path().to_path_buf();
    let (file, msg) = load_err(
        &dir,
        &scene_text("\n[materials.metal]\ntype = \"conductor\"\nroughness = -0.1\ncolour = [0.9, 0.6, 0.3]\n"),
    );
    assert_eq!(
        msg,
        format!("{file}: materials.metal.roughness: expected a number in [0, 100] (the GGX alpha), got -0.1")
    );
}

#[test]
fn negative_radiance() {
    let tmp = temp_dir("radiance");
    let dir = tmp.path().to_path_buf();
    let text = scene_text("").replace("radiance = [1, 1, 1]", "radiance = [-1, 0, 0]");
    let (file, msg) = load_err(&dir, &text);
    assert_eq!(
        msg,
        format!("{file}: shapes[1].emission.radiance: expected [r, g, b] with every component ≥ 0, got [-1, 0, 0]")
    );
}

#[test]
fn other_range_errors() {
    let tmp = temp_dir("ranges");
    let dir = tmp.path().to_path_buf();
    let (file, msg) = load_err(&dir, &scene_text("\n[materials.glass]\ntype = \"dielectric\"\nior = -1.5\n"));
    assert_eq!(msg, format!("{file}: materials.glass.ior: expected a number > 0, got -1.5"));
    let (file, msg) = load_err(&dir, &scene_text("").replace("reflectance = 0.5", "reflectance = [0.5, 1.2, 0.5]"));
    assert_eq!(msg, format!("{file}: materials.white.reflectance: expected [r, g, b] with every component in [0, 1], got [0.5, 1.2, 0.5]"));
    let (file, msg) = load_err(&dir, &scene_text("\n[[shapes]]\ntype = \"quad\"\nmaterial = \"chrome\"\n"));
    assert_eq!(msg, format!("{file}: shapes[2].material: unknown material 'chrome' (defined: white)"));
    let (file, msg) = load_err(&dir, &scene_text("\n[[shapes]]\ntype = \"cone\"\nmaterial = \"white\"\n"));
    assert_eq!(msg, format!("{file}: shapes[2].type: expected one of: obj, ply, quad, box, disk, sphere, got 'cone'"));
    let (file, msg) = load_err(&dir, &scene_text("\n[render]\naccel = \"kdtree\"\n"));
    assert!(msg.starts_with(&format!("{file}: line ")), "{msg}");
    assert!(msg.ends_with("key 'accel' in [render]: expected one of: embree, bvh, got 'kdtree'"), "{msg}");
    let (file, msg) = load_err(&dir, &scene_text("\n[render]\nspp = 0\n"));
    assert_eq!(msg, format!("{file}: render.spp: expected an integer > 0, got 0"));
    let (file, msg) = load_err(
        &dir,
        &scene_text("\n[[shapes]]\ntype = \"box\"\nmaterial = \"white\"\ntransform = { scale = [1, 0, 1] }\n"),
    );
    assert_eq!(msg, format!("{file}: shapes[2].transform: expected an invertible transform, got determinant 0"));
    let (file, msg) = load_err(
        &dir,
        &scene_text("\n[[shapes]]\ntype = \"box\"\nmaterial = \"white\"\ntransform = { rotate = [{ axis = [0, 0, 0], angle = 3 }] }\n"),
    );
    assert_eq!(
        msg,
        format!("{file}: shapes[2].transform.rotate.axis: expected a non-zero finite vector, got [0, 0, 0]")
    );
    let (file, msg) = load_err(
        &dir,
        &scene_text("").replace("radiance = [1, 1, 1]", "radiance = [0, 0, 0]").replace("emission", "#"),
    );
    assert_eq!(
        msg,
        format!(
            "{file}: shapes: expected at least one emitter (a shape with 'emission' or an [environment]), found none"
        )
    );
}

#[test]
fn missing_scene_file_and_string_loading() {
    let tmp = temp_dir("missingscene");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("none.toml");
    let e = load_scene(&path, None).err().expect("missing file must fail");
    assert!(matches!(e, SceneError::Read { .. }));
    assert!(e.to_string().starts_with(&format!("{}: cannot read the scene file: ", path.display())), "{e}");
    // From a string, the given name stands for the file.
    let e = load_scene_str("[camera]\n", &dir, "inline.toml", None).err().expect("incomplete scene must fail");
    assert!(e.to_string().starts_with("inline.toml: "), "{e}");
    assert!(e.to_string().contains("missing key"), "{e}");
}

#[test]
fn environment_errors_and_constant_environment() {
    let tmp = temp_dir("environment");
    let dir = tmp.path().to_path_buf();
    let (file, msg) = load_err(&dir, &scene_text("\n[environment]\ntype = \"image\"\nfile = \"nope.exr\"\n"));
    let exr = dir.join("nope.exr");
    assert!(msg.starts_with(&format!("{file}: environment.file: cannot read EXR file '{}': ", exr.display())), "{msg}");
    let (file, msg) =
        load_err(&dir, &scene_text("\n[environment]\ntype = \"constant\"\nradiance = 1\nfile = \"a.exr\"\n"));
    assert_eq!(
        msg,
        format!("{file}: environment: key 'file' does not apply to type 'constant' (expected: type, radiance, scale)")
    );
    let (file, msg) = load_err(&dir, &scene_text("\n[environment]\ntype = \"constant\"\nradiance = [1, -2, 1]\n"));
    assert_eq!(
        msg,
        format!("{file}: environment.radiance: expected [r, g, b] with every component ≥ 0, got [1, -2, 1]")
    );

    let path = dir.join("scene.toml");
    fs::write(&path, scene_text("\n[environment]\ntype = \"constant\"\nradiance = 0.25\nscale = 2\n")).unwrap();
    let s = load_ok(&path).scene;
    let f = s.features();
    assert!(f.constant_environment && !f.environment_distribution && f.image_environment.is_none());
    assert_eq!(s.environment, Some(1), "the environment comes after the area lights");
    match s.environment_light() {
        Some((_, plexus::light::Light::ConstantEnvironment(c))) => assert_eq!(c.radiance, glam::Vec3::splat(0.5)),
        _ => panic!("expected a constant environment"),
    }
}

/// The TOML blocks of docs/scene-format.md, in order. The page is compiled into the test
/// (`include_str!`), not read when it runs: the schema it is checked against is compiled in, so
/// both must come from the same tree. Read at run time, the page could be newer than the binary:
/// a merge or checkout in the working tree while a full suite runs (how the test failed once and
/// then passed alone), or a binary built before the page changed (a test binary of 13:16 fails
/// every run against the page of 15:43: "invalid type: map" at the texture example its schema
/// does not know), and cargo did not rebuild the test when only the page changed; now it does.
fn doc_blocks() -> Vec<String> {
    let doc = include_str!("../../docs/scene-format.md");
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in doc.lines() {
        match (&mut current, line.trim_end()) {
            (None, "```toml") => current = Some(String::new()),
            (Some(b), "```") => {
                blocks.push(std::mem::take(b));
                current = None;
            }
            (Some(b), l) => {
                b.push_str(l);
                b.push('\n');
            }
            _ => {}
        }
    }
    blocks
}

#[test]
fn documentation_examples_are_valid() {
    let blocks = doc_blocks();
    assert!(blocks.len() >= 10, "found {} TOML blocks", blocks.len());
    // The first block is a complete scene: it must load.
    let tmp = temp_dir("docs");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("doc.toml");
    fs::write(&path, &blocks[0]).unwrap();
    let s = load_ok(&path).scene;
    assert_eq!(s.meshes.len(), 2);
    assert!(s.features().constant_environment);
    // Every other block that is a table must at least match the schema (no unknown keys, right
    // types); blocks of bare `transform = ...` lines are checked inside a shape.
    let camera = "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov = 40\nresolution = [8, 8]\n";
    let mut scenes = Vec::new();
    for b in &blocks[1..] {
        if b.starts_with("[camera]") {
            scenes.push(b.clone());
        } else if b.starts_with('[') {
            scenes.push(format!("{camera}{b}"));
        } else {
            // Bare `transform = ...` lines: one shape each.
            scenes.extend(b.lines().map(|l| format!("{camera}[[shapes]]\ntype = \"box\"\nmaterial = \"m\"\n{l}\n")));
        }
    }
    for t in &scenes {
        if let Err(e) = toml::from_str::<plexus::scene::desc::SceneDesc>(t) {
            panic!("documentation example does not match the schema: {e}\n{t}");
        }
    }
    let checked = scenes.len();
    assert!(checked >= 12, "{checked}");
}

/// The door scene's point: light reaches the visible room only through the doorway. Every
/// unoccluded segment from the light to a grid of points in the visible room must cross the wall
/// plane inside the doorway (the portal quad), and some must exist.
#[test]
fn veach_ajar_light_enters_only_through_the_doorway() {
    let s = load_ok(&scenes_dir().join("veach-ajar.toml")).scene;
    let light = s.shapes.iter().position(|i| i.light.is_some()).expect("one area light");
    let lb = s.meshes[light].bounds();
    let portal = s.portals[0];
    let wall_x = portal.corner.x;
    let (y0, y1) = (portal.corner.y, portal.corner.y + portal.edge_v.y);
    let (z0, z1) = (portal.corner.z, portal.corner.z + portal.edge_u.z);
    let lerp = |a: f32, b: f32, i: usize, n: usize| a + (b - a) * (i as f32 + 0.5) / n as f32;
    let (mut through, mut blocked) = (0, 0);
    for li in 0..36 {
        // In front of the light (it faces -z).
        let p =
            glam::Vec3::new(lerp(lb.min.x, lb.max.x, li % 6, 6), lerp(lb.min.y, lb.max.y, li / 6, 6), lb.min.z - 1e-3);
        for qi in 0..(12 * 6 * 12) {
            let q = glam::Vec3::new(
                lerp(-2.7, 7.3, qi % 12, 12),
                lerp(0.05, 3.75, (qi / 12) % 6, 6),
                lerp(-7.5, 0.5, qi / 72, 12),
            );
            let d = q - p;
            let len = d.length();
            let ray = plexus::geometry::Ray { o: p, d: d / len, t_min: 1e-4 * len, t_max: len * (1.0 - 1e-4) };
            if s.occluded(&ray) {
                blocked += 1;
                continue;
            }
            through += 1;
            let t = (wall_x - p.x) / d.x;
            let c = p + d * t;
            assert!(
                (y0..=y1).contains(&c.y) && (z0..=z1).contains(&c.z),
                "light reaches {q} without passing the doorway (crosses the wall at {c})"
            );
        }
    }
    // 419 of the 31,104 segments get through when this was written.
    assert!(through > 0 && blocked > through, "through {through}, blocked {blocked}");
}
