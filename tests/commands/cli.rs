//! The `plexus` binary as a user meets it: every bad input of the foundation issue gets one clear
//! line `error: ...` naming the file/key and what was expected, with exit code 2 (bad input) — never
//! a panic or a backtrace — and a tiny successful render writes EXR, PNG and the JSON stats.

use std::path::Path;
use std::process::Output;

use crate::common::binary::{plexus, stderr, temp_dir};
use crate::common::inputs::mitsuba_scene;

/// A tiny valid scene: an 8×6 camera looking at a diffuse floor under a one-sided area light.
/// `{MATERIAL}`, `{EMISSION}`, `{RESOLUTION}` and `{EXTRA}` are substituted by the tests.
const TEMPLATE: &str = r#"
[camera]
position = [0.0, 1.0, -3.0]
look_at = [0.0, 0.5, 0.0]
fov = 45.0
resolution = {RESOLUTION}

[materials.floor]
{MATERIAL}

[materials.lamp]
type = "diffuse"
reflectance = [0.0, 0.0, 0.0]

[[shapes]]
type = "quad"
material = "floor"
transform = { scale = [2.0, 2.0, 1.0], rotate = { axis = [1, 0, 0], angle = -90 } }

[[shapes]]
type = "quad"
material = "lamp"
emission = { radiance = {EMISSION} }
transform = { scale = [0.5, 0.5, 1.0], rotate = { axis = [1, 0, 0], angle = 90 }, translate = [0.0, 2.0, 0.0] }
{EXTRA}
"#;

fn scene_text(material: &str, emission: &str, resolution: &str, extra: &str) -> String {
    TEMPLATE
        .replace("{MATERIAL}", material)
        .replace("{EMISSION}", emission)
        .replace("{RESOLUTION}", resolution)
        .replace("{EXTRA}", extra)
}

fn good_scene() -> String {
    scene_text("type = \"diffuse\"\nreflectance = [0.5, 0.5, 0.5]", "[4.0, 4.0, 4.0]", "[8, 6]", "")
}

/// Writes `text` as `name` in `dir` and returns its path as a string.
fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write test file");
    p.to_string_lossy().into_owned()
}

/// Asserts a failure with `code`, exactly one line on stderr starting with `error: `, containing
/// every one of `needles`, and no trace of a panic.
fn assert_error(o: &Output, code: i32, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(code), "exit code; stderr: {err}");
    assert!(!err.contains("panicked") && !err.contains("RUST_BACKTRACE") && !err.contains("internal error"), "{err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected, got: {err}");
    assert!(lines[0].starts_with("error: "), "{err}");
    for n in needles {
        assert!(lines[0].contains(n), "expected '{n}' in: {err}");
    }
}

/// Renders `scene` (a file in `dir`) with extra arguments, expecting bad input.
fn render_fails(dir: &Path, scene: &str, args: &[&str], needles: &[&str]) {
    let mut all = vec!["render", scene];
    all.extend_from_slice(args);
    let o = plexus(&all, dir);
    assert_error(&o, 2, needles);
}

#[test]
fn malformed_toml_names_file_and_line() {
    let tmp = temp_dir("malformed");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "bad.toml", "[camera\nposition = [0, 0, 0]\n");
    render_fails(&dir, &scene, &[], &["bad.toml", "line 1"]);
}

#[test]
fn unknown_key_names_key_and_expected_keys() {
    let tmp = temp_dir("unknown-key");
    let dir = tmp.path().to_path_buf();
    let text = good_scene().replace("fov = 45.0", "fov = 45.0\nfocal_length = 3.0");
    let scene = write(&dir, "s.toml", &text);
    render_fails(&dir, &scene, &[], &["s.toml", "focal_length", "fov"]);
}

#[test]
fn missing_mesh_file_names_the_mesh() {
    let tmp = temp_dir("missing-mesh");
    let dir = tmp.path().to_path_buf();
    let text = format!("{}\n[[shapes]]\ntype = \"obj\"\nfile = \"nowhere.obj\"\nmaterial = \"floor\"\n", good_scene());
    let scene = write(&dir, "s.toml", &text);
    render_fails(&dir, &scene, &[], &["s.toml", "shapes[2].file", "nowhere.obj"]);
}

#[test]
fn nan_vertex_is_rejected() {
    let tmp = temp_dir("nan-vertex");
    let dir = tmp.path().to_path_buf();
    write(&dir, "nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n");
    let text = format!("{}\n[[shapes]]\ntype = \"obj\"\nfile = \"nan.obj\"\nmaterial = \"floor\"\n", good_scene());
    let scene = write(&dir, "s.toml", &text);
    render_fails(&dir, &scene, &[], &["s.toml", "nan.obj", "finite"]);
}

#[test]
fn out_of_range_index_is_rejected() {
    let tmp = temp_dir("bad-index");
    let dir = tmp.path().to_path_buf();
    // PLY, because OBJ readers resolve indices themselves; a face refers to vertex 7 of 3.
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
    write(&dir, "idx.ply", ply);
    let text = format!("{}\n[[shapes]]\ntype = \"ply\"\nfile = \"idx.ply\"\nmaterial = \"floor\"\n", good_scene());
    let scene = write(&dir, "s.toml", &text);
    render_fails(&dir, &scene, &[], &["s.toml", "idx.ply", "7"]);
}

#[test]
fn non_positive_resolution_is_rejected() {
    let tmp = temp_dir("resolution");
    let dir = tmp.path().to_path_buf();
    for res in ["[0, 6]", "[8, -2]"] {
        let text = scene_text("type = \"diffuse\"\nreflectance = 0.5", "[1.0, 1.0, 1.0]", res, "");
        let scene = write(&dir, "s.toml", &text);
        render_fails(&dir, &scene, &[], &["s.toml", "camera.resolution", "positive"]);
    }
}

#[test]
fn negative_roughness_is_rejected() {
    let tmp = temp_dir("roughness");
    let dir = tmp.path().to_path_buf();
    let text =
        scene_text("type = \"conductor\"\nroughness = -0.1\ncolour = [0.9, 0.6, 0.3]", "[1.0, 1.0, 1.0]", "[8, 6]", "");
    let scene = write(&dir, "s.toml", &text);
    render_fails(&dir, &scene, &[], &["s.toml", "materials.floor.roughness", "-0.1"]);
}

#[test]
fn negative_radiance_is_rejected() {
    let tmp = temp_dir("radiance");
    let dir = tmp.path().to_path_buf();
    let text = scene_text("type = \"diffuse\"\nreflectance = 0.5", "[1.0, -2.0, 1.0]", "[8, 6]", "");
    let scene = write(&dir, "s.toml", &text);
    render_fails(&dir, &scene, &[], &["s.toml", "shapes[1].emission.radiance", "-2"]);
}

#[test]
fn unknown_integrator_lists_the_valid_ones() {
    let tmp = temp_dir("integrator");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    render_fails(&dir, &scene, &["--integrator", "magic"], &["unknown integrator 'magic'", "pt"]);
    let in_file = write(&dir, "t.toml", &format!("{}\n[integrator]\ntype = \"magic\"\n", good_scene()));
    render_fails(&dir, &in_file, &[], &["unknown integrator 'magic'", "pt"]);
    // The list is the registry's, every row of it, in its order.
    let every = plexus::integrator::registry::NAMES.join(", ");
    render_fails(&dir, &scene, &["--integrator", "magic"], &[&format!("expected one of {every}")]);
    let help = plexus(&["render", "--help"], &dir);
    assert!(String::from_utf8_lossy(&help.stdout).contains(&every), "render --help lists {every}");
}

/// The session options are offered by the integrator's registry row: every shipped integrator's
/// row offers checkpoints and shards (emlt's since it runs on the chain runner), and a shard of
/// each renders and writes its state. (A row without them refuses both before any work:
/// `Integrator::no_state`; the registry's unit test keeps each row equal to its integrator.)
#[test]
fn session_options_follow_the_registry_capabilities() {
    use plexus::integrator::registry::INTEGRATORS;
    let tmp = temp_dir("capabilities");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    for row in INTEGRATORS {
        assert!(row.capabilities.checkpoint && row.capabilities.shard, "{} offers no sessions", row.name);
        let out = format!("{}.pxstate", row.name);
        // Small chain settings: one shard of two must hold a chain (emlt: a pair of two).
        let small = match row.name {
            "emlt" => vec!["--set", "ensemble_size=8", "--set", "pairs=2", "--set", "bootstrap=1000"],
            "pssmlt" | "mmlt" | "rjmlt" | "pmlt" => vec!["--set", "chains=8", "--set", "bootstrap=1000"],
            _ => vec![],
        };
        let mut args = vec!["render", &scene, "--integrator", row.name, "--spp", "1", "--shard", "0/2", "--out", &out];
        args.extend_from_slice(&small);
        let o = plexus(&args, &dir);
        assert_eq!(o.status.code(), Some(0), "{}: {}", row.name, stderr(&o));
        assert!(dir.join(&out).is_file(), "{}", row.name);
    }
}

#[test]
fn unknown_or_ill_typed_setting_is_rejected() {
    let tmp = temp_dir("settings");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    render_fails(&dir, &scene, &["--set", "max_dept=3"], &["max_dept", "max_depth"]);
    render_fails(&dir, &scene, &["--set", "max_depth=lots"], &["max_depth"]);
    render_fails(&dir, &scene, &["--set", "nonsense"], &["key=value"]);
    let in_file = write(&dir, "t.toml", &format!("{}\n[integrator]\ntype = \"pt\"\nrr = 2\n", good_scene()));
    render_fails(&dir, &in_file, &[], &["rr", "rr_depth"]);
}

#[test]
fn output_in_missing_directory_is_rejected_before_rendering() {
    let tmp = temp_dir("missing-dir");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    let out = dir.join("no/such/dir/out.exr");
    render_fails(&dir, &scene, &["--spp", "1", "--out", &out.to_string_lossy()], &["no/such/dir"]);
    assert!(!dir.join("no").exists());
}

#[test]
fn unwritable_format_is_rejected_before_rendering() {
    let tmp = temp_dir("format");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    // A valid first output must not be written either: every path is checked up front.
    let good = dir.join("first.exr");
    render_fails(&dir, &scene, &["--out", &good.to_string_lossy(), "--out", "image.notaformat"], &["image.notaformat"]);
    assert!(!good.exists(), "nothing is written when one output is unusable");
}

#[test]
fn bad_arguments_are_usage_errors() {
    let tmp = temp_dir("usage");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    for args in [
        vec!["render", scene.as_str(), "--spp", "4", "--time", "1"],
        vec!["render", scene.as_str(), "--accel", "octree"],
        vec!["render", scene.as_str(), "--spp", "many"],
        vec!["frobnicate"],
    ] {
        let o = plexus(&args, &dir);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).starts_with("error: "), "{args:?}: {}", stderr(&o));
    }
    render_fails(&dir, &scene, &["--spp", "0"], &["--spp"]);
    render_fails(&dir, &scene, &["--time", "-1"], &["--time"]);
    render_fails(&dir, &scene, &["--threads", "0"], &["--threads"]);
    for bad in ["0", "-2", "NaN", "inf"] {
        render_fails(&dir, &scene, &["--preview-every", bad], &["--preview-every"]);
    }
}

/// `--preview-every` with previews at every pass boundary (an interval of 1 ns; 4096 spp on the
/// 8×6 scene are 3 passes of 1366 samples per pixel): the render succeeds, writes its outputs, and
/// its final image is bit-identical to the same render without previews, so preview writes neither
/// fail the render nor leave a preview where the final image belongs. (That previews arrive at
/// the interval and are normalised is tested on a fake clock in `integrator::driver`; that the
/// CLI writes what it receives, in `cli::progress`.) 3.8 s on 2 cores at load average 15; no
/// clock is involved.
#[test]
fn previews_leave_the_final_image_unchanged() {
    let tmp = temp_dir("preview");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    let common = ["--spp", "4096", "--seed", "5", "--threads", "2"];
    let with =
        plexus(&[&["render", &scene, "--preview-every", "1e-9", "--out", "with.exr"][..], &common].concat(), &dir);
    assert!(with.status.success(), "{}", stderr(&with));
    let without = plexus(&[&["render", &scene, "--out", "without.exr"][..], &common].concat(), &dir);
    assert!(without.status.success(), "{}", stderr(&without));
    let read = |name: &str| {
        exr::prelude::read_first_rgba_layer_from_file(
            dir.join(name),
            |res, _| vec![[0f32; 3]; res.width() * res.height()],
            |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * 8 + pos.x()] = [r, g, b],
        )
        .expect("exr readable")
        .layer_data
        .channel_data
        .pixels
    };
    let (a, b) = (read("with.exr"), read("without.exr"));
    assert!(a.iter().flatten().all(|v| v.is_finite()) && a.iter().flatten().any(|v| *v > 0.0));
    let bits = |p: &Vec<[f32; 3]>| p.iter().map(|v| v.map(f32::to_bits)).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b), "previews changed the final image");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("with.json")).expect("stats written")).expect("JSON");
    assert_eq!(json["integrator_stats"]["passes"], 3);
}

#[test]
fn missing_scene_file_is_bad_input() {
    let tmp = temp_dir("missing-scene");
    let dir = tmp.path().to_path_buf();
    render_fails(&dir, "does-not-exist.toml", &[], &["does-not-exist.toml"]);
}

#[test]
fn tiny_render_writes_exr_png_and_json() {
    let tmp = temp_dir("success");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "tiny.toml", &good_scene());
    let o = plexus(
        &["render", &scene, "--spp", "4", "--seed", "3", "--threads", "2", "--out", "img.exr", "--out", "img.png"],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));

    let png = std::fs::read(dir.join("img.png")).expect("png written");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let exr = exr::prelude::read_first_rgba_layer_from_file(
        dir.join("img.exr"),
        |res, _| vec![[0f32; 3]; res.width() * res.height()],
        |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * 8 + pos.x()] = [r, g, b],
    )
    .expect("exr readable");
    let size = exr.layer_data.size;
    assert_eq!((size.width(), size.height()), (8, 6));
    let pixels = &exr.layer_data.channel_data.pixels;
    assert!(pixels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    assert!(pixels.iter().flatten().any(|v| *v > 0.0), "the lit floor is visible");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("img.json")).expect("stats written"))
            .expect("valid JSON");
    assert_eq!(json["integrator"], "pt");
    assert_eq!(json["seed"], 3);
    assert_eq!(json["threads"], 2);
    assert_eq!(json["accel"], "embree");
    assert_eq!(json["samples"], 8 * 6 * 4);
    assert_eq!(json["settings"]["max_depth"], 16);
    assert!(json["scene"].as_str().is_some_and(|s| s.ends_with("tiny.toml")));
    assert!(json["rays"].as_u64().is_some_and(|r| r >= 8 * 6 * 4));
    assert!(json["rays_per_s"].as_f64().is_some_and(|r| r > 0.0));
    assert!(json["wall_time_s"].as_f64().is_some_and(|t| t > 0.0));
    assert!(json["cpu_time_s"].as_f64().is_some_and(|t| t > 0.0 && t.is_finite()));
    assert_eq!(json["counters"]["nonfinite_dropped"], 0);
    assert_eq!(json["scene_features"]["area_lights"], 1);
    assert!(json["integrator_stats"].is_object());
    // No temporary files left behind.
    let names: Vec<String> = std::fs::read_dir(&dir)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains("tmp")), "{names:?}");
}

#[test]
fn default_outputs_are_named_after_the_scene() {
    let tmp = temp_dir("defaults");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "little.toml", &good_scene());
    let o = plexus(&["render", &scene, "--spp", "1", "--time", "0.2"], &dir);
    assert_eq!(o.status.code(), Some(2), "--spp and --time conflict");
    let o = plexus(&["render", &scene, "--time", "0.2", "--accel", "bvh"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["little.exr", "little.png", "little.json"] {
        assert!(dir.join(f).is_file(), "{f} written");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("little.json")).expect("stats")).expect("JSON");
    assert_eq!(json["accel"], "bvh");
    assert!(json["budget"]["seconds"].as_f64().is_some_and(|s| (s - 0.2).abs() < 1e-9));
    assert!(json["samples"].as_u64().is_some_and(|n| n > 0 && n % 48 == 0), "whole passes: {}", json["samples"]);
}

#[test]
fn info_prints_the_scene_summary() {
    let tmp = temp_dir("info");
    let dir = tmp.path().to_path_buf();
    let scene = write(&dir, "s.toml", &good_scene());
    let o = plexus(&["info", &scene], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("triangles") && out.contains('4'), "{out}");
    let o = plexus(&["info", &scene, "--json"], &dir);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("info JSON");
    assert_eq!(json["triangles"], 4);
    assert_eq!(json["area_lights"], 1);
    let o = plexus(&["info", "missing.toml"], &dir);
    assert_error(&o, 2, &["missing.toml"]);
}

/// `plexus bench` on a tiny scene (about 0.1 s): the progress lines, the Markdown tables and the
/// JSON report, with the counts that do not depend on timing (the generated scene, the recorded
/// rays, every accelerator finding the same hits) as the full run prints them.
#[test]
fn bench_prints_progress_tables_and_json() {
    let tmp = temp_dir("bench");
    let dir = tmp.path().to_path_buf();
    let o = plexus(
        &[
            "bench",
            "--triangles",
            "2000",
            "--resolution",
            "8x6",
            "--repetitions",
            "1",
            "--threads",
            "1",
            "--json",
            "bench.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("scene: ") && lines[0].contains("triangles in 27 meshes"), "{out}");
    assert_eq!(lines[1], "rays: 48 camera, 192 bounce (4 bounces per path at most)", "{out}");
    for accel in ["embree", "bvh", "embree bare loop"] {
        assert!(out.contains(&format!("{accel:>17} 1 thread(s): build ")), "{out}");
        assert!(out.contains(&format!("  {accel}: 48 camera hits, 192 bounce hits")), "{out}");
    }
    assert!(out.contains("  path tracer 1 thread(s): "), "{out}");
    assert!(out.contains("| accelerator | threads | build s (CPU s) |"), "{out}");
    assert!(out.contains("| BVH / Embree | 1 |"), "{out}");
    assert!(out.contains("| pt, 1 spp | 1 |"), "{out}");
    assert!(out.trim_end().ends_with("MB."), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("bench.json")).expect("bench.json written"))
            .expect("bench.json is JSON");
    assert_eq!(json["camera_rays"], 48);
    assert_eq!(json["rows"].as_array().map(Vec::len), Some(3));
    assert_eq!(json["path_tracer"][0]["threads"], 1);
}

/// Every verb that takes a scene takes Mitsuba XML, with the same import warnings: `render`,
/// `info`, `reference` and `converge` (which refused it as malformed TOML).
#[test]
fn every_scene_verb_takes_mitsuba_xml_with_its_warnings() {
    let dir = temp_dir("xml-verbs");
    // An integrator plexus substitutes: the import warning every scene verb must print, line 2.
    let xml = mitsuba_scene("\n  <integrator type=\"sppm\"/>", "camera", "");
    std::fs::write(dir.path().join("floor.xml"), xml).unwrap();
    let runs: [&[&str]; 4] = [
        &["render", "floor.xml", "--spp", "2", "--threads", "1", "--out", "render.exr"],
        &["info", "floor.xml"],
        &["reference", "floor.xml", "--spp", "4", "--threads", "1", "--out", "ref.exr"],
        &[
            "converge",
            "floor.xml",
            "--reference",
            "ref.exr",
            "--integrators",
            "pt",
            "--times",
            "0.2",
            "--seeds",
            "1",
            "--threads",
            "1",
        ],
    ];
    let mut warnings_of_render = None;
    for args in runs {
        let o = plexus(args, dir.path());
        let err = stderr(&o);
        assert!(o.status.success(), "plexus {args:?}: {err}");
        let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("warning: ")).collect();
        assert!(
            warnings.iter().any(|w| w.contains("floor.xml:2: integrator 'sppm'")),
            "plexus {args:?} printed no import warning: {err}"
        );
        let warnings: Vec<String> = warnings.iter().map(|w| w.to_string()).collect();
        let first = warnings_of_render.get_or_insert_with(|| warnings.clone());
        assert_eq!(&warnings, first, "plexus {args:?}: the import warnings differ from render's");
    }
    for file in ["render.exr", "ref.exr", "floor-converge.csv"] {
        assert!(dir.path().join(file).is_file(), "{file} missing");
    }
}
