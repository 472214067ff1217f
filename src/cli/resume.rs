//! `plexus resume FILE`: continue a checkpointed or interrupted render from its state file. The
//! scene is loaded again from the path the state names and must hash the same (the scene file and
//! every file it references); plexus version and settings must match too. The state file is
//! updated in place (atomically) as the render goes on: at the end, on an interrupt, and every
//! `--checkpoint-every` seconds.

use std::path::{Component, Path, PathBuf};
use std::time::Instant;

use clap::Args;

use plexus::integrator::registry;
use plexus::job::{Budget, RenderJob};
use plexus::scene::builtin_cornell_box;
use plexus::state::{StateError, StateFile};

use super::bad_input;
use super::render_run::SessionRun;
use super::state_io::{self, is_state_path};

#[derive(Debug, Args)]
pub struct ResumeArgs {
    /// The state file (.pxstate) of a checkpoint or an interrupted render.
    pub state: PathBuf,
    /// The render's new total samples (mutations) per pixel. Default: the render's own budget.
    #[arg(long, value_name = "N", conflicts_with = "time")]
    pub spp: Option<u64>,
    /// Render for this many more seconds instead.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub time: Option<f64>,
    /// Output images (default: the render's own outputs).
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out: Vec<PathBuf>,
    /// Also save the state every SECONDS seconds (at a pass boundary).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub checkpoint_every: Option<f64>,
    /// Write the current image every SECONDS seconds during the render.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub preview_every: Option<f64>,
    /// Testing hook: stop as an interrupt would when the schedule reaches pass N.
    #[arg(long, value_name = "N", hide = true)]
    pub stop_at_pass: Option<u64>,
}

pub fn run(args: ResumeArgs) -> anyhow::Result<()> {
    let load_start = Instant::now();
    let saved = StateFile::read(&args.state).map_err(bad_input)?;
    let h = saved.header.clone();
    let scene_path = (h.scene != state_io::BUILTIN_SCENE).then(|| PathBuf::from(&h.scene));
    let accel = h.accel.parse().map_err(bad_input)?;
    if let Some(path) = &scene_path {
        if !path.is_file() {
            return Err(bad_input(format!(
                "{}: its scene {} is not there any more",
                args.state.display(),
                path.display()
            )));
        }
    }
    let params: toml::Table =
        toml::from_str(&h.params).map_err(|e| bad_input(format!("{}: {e}", args.state.display())))?;
    let row = registry::lookup(&h.integrator)?;
    let integrator = (row.create)(&params)?;
    if !row.capabilities.resume {
        return Err(bad_input(integrator.no_state().to_string()));
    }
    if integrator.settings_json() != serde_json::from_str::<serde_json::Value>(&h.settings).unwrap_or_default() {
        return Err(bad_input(StateError::Mismatch(format!(
            "{}: the {} settings it was rendered with ({}) are not what this plexus makes of them ({})",
            args.state.display(),
            h.integrator,
            h.settings,
            integrator.settings_json()
        ))));
    }
    // The scene is loaded before its identity is checked: the identity covers every file loading
    // opens (an included file, a mesh named through a `$name` default).
    let (loaded, scene_files) = match &scene_path {
        Some(path) => super::import::load_any_recorded(path, Some(accel))?,
        None => (builtin_cornell_box(Some(accel))?, Vec::new()),
    };
    let (scene_name, hash) = state_io::scene_identity(scene_path.as_deref(), &scene_files)?;
    saved.check_resumable(&args.state, &hash).map_err(bad_input)?;
    let camera = &loaded.scene.camera;
    let budget = match (args.spp, args.time) {
        (Some(n), _) => Budget::SamplesPerPixel(n),
        (None, Some(s)) => Budget::Seconds(s),
        // A time budget's rest, at least one pass.
        (None, None) => match h.budget {
            Budget::Seconds(s) => Budget::Seconds((s - saved.state.wall_time_s).max(1e-3)),
            b => b,
        },
    };
    // The budget's source, named in a refusal: an option given, else the state's own budget.
    let option = match (args.spp, args.time) {
        (Some(_), _) => "--spp",
        (None, Some(_)) => "--time",
        (None, None) => "the state's budget",
    };
    row.check_limits(&loaded.scene, &params, budget, option).map_err(bad_input)?;
    let checkpoint_every = super::render_run::checkpoint_interval(args.checkpoint_every)?;
    let images: Vec<PathBuf> =
        if args.out.is_empty() { outputs_below_state(&args.state, &h.outputs)? } else { args.out.clone() };
    if images.iter().any(|p| is_state_path(p)) {
        return Err(bad_input("resume writes its state to the file it resumes; --out takes images"));
    }
    super::outputs::check_outputs(&images, camera.width as usize, camera.height as usize)?;
    let names: Vec<String> = images.iter().map(|p| p.display().to_string()).collect();
    eprintln!("resume {}: writes {}", args.state.display(), names.join(", "));
    let load_time = load_start.elapsed().as_secs_f64();

    let job = RenderJob { budget, seed: h.seed, threads: h.threads.max(1) };
    let header = plexus::state::StateHeader { budget, outputs: images.clone(), ..h.clone() };
    super::render_run::run(SessionRun {
        integrator: integrator.as_ref(),
        keeps_state: true,
        scene: &loaded.scene,
        scene_name,
        job,
        header,
        checkpoint: checkpoint_every.map(|every| (args.state.clone(), every)),
        stop_at_pass: args.stop_at_pass,
        preview_every: args.preview_every,
        resume: Some((&saved.state, &args.state)),
        shard: None,
        images,
        states: vec![args.state.clone()],
        load_time,
    })
}

/// The outputs a state file names, as resume writes them without `--out`: only paths below the
/// state file's directory (a state file may come from anywhere, so the paths in it are not trusted
/// to name a place the user chose). Each must lie in that directory or below it, lexically (no
/// `..`) and for real (no directory link leading out); the rest is refused, naming the path.
fn outputs_below_state(state: &Path, outputs: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let dir = plexus::interrupt::directory_of(state);
    let as_given = std::path::absolute(dir).map_err(|e| bad_input(format!("{}: {e}", state.display())))?;
    let real = dir.canonicalize().map_err(|e| bad_input(format!("{}: {e}", state.display())))?;
    let refuse = |p: &Path| {
        bad_input(format!(
            "{}: its output '{}' is not below the state file's directory, and resume writes only \
             there unless told: give --out",
            state.display(),
            p.display()
        ))
    };
    let mut below = Vec::with_capacity(outputs.len());
    for p in outputs {
        if p.components().any(|c| matches!(c, Component::ParentDir)) {
            return Err(refuse(p));
        }
        let full = if p.is_absolute() { p.clone() } else { as_given.join(p) };
        let rel = full.strip_prefix(&as_given).or_else(|_| full.strip_prefix(&real)).map_err(|_| refuse(p))?;
        if rel.as_os_str().is_empty() {
            return Err(refuse(p));
        }
        let path = dir.join(rel);
        // The directory the image lands in, with every link resolved, is still below.
        let parent = plexus::interrupt::directory_of(&path);
        if let Ok(parent_real) = parent.canonicalize() {
            if !parent_real.starts_with(&real) {
                return Err(refuse(p));
            }
        }
        below.push(path);
    }
    Ok(below)
}
