//! The render that `plexus render` and `plexus resume` share once their arguments are resolved:
//! the interrupt handler, periodic checkpoints, the progress bar with previews, the render under a
//! `Session`, and writing the images, state files and JSON with the one-line summary. The two
//! verbs differ only in where the job, the state header and the outputs come from.

use std::path::{Path, PathBuf};
use std::time::Duration;

use plexus::integrator::Integrator;
use plexus::job::{Budget, RenderJob, RunControl};
use plexus::scene::Scene;
use plexus::state::{RenderState, Session, SessionOutput, Shard, StateFile, StateHeader};

use super::bad_input;
use super::progress::{bar_wanted, BarProgress, Previews};
use super::state_io;
use super::stats_json::RenderStats;

/// `--checkpoint-every SECONDS` as a positive duration.
pub fn checkpoint_interval(seconds: Option<f64>) -> anyhow::Result<Option<Duration>> {
    seconds
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .ok()
                .filter(|d| !d.is_zero())
                .ok_or_else(|| bad_input(format!("--checkpoint-every must be a positive number of seconds, got {s}")))
        })
        .transpose()
}

/// One render of `render` or `resume`, resolved.
pub struct SessionRun<'a> {
    pub integrator: &'a dyn Integrator,
    /// Whether the integrator keeps a state (its registry row's checkpoint capability): without,
    /// it renders from start to end and its state record only describes a complete run.
    pub keeps_state: bool,
    pub scene: &'a Scene,
    /// The scene as the JSON names it.
    pub scene_name: String,
    pub job: RenderJob,
    /// The header every state file of the render carries.
    pub header: StateHeader,
    /// Where periodic checkpoints go, with their interval.
    pub checkpoint: Option<(PathBuf, Duration)>,
    /// Testing hook: stop as an interrupt would at this pass.
    pub stop_at_pass: Option<u64>,
    pub preview_every: Option<f64>,
    /// The state to continue (`resume`), and the file it was read from.
    pub resume: Option<(&'a RenderState, &'a Path)>,
    pub shard: Option<Shard>,
    pub images: Vec<PathBuf>,
    /// The state files written at the end (an interrupted render without one saves beside its
    /// first image).
    pub states: Vec<PathBuf>,
    /// Seconds spent loading before the render.
    pub load_time: f64,
}

/// Renders and writes everything; an interrupted render ends in the `Interrupted` error (exit 130)
/// after its outputs are written.
pub fn run(r: SessionRun<'_>) -> anyhow::Result<()> {
    let SessionRun {
        integrator,
        keeps_state,
        scene,
        scene_name,
        job,
        header,
        checkpoint,
        stop_at_pass,
        preview_every,
        resume,
        shard,
        images,
        mut states,
        load_time,
    } = r;
    let write_checkpoint = |state: RenderState| {
        if let Some((path, _)) = &checkpoint {
            if let Err(e) = (StateFile { header: header.clone(), state }).write(path) {
                eprintln!("warning: checkpoint not written: {e}");
            }
        }
    };
    plexus::interrupt::install().map_err(|e| anyhow::anyhow!("cannot install the interrupt handler: {e}"))?;
    let checkpoint_every = checkpoint.as_ref().map(|(_, every)| *every);
    let session = Session {
        control: RunControl { stop: Some(plexus::interrupt::stop_flag()), stop_at_pass, checkpoint_every },
        checkpoint: checkpoint_every.is_some().then_some(&write_checkpoint as &dyn Fn(RenderState)),
        resume: resume.map(|(state, _)| state),
        shard,
    };
    let progress = BarProgress::new(
        match job.budget {
            Budget::Seconds(s) => Some(s),
            Budget::SamplesPerPixel(_) => None,
        },
        bar_wanted(),
    )
    .with_previews(preview_every.map(|every_seconds| Previews { every_seconds, outputs: images.clone() }));
    let cpu_start = plexus::bench::timing::process_cpu_time();
    let rendered = if keeps_state {
        integrator.render_session(scene, &job, &progress, &session)
    } else {
        integrator.render(scene, &job, &progress).map(|output| SessionOutput { output, state: complete_run() })
    };
    progress.finish();
    let cpu_time = plexus::bench::timing::process_cpu_time().saturating_sub(cpu_start);
    let rendered = rendered?;
    let file = StateFile { header, state: rendered.state };
    // Without a state file to write, an interrupted render still saves its state, beside its first
    // image, under a name no other file has.
    if file.state.interrupted && states.is_empty() {
        states.extend(images.first().map(|p| super::outputs::free_interrupt_state_path(p)));
    }
    let output = rendered.output;
    super::warnings::print_render_warnings(&output);

    state_io::write_images(&images, &output)?;
    state_io::write_states(&states, &file)?;
    let mut stats = RenderStats::new(
        scene_name,
        integrator.name().to_string(),
        integrator.settings_json(),
        job.budget,
        job.seed,
        job.threads,
        file.header.accel.clone(),
        load_time,
        Some(scene.features()),
        &output,
        images.clone(),
    );
    stats.run = state_io::run_info(&file, &states, resume.map(|(_, path)| path), 0);
    stats.cpu_time_s = Some(cpu_time.as_secs_f64());
    let stats_files = state_io::write_stats(&images, &states, &stats)?;
    let written: Vec<PathBuf> = images.iter().chain(&states).chain(&stats_files).cloned().collect();
    state_io::finish(&stats, &written, &file, &states)
}

/// The state record of a render that keeps no state: complete, nothing to continue.
fn complete_run() -> RenderState {
    RenderState {
        passes_done: 0,
        unit_count: 0,
        film_width: 0,
        film_height: 0,
        film: Vec::new(),
        counters: Default::default(),
        part: Vec::new(),
        complete: true,
        interrupted: false,
        wall_time_s: 0.0,
        units: None,
    }
}
