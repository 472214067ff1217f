//! The parallel render driver every integrator reuses, and the render model they share.
//!
//! # The render model
//!
//! A render is a set of deterministic *work items*: every *unit* (an image tile, a batch of light
//! paths, a Markov chain) is visited once per *pass*, and item `(pass, unit)` draws only from the
//! random stream `Rng::new(seed, pass · units + unit)`. What an item adds to the film is recorded
//! in the unit's own [`SplatBuffer`] (its tile's samples, or splats to any pixel) and, when the
//! pass ends, the buffers are applied to the one film **in unit order**. The film's bytes therefore
//! depend on the seed and the work units only: neither on the thread count nor on which thread ran
//! which unit, for splatting integrators (light tracing, BDPT's t = 1 techniques) as much as for
//! tiles. (A buffer applied one value at a time in recorded order gives exactly the sums the unit
//! would have added directly, see [`Accumulator::apply`].) The price is memory: a pass's
//! contributions are all held until it ends, 16 bytes each — a pass of one sample per pixel at
//! 1920×1080 is 33 MB for the path tracer, and a few times that for light tracing or BDPT (one
//! entry per camera connection). Applying each buffer as soon as all lower units are done would
//! bound it, if that ever matters.
//!
//! The film holds **unnormalised sums**. The normalisation (1 / samples per pixel; MLT's per-depth
//! b / mutations) is applied only when an image is produced: the final output and previews. So a
//! film can be merged with another, resumed, or shown at any pass boundary without undoing a scale.
//!
//! A **pass boundary** is where a render can stop, save and resume (interrupts, checkpoints and
//! shards build on it). Everything the rest of the render depends on is then in
//! a [`PassBoundary`]: the passes done, the film's sums, the units' states (a chain's sampler and
//! current path) and the slots' counters and per-slot states. With the scene, the job and the
//! integrator's settings, that is what a checkpoint must save; the next pass is `passes_done` for
//! every unit, whatever machine or thread count resumes it.
//!
//! # Threads
//!
//! Within a pass, unit `u` runs on worker *slot* `u mod threads`, in increasing unit order. A slot
//! owns [`Counters`] (integer sums, so their merge does not depend on the dealing) and the
//! integrator's per-slot state `S` (scratch buffers; statistics). Per-slot state is created once per
//! slot and returned in slot order; it must not carry anything the image depends on, or the image
//! would depend on the dealing again — what a unit's future depends on belongs in the unit. Every
//! worker thread sets flush-to-zero / denormals-are-zero in its start handler (Embree wants it, and
//! it keeps both accelerators' arithmetic identical), and every item runs inside the pool, so no
//! ray is traced from a thread without the flags.
//!
//! # Budgets and the clock
//!
//! A sample budget is a fixed number of passes. A time budget runs passes while the next one is
//! predicted to end before the deadline (at least one pass always runs). Time is read from a
//! [`Clock`]: the wall clock in renders, a fake one in tests, so the budget and preview logic are
//! tested exactly rather than against a loaded machine's timing.
//!
//! # How the integrators fit
//!
//! - **Path tracing, BDPT, light tracing** ([`ImageRender`]): a unit is a tile; an item takes
//!   `spp_in_pass` samples for each of the tile's pixels (for light tracing: as many light paths,
//!   splatted wherever they land) with the item's stream. The image is the film over the samples
//!   per pixel; [`ImagePlan`] computes tiles and the pass schedule.
//! - **MCMC**: a unit is a Markov chain whose state lives in the unit value `U` itself, which the
//!   driver hands back mutably to the kernel on every pass and returns at the end; an item is a
//!   chain *segment* of a fixed number of mutations. The chain keeps its own
//!   `Rng::new(seed, chain)` and may ignore the item stream. A time budget just runs more segments.
//!   Images that are normalised separately share the one film as layers: MLT's per-depth images
//!   are rows [d·H, (d+1)·H) of a W × (H·D) film (`SplatBuffer::splat_in_layer`), each scaled by
//!   its own b_d / iterations only at output, so its image too depends on the seed and the chain
//!   count only, not on the threads.

use std::sync::Arc;
use std::time::{Duration, Instant};

use rayon::{ThreadPool, ThreadPoolBuilder};

use super::{Progress, RenderError, RenderJob};
use crate::film::{Accumulator, Image, SplatBuffer};
use crate::sampling::Rng;
use crate::stats::Counters;

pub mod bootstrap;
mod chains;
mod image;
pub use chains::{
    boundary_counters, chain_output_of_state, chain_scale, expected_value_splats, layers_to_image, load_units,
    merge_chain_parts, run_chains, save_units, ChainBootstrap, ChainEngine, ChainIntegrator, ChainPart, ChainRender,
    ChainRun, ChainStats, Tally,
};
pub use image::{
    state_film, ImageEngine, ImageIntegrator, ImagePart, ImagePlan, ImageRender, ImageRun, Tile, TileSamples, TILE_SIZE,
};

/// A pass should hold at least this many pixel samples, so that the per-pass synchronisation
/// costs nothing measurable even for tiny images.
const MIN_SAMPLES_PER_PASS: u64 = 1 << 16;

/// Where the driver reads the time: the render's budget, pass predictions and preview interval.
pub trait Clock: Send + Sync {
    /// Time since the clock's origin (any fixed instant before the render).
    fn now(&self) -> Duration;
}

/// The real clock: time since it was created.
pub struct WallClock {
    origin: Instant,
}

impl WallClock {
    pub fn new() -> WallClock {
        WallClock { origin: Instant::now() }
    }
}

impl Default for WallClock {
    fn default() -> WallClock {
        WallClock::new()
    }
}

impl Clock for WallClock {
    fn now(&self) -> Duration {
        self.origin.elapsed()
    }
}

/// How many passes to run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Passes {
    /// Exactly this many passes.
    Count(u64),
    /// Passes until this many seconds have elapsed since the run started: a new pass starts only
    /// if it is predicted to end before the deadline (at least one pass always runs). The
    /// prediction is the longer of the last pass and the mean pass so far: the last follows a
    /// change of the machine's load or of the work (a chain segment meeting long paths), the mean
    /// keeps one fast pass from starting a slow one.
    Seconds(f64),
    /// Passes until the driver's clock reads this, by the same rule as `Seconds`: for renders
    /// that work before the run (setup, MLT's bootstrap) and must fit into the user's budget.
    Deadline(Duration),
}

impl Passes {
    /// This schedule with a `Seconds` budget counted from the clock reading `start` (when the
    /// render began, before its setup) instead of from the start of the run, so that setup is
    /// inside the budget. A budget too long for a `Duration` stays `Seconds` (and then never ends
    /// a run early).
    pub fn counted_from(self, start: Duration) -> Passes {
        match self {
            Passes::Seconds(s) => {
                match Duration::try_from_secs_f64(s.max(0.0)).ok().and_then(|d| start.checked_add(d)) {
                    Some(at) => Passes::Deadline(at),
                    None => self,
                }
            }
            other => other,
        }
    }
}

/// One work item: which pass and which unit, and its random stream.
#[derive(Clone, Copy, Debug)]
pub struct WorkItem {
    pub pass: u64,
    pub unit: usize,
    /// `pass · units + unit`: the item's stream index.
    pub stream: u64,
    pub seed: u64,
}

impl WorkItem {
    /// The item's own random stream, derived from (seed, item index) only.
    pub fn rng(&self) -> Rng {
        Rng::new(self.seed, self.stream)
    }
}

/// What a worker slot owns while it runs a unit.
pub struct Slot<S> {
    /// Slot index, 0..threads.
    pub index: usize,
    /// The film contributions of the item being run: the unit's own buffer, which the driver
    /// swaps in for the item and applies to the film in unit order when the pass ends.
    pub film: SplatBuffer,
    pub counters: Counters,
    pub state: S,
}

/// A run between two passes: everything the rest of the render depends on (see the module docs),
/// so what a checkpoint would save. Previews are built from it.
pub struct PassBoundary<'a, U, S> {
    /// Passes completed; the next pass runs items `(passes_done, unit)` for every unit.
    pub passes_done: u64,
    /// Unnormalised sums of every contribution of the passes done, applied in unit order.
    pub film: &'a Accumulator,
    /// The units, in unit order, with the state the kernel left in them.
    pub units: &'a [U],
    /// The slots (counters and per-slot state; their buffers are empty), in slot order.
    pub slots: &'a [Slot<S>],
    /// Clock time the run has taken, and its last pass took: what a time budget's next decision
    /// depends on.
    pub elapsed: Duration,
    pub last_pass: Duration,
}

/// Builds a preview image from a pass boundary (see `Driver::run`).
pub type Snapshot<'a, U, S> = dyn Fn(&PassBoundary<'_, U, S>) -> Image + 'a;

/// Receives a pass boundary to save as a checkpoint (see [`RunControl::checkpoint_every`]).
pub type CheckpointHook<'a, U, S> = dyn Fn(&PassBoundary<'_, U, S>) + 'a;

// What can stop a run lives in the job layer, below the state files that carry it in a
// `Session`; it is the driver that reads it.
pub use crate::job::RunControl;

/// Which side of a pass a [`PassHook`] is called on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PassEdge {
    /// Before the pass's items run.
    Before,
    /// After its buffers are applied, before previews and checkpoints read the boundary.
    After,
}

/// Work on the units between passes, on the driver's thread (ensemble MLT moves the fixed
/// ensemble's paths into the view its chains read during the pass, and back after it).
pub type PassHook<'a, U> = dyn Fn(PassEdge, u64, &mut [U]) + 'a;

/// Which passes of the schedule a run renders: pass p when p mod `count` = `index` (the pass
/// shards of pt, BDPT and light tracing); every pass by default.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassSet {
    pub index: u64,
    pub count: u64,
}

impl PassSet {
    pub const ALL: PassSet = PassSet { index: 0, count: 1 };

    pub fn contains(&self, pass: u64) -> bool {
        pass % self.count.max(1) == self.index
    }

    /// How many of passes `0..n` are in the set.
    pub fn count_below(&self, n: u64) -> u64 {
        let count = self.count.max(1);
        n / count + u64::from(n % count > self.index)
    }
}

/// Where a run starts: the schedule position and what the passes before left (a resumed render),
/// or the beginning ([`RunStart::fresh`]).
pub struct RunStart<U, S> {
    pub units: Vec<U>,
    /// The first pass of the schedule this run may render.
    pub next_pass: u64,
    /// The film's sums so far; a zero film when `None`.
    pub film: Option<Accumulator>,
    /// The counters and per-slot state the earlier runs' slots summed to: slot 0 starts from them
    /// (the end-of-run merge in slot order then adds them first), the others from `init_slot`.
    pub saved_slot: Option<(Counters, S)>,
    pub passes: PassSet,
}

impl<U, S> RunStart<U, S> {
    /// A run from pass 0 with a zero film, every pass.
    pub fn fresh(units: Vec<U>) -> RunStart<U, S> {
        RunStart { units, next_pass: 0, film: None, saved_slot: None, passes: PassSet::ALL }
    }
}

/// What a run produced.
pub struct RunOutput<U, S> {
    /// The film: unnormalised sums, every unit's contributions applied in unit order.
    pub film: Accumulator,
    /// The slots' counters summed in slot order.
    pub counters: Counters,
    /// The units, in unit order, with whatever state the kernel left in them.
    pub units: Vec<U>,
    /// Per-slot states, in slot order.
    pub slot_states: Vec<S>,
    /// The schedule position reached: every pass below it that the run's `PassSet` holds is done.
    pub passes: u64,
    /// Passes this run rendered (fewer than `passes` for a resumed or sharded run).
    pub passes_run: u64,
    /// Whether the run ended early because its `RunControl` asked it to stop.
    pub stopped: bool,
    /// Clock time the run took.
    pub elapsed: Duration,
}

/// A thread pool, a clock and the job's seed: runs passes of work items deterministically.
pub struct Driver {
    pool: ThreadPool,
    threads: usize,
    seed: u64,
    width: usize,
    height: usize,
    clock: Arc<dyn Clock>,
}

impl Driver {
    /// A driver for a `width`×`height` film with the job's thread count (0 means all available
    /// cores) and seed, on the wall clock.
    pub fn new(job: &RenderJob, width: u32, height: u32) -> Result<Driver, RenderError> {
        Driver::with_clock(job, width, height, Arc::new(WallClock::new()))
    }

    /// The same on the given clock.
    pub fn with_clock(job: &RenderJob, width: u32, height: u32, clock: Arc<dyn Clock>) -> Result<Driver, RenderError> {
        // Work units record pixels as u32 indices (`SplatBuffer`).
        if width as u64 * height as u64 > u32::MAX as u64 {
            return Err(RenderError::FilmTooLarge { width, height });
        }
        let threads =
            if job.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { job.threads };
        super::check_threads(threads, "threads")?;
        let pool = ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("plexus-worker-{i}"))
            .start_handler(|_| crate::process::denormals::set_flush_denormals())
            .build()
            .map_err(|e| RenderError::ThreadPool(e.to_string()))?;
        Ok(Driver { pool, threads, seed: job.seed, width: width as usize, height: height as usize, clock })
    }

    /// Number of worker slots (= threads).
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// The clock the driver's budgets and previews read.
    pub fn clock(&self) -> &dyn Clock {
        self.clock.as_ref()
    }

    /// Runs `kernel` on every (pass, unit) item. The kernel gets the item, its unit's state and its
    /// slot (whose `film` is the unit's buffer), and returns the progress units it completed (e.g.
    /// pixel samples), which are reported to `progress` after each item. When `progress` asks for
    /// previews (`Progress::preview_interval`) and a `snapshot` is given, at pass boundaries at
    /// most that often (by the clock) `snapshot` builds the current normalised image, which
    /// `progress.preview` receives. Previews only read the boundary, so the image and its
    /// determinism do not depend on them.
    pub fn run<U, S, K>(
        &self,
        units: Vec<U>,
        passes: Passes,
        progress: &dyn Progress,
        init_slot: impl Fn(usize) -> S,
        kernel: K,
        snapshot: Option<&Snapshot<'_, U, S>>,
    ) -> RunOutput<U, S>
    where
        U: Send,
        S: Send + Sync,
        K: Fn(&WorkItem, &mut U, &mut Slot<S>) -> u64 + Sync,
    {
        self.run_from(
            RunStart::fresh(units),
            passes,
            progress,
            init_slot,
            kernel,
            snapshot,
            RunControl::default(),
            None,
            None,
        )
    }

    /// [`Driver::run`] from `start` (a resumed render, or a shard's set of passes), under
    /// `control`: before each pass the run ends if `control` asks it to stop, and after a pass at
    /// most every `control.checkpoint_every` the boundary goes to `checkpoint`; `hook` sees the
    /// units before and after every pass it runs. A budget of
    /// `Passes::Count(n)` means schedule positions below n, so a resumed run ends where the
    /// uninterrupted one would have; a time budget counts from this run's start.
    #[allow(clippy::too_many_arguments)]
    pub fn run_from<U, S, K>(
        &self,
        start: RunStart<U, S>,
        passes: Passes,
        progress: &dyn Progress,
        init_slot: impl Fn(usize) -> S,
        kernel: K,
        snapshot: Option<&Snapshot<'_, U, S>>,
        control: RunControl<'_>,
        checkpoint: Option<&CheckpointHook<'_, U, S>>,
        hook: Option<&PassHook<'_, U>>,
    ) -> RunOutput<U, S>
    where
        U: Send,
        S: Send + Sync,
        K: Fn(&WorkItem, &mut U, &mut Slot<S>) -> u64 + Sync,
    {
        let RunStart { mut units, next_pass, film: start_film, saved_slot, passes: pass_set } = start;
        let clock = self.clock.as_ref();
        let start = clock.now();
        let preview_every = progress
            .preview_interval()
            .filter(|s| s.is_finite() && *s > 0.0)
            .and_then(|s| Duration::try_from_secs_f64(s).ok());
        let mut last_preview = start;
        let mut last_checkpoint = start;
        let unit_count = units.len();
        let threads = self.threads;
        let (width, height) = (self.width, self.height);
        let mut film = start_film.unwrap_or_else(|| Accumulator::new(width, height));
        debug_assert_eq!((film.width, film.height), (width, height));
        let mut buffers: Vec<SplatBuffer> = (0..unit_count).map(|_| SplatBuffer::new(width, height)).collect();
        let mut slots: Vec<Slot<S>> = (0..threads)
            .map(|index| Slot {
                index,
                film: SplatBuffer::new(width, height),
                counters: Counters::default(),
                state: init_slot(index),
            })
            .collect();
        if let (Some((counters, state)), Some(first)) = (saved_slot, slots.first_mut()) {
            first.counters = counters;
            first.state = state;
        }

        let seed = self.seed;
        // The clock reading by which passes must end; `None` for pass counts, and for a budget
        // beyond what a `Duration` can hold (which then never ends a run early).
        let deadline = match passes.counted_from(start) {
            Passes::Deadline(at) => Some(at),
            _ => None,
        };
        let mut pass = next_pass;
        let mut passes_run = 0u64;
        let mut stopped = false;
        let mut last_pass = Duration::ZERO;
        loop {
            while !pass_set.contains(pass) {
                pass += 1;
            }
            let go = unit_count > 0
                && match passes {
                    Passes::Count(n) => pass < n,
                    Passes::Seconds(_) | Passes::Deadline(_) => {
                        let now = clock.now();
                        let mean = now.saturating_sub(start).div_f64(passes_run.max(1) as f64);
                        let predicted = last_pass.max(mean);
                        passes_run == 0
                            || deadline.is_none_or(|at| now.checked_add(predicted).is_some_and(|end| end <= at))
                    }
                };
            if !go {
                break;
            }
            if control.stop_requested(pass) {
                stopped = true;
                break;
            }
            let pass_start = clock.now();
            if let Some(hook) = hook {
                hook(PassEdge::Before, pass, &mut units);
            }
            // Deal the units to slots: unit u to slot u mod threads, in increasing unit order.
            let mut dealt: Vec<Vec<(usize, &mut U, &mut SplatBuffer)>> =
                (0..threads).map(|_| Vec::with_capacity(unit_count / threads + 1)).collect();
            for (u, (unit, buffer)) in units.iter_mut().zip(buffers.iter_mut()).enumerate() {
                dealt[u % threads].push((u, unit, buffer));
            }
            let kernel = &kernel;
            self.pool.scope(|scope| {
                for (slot, items) in slots.iter_mut().zip(dealt) {
                    scope.spawn(move |_| {
                        for (u, unit, buffer) in items {
                            let item = WorkItem { pass, unit: u, stream: pass * unit_count as u64 + u as u64, seed };
                            std::mem::swap(&mut slot.film, buffer);
                            let done = kernel(&item, unit, slot);
                            std::mem::swap(&mut slot.film, buffer);
                            progress.advance(done);
                        }
                    });
                }
            });
            // The merge in unit order that makes the film independent of the dealing.
            for buffer in buffers.iter_mut() {
                film.apply(buffer);
                buffer.clear();
            }
            if let Some(hook) = hook {
                hook(PassEdge::After, pass, &mut units);
            }
            let now = clock.now();
            last_pass = now.saturating_sub(pass_start);
            pass += 1;
            passes_run += 1;
            let preview_due = preview_every.filter(|every| now.saturating_sub(last_preview) >= *every).and(snapshot);
            let checkpoint_due =
                control.checkpoint_every.filter(|every| now.saturating_sub(last_checkpoint) >= *every).and(checkpoint);
            if preview_due.is_some() || checkpoint_due.is_some() {
                let boundary = PassBoundary {
                    passes_done: pass,
                    film: &film,
                    units: &units,
                    slots: &slots,
                    elapsed: now.saturating_sub(start),
                    last_pass,
                };
                if let Some(snapshot) = preview_due {
                    progress.preview(&snapshot(&boundary));
                    last_preview = now;
                }
                if let Some(checkpoint) = checkpoint_due {
                    checkpoint(&boundary);
                    last_checkpoint = clock.now();
                }
            }
        }

        if let Passes::Count(n) = passes {
            // Skipping another set's passes may have stepped past the end of the schedule.
            pass = pass.min(n.max(next_pass));
        }
        let mut counters = Counters::default();
        let mut slot_states = Vec::with_capacity(threads);
        for slot in slots {
            counters.merge(&slot.counters);
            slot_states.push(slot.state);
        }
        RunOutput {
            film,
            counters,
            units,
            slot_states,
            passes: pass,
            passes_run,
            stopped,
            elapsed: clock.now().saturating_sub(start),
        }
    }
}

#[cfg(test)]
mod tests;
