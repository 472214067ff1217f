//! Running the `plexus` binary as a user would, for the CLI-level tests (cli, hostile, limits).

use std::path::Path;
use std::process::{Command, Output};

/// A fresh, empty directory for one test, removed when the guard drops.
pub fn temp_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("plexus-test-{name}-")).tempdir().expect("create temp dir")
}

/// Runs `plexus ARGS` in `cwd` as CI does (`CI=true`: no progress bar; no backtraces).
pub fn plexus(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_plexus"))
        .args(args)
        .current_dir(cwd)
        .env("CI", "true")
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("run plexus")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A tiny valid scene: a camera of `resolution` (a TOML array, e.g. `"[8, 6]"`) looking at a
/// diffuse floor under a one-sided area light, with `extra` (e.g. a `[render]` table) appended.
pub fn tiny_scene(resolution: &str, extra: &str) -> String {
    TINY_SCENE.replace("{RESOLUTION}", resolution).replace("{EXTRA}", extra)
}

const TINY_SCENE: &str = r#"
[camera]
position = [0.0, 1.0, -3.0]
look_at = [0.0, 0.5, 0.0]
fov = 45.0
resolution = {RESOLUTION}

[materials.floor]
type = "diffuse"
reflectance = [0.5, 0.5, 0.5]

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
emission = { radiance = [4.0, 4.0, 4.0] }
transform = { scale = [0.5, 0.5, 1.0], rotate = { axis = [1, 0, 0], angle = 90 }, translate = [0.0, 2.0, 0.0] }
{EXTRA}
"#;

/// Runs `binary ARGS` in `cwd` as [`plexus`] does (`CI=true`, no backtraces, no standard input),
/// killing it after `seconds`: its exit status and stderr (stdout is discarded), or `None` when it
/// had to be killed. A hang detector, not a time bound: callers give it orders of magnitude of
/// slack. Stderr is read on a thread so a chatty child cannot block on a full pipe.
pub fn run_within(binary: &Path, args: &[&str], cwd: &Path, seconds: u64) -> Option<Output> {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = Command::new(binary)
        .args(args)
        .current_dir(cwd)
        .env("CI", "true")
        .env_remove("RUST_BACKTRACE")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn plexus");
    let mut pipe = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = pipe.read_to_end(&mut bytes);
        bytes
    });
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(seconds);
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let stderr = reader.join().unwrap_or_default();
            return Some(Output { status, stdout: Vec::new(), stderr });
        }
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// [`run_within`] for this build's `plexus`, failing the test when it had to be killed (the
/// input made plexus hang).
pub fn plexus_within(args: &[&str], cwd: &Path, seconds: u64) -> Output {
    run_within(Path::new(env!("CARGO_BIN_EXE_plexus")), args, cwd, seconds)
        .unwrap_or_else(|| panic!("plexus {args:?} still ran after {seconds} s"))
}
