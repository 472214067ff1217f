//! The binary's side of interrupts, checkpoints, resume and merge (issues 19 and 21): a real
//! SIGINT, two in a row while previews are written, the one-line refusals (exit 2), and a merge
//! through the command line. The library's properties are in tests/commands/state.rs.

use std::path::Path;
use std::process::{Child, Command, Stdio};

use crate::common::binary::{plexus, stderr, temp_dir, tiny_scene};
use plexus::state::StateFile;

fn write(dir: &Path, name: &str, text: &str) -> String {
    std::fs::write(dir.join(name), text).expect("write test file");
    name.to_string()
}

fn spawn(args: &[&str], cwd: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_plexus"))
        .args(args)
        .current_dir(cwd)
        .env("CI", "true")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start plexus")
}

fn signal(child: &Child, signal: libc::c_int) {
    // SAFETY: `kill` with the pid of our own child process.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0, "kill");
}

/// Waits (polling, no time limit) until `path` exists: the render has reached its loop.
fn wait_for(path: &Path) {
    while !path.exists() {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

fn files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read json")).expect("parse json")
}

/// One real SIGINT during a render with a budget of hours (8×6 pixels, 2^30 samples per pixel,
/// passes of 2^16 samples, previews after every pass): exit 130 after the current pass, with the
/// image, the JSON (interrupted, the passes spent) and the checkpoint written and no temporary
/// file left; `plexus resume` then completes the render to a budget just past what was done.
#[test]
fn sigint_writes_image_json_and_checkpoint_then_resume_completes() {
    let tmp = temp_dir("sigint");
    let dir = tmp.path();
    let scene = write(dir, "s.toml", &tiny_scene("[8, 6]", ""));
    let args = [
        "render",
        &scene,
        "--spp",
        "1073741824",
        "--threads",
        "2",
        "--out",
        "o.exr",
        "--out",
        "o.png",
        "--checkpoint",
        "run.pxstate",
        "--checkpoint-every",
        "0.01",
        "--preview-every",
        "1e-9",
    ];
    let child = spawn(&args, dir);
    // The first periodic checkpoint: the handler is installed and passes are running.
    wait_for(&dir.join("run.pxstate"));
    signal(&child, libc::SIGINT);
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("plexus resume run.pxstate"), "{err}");
    assert_eq!(files(dir), ["o.exr", "o.json", "o.png", "run.pxstate", "s.toml"]);
    let stats = json(&dir.join("o.json"));
    assert_eq!(stats["run"]["interrupted"], true, "{stats}");
    let passes = stats["run"]["budget_spent"]["passes"].as_u64().expect("passes");
    let spp = stats["integrator_stats"]["spp"].as_u64().expect("spp");
    assert!(passes >= 1 && spp == passes * 1366, "{passes} passes, {spp} spp");
    let state = StateFile::read(&dir.join("run.pxstate")).expect("checkpoint readable");
    assert!(state.state.interrupted && state.state.passes_done == passes);

    // Two more passes' worth of samples, then the render is complete.
    let total = (spp + 2 * 1366).to_string();
    let o = plexus(&["resume", "run.pxstate", "--spp", &total], dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let stats = json(&dir.join("o.json"));
    assert_eq!(stats["run"]["complete"], true, "{stats}");
    assert_eq!(stats["integrator_stats"]["spp"].as_u64(), Some(spp + 2 * 1366), "{stats}");
    assert_eq!(stats["samples"].as_u64(), Some((spp + 2 * 1366) * 48), "{stats}");
    assert_eq!(files(dir), ["o.exr", "o.json", "o.png", "run.pxstate", "s.toml"]);
}

/// Two SIGINTs in a row while previews of a 256×192 image are written after every pass (so the
/// preview writer is busy most of the time): the second exits with 130, and leaves nothing but
/// complete outputs (no hidden temporary file, no output-check probe). Five runs, each signalled a
/// little later; on a handler that exits without the clean-up (signal-hook's
/// `register_conditional_shutdown`) a run that caught the writer left a `.o.plexus-tmp-*` file.
/// A handler that removed the registered temporary files and exited at once (main before
/// session 20) failed it in 2 of 40 runs: the output-check probe or the image's temporary file
/// came into being just before its name was registered. The race is rare, so this test only
/// catches it now and then; `scripts/stress_second_interrupt.py 600 OLD NEW` repeats the protocol:
/// 15 of 1,200 renders failed on the old handler, 0 of 1,200 on the new (two runs, session 20).
#[test]
fn a_second_interrupt_exits_and_leaves_only_complete_outputs() {
    let tmp = temp_dir("sigint2");
    let dir = tmp.path();
    let scene = write(dir, "s.toml", &tiny_scene("[256, 192]", ""));
    for run in 0..5u64 {
        let out_dir = dir.join(format!("run{run}"));
        std::fs::create_dir(&out_dir).expect("dir");
        let args = [
            "render",
            "../s.toml",
            "--time",
            "1000",
            "--threads",
            "1",
            "--set",
            "max_depth=1",
            "--out",
            "o.exr",
            "--out",
            "o.png",
            "--preview-every",
            "1e-9",
        ];
        let child = spawn(&args, &out_dir);
        wait_for(&out_dir.join("o.png"));
        std::thread::sleep(std::time::Duration::from_millis(7 * run));
        signal(&child, libc::SIGINT);
        // Apart, so that the kernel does not merge them into one pending signal.
        std::thread::sleep(std::time::Duration::from_millis(5));
        signal(&child, libc::SIGINT);
        let out = child.wait_with_output().expect("wait");
        assert_eq!(out.status.code(), Some(130), "run {run}: {}", String::from_utf8_lossy(&out.stderr));
        let outputs = ["o.exr", "o.json", "o.png", "o.pxstate"];
        let left: Vec<String> = files(&out_dir).into_iter().filter(|n| !outputs.contains(&n.as_str())).collect();
        assert!(left.is_empty(), "run {run} left {left:?}");
    }
    let _ = scene;
}

/// The signals a process running [`signals_during_a_write_child`] raises at itself, inside the
/// write of one file; its exit status, stdout and stderr, the files left in its directory and
/// the written file's text.
fn signals_during_a_write(signals: u32) -> (Option<i32>, String, String, Vec<String>, Option<String>) {
    let tmp = temp_dir(&format!("signals{signals}"));
    let out = Command::new(std::env::current_exe().expect("test binary"))
        .args(["--exact", "interrupt::signals_during_a_write_child", "--ignored", "--nocapture", "--test-threads", "1"])
        .env("PLEXUS_TEST_SIGNAL_CHILD", format!("{signals}"))
        .env("PLEXUS_TEST_SIGNAL_DIR", tmp.path())
        .output()
        .expect("run the child");
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    let written = std::fs::read_to_string(tmp.path().join("o.txt")).ok();
    (out.status.code(), text(&out.stdout), text(&out.stderr), files(tmp.path()), written)
}

/// Not a test of its own: the child process of the one below (it does nothing without
/// `PLEXUS_TEST_SIGNAL_CHILD`). Installs the handler, and writes `o.txt` through
/// `write_atomically`, raising SIGINT at itself that many times in the middle of the write
/// (`raise` runs the handler before it returns), then finishing the file.
#[test]
#[ignore = "run by second_signal_waits_for_the_file_being_written_and_a_third_does_not"]
fn signals_during_a_write_child() {
    use std::io::Write;
    let Ok(signals) = std::env::var("PLEXUS_TEST_SIGNAL_CHILD") else { return };
    let dir = std::path::PathBuf::from(std::env::var("PLEXUS_TEST_SIGNAL_DIR").expect("dir"));
    plexus::interrupt::install().expect("install the handler");
    let written = plexus::interrupt::write_atomically(
        &dir.join("o.txt"),
        false,
        |e| e,
        |_, file| {
            file.write_all(b"first half, ")?;
            for _ in 0..signals.parse::<u32>().expect("count") {
                // SAFETY: raising a signal at our own thread; the handler is installed.
                unsafe { libc::raise(libc::SIGINT) };
            }
            file.write_all(b"second half")?;
            println!("the write went on after the signals");
            std::io::stdout().flush()
        },
    );
    written.expect("write");
    println!("the process went on after the write");
}

/// Signals during the write of a file, without timing: a second one lets the write finish, puts
/// the complete file in place and exits with 130 when it is done (not before, and not later); a
/// third exits at once, removing the temporary file. The handler before session 20 exited at the
/// second signal: then the first case's child prints nothing and leaves no file, and fails this.
#[test]
fn second_signal_waits_for_the_file_being_written_and_a_third_does_not() {
    let (code, stdout, stderr, left, written) = signals_during_a_write(2);
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stdout.contains("the write went on after the signals"), "{stdout}\n{stderr}");
    assert!(!stdout.contains("the process went on after the write"), "{stdout}");
    assert!(stderr.contains("interrupted again: quitting as soon as the file being written is complete"), "{stderr}");
    assert_eq!(left, ["o.txt"]);
    assert_eq!(written.as_deref(), Some("first half, second half"));

    let (code, stdout, stderr, left, _) = signals_during_a_write(3);
    assert_eq!(code, Some(130), "{stderr}");
    assert!(!stdout.contains("the write went on"), "{stdout}");
    assert!(left.is_empty(), "{left:?}");
}

/// Resume and merge refuse, with one line and exit 2, a state of a changed scene (a mesh it
/// references), of another plexus version, of other settings, a file that is not a state, a
/// shard given to resume; shards need a sample budget and a .pxstate output; merge refuses
/// shards of different seeds. And shards merged on the command line give the whole render's image.
#[test]
fn resume_and_merge_refuse_what_does_not_belong_and_merge_matches_the_render() {
    let tmp = temp_dir("refuse");
    let dir = tmp.path();
    let mesh = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3\nf 1 3 4\n";
    write(dir, "floor.obj", mesh);
    let extra = "[[shapes]]\ntype = \"obj\"\nfile = \"floor.obj\"\nmaterial = \"floor\"\n";
    let scene = write(dir, "s.toml", &tiny_scene("[16, 12]", extra));
    let refused = |args: &[&str], expect: &str| {
        let o = plexus(args, dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: one line: {err}");
        assert!(err.starts_with("error: ") && err.contains(expect), "{args:?}: {err}");
    };
    let o = plexus(&["render", &scene, "--spp", "700", "--out", "a.exr", "--stop-at-pass", "1"], dir);
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(dir.join("a.pxstate").exists(), "an interrupted render saves its state beside the image");

    let edit = |f: &dyn Fn(&mut StateFile), name: &str| {
        let mut state = StateFile::read(&dir.join("a.pxstate")).expect("read");
        f(&mut state);
        state.write(&dir.join(name)).expect("write");
    };
    edit(&|s| s.header.plexus_version = "0.0.1".into(), "old.pxstate");
    refused(&["resume", "old.pxstate"], "written by plexus 0.0.1");
    edit(&|s| s.header.settings = "{\"max_depth\":2}".into(), "settings.pxstate");
    refused(&["resume", "settings.pxstate"], "settings");
    edit(&|s| s.header.shard = Some("0/2".parse().expect("shard")), "shard.pxstate");
    refused(&["resume", "shard.pxstate"], "is a shard");
    write(dir, "junk.pxstate", "not a state");
    refused(&["resume", "junk.pxstate"], "not a plexus state file");
    std::fs::write(dir.join("trunc.pxstate"), &std::fs::read(dir.join("a.pxstate")).expect("read")[..200])
        .expect("write");
    refused(&["resume", "trunc.pxstate"], "damaged or truncated");
    refused(&["render", &scene, "--time", "1", "--shard", "0/2", "--out", "x.pxstate"], "sample budget");
    refused(&["render", &scene, "--spp", "4", "--shard", "0/2", "--out", "x.exr"], "--out SHARD.pxstate");
    let o = plexus(&["render", &scene, "--spp", "4", "--shard", "2/2", "--out", "x.pxstate"], dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("expected K/N"), "{}", stderr(&o));

    // Shards through the command line, merged, against the whole render.
    let o = plexus(&["render", &scene, "--spp", "1400", "--seed", "5", "--out", "whole.exr"], dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for k in ["0/2", "1/2"] {
        let out = format!("s{}.pxstate", &k[..1]);
        let o = plexus(&["render", &scene, "--spp", "1400", "--seed", "5", "--shard", k, "--out", &out], dir);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let o = plexus(&["merge", "s1.pxstate", "s0.pxstate", "--out", "merged.exr"], dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let read = |n: &str| plexus::film::exr_io::read_exr(&dir.join(n)).expect("read exr").pixels;
    // Within one f32 rounding step (tests/commands/state.rs states why); measured: identical.
    for (a, b) in read("merged.exr").iter().zip(read("whole.exr")) {
        for (x, y) in a.to_array().into_iter().zip(b.to_array()) {
            assert!(x.to_bits().abs_diff(y.to_bits()) <= 1, "merged {x} against the whole render's {y}");
        }
    }
    assert_eq!(json(&dir.join("merged.json"))["run"]["merged_shards"], 2);
    let o = plexus(&["render", &scene, "--spp", "1400", "--seed", "6", "--shard", "1/2", "--out", "t1.pxstate"], dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    refused(&["merge", "s0.pxstate", "t1.pxstate", "--out", "m.exr"], "different seeds");
    refused(&["merge", "s0.pxstate", "s0.pxstate", "--out", "m.exr"], "overlap");

    // Last: the scene's mesh changes, and the checkpoint no longer belongs to it.
    write(dir, "floor.obj", &mesh.replace("v -1 0 -1", "v -2 0 -1"));
    refused(&["resume", "a.pxstate"], "belongs to another scene");
}
