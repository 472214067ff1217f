//! `plexus import SCENE.xml [--out SCENE.toml]`: a Mitsuba scene as a plexus TOML scene, and the
//! loading of Mitsuba files given where a scene is expected (`plexus render SCENE.xml`, `info`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use clap::Args;

use plexus::accel::AccelKind;
use plexus::scene::import::{import_mitsuba, is_mitsuba_file, load_mitsuba, ImportOptions, Warnings};
use plexus::scene::{load_scene, load_scene_str, LoadedScene};

use super::bad_input;

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// Mitsuba scene (0.5/0.6 or 3 XML).
    pub scene: PathBuf,
    /// The TOML to write (default: SCENE with the extension .toml, beside the XML). Mesh and texture
    /// paths in it are relative to its directory; meshes converted from .serialized are written
    /// beside it as PLY.
    #[arg(long = "out", short = 'o', value_name = "SCENE.toml")]
    pub out: Option<PathBuf>,
    /// A value for `$name` in the file, overriding its <default> (repeatable).
    #[arg(short = 'D', long = "define", value_name = "NAME=VALUE")]
    pub define: Vec<String>,
    /// Leave out shapes whose mesh file is missing (each named in a warning) instead of failing.
    #[arg(long)]
    pub skip_missing_meshes: bool,
}

pub fn run(args: ImportArgs) -> anyhow::Result<()> {
    let mut defines = HashMap::new();
    for d in &args.define {
        let (k, v) = d.split_once('=').ok_or_else(|| bad_input(format!("-D expects NAME=VALUE, got '{d}'")))?;
        defines.insert(k.to_string(), v.to_string());
    }
    let out = args.out.clone().unwrap_or_else(|| args.scene.with_extension("toml"));
    let out_dir = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !out_dir.is_dir() {
        return Err(bad_input(format!("--out: directory '{}' does not exist", out_dir.display())));
    }
    let options = ImportOptions {
        toml_dir: Some(out_dir.clone()),
        mesh_dir: None,
        defines,
        skip_missing_meshes: args.skip_missing_meshes,
    };
    if is_same_file(&out, &args.scene) {
        return Err(bad_input(format!(
            "--out '{}' is the scene being imported: choose another name for the TOML",
            out.display()
        )));
    }
    let imported = import_mitsuba(&args.scene, &options).map_err(bad_input)?;
    print_warnings(&imported.warnings);
    // The result must load: check it with the real loader before anything is replaced, then write
    // it through a temporary file renamed into place (which replaces a link, never its target).
    let name = out.display().to_string();
    let loaded = load_scene_str(&imported.toml, &out_dir, &name, None)
        .map_err(|e| bad_input(format!("the TOML for {name} does not load, so it was not written: {e}")))?;
    plexus::interrupt::write_atomically(
        &out,
        false,
        |e| bad_input(format!("cannot write '{}': {e}", out.display())),
        |_, file| {
            use std::io::Write;
            file.write_all(imported.toml.as_bytes()).map_err(|e| bad_input(format!("cannot write '{name}': {e}")))
        },
    )?;
    let scene = &loaded.scene;
    eprintln!(
        "wrote {} ({} shapes, {} triangles, {} materials, {} lights; {} warnings)",
        out.display(),
        scene.meshes.len(),
        scene.triangle_count(),
        scene.materials.len(),
        scene.lights.len(),
        imported.warnings.lines().len()
    );
    Ok(())
}

/// Whether `a` and `b` are one file (the same device and inode; false when either is missing).
fn is_same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Every warning as one line on stderr.
pub fn print_warnings(w: &Warnings) {
    for line in w.lines() {
        eprintln!("warning: {line}");
    }
}

/// [`load_any`], with every file the scene was made of (the scene's identity in state files).
pub fn load_any_recorded(path: &Path, accel: Option<AccelKind>) -> anyhow::Result<(LoadedScene, Vec<PathBuf>)> {
    let (loaded, files) = plexus::input_file::recording_reads(|| load_any(path, accel));
    Ok((loaded?, files))
}

/// Loads a scene file: TOML, or Mitsuba XML (imported on the fly, its warnings printed).
pub fn load_any(path: &Path, accel: Option<AccelKind>) -> anyhow::Result<LoadedScene> {
    if is_mitsuba_file(path) {
        let (loaded, warnings) = load_mitsuba(path, &ImportOptions::default(), accel).map_err(bad_input)?;
        print_warnings(&warnings);
        Ok(loaded)
    } else {
        Ok(load_scene(path, accel)?)
    }
}
