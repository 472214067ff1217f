//! The image-space integrators' side of the driver (pt, BDPT, light tracing): tiles as units,
//! the pass schedule of a sample or time budget ([`ImagePlan`]), the render around a per-sample
//! kernel ([`ImageRender`]) and what their states hold ([`ImagePart`]).

use std::sync::Arc;
use std::time::Duration;

use super::MIN_SAMPLES_PER_PASS;
use super::{CheckpointHook, Clock, Driver, PassBoundary, PassSet, Passes, RunStart, Slot, WallClock};
use crate::film::Accumulator;
use crate::integrator::{Budget, Engine, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::{PixelSampler, Rng, SamplerKind};
use crate::scene::Scene;
use crate::state::{RenderState, Session, StateError};
use crate::stats::Counters;

/// The film's normalisation for `spp` samples in every pixel: 1/spp (0 before any sample), for
/// the final image, previews and a state's image alike (the chains' is `chains::chain_scale`).
fn per_sample_scale(spp: u64) -> f64 {
    if spp > 0 {
        1.0 / spp as f64
    } else {
        0.0
    }
}

/// Side length in pixels of the square tiles image-space integrators split the film into.
pub const TILE_SIZE: u32 = 16;

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

/// The samples of one tile in one pass: sample `s` of pixel (x, y) is point `first + s` of the
/// pixel's sequence, for s below `spp`; `kind` and `seed` make its sampler
/// (`PixelSampler::new`).
pub struct TileSamples<'a> {
    pub tile: &'a Tile,
    pub first: u64,
    pub spp: u64,
    pub kind: SamplerKind,
    pub seed: u64,
}

impl TileSamples<'_> {
    /// (x, y, index in the pixel's sequence) of every sample, in the order the film takes them:
    /// the tile's pixels in row-major order, a pixel's samples in a row.
    pub fn iter(&self) -> impl Iterator<Item = (u32, u32, u64)> + '_ {
        self.tile.pixels().flat_map(move |(x, y)| (self.first..self.first + self.spp).map(move |i| (x, y, i)))
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
        let scale = per_sample_scale(part.spp_done);
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
    /// The numbers each sample reads.
    sampler: SamplerKind,
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

impl ImageRun {
    /// The output and the state: what `Integrator::run_session` returns.
    pub fn into_session(self) -> (RenderOutput, Option<RenderState>) {
        (self.output, self.state)
    }
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
        crate::integrator::check_budget(job.budget, width, height, "budget")?;
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
            sampler: SamplerKind::Independent,
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
                // A shard beyond the passes would render nothing and say it had succeeded.
                if shard.index >= n {
                    return Err(RenderError::Limit(format!(
                        "shard {shard} would render nothing: this render has {n} passes ({} samples per pixel \
                         each), so it splits into at most {n} shards",
                        self.plan.spp_per_pass
                    )));
                }
                self.progress.set_total(self.plan.spp_in_set(self.passes, n) * width as u64 * height as u64);
            }
        }
        self.session = session;
        Ok(self)
    }

    /// Samples read `kind`'s numbers (`SamplerKind::Independent` unless set).
    pub fn with_sampler(mut self, kind: SamplerKind) -> Self {
        self.sampler = kind;
        self
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
            units: self.session.shard,
        }
    }

    /// Renders: for every pass and tile, `sample(x, y, sampler, slot)` once per sample of each of
    /// the tile's pixels (pixels in row-major order, a pixel's samples in a row), drawing from
    /// `sampler` (the item's stream, or the pixel's Sobol points at the sample's index in the
    /// schedule: `sampling::PixelSampler`) and adding to `slot.film` — at (x, y), or anywhere
    /// (light tracing uses (x, y) only to count its paths). `init_slot` creates the per-slot state, which is returned
    /// in slot order.
    pub fn run<S, K>(&self, init_slot: impl Fn(usize) -> S, sample: K) -> (ImageRun, Vec<S>)
    where
        S: Send + Sync,
        K: Fn(u32, u32, &mut PixelSampler<'_>, &mut Slot<S>) + Sync,
    {
        self.run_tiles(init_slot, |samples, rng, slot| {
            for (x, y, index) in samples.iter() {
                let mut sampler = PixelSampler::new(samples.kind, rng, samples.seed, x, y, index);
                sample(x, y, &mut sampler, slot);
            }
        })
    }

    /// [`Self::run`] with the kernel handed a tile's samples of a pass at once
    /// ([`TileSamples`], in `run`'s order) and the work item's random stream (what an
    /// independent sampler draws from), so that it can take several samples' first steps together
    /// (pt traces a tile's camera rays in packets). Every sample must still add its own
    /// contributions, in the order of [`TileSamples::iter`], for the film to be `run`'s.
    pub fn run_tiles<S, K>(&self, init_slot: impl Fn(usize) -> S, kernel: K) -> (ImageRun, Vec<S>)
    where
        S: Send + Sync,
        K: Fn(&TileSamples<'_>, &mut Rng, &mut Slot<S>) + Sync,
    {
        let plan = &self.plan;
        let set = self.passes;
        let kind = self.sampler;
        let preview = |at: &PassBoundary<'_, Tile, S>| {
            let spp = plan.spp_in_set(set, at.passes_done);
            at.film.to_image(per_sample_scale(spp))
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
                // The index of the pass's first sample in every pixel's sequence: a function of the
                // pass alone (its work unit's key), so shards and resumed runs read the points the
                // whole render would, and passes never share points. Every pass but a sample
                // budget's last is full, so these are the indices 0, 1, … of the render's samples.
                let first = item.pass * plan.spp_per_pass;
                let mut rng = item.rng();
                kernel(&TileSamples { tile, first, spp, kind, seed: item.seed }, &mut rng, slot);
                let samples = spp * tile.pixel_count();
                slot.counters.samples += samples;
                samples
            },
            Some(&preview),
            self.session.control,
            self.session.checkpoint.is_some().then_some(&checkpoint as &CheckpointHook<'_, Tile, S>),
            None,
        );
        let spp = plan.spp_in_set(set, out.passes);
        let scale = per_sample_scale(spp);
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

/// An integrator whose render is the image driver's (pt, bdpt, light): what it implements is its
/// render under a session, with its unnormalised film; [`ImageEngine`] does the rest.
pub trait ImageIntegrator {
    /// The render under `session` (`crate::state`): resumed, sharded, stopped early; with `save`,
    /// `ImageRun::state` holds the state reached.
    fn render_run_session(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: Session,
        save: bool,
    ) -> Result<ImageRun, RenderError>;
}

/// The engine of image integrators (`integrator::Plugin`): their states are one [`ImagePart`].
pub struct ImageEngine;

impl<I: ImageIntegrator> Engine<I> for ImageEngine {
    fn run_session(
        integrator: &I,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(RenderOutput, Option<RenderState>), RenderError> {
        integrator.render_run_session(scene, job, progress, *session, save).map(ImageRun::into_session)
    }

    fn output_of_state(_integrator: &I, state: &RenderState) -> Result<RenderOutput, RenderError> {
        ImagePart::output_of_state(state)
    }

    fn merge_parts(parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        ImagePart::merge(parts)
    }
}
