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
//! shards, issues 19 and 21, build on it). Everything the rest of the render depends on is then in
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

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rayon::{ThreadPool, ThreadPoolBuilder};

use super::{Budget, Progress, RenderError, RenderJob, RenderOutput};
use crate::film::{Accumulator, Image, SplatBuffer};
use crate::sampling::Rng;
use crate::state::{RenderState, Session, StateError};
use crate::stats::Counters;

/// Side length in pixels of the square tiles image-space integrators split the film into.
pub const TILE_SIZE: u32 = 16;

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

/// What can end a run before its budget, and how often it offers checkpoints: both only at pass
/// boundaries, so what is saved is a state the render model can resume from (issue 19).
#[derive(Clone, Copy, Debug, Default)]
pub struct RunControl<'a> {
    /// Set (by a signal handler) to stop at the next pass boundary.
    pub stop: Option<&'a AtomicBool>,
    /// Stop when the schedule reaches this pass (`passes_done` ≥ it): a deterministic stand-in for
    /// a signal, for tests of interrupt and resume.
    pub stop_at_pass: Option<u64>,
    /// Offer a checkpoint at a pass boundary once at least this long has passed since the run
    /// started or the last one.
    pub checkpoint_every: Option<Duration>,
}

impl RunControl<'_> {
    fn stop_requested(&self, passes_done: u64) -> bool {
        self.stop.is_some_and(|f| f.load(Ordering::SeqCst)) || self.stop_at_pass.is_some_and(|n| passes_done >= n)
    }
}

/// Which passes of the schedule a run renders: pass p when p mod `count` = `index` (issue 21:
/// the pass shards of pt, BDPT and light tracing); every pass by default.
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
            .start_handler(|_| crate::accel::embree::set_flush_denormals())
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
        )
    }

    /// [`Driver::run`] from `start` (a resumed render, or a shard's set of passes), under
    /// `control`: before each pass the run ends if `control` asks it to stop, and after a pass at
    /// most every `control.checkpoint_every` the boundary goes to `checkpoint`. A budget of
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

/// A rectangle of pixels `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Tile {
    pub fn pixel_count(&self) -> u64 {
        (self.x1 - self.x0) as u64 * (self.y1 - self.y0) as u64
    }
    /// The tile's pixels in row-major order.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| (x, y)))
    }
}

/// The schedule of an image-space integrator (one sample = one camera path per pixel): tiles, and
/// how many samples per pixel each pass takes. Depends only on the resolution and budget (and, for
/// a resumed render, on what the saved passes took), so it is part of what makes a render
/// reproducible.
#[derive(Clone, Debug)]
pub struct ImagePlan {
    pub tiles: Vec<Tile>,
    /// Samples per pixel in each pass.
    pub spp_per_pass: u64,
    pub passes: Passes,
    /// Total samples per pixel, when known in advance (sample budgets).
    pub total_spp: Option<u64>,
    /// A resumed render: passes done before, and the samples per pixel they took. The passes from
    /// `base_passes` on take `spp_per_pass` each (the last of a sample budget fewer).
    pub base_passes: u64,
    pub base_spp: u64,
}

impl ImagePlan {
    /// Tiles the `width`×`height` film. For `Budget::SamplesPerPixel(n)` the passes take
    /// `spp_per_pass` samples each (as many as make a pass hold about 2^16 pixel samples, but never
    /// more than `n`), the last pass fewer if needed; the image is the per-pixel mean. For a time
    /// budget every pass takes one sample per pixel, so the image stays the mean of equally many
    /// samples at every pixel and the budget is overrun by less than one such pass.
    pub fn new(width: u32, height: u32, budget: Budget) -> ImagePlan {
        let pixels = (width as u64 * height as u64).max(1);
        let per_pass = match budget {
            Budget::SamplesPerPixel(n) => MIN_SAMPLES_PER_PASS.div_ceil(pixels).max(1).min(n.max(1)),
            Budget::Seconds(_) => 1,
        };
        ImagePlan::resumed(width, height, budget, per_pass, 0, 0)
    }

    /// The plan that continues a render after `base_passes` passes of `spp_per_pass` samples per
    /// pixel (`base_spp` in all) with `budget`: for a sample budget the render's new total, for
    /// a time budget the time this run may take.
    pub fn resumed(
        width: u32,
        height: u32,
        budget: Budget,
        spp_per_pass: u64,
        base_passes: u64,
        base_spp: u64,
    ) -> Self {
        let mut tiles = Vec::new();
        for y0 in (0..height).step_by(TILE_SIZE as usize) {
            for x0 in (0..width).step_by(TILE_SIZE as usize) {
                tiles.push(Tile { x0, y0, x1: (x0 + TILE_SIZE).min(width), y1: (y0 + TILE_SIZE).min(height) });
            }
        }
        let spp_per_pass = spp_per_pass.max(1);
        let (passes, total_spp) = match budget {
            Budget::SamplesPerPixel(n) => {
                (Passes::Count(base_passes + n.saturating_sub(base_spp).div_ceil(spp_per_pass)), Some(n.max(base_spp)))
            }
            Budget::Seconds(s) => (Passes::Seconds(s), None),
        };
        ImagePlan { tiles, spp_per_pass, passes, total_spp, base_passes, base_spp }
    }

    /// Samples per pixel that pass `pass` (at or after `base_passes`) takes (the last pass of a
    /// sample budget may take fewer).
    pub fn spp_in_pass(&self, pass: u64) -> u64 {
        let before = self.base_spp + pass.saturating_sub(self.base_passes) * self.spp_per_pass;
        match self.total_spp {
            Some(total) => self.spp_per_pass.min(total.saturating_sub(before)),
            None => self.spp_per_pass,
        }
    }

    /// Samples per pixel after the passes below `passes` are done.
    pub fn spp_after(&self, passes: u64) -> u64 {
        let run = passes.saturating_sub(self.base_passes) * self.spp_per_pass;
        self.base_spp
            + match self.total_spp {
                Some(total) => run.min(total - self.base_spp),
                None => run,
            }
    }

    /// Samples per pixel that the passes of `set` below `passes` took (a shard's share; the
    /// whole render's for `PassSet::ALL`). Every pass but a sample budget's last is full.
    pub fn spp_in_set(&self, set: PassSet, passes: u64) -> u64 {
        if set == PassSet::ALL || passes <= self.base_passes {
            return self.spp_after(passes);
        }
        let last = passes - 1;
        let full = set.count_below(last).saturating_sub(set.count_below(self.base_passes)) * self.spp_per_pass;
        full + if set.contains(last) { self.spp_in_pass(last) } else { 0 }
    }
}

/// The integrator part of the state of a pt, BDPT or light tracing render (`crate::state`): the
/// tiles carry nothing between passes, so what the render did is the schedule position (in the
/// state), the pass size and the samples per pixel its film holds.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImagePart {
    pub spp_per_pass: u64,
    pub spp_done: u64,
}

impl ImagePart {
    /// Merges shards' parts: their samples per pixel add up.
    pub fn merge(parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        let mut merged: Option<ImagePart> = None;
        for bytes in parts {
            let part: ImagePart = crate::state::decode(bytes)?;
            match merged.as_mut() {
                None => merged = Some(part),
                Some(m) if m.spp_per_pass == part.spp_per_pass => m.spp_done += part.spp_done,
                Some(_) => {
                    return Err(
                        StateError::Mismatch("the shards' passes take different samples per pixel".into()).into()
                    )
                }
            }
        }
        Ok(crate::state::encode(&merged.ok_or_else(|| StateError::Mismatch("no shard".into()))?)?)
    }

    /// The output of a state: the film over its samples per pixel, with the statistics a render
    /// reports (`ImageRender::run`).
    pub fn output_of_state(state: &RenderState) -> Result<RenderOutput, RenderError> {
        let part: ImagePart = crate::state::decode(&state.part)?;
        let film = state_film(state);
        let scale = if part.spp_done > 0 { 1.0 / part.spp_done as f64 } else { 0.0 };
        Ok(RenderOutput {
            image: film.to_image(scale),
            layers: Vec::new(),
            counters: state.counters.clone(),
            wall_time: Duration::try_from_secs_f64(state.wall_time_s).unwrap_or_default(),
            extra_stats: serde_json::json!({
                "spp": part.spp_done,
                "passes": state.passes_done,
                "spp_per_pass": part.spp_per_pass,
                "tiles": state.unit_count,
            }),
        })
    }
}

/// The film of a state, as an accumulator.
pub fn state_film(state: &RenderState) -> Accumulator {
    Accumulator::from_sums(state.film_width as usize, state.film_height as usize, state.film.clone())
}

/// What every image-space integrator (pt, BDPT, light tracing) does around its per-sample kernel:
/// the schedule, the progress total, the driver, previews, the normalisation and the output with
/// its common statistics. The clock starts when it is created, so the integrator's setup between
/// `new` and `run` is inside a time budget and the reported wall time.
pub struct ImageRender<'a> {
    driver: Driver,
    plan: ImagePlan,
    progress: &'a dyn Progress,
    /// The clock's reading when the render began.
    started: Duration,
    session: Session<'a>,
    passes: PassSet,
    /// Wall time of the runs a resumed render continues.
    earlier_seconds: f64,
    /// Whether `run` returns the state reached (`ImageRun::state`).
    save: bool,
}

/// What [`ImageRender::run`] produced.
pub struct ImageRun {
    /// The image (film × `scale`), counters, wall time, and the statistics `spp`, `passes`,
    /// `spp_per_pass`, `tiles`, `threads`; no layers.
    pub output: RenderOutput,
    /// The film: unnormalised sums, every unit applied in unit order.
    pub film: Accumulator,
    /// The normalisation applied to the film: 1 / samples per pixel (0 if no pass ran), for any
    /// further films an integrator keeps (BDPT's technique layers).
    pub scale: f64,
    /// The state reached, when the render ran under a session (`ImageRender::with_session`).
    pub state: Option<RenderState>,
}

impl<'a> ImageRender<'a> {
    /// A render of the job on a `width`×`height` film, on the wall clock.
    pub fn new(job: &RenderJob, width: u32, height: u32, progress: &'a dyn Progress) -> Result<Self, RenderError> {
        ImageRender::with_clock(job, width, height, progress, Arc::new(WallClock::new()))
    }

    /// The same on the given clock.
    pub fn with_clock(
        job: &RenderJob,
        width: u32,
        height: u32,
        progress: &'a dyn Progress,
        clock: Arc<dyn Clock>,
    ) -> Result<Self, RenderError> {
        // Before any product of the budget with the pixels (`progress.set_total`, the passes).
        super::check_budget(job.budget, width, height, "budget")?;
        let started = clock.now();
        let plan = ImagePlan::new(width, height, job.budget);
        if let Some(spp) = plan.total_spp {
            progress.set_total(spp * width as u64 * height as u64);
        }
        let driver = Driver::with_clock(job, width, height, clock)?;
        Ok(ImageRender {
            driver,
            plan,
            progress,
            started,
            session: Session::default(),
            passes: PassSet::ALL,
            earlier_seconds: 0.0,
            save: false,
        })
    }

    /// Runs under `session` (`crate::state`), with `save` returning the state reached: a resumed render continues the saved schedule from
    /// its state (the job's budget is then the new total, or the time this run may take); a shard
    /// renders passes p ≡ K (mod N) of the schedule.
    pub fn with_session(mut self, session: Session<'a>, save: bool) -> Result<Self, RenderError> {
        self.save = save;
        let (width, height) = (self.driver.width as u32, self.driver.height as u32);
        if let Some(state) = session.resume {
            if (state.film_width, state.film_height) != (width, height)
                || state.unit_count != self.plan.tiles.len() as u64
            {
                return Err(
                    StateError::Mismatch("the checkpoint's film does not match the scene's resolution".into()).into()
                );
            }
            let part: ImagePart = crate::state::decode(&state.part)?;
            let budget = match self.plan.total_spp {
                Some(n) => Budget::SamplesPerPixel(n),
                None => match self.plan.passes {
                    Passes::Seconds(s) => Budget::Seconds(s),
                    _ => Budget::Seconds(0.0),
                },
            };
            self.plan = ImagePlan::resumed(width, height, budget, part.spp_per_pass, state.passes_done, part.spp_done);
            self.earlier_seconds = state.wall_time_s;
            if let Some(total) = self.plan.total_spp {
                self.progress.set_total((total - part.spp_done) * width as u64 * height as u64);
            }
        }
        if let Some(shard) = session.shard {
            self.passes = PassSet { index: shard.index, count: shard.count };
            if let Passes::Count(n) = self.plan.passes {
                self.progress.set_total(self.plan.spp_in_set(self.passes, n) * width as u64 * height as u64);
            }
        }
        self.session = session;
        Ok(self)
    }

    pub fn plan(&self) -> &ImagePlan {
        &self.plan
    }

    /// The state at a pass boundary: the film, the slots' counters, the samples per pixel done.
    fn state_at(&self, passes_done: u64, film: &Accumulator, counters: Counters, elapsed: Duration) -> RenderState {
        let spp_done = self.plan.spp_in_set(self.passes, passes_done);
        let part = ImagePart { spp_per_pass: self.plan.spp_per_pass, spp_done };
        let complete = match self.plan.passes {
            Passes::Count(n) => passes_done >= n,
            _ => false,
        };
        RenderState {
            passes_done,
            unit_count: self.plan.tiles.len() as u64,
            film_width: film.width as u32,
            film_height: film.height as u32,
            film: film.sums().to_vec(),
            counters,
            // An `ImagePart` is two integers: its encoding cannot fail.
            part: crate::state::encode(&part).unwrap_or_default(),
            complete,
            interrupted: false,
            wall_time_s: if self.session.shard.is_some() { 0.0 } else { self.earlier_seconds + elapsed.as_secs_f64() },
        }
    }

    /// Renders: for every pass and tile, `sample(x, y, rng, slot)` once per sample of each of the
    /// tile's pixels (pixels in row-major order, a pixel's samples in a row), all drawing from the
    /// item's stream `rng` and adding to `slot.film` — at (x, y), or anywhere (light tracing uses
    /// (x, y) only to count its paths). `init_slot` creates the per-slot state, which is returned
    /// in slot order.
    pub fn run<S, K>(&self, init_slot: impl Fn(usize) -> S, sample: K) -> (ImageRun, Vec<S>)
    where
        S: Send + Sync,
        K: Fn(u32, u32, &mut Rng, &mut Slot<S>) + Sync,
    {
        let plan = &self.plan;
        let set = self.passes;
        let preview = |at: &PassBoundary<'_, Tile, S>| {
            let spp = plan.spp_in_set(set, at.passes_done);
            at.film.to_image(if spp > 0 { 1.0 / spp as f64 } else { 0.0 })
        };
        let merged_counters = |slots: &[Slot<S>]| {
            let mut counters = Counters::default();
            for slot in slots {
                counters.merge(&slot.counters);
            }
            counters
        };
        let checkpoint = |at: &PassBoundary<'_, Tile, S>| {
            if let Some(sink) = self.session.checkpoint {
                let elapsed = self.driver.clock().now().saturating_sub(self.started);
                sink(self.state_at(at.passes_done, at.film, merged_counters(at.slots), elapsed));
            }
        };
        let resume = self.session.resume;
        let start = RunStart {
            units: plan.tiles.clone(),
            next_pass: resume.map_or(0, |s| s.passes_done),
            film: resume.map(state_film),
            saved_slot: resume.map(|s| (s.counters.clone(), init_slot(0))),
            passes: set,
        };
        let out = self.driver.run_from(
            start,
            plan.passes.counted_from(self.started),
            self.progress,
            init_slot,
            |item, tile, slot| {
                let spp = plan.spp_in_pass(item.pass);
                let mut rng = item.rng();
                for (x, y) in tile.pixels() {
                    for _ in 0..spp {
                        sample(x, y, &mut rng, slot);
                    }
                }
                let samples = spp * tile.pixel_count();
                slot.counters.samples += samples;
                samples
            },
            Some(&preview),
            self.session.control,
            self.session.checkpoint.is_some().then_some(&checkpoint as &CheckpointHook<'_, Tile, S>),
        );
        let spp = plan.spp_in_set(set, out.passes);
        let scale = if spp > 0 { 1.0 / spp as f64 } else { 0.0 };
        let wall_time = self.driver.clock().now().saturating_sub(self.started);
        let state = self.save.then(|| {
            let mut state = self.state_at(out.passes, &out.film, out.counters.clone(), wall_time);
            state.interrupted = out.stopped;
            state
        });
        let output = RenderOutput {
            image: out.film.to_image(scale),
            layers: Vec::new(),
            counters: out.counters,
            wall_time: wall_time + Duration::try_from_secs_f64(self.earlier_seconds).unwrap_or_default(),
            extra_stats: serde_json::json!({
                "spp": spp,
                "passes": out.passes,
                "spp_per_pass": plan.spp_per_pass,
                "tiles": plan.tiles.len(),
                "threads": self.driver.threads(),
            }),
        };
        (ImageRun { output, film: out.film, scale, state }, out.slot_states)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Mutex;

    use super::*;
    use crate::integrator::NoProgress;
    use crate::spectrum::Rgb;

    /// A clock that only moves when told: kernels advance it by what their work "costs", so a
    /// pass's duration is the sum of its items' costs, whatever the threads and the machine's load.
    #[derive(Default)]
    struct FakeClock(AtomicU64);

    impl FakeClock {
        fn advance(&self, by: Duration) {
            self.0.fetch_add(by.as_nanos() as u64, Ordering::SeqCst);
        }
    }

    impl Clock for FakeClock {
        fn now(&self) -> Duration {
            Duration::from_nanos(self.0.load(Ordering::SeqCst))
        }
    }

    const MS: Duration = Duration::from_millis(1);

    fn job(threads: usize, seed: u64) -> RenderJob {
        RenderJob { budget: Budget::SamplesPerPixel(1), seed, threads }
    }

    /// A kernel that splats random values to random pixels: the worst case for determinism.
    fn splat_run(threads: usize, seed: u64) -> (Accumulator, Counters, u64) {
        let driver = Driver::new(&job(threads, seed), 7, 5).expect("pool");
        let out = driver.run(
            vec![0u32; 13],
            Passes::Count(3),
            &NoProgress,
            |_| (),
            |item, visits, slot| {
                let mut rng = item.rng();
                for _ in 0..50 {
                    let x = (rng.uniform() * 7.0) as usize;
                    let y = (rng.uniform() * 5.0) as usize;
                    // Values over 2^±30: wider than f64 can sum exactly, so the order of the
                    // additions shows in the film's bits.
                    let value = rng.uniform() * 2f32.powi((rng.uniform() * 60.0) as i32 - 30);
                    slot.film.add(x, y, Rgb::splat(value));
                }
                *visits += 1;
                slot.counters.samples += 50;
                50
            },
            None,
        );
        assert!(out.units.iter().all(|&v| v == 3), "every unit runs once per pass");
        (out.film, out.counters, out.passes)
    }

    fn film_bits(film: &Accumulator) -> Vec<[u64; 3]> {
        film.sums().iter().map(|s| s.map(f64::to_bits)).collect()
    }

    /// Same seed: a bit-identical film for 1, 2 and 3 threads (units applied in unit order);
    /// other seed: another film. With a film per slot merged in slot order (the old driver), the
    /// film sums of 1 and 3 threads differed at 18 of the 35 pixels.
    #[test]
    fn splatting_run_depends_on_seed_only_not_on_threads() {
        let (a, ca, pa) = splat_run(3, 11);
        assert_eq!(pa, 3);
        assert_eq!(ca.samples, 13 * 3 * 50);
        for threads in [1, 2, 3] {
            let (b, cb, _) = splat_run(threads, 11);
            assert_eq!(film_bits(&a), film_bits(&b), "{threads} threads");
            assert_eq!(cb.samples, ca.samples);
        }
        let (c, _, _) = splat_run(3, 12);
        assert_ne!(film_bits(&a), film_bits(&c));
    }

    /// Runs 4 units on 2 threads; the unit of pass p costs `cost(p)` on the fake clock and adds 1
    /// to pixel (0, 0). Returns the run and the clock.
    fn timed_run(
        passes: Passes,
        progress: &dyn Progress,
        clock: Arc<FakeClock>,
        cost: impl Fn(u64) -> Duration + Sync,
    ) -> RunOutput<(), ()> {
        let driver = Driver::with_clock(&job(2, 1), 4, 4, clock.clone()).expect("pool");
        driver.run(
            vec![(); 4],
            passes,
            progress,
            |_| (),
            |item, _, slot| {
                clock.advance(cost(item.pass));
                slot.film.add(0, 0, Rgb::ONE);
                1
            },
            // Four units per pass each add 1 to pixel (0, 0): the normalised image reads 1.
            Some(&|at: &PassBoundary<'_, (), ()>| at.film.to_image(1.0 / (4 * at.passes_done) as f64)),
        )
    }

    /// 4 units × 5 ms = 20 ms per pass: a 0.1 s budget holds exactly 5 passes (the fifth is
    /// predicted to end at 100 ms, which fits; a sixth would end at 120 ms).
    #[test]
    fn time_budget_runs_exactly_the_passes_that_fit() {
        let clock = Arc::new(FakeClock::default());
        let out = timed_run(Passes::Seconds(0.1), &NoProgress, clock.clone(), |_| 5 * MS);
        assert_eq!(out.passes, 5);
        assert_eq!(out.elapsed, 100 * MS);
        assert_eq!(clock.now(), 100 * MS);
        // A deadline on the clock, with 30 ms gone before the run (setup): 3 passes fit in 70 ms.
        let clock = Arc::new(FakeClock::default());
        clock.advance(30 * MS);
        let out = timed_run(Passes::Deadline(100 * MS), &NoProgress, clock.clone(), |_| 5 * MS);
        assert_eq!((out.passes, clock.now()), (3, 90 * MS));
        // `counted_from` turns a budget into a deadline from the render's start.
        assert_eq!(Passes::Seconds(0.1).counted_from(30 * MS), Passes::Deadline(130 * MS));
        assert_eq!(Passes::Count(3).counted_from(30 * MS), Passes::Count(3));
        assert_eq!(Passes::Seconds(1e300).counted_from(MS), Passes::Seconds(1e300));
    }

    /// A pass starts only if predicted to fit, the prediction being the longer of the last pass
    /// and the mean pass. Budget 0.1 s:
    /// - passes of 10, 10, 10, 50 ms end at 80 ms; the next is predicted at 50 ms (the last) and
    ///   does not start, where a mean-only rule (20 ms) would start a fifth (which, were it as slow
    ///   as the fourth, would end at 130 ms);
    /// - two passes of 30 ms, then passes of 1 ms: the 40th ends at 98 ms, when the mean (2.45 ms)
    ///   predicts an end at 100.45 ms, so no 41st starts; a last-only rule would run 42 passes.
    #[test]
    fn a_pass_starts_only_if_predicted_to_fit() {
        let slow_fourth = |p: u64| if p == 3 { 50 * MS / 4 } else { 10 * MS / 4 };
        let clock = Arc::new(FakeClock::default());
        let out = timed_run(Passes::Seconds(0.1), &NoProgress, clock.clone(), slow_fourth);
        assert_eq!((out.passes, clock.now()), (4, 80 * MS));
        let slow_start = |p: u64| if p < 2 { 30 * MS / 4 } else { MS / 4 };
        let clock = Arc::new(FakeClock::default());
        let out = timed_run(Passes::Seconds(0.1), &NoProgress, clock.clone(), slow_start);
        assert_eq!((out.passes, clock.now()), (40, 98 * MS));
    }

    /// At least one pass always runs, so there is an image: a zero budget, and a deadline that
    /// setup has already passed.
    #[test]
    fn at_least_one_pass_runs() {
        let out = timed_run(Passes::Seconds(0.0), &NoProgress, Arc::new(FakeClock::default()), |_| MS);
        assert_eq!(out.passes, 1);
        let clock = Arc::new(FakeClock::default());
        clock.advance(200 * MS);
        let out = timed_run(Passes::Deadline(100 * MS), &NoProgress, clock, |_| MS);
        assert_eq!(out.passes, 1);
    }

    /// Records the preview images' pixel (0, 0) and the clock when each arrived.
    struct Recorder {
        every: f64,
        clock: Arc<FakeClock>,
        previews: Mutex<Vec<(Duration, f32)>>,
    }

    impl Progress for Recorder {
        fn set_total(&self, _: u64) {}
        fn advance(&self, _: u64) {}
        fn message(&self, _: &str) {}
        fn preview_interval(&self) -> Option<f64> {
            Some(self.every)
        }
        fn preview(&self, image: &Image) {
            self.previews.lock().expect("lock").push((self.clock.now(), image.pixels[0].x));
        }
    }

    /// Previews arrive at pass boundaries once at least the interval has passed since the last
    /// (or the start), and show the normalised image so far. 20 ms passes, 50 ms interval, 30
    /// passes: a preview after every third pass (60, 120, ..., 600 ms), each reading exactly 1.
    #[test]
    fn previews_are_rate_limited_and_normalised() {
        let clock = Arc::new(FakeClock::default());
        let recorder = Recorder { every: 0.05, clock: clock.clone(), previews: Mutex::new(Vec::new()) };
        let out = timed_run(Passes::Count(30), &recorder, clock, |_| 5 * MS);
        assert_eq!(out.passes, 30);
        let previews = recorder.previews.into_inner().expect("lock");
        let expected: Vec<(Duration, f32)> = (1..=10).map(|k| (60 * k * MS, 1.0)).collect();
        assert_eq!(previews, expected);
    }

    /// The image-space render on the fake clock: setup between `new` and `run` counts in the time
    /// budget; the image and previews are the film over the samples per pixel. 16×16 pixels (one
    /// tile), 0.1 ms per sample: 25.6 ms per pass. With 40 ms of setup in a 0.1 s budget, two
    /// passes fit (ending at 91.2 ms); counted from the run's start instead, three would.
    #[test]
    fn image_render_counts_setup_in_the_budget_and_normalises() {
        let clock = Arc::new(FakeClock::default());
        let recorder = Recorder { every: 1e-9, clock: clock.clone(), previews: Mutex::new(Vec::new()) };
        let job = RenderJob { budget: Budget::Seconds(0.1), seed: 5, threads: 2 };
        let render = ImageRender::with_clock(&job, 16, 16, &recorder, clock.clone()).expect("render");
        clock.advance(40 * MS);
        let (run, _) = render.run(
            |_| (),
            |x, y, _, slot| {
                clock.advance(Duration::from_micros(100));
                slot.film.add(x as usize, y as usize, Rgb::splat(0.5));
            },
        );
        assert_eq!(run.output.extra_stats["passes"], 2);
        assert_eq!(run.output.extra_stats["spp"], 2);
        assert_eq!(run.scale, 0.5);
        assert_eq!(run.output.wall_time, Duration::from_micros(91_200));
        assert_eq!(run.output.counters.samples, 2 * 256);
        assert!(run.output.image.pixels.iter().all(|p| *p == Rgb::splat(0.5)));
        let previews = recorder.previews.into_inner().expect("lock");
        let times: Vec<Duration> = previews.iter().map(|p| p.0).collect();
        assert_eq!(times, [Duration::from_micros(65_600), Duration::from_micros(91_200)]);
        assert!(previews.iter().all(|p| p.1 == 0.5), "{previews:?}");
    }

    #[test]
    fn a_film_beyond_u32_pixel_indices_is_an_error() {
        let err = Driver::new(&job(1, 1), 70_000, 70_000).err().expect("too large");
        assert!(err.to_string().contains("70000×70000"), "{err}");
    }

    /// The library refuses what the CLI refuses, for callers that skip the CLI: a sample budget
    /// whose product with the pixels passes 2^53 (it overflowed `progress.set_total` before), a
    /// time budget beyond 30 days, more than 1024 threads.
    #[test]
    fn budgets_and_threads_beyond_the_limits_are_errors_before_any_work() {
        let over = RenderJob { budget: Budget::SamplesPerPixel(1 << 50), seed: 1, threads: 1 };
        let err = ImageRender::new(&over, 16, 16, &crate::integrator::NoProgress).err().expect("too many samples");
        assert!(err.to_string().contains("2^53"), "{err}");
        let long = RenderJob { budget: Budget::Seconds(1e20), seed: 1, threads: 1 };
        assert!(ImageRender::new(&long, 4, 4, &crate::integrator::NoProgress).is_err());
        let err = Driver::new(&job(2000, 1), 4, 4).err().expect("too many threads");
        assert!(err.to_string().contains("1024"), "{err}");
    }

    #[test]
    fn image_plan_covers_the_film_and_the_budget() {
        let plan = ImagePlan::new(37, 20, Budget::SamplesPerPixel(1000));
        let covered: u64 = plan.tiles.iter().map(Tile::pixel_count).sum();
        assert_eq!(covered, 37 * 20);
        let Passes::Count(n) = plan.passes else { panic!("sample budget gives a pass count") };
        assert_eq!((0..n).map(|p| plan.spp_in_pass(p)).sum::<u64>(), 1000);
        assert_eq!(plan.spp_after(n), 1000);
        assert_eq!(plan.scale_after(n), 1e-3);
        assert_eq!(plan.scale_after(0), 0.0);
        let small = ImagePlan::new(1920, 1080, Budget::SamplesPerPixel(4));
        assert_eq!(small.spp_per_pass, 1);
    }
}
