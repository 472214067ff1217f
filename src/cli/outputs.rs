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

fn check_stats_path(path: &Path) -> anyhow::Result<()> {
    if path.is_dir() {
        return Err(bad_input(format!(
            "cannot write the stats file '{}': it is a directory (the stats go beside each image, \
             with the extension .json)",
            path.display()
        )));
    }
    Ok(())
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
