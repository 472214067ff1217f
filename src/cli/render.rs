//! `plexus render`: load a scene (or the built-in Cornell box), apply the command-line overrides,
//! check every output path before any work, render with a progress bar, and write the images and
//! the JSON stats file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use plexus::integrator::{self, registry, INTEGRATOR_NAMES};
use plexus::job::{Budget, RenderJob};
use plexus::scene::{builtin_cornell_box, LoadedScene};
use plexus::state::Shard;

use super::bad_input;
use super::options::RenderOptions;
use super::outputs::check_outputs;
use super::render_run::SessionRun;
use super::state_io::{self, is_state_path};

/// Samples per pixel when neither the command line nor the scene gives a budget.
pub const DEFAULT_SPP: u64 = 64;

/// Name of the built-in scene, used for default output names.
const BUILTIN_STEM: &str = "cornell-box";

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (TOML, or Mitsuba XML imported on the fly). Without it the built-in Cornell box
    /// is rendered.
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
    #[command(flatten)]
    pub options: RenderOptions,
    /// Seed of every random stream (same seed and thread count: same image, bit for bit).
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Output image (format from the extension: .exr, .png, .hdr, .tif, ...); repeatable.
    /// Default: the scene's outputs, else <scene-stem>.exr and <scene-stem>.png here.
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out: Vec<PathBuf>,
    /// During the render, write the current image to the outputs at most every SECONDS seconds
    /// (between passes), so a long render can be watched.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub preview_every: Option<f64>,
    /// Save the render's state to FILE (.pxstate) when it ends or is interrupted, and every
    /// --checkpoint-every seconds; continue it with `plexus resume FILE`.
    #[arg(long, value_name = "FILE.pxstate")]
    pub checkpoint: Option<PathBuf>,
    /// With --checkpoint: also save at the first pass boundary after every SECONDS seconds.
    #[arg(long, value_name = "SECONDS", requires = "checkpoint", allow_negative_numbers = true)]
    pub checkpoint_every: Option<f64>,
    /// Render only the K-th (0-based) of N disjoint sets of work units (passes for pt, bdpt and
    /// light; chains for the MLT family) into --out SHARD.pxstate; `plexus merge` combines them.
    /// Sample budgets only.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Testing hook: stop as an interrupt would when the schedule reaches pass N.
    #[arg(long, value_name = "N", hide = true)]
    pub stop_at_pass: Option<u64>,
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
    let overrides = args.options.overrides()?;
    args.options.check_threads()?;
    if let Some(s) = args.preview_every {
        if !(s.is_finite() && s > 0.0) {
            return Err(bad_input(format!("--preview-every must be a positive number of seconds, got {s}")));
        }
    }

    let load_start = Instant::now();
    let (loaded, scene_files) = match &args.scene {
        Some(path) => super::import::load_any_recorded(path, args.options.accel)?,
        None => (builtin_cornell_box(args.options.accel)?, Vec::new()),
    };
    let plan = resolve(&args, &loaded, &overrides)?;
    let row = registry::lookup(&plan.integrator)?;
    let integrator = (row.create)(&plan.params)?;
    let budget_option = match (args.spp, args.time, plan.budget) {
        (Some(_), _, _) => "--spp",
        (None, Some(_), _) => "--time",
        (None, None, Budget::SamplesPerPixel(_)) => "render.spp",
        (None, None, Budget::Seconds(_)) => "render.time",
    };
    row.check_limits(&loaded.scene, &plan.params, plan.budget, budget_option).map_err(bad_input)?;

    // Every output is checked before any work, so a typo costs nothing.
    let (states, images): (Vec<PathBuf>, Vec<PathBuf>) = plan.outputs.iter().cloned().partition(|p| is_state_path(p));
    let mut state_paths = states.clone();
    if let Some(shard) = args.shard {
        if matches!(plan.budget, Budget::Seconds(_)) {
            return Err(bad_input(
                "--shard needs a sample budget (--spp): a time budget would make shards overlap or miss work",
            ));
        }
        if states.is_empty() || !images.is_empty() {
            return Err(bad_input(format!(
                "--shard {shard} writes a state file, not images: give --out SHARD.pxstate"
            )));
        }
        if args.checkpoint.is_some() {
            return Err(bad_input(
                "--shard and --checkpoint: a shard is not checkpointed (render it again if it fails)",
            ));
        }
    }
    if let Some(path) = &args.checkpoint {
        if !is_state_path(path) {
            return Err(bad_input(format!("--checkpoint {}: a checkpoint is a .pxstate file", path.display())));
        }
        state_paths.push(path.clone());
    }
    let checkpoint_every = super::render_run::checkpoint_interval(args.checkpoint_every)?;
    let camera = &loaded.scene.camera;
    check_outputs(&images, camera.width as usize, camera.height as usize)?;
    super::outputs::check_state_paths(&state_paths)?;
    let can = row.capabilities;
    if (!can.checkpoint && (!state_paths.is_empty() || checkpoint_every.is_some()))
        || (!can.shard && args.shard.is_some())
    {
        return Err(bad_input(integrator.no_state().to_string()));
    }
    let scene_id = state_io::scene_identity(args.scene.as_deref(), &scene_files)?;
    let load_time = load_start.elapsed().as_secs_f64();

    let scene = &loaded.scene;
    let job = RenderJob { budget: plan.budget, seed: plan.seed, threads: plan.threads };
    let header = state_io::header(
        scene_id,
        scene.accel.kind().to_string(),
        integrator.as_ref(),
        &plan.params,
        &job,
        (camera.width, camera.height),
        args.shard,
        &images,
    );
    let scene_name = match &args.scene {
        Some(p) => p.display().to_string(),
        None => state_io::BUILTIN_SCENE.to_string(),
    };
    super::render_run::run(SessionRun {
        integrator: integrator.as_ref(),
        keeps_state: can.checkpoint,
        scene,
        scene_name,
        job,
        header,
        checkpoint: args.checkpoint.clone().zip(checkpoint_every),
        stop_at_pass: args.stop_at_pass,
        preview_every: args.preview_every,
        resume: None,
        shard: args.shard,
        images,
        states: state_paths,
        load_time,
    })
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
    // The budget's limits are checked with the memory (`Row::check_limits`), which knows the film.
    let threads = args.options.threads_or(render.threads)?;

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
