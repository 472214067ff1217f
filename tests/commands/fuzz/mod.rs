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
//! `PLEXUS_FUZZ_SEED=S PLEXUS_FUZZ_CASES=1 cargo test --release --test commands fuzz::replay -- --ignored`.
//! `scripts/fuzz.sh SECONDS` runs the same harness from a random seed for a given time.
//! `PLEXUS_FUZZ_BINARY=PATH` runs the binary cases against another build of plexus (to check that
//! a kind of case catches the defect an older build has).
//!
//! Layout: this file is the harness (the cases' schedule, the watchdog, the property each outcome
//! must have, the first three kinds); `mutate.rs` holds the mutators, `hostile.rs` the four
//! hostile kinds.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use toml::Value;

mod hostile;
mod mutate;

use crate::common::binary::{run_within, temp_dir, tiny_scene};
use hostile::{file_type_case, import_case, make_states, nesting_case, state_case};
use mutate::{corrupt, mutated_scene};

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
    run_within(&binary(), args, cwd, WATCHDOG)
        .map(|o| (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned()))
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
