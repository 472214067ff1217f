//! What `render`, `resume` and `merge` share around state files (`plexus::state`): the outputs
//! of a run (images with their layers, `.pxstate` files, the JSON), the JSON's `run` record, the
//! scene's identity, and the interrupt's exit.

use std::path::{Path, PathBuf};

use plexus::film::oiio::{write_image, WriteOptions};
use plexus::integrator::registry::Space;
use plexus::job::RenderOutput;
use plexus::state::{StateFile, StateHeader};

use super::bad_input;
use super::stats_json::{self, RenderStats};

/// The extension of state files.
pub const STATE_EXTENSION: &str = "pxstate";

/// Scene name recorded for the built-in scene.
pub const BUILTIN_SCENE: &str = "<built-in cornell-box>";

/// A render that stopped on SIGINT/SIGTERM after writing its outputs: exit status 130, and this
/// message (not an error) on stderr.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(pub String);

/// Whether `path` names a state file (`.pxstate`) rather than an image.
pub fn is_state_path(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case(STATE_EXTENSION))
}

/// The scene's name and hash for the state header: the files it was loaded from (`files`, as
/// `import::load_any_recorded` lists them), or the built-in scene's text.
pub fn scene_identity(scene: Option<&Path>, files: &[PathBuf]) -> anyhow::Result<(String, String)> {
    match scene {
        Some(path) => {
            let hash = plexus::state::scene_hash(files).map_err(bad_input)?;
            let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
            Ok((absolute.display().to_string(), hash))
        }
        None => Ok((BUILTIN_SCENE.to_string(), plexus::state::builtin_scene_hash())),
    }
}

/// Writes the images (EXR outputs with their layers beside them as `<stem>.<layer>.exr`).
pub fn write_images(images: &[PathBuf], output: &RenderOutput) -> anyhow::Result<()> {
    for path in images {
        write_image(path, &output.image, &WriteOptions::default())?;
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
            let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            for (name, layer) in &output.layers {
                write_image(&path.with_file_name(format!("{stem}.{name}.exr")), layer, &WriteOptions::default())?;
            }
        }
    }
    Ok(())
}

/// Writes `file` to every state path.
pub fn write_states(paths: &[PathBuf], file: &StateFile) -> anyhow::Result<()> {
    for path in paths {
        file.write(path)?;
    }
    Ok(())
}

/// The JSON's `run` record: whether the render was interrupted or complete, the budget spent, the
/// state files written, a shard's units, the state it resumed.
pub fn run_info(file: &StateFile, states: &[PathBuf], resumed_from: Option<&Path>, merged: usize) -> serde_json::Value {
    let (h, s) = (&file.header, &file.state);
    let units = match h.shard {
        None => serde_json::json!({ "all": s.unit_count }),
        Some(shard) => {
            // A shard's units are what its integrator's row says they are (the render model).
            let space = plexus::integrator::registry::lookup(&h.integrator).map(|r| r.capabilities.space);
            let kind = if space.is_ok_and(|s| s == Space::Image) { "passes" } else { "chains" };
            serde_json::json!({ kind: format!("{kind} i with i mod {} = {}", shard.count, shard.index), "shard": shard.to_string() })
        }
    };
    serde_json::json!({
        "interrupted": s.interrupted,
        "complete": s.complete,
        "budget_spent": { "passes": s.passes_done, "samples": s.counters.samples, "seconds": s.wall_time_s },
        "state_files": states,
        "resumed_from": resumed_from,
        "shard": h.shard.map(|k| k.to_string()),
        "units": units,
        "merged_shards": (merged > 0).then_some(merged),
    })
}

/// Writes the stats JSON beside each image (or beside each state file when there is no image)
/// and returns the paths written.
pub fn write_stats(images: &[PathBuf], states: &[PathBuf], stats: &RenderStats) -> anyhow::Result<Vec<PathBuf>> {
    let beside: Vec<PathBuf> = if images.is_empty() { states.to_vec() } else { images.to_vec() };
    let files = stats_json::stats_paths(&beside);
    for path in &files {
        stats_json::write(path, stats)?;
    }
    Ok(files)
}

/// The one-line summary on stderr, and the interrupt's exit when the state says it stopped early.
pub fn finish(stats: &RenderStats, written: &[PathBuf], file: &StateFile, states: &[PathBuf]) -> anyhow::Result<()> {
    let dropped = if stats.counters.nonfinite_dropped > 0 {
        format!(", {} non-finite contributions dropped", stats.counters.nonfinite_dropped)
    } else {
        String::new()
    };
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    eprintln!(
        "{}: {} samples in {:.2} s ({:.2} M rays/s, {} threads{dropped}) -> {}",
        stats.integrator,
        stats.samples,
        stats.wall_time_s,
        stats.rays_per_s * 1e-6,
        stats.threads,
        names.join(", ")
    );
    if file.state.interrupted {
        let resume =
            states.first().map_or(String::new(), |p| format!(": continue with `plexus resume {}`", p.display()));
        return Err(anyhow::Error::new(Interrupted(format!(
            "interrupted after {} passes; the image, the JSON and the checkpoint are written{resume}",
            file.state.passes_done
        ))));
    }
    Ok(())
}

/// The header of a render's state files.
#[allow(clippy::too_many_arguments)]
pub fn header(
    scene: (String, String),
    accel: String,
    integrator: &dyn plexus::integrator::Integrator,
    params: &toml::Table,
    job: &plexus::job::RenderJob,
    size: (u32, u32),
    shard: Option<plexus::state::Shard>,
    outputs: &[PathBuf],
) -> StateHeader {
    StateHeader {
        plexus_version: plexus::state::PLEXUS_VERSION.to_string(),
        sampling_revision: plexus::state::SAMPLING_REVISION,
        scene: scene.0,
        scene_hash: scene.1,
        accel,
        integrator: integrator.name().to_string(),
        params: toml::to_string(params).unwrap_or_default(),
        settings: integrator.settings_json().to_string(),
        seed: job.seed,
        threads: if shard.is_some() { 0 } else { job.threads },
        budget: job.budget,
        width: size.0,
        height: size.1,
        shard,
        outputs: outputs.iter().map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone())).collect(),
    }
}
