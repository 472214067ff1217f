//! The checks on everything `plexus render` will write, made before any work (README: "Every path
//! is checked ... before rendering starts"), so a typo or an unwritable place costs no render.

use std::path::{Path, PathBuf};

use plexus::film::oiio::check_output;

use super::bad_input;
use super::stats_json::stats_paths;

/// Checks every image output for a `width`×`height` image (see [`check_output`]) and the JSON
/// stats file beside each: the first that cannot be written is bad input, named with its reason.
pub fn check_outputs(images: &[PathBuf], width: usize, height: usize) -> anyhow::Result<()> {
    for path in images {
        check_output(path, width, height).map_err(bad_input)?;
    }
    // A stats file shares its image's directory, checked above; only its own name can be wrong.
    for path in stats_paths(images) {
        check_stats_path(&path)?;
    }
    Ok(())
}

/// A stats file replaces only what is absent or a stats file of an earlier render: `--out
/// notes.png` must not destroy a `notes.json` of the user's.
pub fn check_stats_path(path: &Path) -> anyhow::Result<()> {
    if path.is_dir() {
        return Err(bad_input(format!(
            "cannot write the stats file '{}': it is a directory (the stats go beside each image, \
             with the extension .json)",
            path.display()
        )));
    }
    let Ok(meta) = std::fs::symlink_metadata(path) else { return Ok(()) };
    if !(meta.file_type().is_file() && is_render_record(path, meta.len())) {
        return Err(bad_input(format!(
            "'{}' exists and is not a plexus render record: the render's statistics (written beside \
             each image, with the extension .json) would replace it; move it or choose another --out",
            path.display()
        )));
    }
    Ok(())
}

/// Whether the regular file `path` of `len` bytes is a stats file plexus wrote (a JSON object
/// with the keys every `RenderStats` has).
fn is_render_record(path: &Path, len: u64) -> bool {
    // Far above any stats file (a few kB); a larger file is someone else's.
    const MAX_RECORD_BYTES: u64 = 1 << 24;
    if len > MAX_RECORD_BYTES {
        return false;
    }
    let Ok(text) = plexus::input_file::read_regular_text(path, MAX_RECORD_BYTES) else { return false };
    let Ok(serde_json::Value::Object(record)) = serde_json::from_str::<serde_json::Value>(&text) else { return false };
    ["plexus_version", "integrator", "budget", "outputs", "run"].iter().all(|k| record.contains_key(*k))
}

/// A name for the state an interrupted render saves without `--checkpoint`: `<stem>.pxstate`
/// beside `image` if nothing is there, else `<stem>.<k>.pxstate` for the first free k, so that an
/// unrelated state (another render's) is never replaced.
pub fn free_interrupt_state_path(image: &Path) -> PathBuf {
    let first = image.with_extension(super::state_io::STATE_EXTENSION);
    let taken = |p: &Path| std::fs::symlink_metadata(p).is_ok();
    if !taken(&first) {
        return first;
    }
    let stem = image.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    (1u64..)
        .map(|k| image.with_file_name(format!("{stem}.{k}.{}", super::state_io::STATE_EXTENSION)))
        .find(|p| !taken(p))
        .expect("some k is free")
}

/// Checks the state files a render will write (`--checkpoint`, `.pxstate` outputs): the same
/// directory and name checks as images, before any work.
pub fn check_state_paths(paths: &[PathBuf]) -> anyhow::Result<()> {
    for path in paths {
        let dir = plexus::interrupt::directory_of(path);
        if path.is_dir() || path.as_os_str().to_string_lossy().ends_with('/') {
            return Err(bad_input(format!("cannot write the state file '{}': it is a directory", path.display())));
        }
        if !dir.is_dir() {
            return Err(bad_input(format!(
                "cannot write the state file '{}': the directory '{}' does not exist",
                path.display(),
                dir.display()
            )));
        }
        tempfile::Builder::new()
            .prefix(".plexus-check-")
            .tempfile_in(dir)
            .map_err(|e| bad_input(format!("cannot write the state file '{}': {e}", path.display())))?;
    }
    Ok(())
}
