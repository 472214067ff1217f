//! The JSON stats file written next to the images of a render: what the render cost (wall time,
//! rays, samples) and how it was configured (integrator and settings, seed, threads, accelerator,
//! scene and the scene features that were built), plus the integrator's own statistics.

use std::path::{Path, PathBuf};

use serde::Serialize;

use plexus::job::{Budget, RenderOutput};
use plexus::scene::SceneFeatures;
use plexus::stats::Counters;

/// Everything the stats file records about one render.
#[derive(Debug, Serialize)]
pub struct RenderStats {
    pub plexus_version: &'static str,
    /// The scene file, or "<built-in cornell-box>".
    pub scene: String,
    pub integrator: String,
    /// The integrator's settings in effect (defaults filled in).
    pub settings: serde_json::Value,
    pub budget: Budget,
    pub seed: u64,
    pub threads: usize,
    pub accel: String,
    pub resolution: [u32; 2],
    /// Seconds spent loading the scene and building the accelerator.
    pub load_time_s: f64,
    /// Seconds spent rendering (the integrator's own measurement).
    pub wall_time_s: f64,
    /// CPU seconds the process (all its threads) spent during the render: on a shared machine
    /// the cost that the load does not inflate as it does the wall time. Null where no render ran
    /// in this process (merges).
    pub cpu_time_s: Option<f64>,
    /// Closest-hit plus shadow queries.
    pub rays: u64,
    pub rays_per_s: f64,
    /// Camera samples, or Markov chain iterations for MCMC integrators.
    pub samples: u64,
    pub samples_per_s: f64,
    /// All counters, including contributions dropped as non-finite and per-strategy acceptance.
    pub counters: Counters,
    /// Which optional scene machinery was built (environment distribution, portals, lights by kind);
    /// null for a merge of shards, which loads no scene.
    pub scene_features: Option<SceneFeatures>,
    /// Integrator-specific statistics.
    pub integrator_stats: serde_json::Value,
    /// Per-channel mean of the image.
    pub image_mean: [f64; 3],
    /// The images this render wrote.
    pub outputs: Vec<PathBuf>,
    /// How the render ran (`cli::state_io::run_info`): interrupted or complete, the budget spent,
    /// the state file, a shard's units, the run it resumed.
    pub run: serde_json::Value,
}

impl RenderStats {
    /// Fills in rates from the render output.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: String,
        integrator: String,
        settings: serde_json::Value,
        budget: Budget,
        seed: u64,
        threads: usize,
        accel: String,
        load_time_s: f64,
        features: Option<SceneFeatures>,
        output: &RenderOutput,
        outputs: Vec<PathBuf>,
    ) -> RenderStats {
        let wall = output.wall_time.as_secs_f64();
        let rate = |n: u64| if wall > 0.0 { n as f64 / wall } else { 0.0 };
        let rays = output.counters.total_rays();
        RenderStats {
            plexus_version: env!("CARGO_PKG_VERSION"),
            scene,
            integrator,
            settings,
            budget,
            seed,
            threads,
            accel,
            resolution: [output.image.width as u32, output.image.height as u32],
            load_time_s,
            wall_time_s: wall,
            cpu_time_s: None,
            rays,
            rays_per_s: rate(rays),
            samples: output.counters.samples,
            samples_per_s: rate(output.counters.samples),
            counters: output.counters.clone(),
            scene_features: features,
            integrator_stats: output.extra_stats.clone(),
            image_mean: output.image.mean(),
            outputs,
            run: serde_json::Value::Null,
        }
    }
}

/// The stats files for a list of images: `<image without extension>.json`, once per distinct
/// name (`out.exr` and `out.png` share `out.json`).
pub fn stats_paths(images: &[PathBuf]) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = Vec::new();
    for image in images {
        let p = image.with_extension("json");
        if !paths.contains(&p) {
            paths.push(p);
        }
    }
    paths
}

/// Writes `stats` as pretty JSON to `path`, through a hidden temporary file beside it that is
/// renamed into place when complete and removed otherwise.
pub fn write(path: &Path, stats: &RenderStats) -> anyhow::Result<()> {
    use std::io::Write;
    let text = serde_json::to_string_pretty(stats)? + "\n";
    plexus::interrupt::write_atomically(path, false, |e| e, |_, file| file.write_all(text.as_bytes()))
        .map_err(|e| anyhow::anyhow!("cannot write the stats file {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_stats_file_per_image_name() {
        let p = stats_paths(&[PathBuf::from("a/x.exr"), PathBuf::from("a/x.png"), PathBuf::from("y.hdr")]);
        assert_eq!(p, vec![PathBuf::from("a/x.json"), PathBuf::from("y.json")]);
    }
}
