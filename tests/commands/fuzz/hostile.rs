//! The inputs a hostile download can hand plexus: files that are not files, deep and exploding
//! XML, damaged states and shards, an import directory already full of names (the kinds of the
//! module docs of `main.rs` past the first three).

use std::path::{Path, PathBuf};

use super::*;
use crate::common::inputs::{mitsuba_scene, mkfifo, serialized_triangles};

/// The shared Mitsuba scene (`common::inputs::mitsuba_scene`) with `extra` before `</scene>`.
pub(crate) fn mitsuba(extra: &str) -> String {
    mitsuba_scene("", "camera", extra)
}

/// A fresh, empty directory `name` in `dir` for one case.
pub(crate) fn fresh(dir: &Path, name: &str) -> PathBuf {
    let d = dir.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create the case directory");
    d
}

/// A file-type case: a file the scene names (a mesh, a texture, an environment map, an XML
/// include, or the scene itself) is `/dev/zero`, a directory or a FIFO. Exit 2 with one line
/// naming it, at once: a reader that opens it blocks (FIFO) or reads for ever (`/dev/zero`).
pub(crate) fn file_type_case(seed: u64, dir: &Path) -> Result<(), Failure> {
    let mut rng = Rng(seed);
    let d = fresh(dir, "file-type");
    let target = match rng.below(3) {
        0 => "/dev/zero".to_string(),
        1 => {
            std::fs::create_dir(d.join("a-directory")).expect("create directory");
            "a-directory".to_string()
        }
        _ => {
            mkfifo(&d.join("a-fifo"));
            "a-fifo".to_string()
        }
    };
    let quoted = toml::Value::String(target.clone());
    let (scene_name, text) = match rng.below(5) {
        0 => (
            "s.toml",
            tiny_scene(
                "[8, 6]",
                &format!(
                    "[[shapes]]\ntype = \"{}\"\nfile = {quoted}\nmaterial = \"floor\"\n",
                    rng.pick(&["obj", "ply"])
                ),
            ),
        ),
        1 => (
            "s.toml",
            tiny_scene(
                "[8, 6]",
                &format!(
                    "[materials.tex]\ntype = \"diffuse\"\nreflectance = {{ texture = \"bitmap\", file = {quoted} }}\n\
                     [[shapes]]\ntype = \"quad\"\nmaterial = \"tex\"\n"
                ),
            ),
        ),
        2 => ("s.toml", tiny_scene("[8, 6]", &format!("[environment]\ntype = \"image\"\nfile = {quoted}\n"))),
        3 => ("s.xml", mitsuba(&format!("<include filename=\"{target}\"/>"))),
        _ => (target.as_str(), String::new()),
    };
    if !text.is_empty() {
        std::fs::write(d.join(scene_name), &text).expect("write scene");
    }
    let args: Vec<&str> = if rng.chance(0.5) {
        vec!["info", scene_name]
    } else {
        vec!["render", scene_name, "--spp", "1", "--threads", "1", "--out", "o.exr"]
    };
    one_line_error(run_watched(&args, &d), &target).map_err(|what| Failure {
        seed,
        what: format!("{scene_name} naming {target}, args {args:?}: {what}"),
        input: text.into_bytes(),
    })
}

/// A nesting case: Mitsuba XML nested 2 to 30,000 levels deep (BSDFs or plain elements), or
/// a DAG of includes fanning out 2–3 ways over up to 30 levels (2^30 to 3^30 elements at the top,
/// no cycle).
/// Exit 0, or exit 2 with one line; never a stack overflow, an abort or a hang.
pub(crate) fn nesting_case(seed: u64, dir: &Path) -> Result<(), Failure> {
    let mut rng = Rng(seed);
    let d = fresh(dir, "nesting");
    let (text, shape) = if rng.chance(0.5) {
        // Half log-uniform in [2, 30,000] (shallow trees, either side of the bound of 256), half
        // uniform in [15,000, 30,000] (deep enough to overflow a recursive reader's 8 MiB stack).
        let unit = (rng.next() >> 11) as f64 / (1u64 << 53) as f64;
        let depth =
            if rng.chance(0.5) { (2.0 * 15_000f64.powf(unit)) as usize } else { 15_000 + (15_000.0 * unit) as usize };
        let (open, close) = match rng.below(3) {
            0 => ("<bsdf type=\"twosided\">", "</bsdf>"),
            1 => ("<group>", "</group>"),
            _ => ("<transform name=\"to_world\">", "</transform>"),
        };
        let inner = if rng.chance(0.5) { "<bsdf type=\"diffuse\"/>" } else { "" };
        let nested = format!("{}{inner}{}", open.repeat(depth), close.repeat(depth));
        let nested = if rng.chance(0.5) { format!("<shape type=\"sphere\">{nested}</shape>") } else { nested };
        (mitsuba(&nested), format!("{open} nested {depth} deep"))
    } else {
        // Each level includes the one below it 2-3 times (and sometimes the one below that): at
        // least 2^levels elements.
        let levels = 1 + rng.below(30);
        std::fs::write(d.join("l0.xml"), mitsuba("")).expect("write leaf");
        let mut top = String::new();
        for k in 1..=levels {
            let fan = 2 + rng.below(2);
            let includes: String = (0..fan)
                .map(|i| {
                    format!("<include filename=\"l{}.xml\"/>", k - 1 - if i == 0 { 0 } else { rng.below(k.min(2)) })
                })
                .collect();
            top = format!("<scene version=\"3.0.0\">{includes}</scene>\n");
            std::fs::write(d.join(format!("l{k}.xml")), &top).expect("write level");
        }
        std::fs::write(d.join("s.xml"), &top).expect("write top");
        (top, format!("includes fanning out over {levels} levels"))
    };
    if text.starts_with("<scene version=\"3.0.0\">\n") {
        std::fs::write(d.join("s.xml"), &text).expect("write scene");
    }
    let outcome = run_watched(&["info", "s.xml"], &d);
    let result = match &outcome {
        Some((Some(0), _)) => Ok(()),
        _ => one_line_error(outcome, ""),
    };
    result.map_err(|what| Failure {
        seed,
        what: format!("XML of {shape} ({} bytes): {what}", text.len()),
        input: text.into_bytes(),
    })
}

/// The states the corruption cases start from, made once per run by the binary under test: a
/// whole render interrupted after its first pass, and shards 0/2 and 1/2 of another.
pub(crate) struct States {
    dir: PathBuf,
    interrupted: Vec<u8>,
    shards: [Vec<u8>; 2],
}

pub(crate) fn make_states(dir: &Path) -> Result<States, String> {
    let d = fresh(dir, "states");
    std::fs::write(d.join("s.toml"), tiny_scene("[16, 12]", "")).expect("write scene");
    let run = |args: &[&str], want: i32| match run_watched(args, &d) {
        Some((Some(c), _)) if c == want => Ok(()),
        other => Err(format!("making a state with {args:?}: {other:?}")),
    };
    run(&["render", "s.toml", "--spp", "700", "--threads", "1", "--out", "a.exr", "--stop-at-pass", "1"], 130)?;
    // 128 samples per pixel at 32×32 pixels make two passes of 64 (a shard is at least one pass).
    std::fs::write(d.join("small.toml"), tiny_scene("[32, 32]", "")).expect("write scene");
    for k in 0..2 {
        let (shard, out) = (format!("{k}/2"), format!("shard{k}.pxstate"));
        run(&["render", "small.toml", "--spp", "128", "--threads", "1", "--shard", &shard, "--out", &out], 0)?;
    }
    let read = |name: &str| std::fs::read(d.join(name)).map_err(|e| format!("{name}: {e}"));
    Ok(States { interrupted: read("a.pxstate")?, shards: [read("shard0.pxstate")?, read("shard1.pxstate")?], dir: d })
}

/// A state-corruption case: a state with bits flipped, truncated, or with a slice of another state
/// spliced in, resumed (or merged with an intact shard). Any change is refused with one line
/// naming the file (the state ends with a SHA-256 of the rest): never exit 0, which would write an
/// image of another render, never a panic or an abort on a length read from the damaged bytes.
pub(crate) fn state_case(seed: u64, states: &States) -> Result<(), Failure> {
    let mut rng = Rng(seed);
    let merge = rng.chance(0.4);
    let which = rng.below(2);
    let original = if merge { &states.shards[which] } else { &states.interrupted };
    let other = if merge { &states.interrupted } else { &states.shards[rng.below(2)] };
    let mut bytes = original.clone();
    for _ in 0..1 + rng.below(3) {
        let i = rng.below(bytes.len());
        match rng.below(4) {
            0 => bytes.truncate(i),
            1 | 2 => {
                for _ in 0..1 + rng.below(4) {
                    let j = rng.below(bytes.len());
                    bytes[j] ^= 1 << rng.below(8);
                }
            }
            _ => {
                let from = rng.below(other.len());
                let slice = &other[from..(from + 1 + rng.below(256)).min(other.len())];
                let end = (i + rng.below(2 * slice.len())).min(bytes.len());
                bytes.splice(i..end, slice.iter().copied());
            }
        }
        if bytes.is_empty() {
            bytes.push(0);
        }
    }
    if bytes == *original {
        let j = rng.below(bytes.len());
        bytes[j] ^= 1;
    }
    std::fs::write(states.dir.join("bad.pxstate"), &bytes).expect("write corrupted state");
    let _ = std::fs::remove_file(states.dir.join("r.exr"));
    let intact = format!("shard{}.pxstate", 1 - which);
    let args: Vec<&str> = if merge {
        if which == 0 {
            vec!["merge", "bad.pxstate", &intact, "--out", "r.exr"]
        } else {
            vec!["merge", &intact, "bad.pxstate", "--out", "r.exr"]
        }
    } else {
        vec!["resume", "bad.pxstate", "--out", "r.exr"]
    };
    one_line_error(run_watched(&args, &states.dir), "bad.pxstate").map_err(|what| Failure {
        seed,
        what: format!("corrupted state ({} of {} bytes), args {args:?}: {what}", bytes.len(), original.len()),
        input: bytes,
    })
}

/// What a path was before the import, to compare after it.
#[derive(Debug, PartialEq)]
pub(crate) enum Existing {
    Link(PathBuf),
    File(Vec<u8>),
    Directory,
}

pub(crate) fn existing(path: &Path) -> Option<Existing> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    Some(if meta.file_type().is_symlink() {
        Existing::Link(std::fs::read_link(path).ok()?)
    } else if meta.is_dir() {
        Existing::Directory
    } else {
        Existing::File(std::fs::read(path).ok()?)
    })
}

/// An import-write case: `plexus import` of a scene with `.serialized` meshes into a directory
/// where names the import may write (its PLY meshes and their de-duplicated names, the TOML, the
/// stats) already exist as links to a sentinel file outside it, files with other content, or
/// directories. The sentinel and every existing entry are unchanged afterwards, and the import
/// exits 0 or 2 with one line.
pub(crate) fn import_case(seed: u64, dir: &Path, sentinel: &Path) -> Result<(), Failure> {
    const SENTINEL: &[u8] = b"the sentinel: nothing may write here\n";
    let mut rng = Rng(seed);
    let d = fresh(dir, "import");
    std::fs::write(sentinel, SENTINEL).expect("write sentinel");
    std::fs::create_dir_all(d.join("a")).expect("create a/");
    std::fs::create_dir_all(d.join("b")).expect("create b/");
    std::fs::write(d.join("a/m.serialized"), serialized_triangles(1)).expect("write a/m.serialized");
    std::fs::write(d.join("b/m.serialized"), serialized_triangles(3)).expect("write b/m.serialized");
    let mut shapes = String::new();
    for _ in 0..1 + rng.below(4) {
        let (file, index) = if rng.chance(0.4) { ("a/m.serialized", 0) } else { ("b/m.serialized", rng.below(3)) };
        shapes += &format!(
            "<shape type=\"serialized\"><string name=\"filename\" value=\"{file}\"/>\
             <integer name=\"shape_index\" value=\"{index}\"/></shape>\n"
        );
    }
    let xml = mitsuba(&shapes);
    std::fs::write(d.join("scene.xml"), &xml).expect("write scene");
    let out = *rng.pick(&["scene.toml", "out/scene.toml"]);
    if out.starts_with("out/") {
        std::fs::create_dir(d.join("out")).expect("create out/");
    }
    let out_dir = if out.starts_with("out/") { d.join("out") } else { d.clone() };
    let mut names: Vec<String> = vec!["scene.json".into(), "m.ply".into()];
    for m in 0..3 {
        names.push(format!("m_{m}.ply"));
        for k in 2..5 {
            names.push(format!("m_{m}-{k}.ply"));
        }
    }
    let mut before = Vec::new();
    for name in names {
        if !rng.chance(0.3) {
            continue;
        }
        let path = out_dir.join(&name);
        match rng.below(3) {
            0 => std::os::unix::fs::symlink(sentinel, &path).expect("symlink"),
            1 => std::fs::write(&path, format!("the user's own {name}\n")).expect("write file"),
            _ => std::fs::create_dir(&path).expect("create directory"),
        }
        before.push((name.clone(), existing(&path)));
    }
    let args = ["import", "scene.xml", "--out", out];
    let outcome = run_watched(&args, &d);
    let mut problems = Vec::new();
    match &outcome {
        Some((Some(0), _)) => {}
        _ => {
            if let Err(e) = one_line_error(outcome.clone(), "") {
                problems.push(e);
            }
        }
    }
    if std::fs::read(sentinel).ok().as_deref() != Some(SENTINEL) {
        problems.push("the sentinel outside the directory changed".into());
    }
    for (name, was) in &before {
        let now = existing(&out_dir.join(name));
        if &now != was {
            problems.push(format!("{name} was {was:?}, is {now:?}"));
        }
    }
    if problems.is_empty() {
        return Ok(());
    }
    let existing_names: Vec<&str> = before.iter().map(|(n, _)| n.as_str()).collect();
    Err(Failure {
        seed,
        what: format!("import --out {out} over existing {existing_names:?}: {}", problems.join("; ")),
        input: xml.into_bytes(),
    })
}
