//! What a downloaded scene, checkpoint or import can make plexus write: only what the user asked
//! for, where they asked. Each test is a way a hostile or careless input once wrote elsewhere or
//! replaced a file nobody asked to replace; each fails on a binary without its guard.

use std::path::Path;

use crate::common::binary::{plexus, plexus_within, stderr, temp_dir, tiny_scene};
use crate::common::inputs::{mitsuba_scene, mkfifo, serialized, serialized_triangles, SerializedMesh};

/// The shared Mitsuba scene with sensor id `sensor_id` and `tail` before `</scene>`.
fn mitsuba(sensor_id: &str, tail: &str) -> String {
    mitsuba_scene("", sensor_id, tail)
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

/// `plexus import` converts `.serialized` meshes without writing through a link, replacing a file
/// it did not make, or letting two sources of the same name share one PLY.
#[test]
fn import_never_writes_through_links_or_replaces_files() {
    let dir = temp_dir("trust-serialized");
    let d = dir.path();
    std::fs::create_dir_all(d.join("a")).unwrap();
    std::fs::create_dir_all(d.join("b")).unwrap();
    std::fs::write(d.join("a/m.serialized"), serialized_triangles(1)).unwrap();
    std::fs::write(d.join("b/m.serialized"), serialized_triangles(2)).unwrap();
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

/// A checkpoint write killed with SIGKILL leaves its hidden temporary file: the next write of
/// the same file removes it when the process that wrote it is gone from this machine, and leaves
/// a live process's (pid 1 here) and another machine's alone.
#[test]
fn a_killed_writers_temporary_files_are_removed() {
    let dir = temp_dir("trust-stale-temp");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), tiny_scene("[16, 12]", "")).unwrap();
    // The host name as the temporary names carry it: its letters, digits and underscores.
    let host: String = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .unwrap()
        .trim()
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    let mut child = std::process::Command::new("true").spawn().unwrap();
    let dead = child.id();
    child.wait().unwrap();
    let stale =
        [format!(".run.pxstate.plexus-tmp-{host}-{dead}-k1LLed"), format!(".img.plexus-tmp-{host}-{dead}-k1LLed.exr")];
    let kept = [
        format!(".run.pxstate.plexus-tmp-{host}-1-l1Ving"),
        format!(".run.pxstate.plexus-tmp-elsewhere-{dead}-r3Mote"),
    ];
    for name in stale.iter().chain(&kept) {
        std::fs::write(d.join(name), "partial").unwrap();
    }
    let args = ["render", "s.toml", "--spp", "4", "--threads", "1", "--checkpoint", "run.pxstate", "--out", "img.exr"];
    let o = plexus(&args, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let left = files_in(d);
    for name in &stale {
        assert!(!left.contains(name), "{name} was left: {left:?}");
    }
    for name in &kept {
        assert!(left.contains(name), "{name} was removed: {left:?}");
    }
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

/// One line `error: ...` containing every needle, exit 2.
fn assert_one_line_error(o: &std::process::Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: ") && err.trim_end().lines().count() == 1, "{err}");
    for n in needles {
        assert!(err.contains(n), "'{n}' not in: {err}");
    }
}

/// Textures, included XML files, scenes and states that are devices or FIFOs are one-line errors
/// at once: before, OpenImageIO blocked on a FIFO texture and read `/dev/zero` for ever, and a
/// FIFO include, scene or state file blocked its reader. An OBJ's `mtllib /dev/zero` opens
/// nothing (it read until memory ran out).
#[test]
fn devices_and_fifos_are_refused_by_every_reader() {
    let dir = temp_dir("trust-fifo");
    let d = dir.path();
    mkfifo(&d.join("fifo"));
    for file in ["/dev/zero", "fifo"] {
        let material = format!(
            "[materials.tex]\ntype = \"diffuse\"\nreflectance = {{ texture = \"bitmap\", file = \"{file}\" }}\n\
             [[shapes]]\ntype = \"quad\"\nmaterial = \"tex\"\n"
        );
        std::fs::write(d.join("tex.toml"), tiny_scene("[8, 6]", &material)).unwrap();
        let o = plexus_within(&["render", "tex.toml", "--spp", "1", "--threads", "1"], d, 20);
        assert_one_line_error(&o, &[file, "not a regular file"]);
    }
    std::fs::write(d.join("mtl.obj"), "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 0 1\nusemtl x\nf 1 2 3\n").unwrap();
    let shape = "[[shapes]]\ntype = \"obj\"\nfile = \"mtl.obj\"\nmaterial = \"floor\"\n";
    std::fs::write(d.join("mtl.toml"), tiny_scene("[8, 6]", shape)).unwrap();
    let o = plexus_within(&["info", "mtl.toml"], d, 20);
    assert!(o.status.success(), "{}", stderr(&o));

    let include = mitsuba("cam", "<include filename=\"fifo\"/>");
    std::fs::write(d.join("inc.xml"), include).unwrap();
    let o = plexus_within(&["info", "inc.xml"], d, 20);
    assert_one_line_error(&o, &["fifo", "not a regular file"]);
    mkfifo(&d.join("scene.toml"));
    let o = plexus_within(&["info", "scene.toml"], d, 20);
    assert_one_line_error(&o, &["scene.toml", "not a regular file"]);
    mkfifo(&d.join("run.pxstate"));
    let o = plexus_within(&["resume", "run.pxstate"], d, 20);
    assert_one_line_error(&o, &["run.pxstate", "not a regular file"]);
}

/// XML nested 20,000 deep (it overflowed the stack) and includes that double at every level
/// (2^30 elements without a cycle: it ran for minutes) are refused in seconds.
#[test]
fn deep_and_exploding_xml_is_refused() {
    let dir = temp_dir("trust-xml-size");
    let d = dir.path();
    let deep = format!("{}{}", "<bsdf type=\"twosided\">".repeat(20_000), "</bsdf>".repeat(20_000));
    std::fs::write(d.join("deep.xml"), mitsuba("cam", &deep)).unwrap();
    let o = plexus_within(&["info", "deep.xml"], d, 30);
    assert_one_line_error(&o, &["nested more than 256 deep"]);

    let mut level = mitsuba("cam", "");
    std::fs::write(d.join("l0.xml"), &level).unwrap();
    for k in 1..=30 {
        let prev = format!("l{}.xml", k - 1);
        level =
            format!("<scene version=\"3.0.0\"><include filename=\"{prev}\"/><include filename=\"{prev}\"/></scene>\n");
        std::fs::write(d.join(format!("l{k}.xml")), &level).unwrap();
    }
    let o = plexus_within(&["info", "l30.xml"], d, 60);
    assert_one_line_error(&o, &["elements", "refused as unbounded"]);
}

/// A `.serialized` header declaring 2^31 triangles in under 100 bytes is an error, not an abort on a
/// 24 GiB allocation.
#[test]
fn a_serialized_header_cannot_size_an_allocation() {
    let dir = temp_dir("trust-serialized-size");
    let d = dir.path();
    // Three vertices and no triangle data behind a header declaring 2^31 triangles.
    let mut lying = SerializedMesh::triangle(1.0);
    (lying.triangles, lying.declared_triangles) = (Vec::new(), 1 << 31);
    let data = serialized(&[lying]);
    assert!(data.len() < 100, "{} bytes", data.len());
    std::fs::write(d.join("big.serialized"), &data).unwrap();
    let shape = "<shape type=\"serialized\"><string name=\"filename\" value=\"big.serialized\"/></shape>";
    std::fs::write(d.join("scene.xml"), mitsuba("cam", shape)).unwrap();
    for verb in [&["info", "scene.xml"][..], &["import", "scene.xml"], &["render", "scene.xml", "--spp", "1"]] {
        let o = plexus_within(verb, d, 30);
        assert_one_line_error(&o, &["big.serialized"]);
    }
}

/// What a state records is checked: a flipped bit, a relabelled shard, a scene changed in an
/// included file, another sampling revision — each refused with one line where it resumed or
/// merged with exit 0 before.
#[test]
fn states_are_checked_before_they_are_used() {
    use plexus::state::StateFile;
    let dir = temp_dir("trust-states");
    let d = dir.path();
    // The scene: an XML that includes the file holding its floor's colour.
    let floor = |grey: &str| {
        format!(
            "<scene version=\"3.0.0\"><bsdf type=\"diffuse\" id=\"floor\"><rgb name=\"reflectance\" value=\"{grey}\"/></bsdf></scene>\n"
        )
    };
    std::fs::write(d.join("floor.xml"), floor("0.5, 0.5, 0.5")).unwrap();
    let scene = mitsuba("cam", "")
        .replace("<scene version=\"3.0.0\">", "<scene version=\"3.0.0\"><include filename=\"floor.xml\"/>")
        .replace(
            "<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5, 0.5, 0.5\"/></bsdf>",
            "<ref id=\"floor\"/>",
        );
    assert!(scene.contains("<ref id=\"floor\"/>"));
    std::fs::write(d.join("scene.xml"), scene).unwrap();
    let base = ["render", "scene.xml", "--spp", "2000", "--threads", "1", "--out", "a.exr"];
    let o = plexus_within(&[&base[..], &["--stop-at-pass", "1"]].concat(), d, 60);
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let bytes = std::fs::read(d.join("a.pxstate")).unwrap();

    // One flipped bit in the film.
    let mut flipped = bytes.clone();
    let at = flipped.len() / 2;
    flipped[at] ^= 0x10;
    std::fs::write(d.join("flipped.pxstate"), &flipped).unwrap();
    let o = plexus_within(&["resume", "flipped.pxstate", "--out", "f.exr"], d, 60);
    assert_one_line_error(&o, &["checksum"]);

    // Another sampling revision.
    let mut file = StateFile::from_bytes(&bytes, Path::new("a.pxstate")).unwrap();
    file.header.sampling_revision += 1;
    file.write(&d.join("old.pxstate")).unwrap();
    let o = plexus_within(&["resume", "old.pxstate", "--out", "o.exr"], d, 60);
    assert_one_line_error(&o, &["sampling revision"]);

    // The included file changed: resuming would blend two scenes.
    std::fs::write(d.join("floor.xml"), floor("0.9, 0.5, 0.5")).unwrap();
    let o = plexus_within(&["resume", "a.pxstate"], d, 60);
    assert_one_line_error(&o, &["another scene"]);
    std::fs::write(d.join("floor.xml"), floor("0.5, 0.5, 0.5")).unwrap();
    let o = plexus_within(&["resume", "a.pxstate"], d, 60);
    assert!(o.status.success(), "{}", stderr(&o));

    // Shards 0/3 and 1/3, the second relabelled as 2/3 (and its checksum made anew): merge
    // would sum shard 1 where shard 2 belongs.
    // 4100 samples per pixel: 8×6 pixels take passes of 1365, so each of three shards has work.
    let shard = |k: &str, out: &str| {
        let args = ["render", "scene.xml", "--spp", "4100", "--threads", "1", "--shard", k, "--out", out];
        let o = plexus_within(&args, d, 60);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    shard("0/3", "s0.pxstate");
    shard("1/3", "s1.pxstate");
    shard("1/3", "s2.pxstate");
    let mut relabelled = StateFile::read(&d.join("s2.pxstate")).unwrap();
    relabelled.header.shard = Some("2/3".parse().unwrap());
    relabelled.write(&d.join("s2.pxstate")).unwrap();
    let o = plexus_within(&["merge", "s0.pxstate", "s1.pxstate", "s2.pxstate", "--out", "m.exr"], d, 60);
    assert_one_line_error(&o, &["s2.pxstate", "labelled shard 2/3"]);
    let mut beyond = StateFile::read(&d.join("s1.pxstate")).unwrap();
    beyond.header.shard = Some(plexus::state::Shard { index: 7, count: 2 });
    beyond.write(&d.join("s7.pxstate")).unwrap();
    let o = plexus_within(&["merge", "s0.pxstate", "s7.pxstate", "--out", "m.exr"], d, 60);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// Values that mean nothing are refused, naming the value and its range, instead of rendering
/// something else: a sun's date and place (month 13, hour 99, latitude 1000), wavelengths of
/// ±1e30 nm, a roughness of 1e30 (which rendered with non-finite contributions dropped).
#[test]
fn meaningless_values_are_refused() {
    let dir = temp_dir("trust-values");
    let d = dir.path();
    for (param, value, needle) in [
        ("integer", "name=\"month\" value=\"13\"", "'month'"),
        ("float", "name=\"hour\" value=\"99\"", "'hour'"),
        ("float", "name=\"latitude\" value=\"1000\"", "'latitude'"),
    ] {
        let sun = format!("<emitter type=\"sun\"><{param} {value}/></emitter>");
        std::fs::write(d.join("sun.xml"), mitsuba("cam", &sun)).unwrap();
        let o = plexus_within(&["info", "sun.xml"], d, 30);
        assert_one_line_error(&o, &[needle, "must be in"]);
    }
    for spectrum in ["-1e30:1, 500:1", "400:1, 1e30:1"] {
        let bsdf =
            format!("<bsdf type=\"diffuse\" id=\"s\"><spectrum name=\"reflectance\" value=\"{spectrum}\"/></bsdf>");
        std::fs::write(d.join("spectrum.xml"), mitsuba("cam", &bsdf)).unwrap();
        let o = plexus_within(&["info", "spectrum.xml"], d, 30);
        assert_one_line_error(&o, &["wavelength", "nanometres"]);
    }
    let rough = "[materials.rough]\ntype = \"conductor\"\ncolour = 0.8\nroughness = 1e30\n\
                 [[shapes]]\ntype = \"quad\"\nmaterial = \"rough\"\n";
    std::fs::write(d.join("rough.toml"), tiny_scene("[8, 6]", rough)).unwrap();
    let o = plexus_within(&["info", "rough.toml"], d, 30);
    assert_one_line_error(&o, &["roughness", "[0, 100]"]);
}

/// Messages name what the user gave: a converted mesh the loader refuses is named by its
/// `.serialized` file and shape index (not the temporary PLY nobody saw); a broken texture's error
/// is the one line on stderr (libpng printed its own first); resume's refusal of the
/// state's own budget does not blame `--time`; a shard beyond the render's passes (or a chain
/// render's chains) is refused instead of rendering nothing with exit 0.
#[test]
fn messages_name_what_the_user_gave() {
    let dir = temp_dir("trust-messages");
    let d = dir.path();
    // A mesh whose triangle names vertex 5 of 3.
    let mut bad = SerializedMesh::triangle(1.0);
    bad.triangles = vec![[0, 1, 5]];
    let data = serialized(&[bad]);
    std::fs::write(d.join("bad.serialized"), &data).unwrap();
    let shape = "<shape type=\"serialized\"><string name=\"filename\" value=\"bad.serialized\"/></shape>";
    std::fs::write(d.join("scene.xml"), mitsuba("cam", shape)).unwrap();
    let o = plexus_within(&["info", "scene.xml"], d, 30);
    let err = stderr(&o);
    assert_one_line_error(&o, &["mesh 0 of", "bad.serialized"]);
    assert!(!err.contains(".tmp") && !err.contains("bad_0.ply"), "{err}");

    // A PNG texture cut off after its header: libpng's own report stays off stderr, whose one
    // line is plexus's error naming the file.
    std::fs::write(d.join("plain.toml"), tiny_scene("[4, 4]", "")).unwrap();
    let o = plexus_within(&["render", "plain.toml", "--spp", "1", "--out", "whole.png"], d, 30);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = std::fs::read(d.join("whole.png")).unwrap();
    std::fs::write(d.join("cut.png"), &png[..40]).unwrap();
    let textured = tiny_scene("[16, 12]", "").replacen(
        "reflectance = [0.5, 0.5, 0.5]",
        "reflectance = { texture = \"bitmap\", file = \"cut.png\" }",
        1,
    );
    std::fs::write(d.join("textured.toml"), textured).unwrap();
    let o = plexus_within(&["render", "textured.toml", "--spp", "1", "--out", "t.exr"], d, 30);
    assert_one_line_error(&o, &["cut.png"]);
    assert!(!stderr(&o).contains("libpng"), "{}", stderr(&o));

    // 6 samples per pixel on 32×32 make one pass: shard 1/3 would render nothing.
    std::fs::write(d.join("s.toml"), tiny_scene("[32, 32]", "")).unwrap();
    let o = plexus_within(&["render", "s.toml", "--spp", "6", "--shard", "1/3", "--out", "s1.pxstate"], d, 30);
    assert_one_line_error(&o, &["shard 1/3 would render nothing", "at most 1 shards"]);
    assert!(!d.join("s1.pxstate").exists());
    // A chain render's shards split its chains: with 2 chains, shard 2/3 would hold none.
    for integrator in ["pssmlt", "pmlt"] {
        let args = ["render", "s.toml", "--integrator", integrator, "--set", "chains=2", "--set", "bootstrap=1000"];
        let o = plexus_within(&[&args[..], &["--spp", "4", "--shard", "2/3", "--out", "c2.pxstate"]].concat(), d, 30);
        assert_one_line_error(&o, &["shard 2/3 would render nothing", "2 chains", "at most 2 shards"]);
        assert!(!d.join("c2.pxstate").exists());
    }

    // A state whose own budget is out of range (as a damaged or hand-made one could be).
    let o = plexus_within(&["render", "s.toml", "--spp", "700", "--out", "a.exr", "--stop-at-pass", "1"], d, 60);
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let mut state = plexus::state::StateFile::read(&d.join("a.pxstate")).unwrap();
    state.header.budget = plexus::integrator::Budget::SamplesPerPixel(u64::MAX);
    state.write(&d.join("a.pxstate")).unwrap();
    let o = plexus_within(&["resume", "a.pxstate"], d, 30);
    let err = stderr(&o);
    assert_one_line_error(&o, &["the state's budget"]);
    assert!(!err.contains("--time"), "{err}");
}

/// A state whose integrator part was rewritten and given a valid checksum (as a hand-made file
/// would be) is refused or resumed, never a crash: MMLT's chains are range-checked on restore. The
/// rewrite sets, one at a time, every 64-bit word of the part that holds 4 (the chains' sample
/// stream count among them) to 2^60: unchecked, the stream count sized a multi-petabyte
/// allocation and aborted. Each rewrite must give exit 0 or one `error: ...` line with exit 2.
#[test]
fn a_rewritten_chain_state_never_crashes() {
    use plexus::state::StateFile;
    let dir = temp_dir("trust-chain-state");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), tiny_scene("[16, 12]", "")).unwrap();
    let args = ["render", "s.toml", "--integrator", "mmlt", "--spp", "400", "--threads", "1", "--out", "a.exr"];
    let o = plexus_within(
        &[&args[..], &["--set", "bootstrap=2000", "--set", "chains=2", "--set", "max_depth=2", "--stop-at-pass", "1"]]
            .concat(),
        d,
        60,
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let original = StateFile::read(&d.join("a.pxstate")).unwrap();
    let four = 4u64.to_le_bytes();
    let places: Vec<usize> =
        (0..original.state.part.len().saturating_sub(8)).filter(|&i| original.state.part[i..i + 8] == four).collect();
    assert!(!places.is_empty());
    for &at in places.iter().take(64) {
        let mut file = original.clone();
        file.state.part[at..at + 8].copy_from_slice(&(1u64 << 60).to_le_bytes());
        file.write(&d.join("b.pxstate")).unwrap();
        let o = plexus_within(&["resume", "b.pxstate", "--out", "b.exr"], d, 60);
        let err = stderr(&o);
        match o.status.code() {
            Some(0) => {}
            // The outputs resume names before rendering, then the one error line.
            Some(2) => {
                let errors: Vec<&str> = err.lines().filter(|l| !l.starts_with("resume b.pxstate: writes")).collect();
                assert!(errors.len() == 1 && errors[0].starts_with("error: "), "byte {at}: {err}");
            }
            other => panic!("byte {at}: exit {other:?}: {err}"),
        }
    }
}

/// The path-space chains (pmlt, emlt) restored from a rewritten state given a valid checksum:
/// at 48 places spread over the part, a NaN (f32 and f64 bit patterns), an infinity or a huge
/// count written over the bytes there; every resume exits 0 or with one `error: ...` line, never
/// a crash: a restored path's vertices, roles and values are range-checked before they become
/// rays (`ChainUnit::check_restored`).
#[test]
fn a_rewritten_path_space_state_never_crashes() {
    use plexus::state::StateFile;
    let dir = temp_dir("trust-path-state");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), tiny_scene("[16, 12]", "")).unwrap();
    for (integrator, settings) in [
        ("pmlt", &["--set", "chains=4", "--set", "bootstrap=2000", "--set", "max_depth=3"][..]),
        ("emlt", &["--set", "ensemble_size=4", "--set", "bootstrap=2000", "--set", "max_depth=3"][..]),
    ] {
        let args = ["render", "s.toml", "--integrator", integrator, "--spp", "64", "--threads", "1", "--out", "a.exr"];
        let o = plexus_within(&[&args[..], settings, &["--stop-at-pass", "1"]].concat(), d, 60);
        assert_eq!(o.status.code(), Some(130), "{integrator}: {}", stderr(&o));
        let original = StateFile::read(&d.join("a.pxstate")).unwrap();
        let len = original.state.part.len();
        assert!(len > 64, "{integrator}: a part of {len} bytes");
        let patterns: [&[u8]; 4] = [
            &f32::NAN.to_le_bytes(),
            &f64::NAN.to_le_bytes(),
            &f32::INFINITY.to_le_bytes(),
            &(1u64 << 60).to_le_bytes(),
        ];
        for k in 0..48 {
            let at = (len - 8) * k / 47;
            let pattern = patterns[k % patterns.len()];
            let mut file = original.clone();
            file.state.part[at..at + pattern.len()].copy_from_slice(pattern);
            file.write(&d.join("b.pxstate")).unwrap();
            let o = plexus_within(&["resume", "b.pxstate", "--out", "b.exr"], d, 60);
            let err = stderr(&o);
            match o.status.code() {
                Some(0) => {}
                Some(2) => {
                    let errors: Vec<&str> =
                        err.lines().filter(|l| !l.starts_with("resume b.pxstate: writes")).collect();
                    assert!(errors.len() == 1 && errors[0].starts_with("error: "), "{integrator} byte {at}: {err}");
                }
                other => panic!("{integrator} byte {at}: exit {other:?}: {err}"),
            }
        }
    }
}
