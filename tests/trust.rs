//! What a downloaded scene, checkpoint or import can make plexus write: only what the user asked
//! for, where they asked. Each test is a way a hostile or careless input once wrote elsewhere or
//! replaced a file nobody asked to replace; each fails on a binary without its guard.

use std::io::Write;
use std::path::Path;

mod common;
use common::binary::{plexus, stderr, temp_dir, tiny_scene};

/// A Mitsuba scene (floor and lamp seen from above) whose sensor id is `sensor_id` and with
/// `extra` before the closing tag.
fn mitsuba(sensor_id: &str, extra: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <sensor type="perspective" id="{sensor_id}">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 3, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/><rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate y="2"/></transform>
    <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter>
  </shape>
{extra}
</scene>
"#
    )
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

/// An XML id with line breaks cannot add TOML to the imported scene: neither `render` of the XML
/// nor the TOML `import` writes gains an output elsewhere, and the TOML has no `[render]` output.
#[test]
fn an_xml_id_cannot_inject_outputs() {
    let dir = temp_dir("trust-inject");
    let elsewhere = temp_dir("trust-elsewhere");
    let target = elsewhere.path().join("x.png");
    let id = format!("cam&#10;[render]&#10;output = [&quot;{}&quot;]&#10;", target.display());
    std::fs::write(dir.path().join("scene.xml"), mitsuba(&id, "")).unwrap();
    let o = plexus(&["render", "scene.xml", "--spp", "1", "--threads", "1"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(files_in(elsewhere.path()).is_empty(), "wrote {:?}", files_in(elsewhere.path()));
    assert!(dir.path().join("scene.png").is_file());

    let o = plexus(&["import", "scene.xml", "--out", "scene.toml"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.path().join("scene.toml")).unwrap();
    let table: toml::Table = toml::from_str(&text).unwrap();
    assert!(table.get("render").and_then(|r| r.get("output")).is_none(), "{text}");
    assert!(text.lines().all(|l| !l.starts_with("output")), "{text}");
    // Rendering the imported TOML writes nothing elsewhere either.
    let o = plexus(&["render", "scene.toml", "--spp", "1", "--threads", "1"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(files_in(elsewhere.path()).is_empty());
}

/// A scene file names its outputs only below the directory the render runs in.
#[test]
fn scene_outputs_outside_the_current_directory_are_refused() {
    let dir = temp_dir("trust-outputs");
    let elsewhere = temp_dir("trust-outputs-elsewhere");
    let absolute = elsewhere.path().join("x.png");
    for output in [absolute.display().to_string(), "../x.png".into(), "a/../../x.png".into()] {
        let extra = format!("[render]\noutput = [{}]\n", toml::Value::String(output.clone()));
        std::fs::write(dir.path().join("s.toml"), tiny_scene("[8, 6]", &extra)).unwrap();
        let o = plexus(&["render", "s.toml", "--spp", "1", "--threads", "1"], dir.path());
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{output}: {err}");
        assert!(err.starts_with("error: ") && err.contains("render.output") && err.lines().count() == 1, "{err}");
    }
    assert!(files_in(elsewhere.path()).is_empty());
    // Below the current directory is fine.
    std::fs::create_dir(dir.path().join("out")).unwrap();
    let extra = "[render]\noutput = [\"./out/x.png\"]\n";
    std::fs::write(dir.path().join("s.toml"), tiny_scene("[8, 6]", extra)).unwrap();
    let o = plexus(&["render", "s.toml", "--spp", "1", "--threads", "1"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("out/x.png").is_file());
}

/// A `.serialized` file with one triangle mesh (format version 4).
fn write_serialized(path: &Path, meshes: usize) {
    let mut data = Vec::new();
    let mut offsets = Vec::new();
    for m in 0..meshes {
        offsets.push(data.len() as u64);
        data.extend_from_slice(&0x041Cu16.to_le_bytes());
        data.extend_from_slice(&4u16.to_le_bytes());
        let mut body = Vec::new();
        body.extend_from_slice(&0u32.to_le_bytes()); // flags: positions and indices only
        body.extend_from_slice(b"mesh\0");
        body.extend_from_slice(&3u64.to_le_bytes());
        body.extend_from_slice(&1u64.to_le_bytes());
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0 + m as f32] {
            body.extend_from_slice(&v.to_le_bytes());
        }
        for i in [0u32, 1, 2] {
            body.extend_from_slice(&i.to_le_bytes());
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).unwrap();
        data.extend_from_slice(&z.finish().unwrap());
    }
    for o in &offsets {
        data.extend_from_slice(&o.to_le_bytes());
    }
    data.extend_from_slice(&(meshes as u32).to_le_bytes());
    std::fs::write(path, data).unwrap();
}

/// `plexus import` converts `.serialized` meshes without writing through a link, replacing a file
/// it did not make, or letting two sources of the same name share one PLY.
#[test]
fn import_never_writes_through_links_or_replaces_files() {
    let dir = temp_dir("trust-serialized");
    let d = dir.path();
    std::fs::create_dir_all(d.join("a")).unwrap();
    std::fs::create_dir_all(d.join("b")).unwrap();
    write_serialized(&d.join("a/m.serialized"), 1);
    write_serialized(&d.join("b/m.serialized"), 2);
    let victim = temp_dir("trust-victim");
    let victim_file = victim.path().join("anything");
    std::fs::write(&victim_file, "keep me").unwrap();
    std::os::unix::fs::symlink(&victim_file, d.join("m_0.ply")).unwrap();
    std::fs::write(d.join("m_1.ply"), "a mesh of the user's").unwrap();
    let shapes = r#"
  <shape type="serialized"><string name="filename" value="a/m.serialized"/><integer name="shape_index" value="0"/></shape>
  <shape type="serialized"><string name="filename" value="b/m.serialized"/><integer name="shape_index" value="0"/></shape>
  <shape type="serialized"><string name="filename" value="b/m.serialized"/><integer name="shape_index" value="1"/></shape>"#;
    std::fs::write(d.join("scene.xml"), mitsuba("cam", shapes)).unwrap();
    let o = plexus(&["import", "scene.xml", "--out", "scene.toml"], d);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(std::fs::read_to_string(&victim_file).unwrap(), "keep me");
    assert!(d.join("m_0.ply").is_symlink());
    assert_eq!(std::fs::read_to_string(d.join("m_1.ply")).unwrap(), "a mesh of the user's");
    assert!(err.contains("m_0.ply' exists and holds something else"), "{err}");
    let toml = std::fs::read_to_string(d.join("scene.toml")).unwrap();
    let files: Vec<&str> = toml.lines().filter(|l| l.starts_with("file = ")).collect();
    assert_eq!(files, ["file = \"m_0-2.ply\"", "file = \"m_0-3.ply\"", "file = \"m_1-2.ply\""], "{toml}");
    // Three distinct meshes (the third vertex's height tells them apart).
    let o = plexus(&["info", "scene.toml", "--json"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    // Importing again reuses the identical files and writes no new ones.
    let before = files_in(d);
    let o = plexus(&["import", "scene.xml", "--out", "scene.toml"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(files_in(d), before);
}

/// `import --out` naming the XML itself is refused and leaves it; an import whose TOML would not
/// load leaves the TOML already there.
#[test]
fn import_keeps_the_input_and_a_good_toml() {
    let dir = temp_dir("trust-import-out");
    let d = dir.path();
    let xml = mitsuba("cam", "");
    std::fs::write(d.join("scene.xml"), &xml).unwrap();
    let o = plexus(&["import", "scene.xml", "--out", "scene.xml"], d);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(d.join("scene.xml")).unwrap(), xml);
    std::os::unix::fs::symlink("scene.xml", d.join("link.xml")).unwrap();
    let o = plexus(&["import", "link.xml", "--out", "scene.xml"], d);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(d.join("scene.xml")).unwrap(), xml);

    // Radiance beyond the loader's bound: the import converts, the TOML does not load.
    let bright = mitsuba("cam", "").replace("\"5, 5, 5\"", "\"1e30, 1e30, 1e30\"");
    std::fs::write(d.join("bright.xml"), bright).unwrap();
    std::fs::write(d.join("bright.toml"), "# the user's own scene\n").unwrap();
    let o = plexus(&["import", "bright.xml", "--out", "bright.toml"], d);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("not written"), "{err}");
    assert_eq!(std::fs::read_to_string(d.join("bright.toml")).unwrap(), "# the user's own scene\n");
}

/// The stats JSON beside an image replaces only an earlier render's record, never a user's file.
#[test]
fn the_stats_file_never_replaces_a_users_json() {
    let dir = temp_dir("trust-json");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), tiny_scene("[8, 6]", "")).unwrap();
    std::fs::write(d.join("notes.json"), "{\"mine\": true}\n").unwrap();
    let o = plexus(&["render", "s.toml", "--spp", "1", "--threads", "1", "--out", "notes.png"], d);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: ") && err.contains("notes.json") && err.lines().count() == 1, "{err}");
    assert_eq!(std::fs::read_to_string(d.join("notes.json")).unwrap(), "{\"mine\": true}\n");
    assert!(!d.join("notes.png").exists());
    let o = plexus(&["reference", "s.toml", "--spp", "1", "--threads", "1", "--out", "notes.exr"], d);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(d.join("notes.json")).unwrap(), "{\"mine\": true}\n");
    // A render's own record is replaced by the next render to the same name.
    for _ in 0..2 {
        let o = plexus(&["render", "s.toml", "--spp", "1", "--threads", "1", "--out", "img.png"], d);
        assert!(o.status.success(), "{}", stderr(&o));
    }
}

/// Without --checkpoint, an interrupted render saves its state beside its first image under a
/// name no other file has: an unrelated `<stem>.pxstate` stays as it was.
#[test]
fn an_interrupt_never_replaces_another_state_file() {
    let dir = temp_dir("trust-pxstate");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), tiny_scene("[16, 12]", "")).unwrap();
    std::fs::write(d.join("a.pxstate"), "another render's state").unwrap();
    let o = plexus(&["render", "s.toml", "--spp", "700", "--threads", "1", "--out", "a.exr", "--stop-at-pass", "1"], d);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert_eq!(std::fs::read_to_string(d.join("a.pxstate")).unwrap(), "another render's state");
    assert!(d.join("a.1.pxstate").is_file() && err.contains("a.1.pxstate"), "{err}");
    let o = plexus(&["resume", "a.1.pxstate"], d);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Without --out, resume writes only below the state file's directory, and says where first.
#[test]
fn resume_writes_only_below_the_state_files_directory() {
    let dir = temp_dir("trust-resume");
    let elsewhere = temp_dir("trust-resume-elsewhere");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), tiny_scene("[16, 12]", "")).unwrap();
    let far = elsewhere.path().join("far.exr");
    let args = ["render", "s.toml", "--spp", "700", "--threads", "1", "--checkpoint", "run.pxstate"];
    let o = plexus(&[&args[..], &["--out", far.to_str().unwrap(), "--stop-at-pass", "1"]].concat(), d);
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    for f in files_in(elsewhere.path()) {
        std::fs::remove_file(elsewhere.path().join(f)).unwrap();
    }
    let o = plexus(&["resume", "run.pxstate"], d);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: ") && err.contains("far.exr") && err.contains("--out"), "{err}");
    assert!(files_in(elsewhere.path()).iter().all(|f| !f.starts_with("far.")), "{:?}", files_in(elsewhere.path()));
    // With --out the user chooses.
    let o = plexus(&["resume", "run.pxstate", "--out", "near.exr"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    // Outputs below the state's directory resume as they are, named before rendering.
    std::fs::create_dir(d.join("sub")).unwrap();
    let o = plexus(&[&args[..], &["--out", "sub/img.exr", "--stop-at-pass", "1"]].concat(), d);
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let o = plexus(&["resume", "run.pxstate"], d);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("writes") && err.contains("sub/img.exr"), "{err}");
}
