//! Every script in scripts/ runs: a smoke check each, cheap (seconds), so that a script users and CI
//! rely on cannot rot unseen. The one-off study scripts live in docs/lab/scripts/ and are not checked.
//!
//! Each script gets the strongest check its dependencies allow here:
//! - a **real run** at a tiny size where everything it needs is in the repository and the built
//!   binary (`bench-bdpt-vs-pt.sh`, `bench-mlt.sh` with `fig4_table.py`, `bench-time-budgets.sh`,
//!   `large-scene.py`, `large-scene.sh`, `stress_second_interrupt.py`, `plexus-binary.sh`,
//!   `same-images.sh`);
//! - a run against a **stand-in** for the expensive program it drives, whose recorded arguments are
//!   then checked against the real one: `make-references.sh` (a stand-in `plexus` that records each
//!   call: every scene it names exists and every flag is one `plexus reference --help` lists) and
//!   `fuzz.sh` (a stand-in `cargo`: the test target and the test it names exist, and the exit code
//!   follows the failures kept);
//! - `--help` where the script has one and needs nothing external for it (`benchmarks.sh`, which
//!   renders for half an hour and rewrites docs/benchmarks.md otherwise);
//! - a **syntax check only** for the scripts that drive an external peer or rewrite committed files:
//!   `crosscheck.py`, `peers.py` and `peers.sh` (Mitsuba 3 and numpy in a venv), `import-scenes.sh`
//!   (rewrites scenes/imported/ from the Mitsuba sources), `benchmarks_page.py` (rewrites
//!   docs/benchmarks.md).
//!
//! `every_script_has_a_smoke_check` fails when a script is added to scripts/ without one.

use crate::common::binary::temp_dir;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn plexus_bin() -> &'static str {
    env!("CARGO_BIN_EXE_plexus")
}

/// The scripts this file checks, and how.
const CHECKED: &[(&str, &str)] = &[
    ("bench-bdpt-vs-pt.sh", "run"),
    ("bench-mlt.sh", "run"),
    ("bench-time-budgets.sh", "run"),
    ("benchmarks.sh", "--help where it has one, else syntax"),
    ("benchmarks_page.py", "syntax"),
    ("crosscheck.py", "syntax"),
    ("fig4_table.py", "run (by bench-mlt.sh) and usage"),
    ("fuzz.sh", "stand-in cargo"),
    ("import-scenes.sh", "syntax"),
    ("large-scene.py", "run"),
    ("large-scene.sh", "run"),
    ("make-references.sh", "stand-in plexus"),
    ("peers.py", "syntax"),
    ("peers.sh", "syntax"),
    ("plexus-binary.sh", "run"),
    ("same-images.sh", "run"),
    ("stress_second_interrupt.py", "run"),
];

fn script(name: &str) -> PathBuf {
    root().join("scripts").join(name)
}

/// Runs `program args` in the repository root with `env`, as CI would (no progress bars).
fn run(program: &str, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(program);
    c.args(args).current_dir(root()).env("CI", "true");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap_or_else(|e| panic!("{program} {args:?}: {e}"))
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn assert_ok(what: &str, o: &Output) -> String {
    let t = text(o);
    assert!(o.status.success(), "{what} failed ({:?}):\n{t}", o.status);
    t
}

/// The shipped Cornell box at `size`×`size` in `dir` (it names no other file, so a copy renders).
fn small_cornell(dir: &Path, size: u32) -> PathBuf {
    let scene = std::fs::read_to_string(root().join("scenes/cornell-box.toml")).expect("cornell-box.toml");
    let lines: Vec<String> = scene
        .lines()
        .map(|l| if l.starts_with("resolution") { format!("resolution = [{size}, {size}]") } else { l.to_string() })
        .collect();
    assert!(lines.iter().any(|l| l.starts_with("resolution")), "cornell-box.toml has no resolution line");
    let path = dir.join("cornell-small.toml");
    std::fs::write(&path, lines.join("\n")).expect("write scene");
    path
}

#[test]
fn every_script_has_a_smoke_check() {
    let mut present: Vec<String> = std::fs::read_dir(root().join("scripts"))
        .expect("scripts/")
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    present.sort();
    let checked: Vec<String> = CHECKED.iter().map(|(n, _)| n.to_string()).collect();
    let unchecked: Vec<&String> = present.iter().filter(|p| !checked.contains(p)).collect();
    let missing: Vec<&String> = checked.iter().filter(|c| !present.contains(c)).collect();
    assert!(
        unchecked.is_empty() && missing.is_empty(),
        "scripts without a smoke check: {unchecked:?}; checks of scripts that are gone: {missing:?} \
         (add a check to tests/commands/scripts.rs, or move a one-off study to docs/lab/scripts/)"
    );
}

/// Every script parses: `bash -n` (or `sh -n` for `#!/bin/sh` scripts) and Python's own parser.
#[test]
fn every_script_parses() {
    for (name, _) in CHECKED {
        let path = script(name);
        let path_s = path.to_str().expect("utf-8 path");
        let o = if name.ends_with(".py") {
            run("python3", &["-c", "import ast, sys; ast.parse(open(sys.argv[1]).read(), sys.argv[1])", path_s], &[])
        } else {
            let first = std::fs::read_to_string(&path).expect("read script").lines().next().unwrap_or("").to_string();
            let shell = if first.contains("/sh") { "sh" } else { "bash" };
            run(shell, &["-n", path_s], &[])
        };
        assert_ok(&format!("parsing scripts/{name}"), &o);
    }
}

/// benchmarks.sh renders for half an hour and rewrites docs/benchmarks.md, so only its `--help` is
/// run, and only when the script handles `--help` (an older one would take it for its first
/// argument and start the benchmark).
#[test]
fn benchmarks_sh_prints_its_usage() {
    let source = std::fs::read_to_string(script("benchmarks.sh")).expect("read benchmarks.sh");
    if !source.contains("--help)") {
        println!("scripts/benchmarks.sh has no --help: checked for syntax only");
        return;
    }
    let t = assert_ok(
        "scripts/benchmarks.sh --help",
        &run("bash", &[script("benchmarks.sh").to_str().unwrap(), "--help"], &[]),
    );
    assert!(t.contains("Usage: scripts/benchmarks.sh"), "{t}");
}

/// `plexus_binary` takes $PLEXUS, and refuses a missing binary or scene with one line naming it.
#[test]
fn plexus_binary_sh_finds_the_binary_and_refuses_what_is_missing() {
    let helper = script("plexus-binary.sh");
    let call = |plexus: &str, scene: &str| {
        run(
            "bash",
            &["-c", &format!("source '{}'; plexus_binary probe {scene}; echo \"found $plexus\"", helper.display())],
            &[("PLEXUS", plexus)],
        )
    };
    let t = assert_ok("plexus_binary with $PLEXUS", &call(plexus_bin(), "scenes/cornell-box.toml"));
    assert!(t.contains(&format!("found {}", plexus_bin())), "{t}");
    let missing = call("/nonexistent/plexus", "");
    assert!(!missing.status.success() && text(&missing).contains("probe: no plexus binary at '/nonexistent/plexus'"));
    let no_scene = call(plexus_bin(), "scenes/no-such-scene.toml");
    assert!(!no_scene.status.success() && text(&no_scene).contains("scene 'scenes/no-such-scene.toml' not found"));
}

#[test]
fn bench_bdpt_vs_pt_sh_runs() {
    let dir = temp_dir("bench-bdpt-vs-pt");
    let scene = small_cornell(dir.path(), 16);
    let out = dir.path().join("out");
    let t = assert_ok(
        "scripts/bench-bdpt-vs-pt.sh",
        &run(
            "bash",
            &[script("bench-bdpt-vs-pt.sh").to_str().unwrap(), scene.to_str().unwrap()],
            &[
                ("PLEXUS", plexus_bin()),
                ("THREADS", "1"),
                ("PT_SPP", "1"),
                ("BDPT_SPP", "1"),
                ("LIGHT_SPP", "1"),
                ("OUTDIR", out.to_str().unwrap()),
            ],
        ),
    );
    for name in ["pt", "bdpt", "light"] {
        assert!(t.contains(&format!("| {name} | 1 | 1 |")), "no {name} row:\n{t}");
    }
}

/// bench-mlt.sh renders PSSMLT, MMLT and RJMLT and prints its tables, the last by fig4_table.py.
#[test]
fn bench_mlt_sh_runs_with_fig4_table() {
    let dir = temp_dir("bench-mlt");
    let scene = small_cornell(dir.path(), 16);
    let out = dir.path().join("out");
    let t = assert_ok(
        "scripts/bench-mlt.sh",
        &run(
            "bash",
            &[script("bench-mlt.sh").to_str().unwrap(), scene.to_str().unwrap()],
            &[
                ("PLEXUS", plexus_bin()),
                ("TIME", "0.5"),
                ("THREADS", "1"),
                ("BOOTSTRAP", "2000"),
                ("OUTDIR", out.to_str().unwrap()),
            ],
        ),
    );
    for row in ["| PSSMLT |", "| MMLT |", "| RJMLT |", "RJMLT jumps in all:", "| depth | (a) RJMLT small steps |"] {
        assert!(t.contains(row), "no '{row}' in the output:\n{t}");
    }
    let usage = run("python3", &[script("fig4_table.py").to_str().unwrap()], &[]);
    assert!(!usage.status.success() && text(&usage).contains("Usage: scripts/fig4_table.py"));
}

#[test]
fn bench_time_budgets_sh_runs() {
    let dir = temp_dir("bench-time-budgets");
    let t = assert_ok(
        "scripts/bench-time-budgets.sh",
        &run(
            "bash",
            &[script("bench-time-budgets.sh").to_str().unwrap()],
            &[("PLEXUS", plexus_bin()), ("TIME", "0.2"), ("THREADS", "1"), ("OUTDIR", dir.path().to_str().unwrap())],
        ),
    );
    for name in ["pt", "bdpt", "light", "pssmlt", "mmlt", "rjmlt"] {
        assert!(t.contains(&format!("| {name} | 0.2 |")), "no {name} row:\n{t}");
    }
}

/// large-scene.py writes a (small) grid and its scene, which `plexus info` loads; large-scene.sh
/// measures its load with each accelerator (it needs /usr/bin/time, Debian's `time` package).
#[test]
fn large_scene_scripts_run_at_a_tiny_size() {
    let dir = temp_dir("large-scene");
    let d = dir.path().to_str().unwrap();
    assert_ok(
        "scripts/large-scene.py",
        &run("python3", &[script("large-scene.py").to_str().unwrap(), d, "--quads", "8"], &[]),
    );
    let info = assert_ok(
        "plexus info on the generated scene",
        &run(plexus_bin(), &["info", &format!("{d}/large-scene.toml"), "--json"], &[]),
    );
    let json: serde_json::Value = serde_json::from_str(&info).expect("info --json");
    assert_eq!(json["triangles"].as_u64(), Some(2 * 8 * 8 + 2), "8×8 quads and the light's two triangles: {json}");
    if Path::new("/usr/bin/time").exists() {
        let t = assert_ok(
            "scripts/large-scene.sh",
            &run("bash", &[script("large-scene.sh").to_str().unwrap(), d], &[("PLEXUS", plexus_bin())]),
        );
        assert!(t.contains("| embree | 1 |") && t.contains("| bvh | 1 |"), "{t}");
    } else {
        println!("/usr/bin/time is missing (Debian's `time` package): large-scene.sh checked for syntax only");
    }
}

/// same-images.sh finds a binary the same as itself and tells a different one apart: the second
/// "binary" is the real one with every `--seed` value changed, so its images differ.
#[test]
fn same_images_sh_tells_same_from_different_binaries() {
    let dir = temp_dir("same-images");
    let args = ["--scenes", "cornell-box", "--integrators", "pt,pmlt", "--size", "8x8", "--spp", "1"];
    let script = script("same-images.sh");
    let script = script.to_str().expect("utf-8 path");
    let same = run("bash", &[&[script, plexus_bin(), plexus_bin()][..], &args].concat(), &[]);
    let t = assert_ok("same-images.sh with one binary twice", &same);
    assert_eq!(t.lines().filter(|l| l.starts_with("same cornell-box")).count(), 2, "{t}");

    let other_seed = dir.path().join("plexus-other-seed");
    std::fs::write(
        &other_seed,
        format!(
            "#!/bin/sh\nfor a in \"$@\"; do\n  shift\n  if [ \"$prev\" = --seed ]; then a=$((a + 1)); fi\n  \
             set -- \"$@\" \"$a\"; prev=$a\ndone\nexec {} \"$@\"\n",
            plexus_bin()
        ),
    )
    .expect("write stand-in");
    std::process::Command::new("chmod").args(["+x", other_seed.to_str().unwrap()]).status().expect("chmod");
    let differ = run("bash", &[&[script, plexus_bin(), other_seed.to_str().unwrap()][..], &args].concat(), &[]);
    let t = text(&differ);
    assert_eq!(differ.status.code(), Some(1), "a different binary must fail the check:\n{t}");
    assert_eq!(t.lines().filter(|l| l.starts_with("DIFF cornell-box")).count(), 2, "{t}");
    // The shrunk scene copies are removed.
    let leftovers = std::fs::read_dir(root().join("scenes"))
        .expect("scenes/")
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(".same-images-"))
        .count();
    assert_eq!(leftovers, 0, "same-images.sh left its scene copies in scenes/");
}

#[test]
fn stress_second_interrupt_py_runs_once() {
    let t = assert_ok(
        "scripts/stress_second_interrupt.py",
        &run("python3", &[script("stress_second_interrupt.py").to_str().unwrap(), "1", plexus_bin()], &[]),
    );
    assert!(t.contains(": 1 runs, 0 failed"), "{t}");
}

/// A stand-in for a program: a shell script that appends its arguments, one call per line, to `log`
/// and exits with `status`.
fn stand_in(dir: &Path, name: &str, log: &Path, status: i32) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\necho \"$@\" >> '{}'\nexit {status}\n", log.display())).expect("write");
    let mut perm = std::fs::metadata(&path).expect("stat").permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perm, 0o755);
    std::fs::set_permissions(&path, perm).expect("chmod");
    path
}

/// make-references.sh with a stand-in `plexus`: every call is `reference SCENE ... --out
/// references/...`, every scene exists, and every flag is one `plexus reference` accepts.
#[test]
fn make_references_sh_calls_plexus_reference_with_valid_arguments() {
    let dir = temp_dir("make-references");
    let log = dir.path().join("calls.log");
    let fake = stand_in(dir.path(), "plexus", &log, 0);
    assert_ok(
        "scripts/make-references.sh",
        &run("sh", &[script("make-references.sh").to_str().unwrap(), "4"], &[("PLEXUS", fake.to_str().unwrap())]),
    );
    let help = assert_ok("plexus reference --help", &run(plexus_bin(), &["reference", "--help"], &[]));
    let calls = std::fs::read_to_string(&log).expect("the stand-in was called");
    assert!(calls.lines().count() >= 8, "{calls}");
    for call in calls.lines() {
        let args: Vec<&str> = call.split_whitespace().collect();
        assert_eq!(args.first(), Some(&"reference"), "{call}");
        assert!(root().join(args[1]).is_file(), "scene {} does not exist: {call}", args[1]);
        for flag in args.iter().filter(|a| a.starts_with("--")) {
            assert!(help.contains(&format!("{flag} ")), "plexus reference has no {flag}: {call}");
        }
        let out = args.iter().position(|a| *a == "--out").map(|i| args[i + 1]).expect("--out");
        assert!(out.starts_with("references/") && out.ends_with(".exr"), "{call}");
    }
}

/// fuzz.sh with a stand-in `cargo`: it runs the fuzz harness's replay test at low priority with the
/// seed, time and directory given, and its exit code is whether failing inputs were kept.
#[test]
fn fuzz_sh_runs_the_harness_and_reports_kept_failures() {
    let dir = temp_dir("fuzz-sh");
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).expect("mkdir");
    let log = dir.path().join("calls.log");
    stand_in(&bin, "cargo", &log, 0);
    let keep = dir.path().join("keep");
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let fuzz = |keep: &Path| {
        run("bash", &[script("fuzz.sh").to_str().unwrap(), "7", "12345", keep.to_str().unwrap()], &[("PATH", &path)])
    };
    assert_ok("scripts/fuzz.sh without failures", &fuzz(&keep));
    let call = std::fs::read_to_string(&log).expect("cargo was called");
    assert_eq!(call.trim(), "test --release --test commands fuzz::replay -- --ignored --nocapture");
    let harness =
        std::fs::read_to_string(root().join("tests/commands/fuzz/mod.rs")).expect("tests/commands/fuzz/mod.rs");
    for needle in ["fn replay", "PLEXUS_FUZZ_SEED", "PLEXUS_FUZZ_SECONDS", "PLEXUS_FUZZ_KEEP"] {
        assert!(harness.contains(needle), "tests/commands/fuzz/mod.rs has no {needle}, which fuzz.sh relies on");
    }
    std::fs::create_dir_all(&keep).expect("mkdir keep");
    std::fs::write(keep.join("fail-1.input"), "x").expect("write");
    let failed = fuzz(&keep);
    assert!(!failed.status.success(), "fuzz.sh exited 0 with a kept failure:\n{}", text(&failed));
}
