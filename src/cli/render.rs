//! `plexus render`: load a scene (or the built-in Cornell box), apply the command-line overrides,
//! check every output path before any work, render with a progress bar, and write the images and
//! the JSON stats file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use plexus::accel::AccelKind;
use plexus::film::oiio::{write_image, WriteOptions};
use plexus::integrator::{self, Budget, RenderJob, INTEGRATOR_NAMES};
use plexus::scene::{builtin_cornell_box, load_scene, LoadedScene};

use super::bad_input;
use super::outputs::check_outputs;
use super::progress::{bar_wanted, BarProgress, Previews};
use super::stats_json::{self, RenderStats};

/// Samples per pixel when neither the command line nor the scene gives a budget.
pub const DEFAULT_SPP: u64 = 64;

/// Name of the built-in scene, used for default output names.
const BUILTIN_STEM: &str = "cornell-box";

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (TOML). Without it the built-in Cornell box is rendered.
    pub scene: Option<PathBuf>,
    /// Integrator to use (overrides the scene's [integrator] type).
    #[arg(long, value_name = "NAME", help = format!("Integrator: {}", INTEGRATOR_NAMES.join(", ")))]
    pub integrator: Option<String>,
    /// Samples per pixel (mutations per pixel for MCMC integrators).
    #[arg(long, value_name = "N", conflicts_with = "time")]
    pub spp: Option<u64>,
    /// Time budget in seconds instead of a sample budget.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub time: Option<f64>,
    /// Worker threads (default: the scene's setting, else all cores).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Seed of every random stream (same seed and thread count: same image, bit for bit).
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Ray-query accelerator: embree or bvh.
    #[arg(long, value_name = "embree|bvh")]
    pub accel: Option<AccelKind>,
    /// Output image (format from the extension: .exr, .png, .hdr, .tif, ...); repeatable.
    /// Default: the scene's outputs, else <scene-stem>.exr and <scene-stem>.png here.
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out: Vec<PathBuf>,
    /// Integrator setting, as a TOML value (e.g. --set max_depth=8); repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// During the render, write the current image to the outputs at most every SECONDS seconds
    /// (between passes), so a long render can be watched.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub preview_every: Option<f64>,
}

/// Everything resolved from the arguments and the scene before rendering.
struct Plan {
    integrator: String,
    params: toml::Table,
    budget: Budget,
    seed: u64,
    threads: usize,
    outputs: Vec<PathBuf>,
}

pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let overrides =
        args.set.iter().map(|s| integrator::parse_set(s)).collect::<Result<Vec<_>, _>>().map_err(bad_input)?;
    if let Some(n) = args.threads {
        plexus::integrator::check_threads(n, "--threads").map_err(bad_input)?;
    }
    if let Some(s) = args.preview_every {
        if !(s.is_finite() && s > 0.0) {
            return Err(bad_input(format!("--preview-every must be a positive number of seconds, got {s}")));
        }
    }

    let load_start = Instant::now();
    let loaded = match &args.scene {
        Some(path) => load_scene(path, args.accel)?,
        None => builtin_cornell_box(args.accel)?,
    };
    let plan = resolve(&args, &loaded, &overrides)?;
    let integrator = integrator::create(&plan.integrator, &plan.params)?;
    let camera = &loaded.scene.camera;
    let budget_option = match (args.spp, args.time, plan.budget) {
        (Some(_), _, _) => "--spp",
        (None, Some(_), _) => "--time",
        (None, None, Budget::SamplesPerPixel(_)) => "render.spp",
        (None, None, Budget::Seconds(_)) => "render.time",
    };
    super::check_render_limits(
        &plan.integrator,
        &plan.params,
        camera.width,
        camera.height,
        plan.budget,
        budget_option,
    )?;

    // Every output is checked before any work, so a typo costs nothing.
    let camera = &loaded.scene.camera;
    check_outputs(&plan.outputs, camera.width as usize, camera.height as usize)?;
    let load_time = load_start.elapsed().as_secs_f64();

    let scene = &loaded.scene;
    let job = RenderJob { budget: plan.budget, seed: plan.seed, threads: plan.threads };
    let progress = BarProgress::new(
        match plan.budget {
            Budget::Seconds(s) => Some(s),
            Budget::SamplesPerPixel(_) => None,
        },
        bar_wanted(),
    )
    .with_previews(args.preview_every.map(|every_seconds| Previews { every_seconds, outputs: plan.outputs.clone() }));
    let output = integrator.render(scene, &job, &progress);
    progress.finish();
    let output = output?;
    // The integrator's warnings (an MLT bootstrap that found no light, ...) are in its JSON
    // statistics; a user who reads only the terminal must see them too.
    for warning in output.extra_stats["warnings"].as_array().into_iter().flatten() {
        eprintln!("warning: {}", warning.as_str().unwrap_or_default());
    }

    for path in &plan.outputs {
        write_image(path, &output.image, &WriteOptions::default())?;
        // Extra layers (e.g. BDPT's per-technique images) go beside each EXR output as
        // `<stem>.<layer>.exr`.
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
            let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            for (name, layer) in &output.layers {
                write_image(&path.with_file_name(format!("{stem}.{name}.exr")), layer, &WriteOptions::default())?;
            }
        }
    }
    let scene_name = match &args.scene {
        Some(p) => p.display().to_string(),
        None => "<built-in cornell-box>".to_string(),
    };
    let stats = RenderStats::new(
        scene_name,
        integrator.name().to_string(),
        integrator.settings_json(),
        plan.budget,
        plan.seed,
        plan.threads,
        scene.accel.kind().to_string(),
        load_time,
        scene.features(),
        &output,
        plan.outputs.clone(),
    );
    let stats_files = stats_json::stats_paths(&plan.outputs);
    for path in &stats_files {
        stats_json::write(path, &stats)?;
    }
    let dropped = if stats.counters.nonfinite_dropped > 0 {
        format!(", {} non-finite contributions dropped", stats.counters.nonfinite_dropped)
    } else {
        String::new()
    };
    let written: Vec<String> = plan.outputs.iter().chain(&stats_files).map(|p| p.display().to_string()).collect();
    eprintln!(
        "{}: {} samples in {:.2} s ({:.2} M rays/s, {} threads{dropped}) -> {}",
        stats.integrator,
        stats.samples,
        stats.wall_time_s,
        stats.rays_per_s * 1e-6,
        stats.threads,
        written.join(", ")
    );
    Ok(())
}

/// Merges the command line over the scene's render settings.
fn resolve(args: &RenderArgs, loaded: &LoadedScene, overrides: &[(String, toml::Value)]) -> anyhow::Result<Plan> {
    let render = &loaded.render;
    // The scene's [integrator] parameters belong to the scene's integrator; choosing another one
    // on the command line starts from that integrator's defaults.
    let (name, base) = match &args.integrator {
        Some(name) if *name != render.integrator => (name.clone(), toml::Table::new()),
        _ => (render.integrator.clone(), render.integrator_params.clone()),
    };
    let params = integrator::merge_params(&base, overrides);

    let budget = match (args.spp, args.time) {
        (Some(n), _) => Budget::SamplesPerPixel(n),
        (None, Some(s)) => Budget::Seconds(s),
        (None, None) => match (render.spp, render.time) {
            (Some(n), _) => Budget::SamplesPerPixel(n),
            (None, Some(s)) => Budget::Seconds(s),
            (None, None) => Budget::SamplesPerPixel(DEFAULT_SPP),
        },
    };
    // The budget's limits are checked in `check_render_limits`, which knows the film.
    let threads = match (args.threads, render.threads) {
        (Some(n), _) => super::resolve_threads(Some(n), "--threads")?,
        (None, n) => super::resolve_threads(n, "render.threads")?,
    };

    let outputs = if !args.out.is_empty() {
        args.out.clone()
    } else if !render.outputs.is_empty() {
        render.outputs.clone()
    } else {
        let stem = args
            .scene
            .as_deref()
            .and_then(Path::file_stem)
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| BUILTIN_STEM.to_string());
        vec![PathBuf::from(format!("{stem}.exr")), PathBuf::from(format!("{stem}.png"))]
    };

    Ok(Plan { integrator: name, params, budget, seed: args.seed.unwrap_or(render.seed), threads, outputs })
}
