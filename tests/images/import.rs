//! The seven Mitsuba scenes of scenes/mitsuba/ (XML, meshes and textures; sources and licences in
//! scenes/mitsuba/LICENSES.md): each imports to exactly the TOML committed in scenes/imported/ (so
//! the committed files are what `plexus import` writes today), with the warnings committed beside
//! it, and each committed TOML loads with the ordinary loader (every mesh and texture found through
//! its relative paths) and renders with `pt`, `bdpt` and `mmlt` (a smoke check: a tiny image,
//! finite and not black, for each). `plexus render SCENE.xml` renders a Mitsuba file directly.

use std::path::{Path, PathBuf};

use plexus::metrics::converge::camera_at_resolution;
use plexus::scene::import::{import_mitsuba, ImportOptions};
use plexus::scene::load_scene;

use crate::common::agreement::render_regions;
use crate::common::binary::{plexus, stderr, temp_dir};

/// (name, XML file, leave out missing meshes): the list scripts/import-scenes.sh imports.
const SCENES: &[(&str, &str, bool)] = &[
    ("cornell-box", "cbox.xml", false),
    ("veach-ajar", "scene_v3.xml", true),
    ("veach-lamp", "scene.xml", false),
    ("torus", "scene.xml", false),
    ("staircase", "scene.xml", false),
    ("breakfast-room", "scene.xml", false),
    ("living-room", "scene.xml", false),
];

/// The directory of the Mitsuba scenes' data, scenes/mitsuba/ in the repository.
fn scene_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/mitsuba")
}

/// Run from the repository root, as scripts/import-scenes.sh is, so that the paths written in the
/// TOML header and warnings are the same (repository-relative).
fn in_root() {
    std::env::set_current_dir(env!("CARGO_MANIFEST_DIR")).expect("cd to the repository");
}

/// Imports scene `name` of `SCENES`, compares with the committed TOML and warnings, and loads the
/// committed TOML.
fn import_and_load(name: &str) {
    in_root();
    let &(_, xml, skip_missing) = SCENES.iter().find(|s| s.0 == name).expect("listed scene");
    let xml_path = PathBuf::from(format!("scenes/mitsuba/{name}/{xml}"));
    let options = ImportOptions {
        toml_dir: Some(PathBuf::from("scenes/imported")),
        skip_missing_meshes: skip_missing,
        ..Default::default()
    };
    let imported = import_mitsuba(&xml_path, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
    let committed_path = format!("scenes/imported/{name}.toml");
    let committed = std::fs::read_to_string(&committed_path).unwrap_or_else(|e| panic!("{committed_path}: {e}"));
    assert!(
        imported.toml == committed,
        "{committed_path} is not what the importer writes today: run scripts/import-scenes.sh"
    );
    let warnings = std::fs::read_to_string(format!("scenes/imported/{name}.warnings")).expect("warnings file");
    for line in imported.warnings.lines() {
        assert!(warnings.contains(&line), "{name}: warning not recorded in {name}.warnings: {line}");
    }
    let mut loaded = load_scene(Path::new(&committed_path), None).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(!loaded.scene.lights.is_empty() && loaded.scene.triangle_count() > 0, "{name}");
    smoke_render(name, &mut loaded.scene);
}

/// Renders `scene` with pt, bdpt and mmlt at about 24 pixels on the long side (the scene's
/// aspect ratio), a few samples (mutations) per pixel: every region mean must be finite and the
/// image not black. A smoke check that each integrator runs on the scene's features (textures,
/// masks, two-sided and rough dielectric materials, environment maps, emitting meshes); agreement is
/// tests/images/crosscheck.rs's business.
fn smoke_render(name: &str, scene: &mut plexus::scene::Scene) {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let g = (1..=w.min(h)).rev().find(|d| w % d == 0 && h % d == 0).unwrap_or(1);
    let (bw, bh) = (w / g, h / g);
    let k = 24u32.div_ceil(bw.max(bh)).max(1);
    scene.camera = camera_at_resolution(&scene.camera, bw * k, bh * k).expect("resolution");
    for (integrator, params) in
        [("pt", "max_depth = 8"), ("bdpt", "max_depth = 8"), ("mmlt", "max_depth = 8\nbootstrap = 20000\nchains = 64")]
    {
        let r = &render_regions(scene, integrator, params, 4, 0, 1)[0];
        assert!(
            r.iter().all(|m| m.is_finite()) && *r.last().expect("image mean") > 0.0,
            "{name} with {integrator}: region means {r:?}"
        );
    }
}

#[test]
fn cornell_box_imports_and_loads() {
    import_and_load("cornell-box");
}
#[test]
fn veach_ajar_imports_and_loads() {
    import_and_load("veach-ajar");
}
#[test]
fn veach_lamp_imports_and_loads() {
    import_and_load("veach-lamp");
}
#[test]
fn torus_imports_and_loads() {
    import_and_load("torus");
}
#[test]
fn staircase_imports_and_loads() {
    import_and_load("staircase");
}
#[test]
fn breakfast_room_imports_and_loads() {
    import_and_load("breakfast-room");
}
#[test]
fn living_room_imports_and_loads() {
    import_and_load("living-room");
}

/// `plexus render SCENE.xml` imports on the fly, prints the warnings with file:line, and renders;
/// `plexus import` of a scene with a missing mesh fails naming it, exit code 2.
#[test]
fn render_and_import_from_the_command_line() {
    let data = scene_data();
    let dir = temp_dir("import");
    let xml = data.join("veach-lamp/scene.xml");
    let out = dir.path().join("lamp.png");
    let o = plexus(
        &["render", xml.to_str().unwrap(), "--spp", "1", "--out", out.to_str().unwrap(), "--threads", "2"],
        dir.path(),
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.is_file());
    assert!(err.contains("scene.xml:36: <bsdf type=\"ward\" id=\"LampMaterial\"> mapped to a GGX conductor"), "{err}");

    let ajar = data.join("veach-ajar/scene_v3.xml");
    let o = plexus(&["import", ajar.to_str().unwrap(), "--out", "ajar.toml"], dir.path());
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.starts_with("error: ") && err.contains("scene_v3.xml:251: mesh file") && err.contains("Mesh009.obj"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
}
