//! The parallel render driver every integrator reuses: a thread pool, a deterministic partition of
//! the work, per-worker film and counters merged in a fixed order, sample and time budgets, and
//! progress reports.
//!
//! # The partition
//!
//! An integrator describes its work as `U` *units* (image tiles, batches of light paths, Markov
//! chains) that are all visited once per *pass*. The driver runs passes until the budget is spent:
//! a fixed number of passes for sample budgets, or passes while the deadline allows for time
//! budgets. Work item `(pass, unit)` has the random stream `Rng::new(seed, pass · U + unit)`.
//!
//! Unit `u` always runs on worker *slot* `u mod threads`, in increasing unit order within a pass and
//! in increasing pass order. Each slot owns one [`Accumulator`] (it may add to any pixel: splats are
//! allowed) and one [`Counters`]; at the end the slots are merged in slot order. Nothing depends on
//! which OS thread executes a slot or on timing, so the same seed and thread count give a
//! bit-identical image. When each unit only writes to its own pixels (a path tracer's tiles), every
//! pixel is written by exactly one slot and the image is even independent of the thread count.
//!
//! # How the integrators fit
//!
//! - **Path tracing / BDPT**: a unit is a tile; an item renders `spp_per_pass` samples for each of
//!   the tile's pixels with the item's stream. [`ImagePlan`] computes tiles and the pass schedule.
//! - **Light tracing**: a unit is a batch of light subpaths (e.g. as many as a tile has pixels
//!   times `spp_per_pass`); each item splats to arbitrary pixels of its slot's accumulator, and the
//!   image is scaled by 1 / (total light paths) at the end.
//! - **MCMC**: a unit is a Markov chain whose state (sampler, current path, its contribution)
//!   lives in the unit value `U` itself, which the driver hands back mutably to the kernel on every
//!   pass (`units: Vec<U>`) and returns at the end; an item is a chain *segment* of a fixed number
//!   of mutations. The chain keeps its own `Rng::new(seed, chain)` inside `U` and may ignore the
//!   item stream. Mutations per pixel translate into `passes × units × segment length`; a time
//!   budget just runs more segments. Per-slot state `S` (scratch buffers, per-slot statistics) is
//!   created once per slot and returned in slot order for a deterministic merge.
//!
//! Every worker thread of the pool sets flush-to-zero / denormals-are-zero in its start handler
//! (Embree wants it, and it keeps both accelerators' arithmetic identical), and every item runs
//! inside the pool, so no ray is traced from a thread without the flags.

use std::time::{Duration, Instant};

use rayon::{ThreadPool, ThreadPoolBuilder};

use super::{Budget, Progress, RenderError, RenderJob};
use crate::film::{Accumulator, Image};
use crate::sampling::Rng;
use crate::stats::Counters;

/// Side length in pixels of the square tiles image-space integrators split the film into.
pub const TILE_SIZE: u32 = 16;

/// A pass should hold at least this many pixel samples, so that the per-pass synchronisation
/// costs nothing measurable even for tiny images.
const MIN_SAMPLES_PER_PASS: u64 = 1 << 16;

/// How many passes to run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Passes {
    /// Exactly this many passes.
    Count(u64),
    /// Passes until this many seconds have elapsed since the run started: a new pass starts only
    /// if it is predicted to end before the deadline (at least one pass always runs). The
    /// prediction is the longer of the last pass and the mean pass: the last follows a change of
    /// the machine's load or of the work (a chain segment meeting long paths), the mean keeps one
    /// fast pass from starting a slow one; the first pass, slow with thread start-up and cold
    /// caches, only counts through the mean.
    Seconds(f64),
    /// Passes until this instant, by the same rule as `Seconds`: for integrators that work before
    /// the run (MLT's bootstrap) and must fit the whole render into the user's budget.
    Deadline(Instant),
}

impl Passes {
    /// This schedule with a `Seconds` budget counted from `start` (when the render began, before
    /// its setup) instead of from the start of the run, so that setup is inside the budget.
    pub fn counted_from(self, start: Instant) -> Passes {
        match self {
            Passes::Seconds(s) => match Duration::try_from_secs_f64(s.max(0.0)).ok().and_then(|d| start.checked_add(d))
            {
                Some(at) => Passes::Deadline(at),
                None => self,
            },
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

/// What a worker slot owns: its film, its counters and the integrator's per-slot state.
pub struct Slot<S> {
    /// Slot index, 0..threads.
    pub index: usize,
    pub film: Accumulator,
    pub counters: Counters,
    pub state: S,
}

/// What a run produced.
pub struct RunOutput<U, S> {
    /// The slots' films summed in slot order.
    pub film: Accumulator,
    /// The slots' counters summed in slot order.
    pub counters: Counters,
    /// The units, in unit order, with whatever state the kernel left in them.
    pub units: Vec<U>,
    /// Per-slot states, in slot order.
    pub slot_states: Vec<S>,
    /// Passes completed.
    pub passes: u64,
    pub elapsed: Duration,
}

/// One slot and the units dealt to it (with their unit indices).
type SlotWork<U, S> = (Slot<S>, Vec<(usize, U)>);

/// A thread pool and the job's seed: runs passes of work items deterministically.
pub struct Driver {
    pool: ThreadPool,
    threads: usize,
    seed: u64,
    width: usize,
    height: usize,
}

impl Driver {
    /// A driver for a `width`×`height` film with the job's thread count (0 means all available
    /// cores) and seed.
    pub fn new(job: &RenderJob, width: u32, height: u32) -> Result<Driver, RenderError> {
        let threads =
            if job.threads == 0 { std::thread::available_parallelism().map_or(1, |n| n.get()) } else { job.threads };
        let pool = ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("plexus-worker-{i}"))
            .start_handler(|_| crate::accel::embree::set_flush_denormals())
            .build()
            .map_err(|e| RenderError::ThreadPool(e.to_string()))?;
        Ok(Driver { pool, threads, seed: job.seed, width: width as usize, height: height as usize })
    }

    /// Number of worker slots (= threads).
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Runs `kernel` on every (pass, unit) item. The kernel gets the item, its unit's state and its
    /// slot, and returns the progress units it completed (e.g. pixel samples), which are reported
    /// to `progress` after each item. When `progress` asks for previews
    /// (`Progress::preview_interval`) and a `snapshot` is given, between passes at most that often
    /// `snapshot(slots, passes done)` builds the current normalised image from the slots, which
    /// `progress.preview` receives. Previews only read the films, so the image and its determinism
    /// do not depend on them.
    pub fn run<U, S, K>(
        &self,
        units: Vec<U>,
        passes: Passes,
        progress: &dyn Progress,
        init_slot: impl Fn(usize) -> S,
        kernel: K,
        snapshot: Option<&Snapshot<'_, S>>,
    ) -> RunOutput<U, S>
    where
        U: Send,
        S: Send + Sync,
        K: Fn(&WorkItem, &mut U, &mut Slot<S>) -> u64 + Sync,
    {
        let preview_every = progress.preview_interval().filter(|s| s.is_finite() && *s > 0.0);
        let mut last_preview = Instant::now();
        let start = Instant::now();
        let unit_count = units.len();
        let threads = self.threads;
        // Deal the units to slots: unit u to slot u mod threads, keeping increasing unit order.
        let mut per_slot: Vec<SlotWork<U, S>> = (0..threads)
            .map(|i| {
                let slot = Slot {
                    index: i,
                    film: Accumulator::new(self.width, self.height),
                    counters: Counters::default(),
                    state: init_slot(i),
                };
                (slot, Vec::with_capacity(unit_count / threads + 1))
            })
            .collect();
        for (u, unit) in units.into_iter().enumerate() {
            per_slot[u % threads].1.push((u, unit));
        }

        let seed = self.seed;
        // The instant by which passes must end; `None` for pass counts, and for a budget beyond what
        // an `Instant` can hold (which then never ends a pass loop early).
        let deadline = match passes.counted_from(start) {
            Passes::Deadline(at) => Some(at),
            _ => None,
        };
        let mut pass = 0u64;
        let mut last_pass = 0.0f64;
        loop {
            let go = match passes {
                Passes::Count(n) => pass < n,
                Passes::Seconds(_) | Passes::Deadline(_) => {
                    let mean = start.elapsed().as_secs_f64() / pass.max(1) as f64;
                    let predicted = Duration::from_secs_f64(last_pass.max(mean));
                    pass == 0
                        || deadline.is_none_or(|at| Instant::now().checked_add(predicted).is_some_and(|end| end <= at))
                }
            };
            if !go || unit_count == 0 {
                break;
            }
            let kernel = &kernel;
            let pass_start = Instant::now();
            self.pool.scope(|scope| {
                for (slot, slot_units) in per_slot.iter_mut() {
                    scope.spawn(move |_| {
                        for (u, unit) in slot_units.iter_mut() {
                            let item = WorkItem { pass, unit: *u, stream: pass * unit_count as u64 + *u as u64, seed };
                            let done = kernel(&item, unit, slot);
                            progress.advance(done);
                        }
                    });
                }
            });
            last_pass = pass_start.elapsed().as_secs_f64();
            pass += 1;
            if let (Some(every), Some(snapshot)) = (preview_every, snapshot) {
                if last_preview.elapsed().as_secs_f64() >= every {
                    let slots: Vec<&Slot<S>> = per_slot.iter().map(|(slot, _)| slot).collect();
                    progress.preview(&snapshot(&slots, pass));
                    last_preview = Instant::now();
                }
            }
        }

        let mut film = Accumulator::new(self.width, self.height);
        let mut counters = Counters::default();
        let mut slot_states = Vec::with_capacity(threads);
        let mut indexed_units = Vec::with_capacity(unit_count);
        for (slot, slot_units) in per_slot {
            film.merge(&slot.film);
            counters.merge(&slot.counters);
            slot_states.push(slot.state);
            indexed_units.extend(slot_units);
        }
        indexed_units.sort_by_key(|(u, _)| *u);
        RunOutput {
            film,
            counters,
            units: indexed_units.into_iter().map(|(_, unit)| unit).collect(),
            slot_states,
            passes: pass,
            elapsed: start.elapsed(),
        }
    }
}

/// The image of integrators whose result is the slots' summed film times `scale` (the path
/// tracer, BDPT, light tracing: `scale` = 1 / samples per pixel so far), for previews.
pub fn scaled_film_image<S>(slots: &[&Slot<S>], scale: f64) -> Image {
    let Some(first) = slots.first() else { return Image::new(0, 0) };
    let mut film = Accumulator::new(first.film.width, first.film.height);
    for slot in slots {
        film.merge(&slot.film);
    }
    film.to_image(scale)
}

/// Builds a preview image from the slots and the number of passes done (see `Driver::run`).
pub type Snapshot<'a, S> = dyn Fn(&[&Slot<S>], u64) -> Image + 'a;

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
/// how many samples per pixel each pass takes. Depends only on the resolution and budget, so it is
/// part of what makes a render reproducible.
#[derive(Clone, Debug)]
pub struct ImagePlan {
    pub tiles: Vec<Tile>,
    /// Samples per pixel in each pass.
    pub spp_per_pass: u64,
    pub passes: Passes,
    /// Total samples per pixel, when known in advance (sample budgets).
    pub total_spp: Option<u64>,
}

impl ImagePlan {
    /// Tiles the `width`×`height` film. For `Budget::SamplesPerPixel(n)` the passes take
    /// `spp_per_pass` samples each (as many as make a pass hold about 2^16 pixel samples, but never
    /// more than `n`), the last pass fewer if needed; the image is the per-pixel mean. For a time
    /// budget every pass takes one sample per pixel, so the image stays the mean of equally many
    /// samples at every pixel and the budget is overrun by less than one such pass.
    pub fn new(width: u32, height: u32, budget: Budget) -> ImagePlan {
        let mut tiles = Vec::new();
        for y0 in (0..height).step_by(TILE_SIZE as usize) {
            for x0 in (0..width).step_by(TILE_SIZE as usize) {
                tiles.push(Tile { x0, y0, x1: (x0 + TILE_SIZE).min(width), y1: (y0 + TILE_SIZE).min(height) });
            }
        }
        let pixels = (width as u64 * height as u64).max(1);
        let per_pass = MIN_SAMPLES_PER_PASS.div_ceil(pixels).max(1);
        match budget {
            Budget::SamplesPerPixel(n) => {
                let spp_per_pass = per_pass.min(n.max(1));
                ImagePlan { tiles, spp_per_pass, passes: Passes::Count(n.div_ceil(spp_per_pass)), total_spp: Some(n) }
            }
            Budget::Seconds(s) => ImagePlan { tiles, spp_per_pass: 1, passes: Passes::Seconds(s), total_spp: None },
        }
    }

    /// Samples per pixel that pass `pass` takes (the last pass of a sample budget may take fewer).
    pub fn spp_in_pass(&self, pass: u64) -> u64 {
        match self.total_spp {
            Some(total) => self.spp_per_pass.min(total.saturating_sub(pass * self.spp_per_pass)),
            None => self.spp_per_pass,
        }
    }

    /// Samples per pixel after `passes` complete passes.
    pub fn spp_after(&self, passes: u64) -> u64 {
        match self.total_spp {
            Some(total) => (passes * self.spp_per_pass).min(total),
            None => passes * self.spp_per_pass,
        }
    }

    /// The preview of an integrator whose image is its slots' summed film over the samples per
    /// pixel so far (the path tracer, BDPT, light tracing): a `Snapshot` for `run`.
    pub fn preview_image<S>(&self, slots: &[&Slot<S>], passes: u64) -> Image {
        scaled_film_image(slots, 1.0 / self.spp_after(passes).max(1) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::NoProgress;
    use crate::spectrum::Rgb;

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
                    slot.film.add(x, y, Rgb::splat(rng.uniform()));
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

    #[test]
    fn splatting_run_is_bit_identical_for_same_seed_and_threads() {
        let (a, ca, pa) = splat_run(3, 11);
        let (b, _, _) = splat_run(3, 11);
        let (c, _, _) = splat_run(3, 12);
        assert_eq!(pa, 3);
        assert_eq!(ca.samples, 13 * 3 * 50);
        let (ia, ib, ic) = (a.to_image(1.0), b.to_image(1.0), c.to_image(1.0));
        assert!(ia
            .pixels
            .iter()
            .zip(&ib.pixels)
            .all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits)));
        assert_ne!(ia, ic);
    }

    #[test]
    fn time_budget_runs_at_least_one_pass_and_stops() {
        let driver = Driver::new(&job(2, 1), 4, 4).expect("pool");
        let t = Instant::now();
        let out = driver.run(
            vec![(); 4],
            Passes::Seconds(0.05),
            &NoProgress,
            |_| (),
            |_, _, _| {
                std::thread::sleep(Duration::from_millis(2));
                1
            },
            None,
        );
        assert!(out.passes >= 1);
        assert!(t.elapsed().as_secs_f64() < 1.0);
    }

    /// A kernel of 4 units × 5 ms on 2 threads: a pass takes about 10 ms.
    fn sleepy_run(passes: Passes, progress: &dyn Progress) -> RunOutput<(), ()> {
        let driver = Driver::new(&job(2, 1), 4, 4).expect("pool");
        driver.run(
            vec![(); 4],
            passes,
            progress,
            |_| (),
            |_, _, slot| {
                std::thread::sleep(Duration::from_millis(5));
                slot.film.add(0, 0, Rgb::ONE);
                1
            },
            // Four units per pass each add 1 to pixel (0, 0).
            Some(&|slots: &[&Slot<()>], passes: u64| scaled_film_image(slots, 1.0 / (4 * passes) as f64)),
        )
    }

    /// A deadline ends the run within one pass of it (the prediction is at least the last pass);
    /// the 50 ms tolerance is a few passes of scheduling noise on a loaded machine. A deadline that
    /// has already passed (setup took the whole budget) still runs one pass, so there is an image.
    #[test]
    fn deadline_is_kept_and_one_pass_always_runs() {
        let start = Instant::now();
        let out = sleepy_run(Passes::Deadline(start + Duration::from_millis(200)), &NoProgress);
        let took = start.elapsed().as_secs_f64();
        assert!(out.passes >= 5, "{} passes", out.passes);
        assert!(took <= 0.25, "{took:.3} s for a 0.2 s deadline");
        let out = sleepy_run(Passes::Deadline(Instant::now()), &NoProgress);
        assert_eq!(out.passes, 1);
        let Passes::Deadline(at) = Passes::Seconds(1.0).counted_from(start) else { panic!("a deadline") };
        assert_eq!(at, start + Duration::from_secs(1));
        assert_eq!(Passes::Count(3).counted_from(start), Passes::Count(3));
    }

    /// Previews arrive between passes, at most once per interval, and show the normalised image
    /// so far (pixel (0, 0) gets 1 per item, so the preview reads 1).
    #[test]
    fn previews_are_rate_limited_and_normalised() {
        use std::sync::Mutex;
        struct Recorder(Mutex<Vec<(Instant, f32)>>);
        impl Progress for Recorder {
            fn set_total(&self, _: u64) {}
            fn advance(&self, _: u64) {}
            fn message(&self, _: &str) {}
            fn preview_interval(&self) -> Option<f64> {
                Some(0.05)
            }
            fn preview(&self, image: &Image) {
                self.0.lock().expect("lock").push((Instant::now(), image.pixels[0].x));
            }
        }
        let recorder = Recorder(Mutex::new(Vec::new()));
        let out = sleepy_run(Passes::Count(30), &recorder);
        let previews = recorder.0.into_inner().expect("lock");
        // 30 passes of ≥ 10 ms are ≥ 0.3 s: at least 4 intervals of 50 ms, at most one per pass.
        assert!(previews.len() >= 4 && (previews.len() as u64) < out.passes, "{} previews", previews.len());
        assert!(previews.iter().all(|&(_, v)| (v - 1.0).abs() < 1e-6), "{previews:?}");
        assert!(previews.windows(2).all(|w| (w[1].0 - w[0].0).as_secs_f64() >= 0.05));
    }

    #[test]
    fn image_plan_covers_the_film_and_the_budget() {
        let plan = ImagePlan::new(37, 20, Budget::SamplesPerPixel(1000));
        let covered: u64 = plan.tiles.iter().map(Tile::pixel_count).sum();
        assert_eq!(covered, 37 * 20);
        let Passes::Count(n) = plan.passes else { panic!("sample budget gives a pass count") };
        assert_eq!((0..n).map(|p| plan.spp_in_pass(p)).sum::<u64>(), 1000);
        assert_eq!(plan.spp_after(n), 1000);
        let small = ImagePlan::new(1920, 1080, Budget::SamplesPerPixel(4));
        assert_eq!(small.spp_per_pass, 1);
    }
}
