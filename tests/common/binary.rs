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
