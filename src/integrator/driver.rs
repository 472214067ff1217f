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

mod chains;
mod image;
pub use chains::{
    boundary_counters, chain_output_of_state, chain_scale, expected_value_splats, layers_to_image, load_units,
    merge_chain_parts, run_chains, save_units, ChainBootstrap, ChainIntegrator, ChainPart, ChainRender, ChainRun,
    ChainStats, Tally,
};
pub use image::{state_film, ImagePart, ImagePlan, ImageRender, ImageRun, Tile, TileSamples, TILE_SIZE};

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
mod tests {
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Mutex;

    use super::*;
    use crate::integrator::{Budget, NoProgress};
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
    /// other seed: another film. With a film per slot merged in slot order instead (the wrong
    /// variant), the film sums of 1 and 3 threads differ at 18 of the 35 pixels.
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
        assert_eq!(plan.spp_after(0), 0);
        // Shards: the passes' samples split between the sets and add up to the budget.
        let per_set = |k| plan.spp_in_set(PassSet { index: k, count: 3 }, n);
        assert_eq!(per_set(0) + per_set(1) + per_set(2), 1000);
        // A resumed plan after 2 full passes continues the same schedule to the same end.
        let resumed =
            ImagePlan::resumed(37, 20, Budget::SamplesPerPixel(1000), plan.spp_per_pass, 2, 2 * plan.spp_per_pass);
        assert_eq!(resumed.passes, plan.passes);
        assert_eq!(
            (2..n).map(|p| resumed.spp_in_pass(p)).collect::<Vec<_>>(),
            (2..n).map(|p| plan.spp_in_pass(p)).collect::<Vec<_>>()
        );
        let small = ImagePlan::new(1920, 1080, Budget::SamplesPerPixel(4));
        assert_eq!(small.spp_per_pass, 1);
    }
}
