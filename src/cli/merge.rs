//! `plexus merge SHARD.pxstate... --out IMAGE.exr`: combines the shards of one render
//! into its image and JSON (and, for a `.pxstate` output, its state). Shards of different scenes,
//! plexus versions, settings, seeds, budgets or resolutions, overlapping or missing shards are
//! refused with one line (exit 2); no scene is loaded.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use plexus::integrator;
use plexus::state::{merge_states, StateError, StateFile};

use super::bad_input;
use super::state_io::{self, is_state_path};
use super::stats_json::RenderStats;

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The shards' state files (`plexus render ... --shard K/N --out SHARD.pxstate`), all N of them.
    #[arg(required = true, value_name = "SHARD.pxstate")]
    pub shards: Vec<PathBuf>,
    /// Output image(s) (format from the extension), or a .pxstate for the merged state; repeatable.
    #[arg(long = "out", short = 'o', value_name = "PATH", required = true)]
    pub out: Vec<PathBuf>,
}

pub fn run(args: MergeArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let files = args
        .shards
        .iter()
        .map(|p| StateFile::read(p).map(|f| (p.clone(), f)))
        .collect::<Result<Vec<_>, _>>()
        .map_err(bad_input)?;
    let Some((_, first)) = files.first() else { return Err(bad_input("no shard to merge")) };
    let h = &first.header;
    if h.plexus_version != plexus::state::PLEXUS_VERSION {
        return Err(bad_input(format!(
            "the shards were rendered by plexus {}, this is plexus {}",
            h.plexus_version,
            plexus::state::PLEXUS_VERSION
        )));
    }
    if h.sampling_revision != plexus::state::SAMPLING_REVISION {
        return Err(bad_input(format!(
            "the shards were rendered with sampling revision {}, this plexus samples with revision {}",
            h.sampling_revision,
            plexus::state::SAMPLING_REVISION
        )));
    }
    let params: toml::Table = toml::from_str(&h.params).map_err(bad_input)?;
    let integrator = integrator::create(&h.integrator, &params)?;
    if integrator.settings_json() != serde_json::from_str::<serde_json::Value>(&h.settings).unwrap_or_default() {
        return Err(bad_input(StateError::Mismatch(format!(
            "the shards' {} settings ({}) are not what this plexus makes of them",
            h.integrator, h.settings
        ))));
    }
    let merged = merge_states(&files, |parts| {
        integrator.merge_parts(parts).map_err(|e| match e {
            integrator::RenderError::State(s) => s,
            other => StateError::Mismatch(other.to_string()),
        })
    })
    .map_err(bad_input)?;
    let (states, images): (Vec<PathBuf>, Vec<PathBuf>) = args.out.iter().cloned().partition(|p| is_state_path(p));
    let (width, height) = (merged.header.width as usize, merged.header.height as usize);
    super::outputs::check_outputs(&images, width, height)?;
    super::outputs::check_state_paths(&states)?;

    let mut output = integrator.output_of_state(&merged.state)?;
    output.wall_time = start.elapsed();
    state_io::write_images(&images, &output)?;
    state_io::write_states(&states, &merged)?;
    let mut stats = RenderStats::new(
        merged.header.scene.clone(),
        integrator.name().to_string(),
        integrator.settings_json(),
        merged.header.budget,
        merged.header.seed,
        0,
        merged.header.accel.clone(),
        0.0,
        None,
        &output,
        images.clone(),
    );
    stats.run = state_io::run_info(&merged, &states, None, files.len());
    let stats_files = state_io::write_stats(&images, &states, &stats)?;
    let written: Vec<PathBuf> = images.iter().chain(&states).chain(&stats_files).cloned().collect();
    eprintln!(
        "merged {} shards -> {}",
        files.len(),
        written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    );
    Ok(())
}
