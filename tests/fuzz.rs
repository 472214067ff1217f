//! Property-based fuzzing: the shipped scenes, mutated at random (keys deleted, added or given
//! values of other types and extreme values; text truncated, bytes flipped, lines dropped or
//! repeated), the mesh (OBJ, ASCII and binary PLY) and EXR readers fed truncated and corrupted
//! files, and the inputs a hostile download can hand plexus (files that are not files, deep XML,
//! damaged states, an import directory already full of names). Seven kinds of case:
//!
//! - **render** (the binary, as a user runs it): a mutated scene rendered at 8×6 pixels and 1
//!   sample per pixel (or the scene's budget) on one thread, with a random integrator. It must exit
//!   0 with a finite image, or exit 2 with exactly one stderr line `error: ...` naming its culprit
//!   (the scene file, the integrator setting or the option). Never a panic, an abort, a signal,
//!   exit 1 or a non-finite pixel.
//! - **scene load** and **file read** (in the test process, through `plexus::scene::load_scene`,
//!   because each binary start costs about 0.35 s of CPU in dynamic linking alone): the load returns
//!   a scene or one line naming the scene file; it never panics.
//! - **file type** (binary, `info` or `render`): a mesh, texture, environment map or XML include
//!   the scene names, or the scene itself, is `/dev/zero`, a directory or a FIFO: exit 2 with one
//!   line naming it (a reader that opened it blocked for ever or read until memory ran out).
//! - **nesting** (binary, `info`): Mitsuba XML nested 2 to 30,000 deep, or includes fanning out
//!   over up to 30 levels: exit 0 or exit 2 with one line (a recursive reader overflowed its
//!   stack; 2^30 included elements ran for minutes).
//! - **state corruption** (binary, `resume` or `merge`): an interrupted render's `.pxstate` or a
//!   shard with bits flipped, truncated or spliced with another state: exit 2 with one line naming
//!   it (a damaged film resumed or merged with exit 0 into another image).
//! - **import write** (binary, `import`): the names the import may write already exist as links
//!   to a sentinel outside the directory, files of other content or directories: the sentinel
//!   and every such entry unchanged, exit 0 or exit 2 with one line (the import wrote through a
//!   link).
//!
//! Shares: seeds ≡ 0, 1, 2, 3 (mod 50) are the four last kinds, 2% each (19 of the suite's 240
//! seeds; the states they damage are made once per run, by three more binary starts); of the
//! rest, [`RENDER_SHARE`] are renders and the others split evenly between scene loads and file
//! reads. The new kinds are quick except the include fan-outs, which plexus refuses only after
//! reading its bound of 2^22 elements (~5-10 s each on a loaded machine).
//!
//! **The one wall-clock limit of the suite**: each case runs under a watchdog of [`WATCHDOG`]
//! seconds, a hang detector only. A case takes well under a second (a binary start, an 8×6 render
//! at 1 spp, veach-ajar's meshes), an include fan-out up to ~10 s; 60 s is ample slack on a loaded
//! machine, so only a real hang (a budget nobody could finish, a reader that never returns, a FIFO
//! opened for reading) trips it.
//!
//! The mutator is a seeded SplitMix64 (no new dependency): a failure is reproduced by its seed,
//! `PLEXUS_FUZZ_SEED=S PLEXUS_FUZZ_CASES=1 cargo test --release --test fuzz replay -- --ignored`.
//! `scripts/fuzz.sh SECONDS` runs the same harness from a random seed for a given time.
//! `PLEXUS_FUZZ_BINARY=PATH` runs the binary cases against another build of plexus (to check that
//! a kind of case catches the defect an older build has).

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use toml::Value;

mod common;
use common::binary::{temp_dir, tiny_scene};

/// Seconds after which a case is declared hung (see the module documentation).
const WATCHDOG: u64 = 60;
/// Cases in the suite. About a tenth are binary renders (`RENDER_SHARE`); the file took 60 s on
/// 2 cores under a load average of 11 (the renders dominate: ~1.4 s each there, 0.35 s idle),
/// and 42 s under a load average of 7 with the four hostile-input kinds added.
const CASES: u64 = 240;
/// The share of render cases among the seeds not ≡ 0-3 (mod 50) (the rest split evenly between
/// scene loads and file reads).
const RENDER_SHARE: f64 = 0.1;

/// SplitMix64 (Steele et al. 2014): a tiny, well-mixed seeded generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
    fn chance(&mut self, p: f64) -> bool {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64 <= p
    }
}

const INTS: &[i64] = &[-1, 0, 1, 2, 3, 7, 64, 1 << 31, 1 << 32, 1 << 53, i64::MAX, i64::MIN, 65537];
const FLOATS: &[f64] = &[
    0.0,
    -0.0,
    -1.0,
    0.5,
    1.0,
    1.5,
    90.0,
    180.0,
    1e-45,
    1e-30,
    1e-12,
    1e12,
    1e30,
    3.4e38,
    1e300,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
];
const STRINGS: &[&str] = &[
    "",
    "x",
    "pt",
    "bdpt",
    "light",
    "mmlt",
    "pssmlt",
    "rjmlt",
    "diffuse",
    "mirror",
    "dielectric",
    "conductor",
    "plastic",
    "quad",
    "box",
    "sphere",
    "disk",
    "obj",
    "ply",
    "constant",
    "image",
    "embree",
    "bvh",
    "balance",
    "/dev/zero",
    "/",
    "missing.obj",
    "s.toml",
    "ünïcödé",
];
const KEYS: &[&str] = &[
    "type",
    "scale",
    "radiance",
    "resolution",
    "fov",
    "file",
    "material",
    "emission",
    "transform",
    "spp",
    "time",
    "threads",
    "seed",
    "max_depth",
    "bootstrap",
    "chains",
    "two_sided",
    "subdivisions",
    "roughness",
    "ior",
    "bogus",
];

fn random_value(rng: &mut Rng, depth: u32) -> Value {
    match rng.below(if depth > 1 { 4 } else { 6 }) {
        0 => Value::Integer(*rng.pick(INTS)),
        1 => Value::Float(*rng.pick(FLOATS)),
        2 => Value::String(rng.pick(STRINGS).to_string()),
        3 => Value::Boolean(rng.chance(0.5)),
        4 => {
            let n = rng.below(5);
            // Mostly homogeneous numeric arrays: the shape of vectors, colours and resolutions.
            let float = rng.chance(0.5);
            Value::Array(
                (0..n)
                    .map(|_| {
                        if rng.chance(0.8) {
                            if float {
                                Value::Float(*rng.pick(FLOATS))
                            } else {
                                Value::Integer(*rng.pick(INTS))
                            }
                        } else {
                            random_value(rng, depth + 1)
                        }
                    })
                    .collect(),
            )
        }
        _ => {
            let mut t = toml::Table::new();
            for _ in 0..rng.below(3) {
                t.insert(rng.pick(KEYS).to_string(), random_value(rng, depth + 1));
            }
            Value::Table(t)
        }
    }
}

#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Index(usize),
}

fn paths(v: &Value, prefix: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    match v {
        Value::Table(t) => {
            for (k, child) in t {
                prefix.push(Seg::Key(k.clone()));
                out.push(prefix.clone());
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(a) => {
            for (i, child) in a.iter().enumerate() {
                prefix.push(Seg::Index(i));
                out.push(prefix.clone());
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn get_mut<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    let mut cur = v;
    for s in path {
        cur = match (s, cur) {
            (Seg::Key(k), Value::Table(t)) => t.get_mut(k)?,
            (Seg::Index(i), Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// One structural mutation of the scene: replace a value, delete a key or element, or add a key.
fn mutate_value(rng: &mut Rng, root: &mut Value) {
    let mut all = Vec::new();
    paths(root, &mut Vec::new(), &mut all);
    if all.is_empty() {
        return;
    }
    let path = rng.pick(&all).clone();
    let (parent_path, last) = path.split_at(path.len() - 1);
    let op = rng.below(4);
    let new = random_value(rng, 0);
    let Some(parent) = get_mut(root, parent_path) else { return };
    match (op, &last[0], parent) {
        (0, Seg::Key(k), Value::Table(t)) => {
            t.remove(k);
        }
        (0, Seg::Index(i), Value::Array(a)) => {
            a.remove(*i);
        }
        (1, _, Value::Table(t)) => {
            t.insert(rng.pick(KEYS).to_string(), new);
        }
        (_, Seg::Key(k), Value::Table(t)) => {
            t.insert(k.clone(), new);
        }
        (_, Seg::Index(i), Value::Array(a)) => a[*i] = new,
        _ => {}
    }
}

/// One textual mutation: truncate, flip a byte, drop or repeat a line.
fn mutate_text(rng: &mut Rng, text: &mut Vec<u8>) {
    if text.is_empty() {
        return;
    }
    match rng.below(4) {
        0 => text.truncate(rng.below(text.len())),
        1 => {
            let i = rng.below(text.len());
            text[i] ^= 1 << rng.below(8);
        }
        _ => {
            let lines: Vec<&[u8]> = text.split(|&b| b == b'\n').collect();
            let k = rng.below(lines.len());
            let repeat = rng.chance(0.5);
            let mut out = Vec::with_capacity(text.len() + 64);
            for (i, l) in lines.iter().enumerate() {
                if i == k && !repeat {
                    continue;
                }
                out.extend_from_slice(l);
                out.push(b'\n');
                if i == k {
                    out.extend_from_slice(l);
                    out.push(b'\n');
                }
            }
            *text = out;
        }
    }
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The shipped scenes, parsed, with file references made absolute and an 8×6 camera (the
/// mutations may still make it larger).
fn shipped_scenes() -> Vec<(String, Value)> {
    let dir = repo().join("scenes");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("scenes/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    names.sort();
    names
        .into_iter()
        .map(|p| {
            let mut v: Value = toml::from_str(&std::fs::read_to_string(&p).expect("read scene")).expect("scene toml");
            let absolute = |f: &mut Value| {
                if let Value::String(s) = f {
                    *s = dir.join(&*s).to_string_lossy().into_owned();
                }
            };
            if let Some(Value::Array(shapes)) = v.get_mut("shapes") {
                for s in shapes {
                    if let Some(f) = s.get_mut("file") {
                        absolute(f);
                    }
                }
            }
            if let Some(f) = v.get_mut("environment").and_then(|e| e.get_mut("file")) {
                absolute(f);
            }
            if let Some(Value::Table(c)) = v.get_mut("camera") {
                c.insert("resolution".into(), Value::Array(vec![Value::Integer(8), Value::Integer(6)]));
            }
            (p.file_name().expect("name").to_string_lossy().into_owned(), v)
        })
        .collect()
}

/// What a case ended as, when it broke the property.
struct Failure {
    seed: u64,
    what: String,
    input: Vec<u8>,
}

/// Runs the binary under the watchdog; `None` when it had to be killed.
fn run_watched(args: &[&str], cwd: &Path) -> Option<(Option<i32>, String)> {
    let mut child = Command::new(binary())
        .args(args)
        .current_dir(cwd)
        .env("CI", "true")
        .env_remove("RUST_BACKTRACE")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn plexus");
    // Read stderr on a thread so a chatty child cannot block on a full pipe.
    let mut pipe = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = pipe.read_to_string(&mut s);
        s
    });
    let deadline = Instant::now() + Duration::from_secs(WATCHDOG);
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let err = reader.join().unwrap_or_default();
            return Some((status.code(), err));
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Checks the property for one finished run; `image` is read when it exited 0.
fn check_outcome(
    outcome: Option<(Option<i32>, String)>,
    image: Option<&Path>,
    culprits: &[&str],
) -> Result<(), String> {
    let Some((code, err)) = outcome else { return Err(format!("hung: still running after {WATCHDOG} s")) };
    if err.contains("panicked") || err.contains("RUST_BACKTRACE") {
        return Err(format!("panic: {err}"));
    }
    match code {
        Some(0) => {
            if let Some(path) = image {
                let img = plexus::film::exr_io::read_exr(path).map_err(|e| format!("exit 0 but no image: {e}"))?;
                if !img.all_finite() {
                    return Err("exit 0 with non-finite pixels".into());
                }
            }
            Ok(())
        }
        Some(2) => {
            let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
            let [line] = lines.as_slice() else { return Err(format!("exit 2 with {} lines: {err}", lines.len())) };
            if !line.starts_with("error: ") {
                return Err(format!("exit 2 without 'error: ': {err}"));
            }
            if !culprits.iter().any(|c| line.contains(c)) {
                return Err(format!("exit 2 naming none of {culprits:?}: {err}"));
            }
            Ok(())
        }
        Some(c) => Err(format!("exit {c}: {err}")),
        None => Err(format!("killed by a signal: {err}")),
    }
}

/// A shipped scene mutated 1–3 times (structurally, then sometimes as text).
fn mutated_scene(rng: &mut Rng, scenes: &[(String, Value)]) -> (String, Vec<u8>) {
    let (name, scene) = rng.pick(scenes);
    let mut value = scene.clone();
    for _ in 0..1 + rng.below(3) {
        mutate_value(rng, &mut value);
    }
    let mut text = toml::to_string(&value).unwrap_or_default().into_bytes();
    if rng.chance(0.25) {
        mutate_text(rng, &mut text);
    }
    (name.clone(), text)
}

/// A render case: a mutated scene rendered by the binary on one thread.
fn render_case(seed: u64, scenes: &[(String, Value)], dir: &Path) -> Result<(), Failure> {
    let mut rng = Rng(seed);
    let (name, text) = mutated_scene(&mut rng, scenes);
    std::fs::write(dir.join("s.toml"), &text).expect("write scene");
    let out = dir.join("o.exr");
    let _ = std::fs::remove_file(&out);
    let integrator = if rng.chance(0.5) { None } else { Some(*rng.pick(plexus::integrator::INTEGRATOR_NAMES)) };
    let mut args = vec!["render", "s.toml", "--threads", "1", "--out", "o.exr"];
    if let Some(i) = integrator {
        args.extend(["--integrator", i]);
        if i.ends_with("mlt") {
            args.extend(["--set", "bootstrap=1000", "--set", "chains=8"]);
        }
    }
    if rng.chance(0.8) {
        args.extend(["--spp", "1"]);
    }
    let outcome = run_watched(&args, dir);
    check_outcome(outcome, Some(&out), &["s.toml", "integrator", "--"]).map_err(|what| Failure {
        seed,
        what: format!("render of mutated {name}, args {args:?}: {what}"),
        input: text,
    })
}

/// Loads `dir/s.toml` in this process under the watchdog: a scene, or one line naming the file;
/// never a panic or a hang.
fn load_in_process(dir: &Path) -> Result<(), String> {
    let path = dir.join("s.toml");
    let (send, recv) = std::sync::mpsc::channel();
    let p = path.clone();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(|| plexus::scene::load_scene(&p, None).map(|_| ()).map_err(|e| e.to_string()));
        let _ = send.send(r);
    });
    match recv.recv_timeout(Duration::from_secs(WATCHDOG)) {
        Err(_) => Err(format!("hung: the load still running after {WATCHDOG} s")),
        Ok(Err(_)) => Err("the load panicked".into()),
        Ok(Ok(Ok(()))) => Ok(()),
        Ok(Ok(Err(msg))) => {
            if msg.contains('\n') || !msg.starts_with(&path.display().to_string()) {
                Err(format!("not one line naming the scene file: {msg}"))
            } else {
                Ok(())
            }
        }
    }
}

/// A scene-load case: a mutated scene loaded in this process.
fn load_case(seed: u64, scenes: &[(String, Value)], dir: &Path) -> Result<(), Failure> {
    let mut rng = Rng(seed);
    let (name, text) = mutated_scene(&mut rng, scenes);
    std::fs::write(dir.join("s.toml"), &text).expect("write scene");
    load_in_process(dir).map_err(|what| Failure { seed, what: format!("load of mutated {name}: {what}"), input: text })
}

/// A small mesh (a cube) as OBJ, ASCII PLY and binary PLY text.
fn mesh_files() -> Vec<(&'static str, Vec<u8>)> {
    let v: [[f32; 3]; 8] = [
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.],
        [0., 0., 1.],
        [1., 0., 1.],
        [1., 1., 1.],
        [0., 1., 1.],
    ];
    let f: [[u32; 4]; 6] = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 4, 7, 3]];
    let mut obj = String::from("# cube\n");
    for p in v {
        obj += &format!("v {} {} {}\nvn 0 0 1\nvt 0.5 0.5\n", p[0], p[1], p[2]);
    }
    for q in f {
        obj += &format!(
            "f {}/{}/{} {}/{}/{} {}/{}/{} {}/{}/{}\n",
            q[0] + 1,
            q[0] + 1,
            q[0] + 1,
            q[1] + 1,
            q[1] + 1,
            q[1] + 1,
            q[2] + 1,
            q[2] + 1,
            q[2] + 1,
            q[3] + 1,
            q[3] + 1,
            q[3] + 1
        );
    }
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
             element face 6\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let mut ascii = header("ascii");
    for p in v {
        ascii += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    for q in f {
        ascii += &format!("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
    }
    let mut binary = header("binary_little_endian").into_bytes();
    for p in v {
        for c in p {
            binary.extend(c.to_le_bytes());
        }
    }
    for q in f {
        binary.push(4);
        for i in q {
            binary.extend((i as i32).to_le_bytes());
        }
    }
    vec![("obj", obj.into_bytes()), ("ply", ascii.into_bytes()), ("ply", binary)]
}

/// Corrupts a file: truncate, flip bytes, overwrite a run with 0xff or with digits (huge counts),
/// or repeat a slice.
fn corrupt(rng: &mut Rng, bytes: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(3) {
        if bytes.is_empty() {
            return;
        }
        let i = rng.below(bytes.len());
        match rng.below(5) {
            0 => bytes.truncate(i),
            1 => bytes[i] ^= 1 << rng.below(8),
            2 => {
                for b in bytes.iter_mut().skip(i).take(1 + rng.below(8)) {
                    *b = 0xff;
                }
            }
            3 => {
                for b in bytes.iter_mut().skip(i).take(1 + rng.below(10)) {
                    *b = b'9';
                }
            }
            _ => {
                let end = (i + 1 + rng.below(64)).min(bytes.len());
                let slice = bytes[i..end].to_vec();
                bytes.splice(i..i, slice);
            }
        }
    }
}

/// A file-read case: a mesh or the shipped sky EXR corrupted, loaded in this process.
fn reader_case(seed: u64, meshes: &[(&str, Vec<u8>)], exr: &[u8], dir: &Path) -> Result<(), Failure> {
    let mut rng = Rng(seed);
    let (kind, mut bytes) = if rng.chance(0.35) {
        ("exr", exr.to_vec())
    } else {
        let (k, b) = rng.pick(meshes);
        (*k, b.clone())
    };
    corrupt(&mut rng, &mut bytes);
    let file = format!("m.{kind}");
    std::fs::write(dir.join(&file), &bytes).expect("write corrupted file");
    let extra = if kind == "exr" {
        format!("[environment]\ntype = \"image\"\nfile = \"{file}\"\n")
    } else {
        format!("[[shapes]]\ntype = \"{kind}\"\nfile = \"{file}\"\nmaterial = \"floor\"\n")
    };
    std::fs::write(dir.join("s.toml"), tiny_scene("[8, 6]", &extra)).expect("write scene");
    load_in_process(dir).map_err(|what| Failure { seed, what: format!("corrupted {file}: {what}"), input: bytes })
}

/// The binary the cases run: the one cargo built, or `PLEXUS_FUZZ_BINARY` (to point the harness
/// at another build, e.g. to check that a kind of case catches a defect an older build has).
fn binary() -> PathBuf {
    std::env::var_os("PLEXUS_FUZZ_BINARY").map_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_plexus")), PathBuf::from)
}

/// Exit 2 with exactly one stderr line `error: ...` containing `culprit`, within the watchdog.
fn one_line_error(outcome: Option<(Option<i32>, String)>, culprit: &str) -> Result<(), String> {
    let Some((code, err)) = outcome else { return Err(format!("hung: still running after {WATCHDOG} s")) };
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    match (code, lines.as_slice()) {
        (Some(2), [line]) if line.starts_with("error: ") && line.contains(culprit) => Ok(()),
        (Some(2), [line]) if line.starts_with("error: ") => Err(format!("exit 2 not naming {culprit}: {err}")),
        (Some(c), _) => Err(format!("exit {c} (expected 2 with one line naming {culprit}): {err}")),
        (None, _) => Err(format!("killed by a signal: {err}")),
    }
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().expect("UTF-8 path")).expect("no NUL");
    // SAFETY: `c` is a NUL-terminated path that outlives the call.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}

/// A Mitsuba scene (a floor under a lamp, 8×6 pixels) with `extra` before the closing tag.
fn mitsuba(extra: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <sensor type="perspective">
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

/// A fresh, empty directory `name` in `dir` for one case.
fn fresh(dir: &Path, name: &str) -> PathBuf {
    let d = dir.join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create the case directory");
    d
}

/// A file-type case: a file the scene names (a mesh, a texture, an environment map, an XML
/// include, or the scene itself) is `/dev/zero`, a directory or a FIFO. Exit 2 with one line
/// naming it, at once: a reader that opens it blocks (FIFO) or reads for ever (`/dev/zero`).
fn file_type_case(seed: u64, dir: &Path) -> Result<(), Failure> {
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
fn nesting_case(seed: u64, dir: &Path) -> Result<(), Failure> {
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
struct States {
    dir: PathBuf,
    interrupted: Vec<u8>,
    shards: [Vec<u8>; 2],
}

fn make_states(dir: &Path) -> Result<States, String> {
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
fn state_case(seed: u64, states: &States) -> Result<(), Failure> {
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

/// A `.serialized` file holding `meshes` one-triangle meshes (format version 4), each told apart
/// by its third vertex's height.
fn serialized(meshes: usize) -> Vec<u8> {
    use std::io::Write;
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
        z.write_all(&body).expect("compress");
        data.extend_from_slice(&z.finish().expect("compress"));
    }
    for o in &offsets {
        data.extend_from_slice(&o.to_le_bytes());
    }
    data.extend_from_slice(&(meshes as u32).to_le_bytes());
    data
}

/// What a path was before the import, to compare after it.
#[derive(Debug, PartialEq)]
enum Existing {
    Link(PathBuf),
    File(Vec<u8>),
    Directory,
}

fn existing(path: &Path) -> Option<Existing> {
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
fn import_case(seed: u64, dir: &Path, sentinel: &Path) -> Result<(), Failure> {
    const SENTINEL: &[u8] = b"the sentinel: nothing may write here\n";
    let mut rng = Rng(seed);
    let d = fresh(dir, "import");
    std::fs::write(sentinel, SENTINEL).expect("write sentinel");
    std::fs::create_dir_all(d.join("a")).expect("create a/");
    std::fs::create_dir_all(d.join("b")).expect("create b/");
    std::fs::write(d.join("a/m.serialized"), serialized(1)).expect("write a/m.serialized");
    std::fs::write(d.join("b/m.serialized"), serialized(3)).expect("write b/m.serialized");
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

/// Runs cases `seeds` and returns the failures (each kept in `keep`, when given, as
/// `fail-SEED.*` for reproduction).
fn run_cases(seeds: impl Iterator<Item = u64>, deadline: Option<Instant>, keep: Option<&Path>) -> (u64, Vec<Failure>) {
    let scenes = shipped_scenes();
    let meshes = mesh_files();
    let exr = std::fs::read(repo().join("scenes/environment/sky.exr")).expect("sky.exr");
    let tmp = temp_dir("fuzz");
    // Outside `tmp`, which the import cases write into.
    let sentinel = temp_dir("fuzz-sentinel");
    let mut states = None;
    let mut failures = Vec::new();
    let mut count = 0;
    for seed in seeds {
        if deadline.is_some_and(|d| Instant::now() > d) {
            break;
        }
        let mut pick = Rng(seed ^ 0x5eed);
        let result = match seed % 50 {
            0 => file_type_case(seed, tmp.path()),
            1 => nesting_case(seed, tmp.path()),
            2 => {
                if states.is_none() {
                    states = Some(make_states(tmp.path()));
                }
                match states.as_ref().expect("made above") {
                    Ok(s) => state_case(seed, s),
                    Err(e) => Err(Failure { seed, what: e.clone(), input: Vec::new() }),
                }
            }
            3 => import_case(seed, tmp.path(), &sentinel.path().join("sentinel")),
            _ if pick.chance(RENDER_SHARE) => render_case(seed, &scenes, tmp.path()),
            _ if pick.chance(0.5) => load_case(seed, &scenes, tmp.path()),
            _ => reader_case(seed, &meshes, &exr, tmp.path()),
        };
        count += 1;
        if let Err(f) = result {
            eprintln!("FUZZ FAILURE seed {}: {}", f.seed, f.what);
            if let Some(dir) = keep {
                let _ = std::fs::write(dir.join(format!("fail-{}.input", f.seed)), &f.input);
            }
            failures.push(f);
        }
    }
    (count, failures)
}

fn report(count: u64, failures: &[Failure]) {
    eprintln!("fuzz: {count} cases, {} failures", failures.len());
    assert!(
        failures.is_empty(),
        "{} of {count} cases broke the property:\n{}",
        failures.len(),
        failures.iter().map(|f| format!("seed {}: {}", f.seed, f.what)).collect::<Vec<_>>().join("\n")
    );
}

/// The suite's share: seeds 1..=`CASES`.
#[test]
fn mutated_scenes_and_files_exit_0_with_a_finite_image_or_2_with_one_line() {
    let (count, failures) = run_cases(1..=CASES, None, None);
    report(count, &failures);
}

/// The long run of `scripts/fuzz.sh`: random seeds from `PLEXUS_FUZZ_SEED` (a start) for
/// `PLEXUS_FUZZ_SECONDS`, or `PLEXUS_FUZZ_CASES` cases; failing inputs go to `PLEXUS_FUZZ_KEEP`.
#[test]
#[ignore = "long: run by scripts/fuzz.sh"]
fn replay() {
    let var = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    let start = var("PLEXUS_FUZZ_SEED").unwrap_or(1);
    let cases = var("PLEXUS_FUZZ_CASES").unwrap_or(u64::MAX - start);
    let deadline = var("PLEXUS_FUZZ_SECONDS").map(|s| Instant::now() + Duration::from_secs(s));
    let keep = std::env::var("PLEXUS_FUZZ_KEEP").ok().map(PathBuf::from);
    if let Some(k) = &keep {
        std::fs::create_dir_all(k).expect("create the keep directory");
    }
    let (count, failures) = run_cases(start..start.saturating_add(cases), deadline, keep.as_deref());
    report(count, &failures);
}
