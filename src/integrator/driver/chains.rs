//! The Markov chain integrators' side of the driver (PSSMLT, MMLT and RJMLT in `pss/mlt`,
//! path-space MLT in `path_space`, ensemble MLT in `ensemble`), as `image.rs` is the image-space
//! integrators': **one runner** ([`run_chains`]) that does everything a chain render does around
//! its chains — the bootstrap's place in a time budget, the chains' start or their restoration
//! from a state, the passes on the driver (and its clock), previews, checkpoints, shards, the
//! statistics merged in slot order and the final state — and how the shards' parts of its states
//! merge ([`merge_chain_parts`]). An integrator supplies what is its own through
//! [`ChainIntegrator`] (its state's types and its normalised output, which needs no scene) and
//! [`ChainRender`] (one render of a scene: its bootstrap, its chains' start and kernel, its
//! statistics).

use std::sync::Arc;
use std::time::Duration;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::{
    state_film, CheckpointHook, Clock, Driver, PassBoundary, PassEdge, PassSet, Passes, RunStart, Slot, WallClock,
};
use crate::film::{Accumulator, Image};
use crate::integrator::{Budget, Engine, Progress, RenderError, RenderJob, RenderOutput};
use crate::scene::Scene;
use crate::spectrum::Rgb;
use crate::state::{decode, encode, RenderState, Session, Shard, StateError, UnitState};
use crate::stats::Counters;

/// What a chain render keeps of its bootstrap in a state: the same in every shard of a render
/// (its streams depend on the seed only), which the merge checks.
pub trait ChainBootstrap: Clone + Serialize + DeserializeOwned {
    /// Whether `other` is the same bootstrap (its sums and sample count; not its time).
    fn same_as(&self, other: &Self) -> bool;
    /// The bootstrap's wall time in seconds (0 in a shard, whose bytes depend on its units only).
    fn seconds_mut(&mut self) -> &mut f64;
}

/// The statistics a chain render keeps in its state: the slots' merged (and whatever else of the
/// render's is not a chain's), added across shards.
pub trait ChainStats: Clone + Serialize + DeserializeOwned {
    /// Adds another shard's statistics.
    fn absorb(&mut self, other: &Self);
    /// Zeroes what measures time, for a shard's state (its bytes depend on its units only).
    fn clear_times(&mut self) {}
}

/// A chain integrator: its state's types, how it renders a scene on the runner, and the normalised
/// output of a film (a render's end, a resumed state's, merged shards').
pub trait ChainIntegrator {
    /// A chain, as the driver's unit: its streams and current state, saved through `UnitState`.
    type Unit: Serialize + DeserializeOwned + Send;
    type Boot: ChainBootstrap;
    type Stats: ChainStats;

    /// The chain's index in the whole render.
    fn unit_index(unit: &Self::Unit) -> u64;

    /// The image, counters and statistics of `film` (the driver's film: all layers) with the
    /// chains `units` (all of the render's, or none for a black render), the merged `stats`, the
    /// bootstrap and the render-level `tally`.
    fn chain_output(
        &self,
        film: &Accumulator,
        units: &[Self::Unit],
        stats: Self::Stats,
        boot: &Self::Boot,
        tally: Tally,
    ) -> Result<RenderOutput, RenderError>;

    /// The render of `scene` under `session` with its time read from `clock` (the wall clock in
    /// `Integrator::run_session`; a fake one in tests of the time budget): its `ChainRender` run by
    /// [`run_chains`], with the unnormalised film and, with `save`, the state reached.
    fn run_on_clock(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
        clock: Arc<dyn Clock>,
    ) -> Result<ChainRun, RenderError>;
}

/// The engine of chain integrators (`integrator::Plugin`): [`ChainIntegrator::run_on_clock`] on
/// the wall clock; their states are one [`ChainPart`].
pub struct ChainEngine;

impl<I: ChainIntegrator> Engine<I> for ChainEngine {
    fn run_session(
        integrator: &I,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(RenderOutput, Option<RenderState>), RenderError> {
        let run = integrator.run_on_clock(scene, job, progress, session, save, Arc::new(WallClock::new()))?;
        Ok((run.output, run.state))
    }

    fn output_of_state(integrator: &I, state: &RenderState) -> Result<RenderOutput, RenderError> {
        chain_output_of_state(integrator, state)
    }

    fn merge_parts(parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        merge_chain_parts::<I>(parts)
    }
}

/// A bootstrap's outcome for render `R`: what the state keeps of it, its counters and, unless it
/// found no light, what the chains start from.
pub type Bootstrapped<R> =
    (<<R as ChainRender>::Integrator as ChainIntegrator>::Boot, Counters, Option<<R as ChainRender>::Start>);

/// One render of a scene by a chain integrator: what the runner asks of it.
pub trait ChainRender: Sync {
    type Integrator: ChainIntegrator;
    /// Per-slot scratch and statistics.
    type Slot: Send + Sync;
    /// What the chains start from (the bootstrap's distributions); not saved.
    type Start: Sync;

    fn integrator(&self) -> &Self::Integrator;
    /// The image's width and height (the budget's pixels).
    fn image_size(&self) -> (u32, u32);
    /// The driver's film: the image, or its layers stacked (MLT's depths, emlt's pairs).
    fn film_size(&self) -> Result<(u32, u32), RenderError>;
    /// Chains of the whole render (a state's `unit_count`).
    fn chains(&self) -> u64;
    /// Mutations per chain and pass.
    fn segment(&self) -> u64;
    /// Mutations a pass makes over the whole render: a sample budget's divisor.
    fn mutations_per_pass(&self) -> u64 {
        self.segment() * self.chains()
    }
    /// Mutations a pass makes over `units` of the chains (the progress bar's total).
    fn mutations_per_pass_of(&self, units: usize) -> u64 {
        self.segment() * units as u64
    }
    /// Whether chain `chain` belongs to `shard`.
    fn in_shard(&self, chain: u64, shard: Shard) -> bool {
        shard.contains(chain)
    }
    fn new_slot(&self) -> Self::Slot;
    /// The bootstrap, at most `time_budget` seconds of it when given: its outcome, its counters and,
    /// unless it found no light, what the chains start from.
    fn bootstrap(
        &self,
        driver: &Driver,
        progress: &dyn Progress,
        time_budget: Option<f64>,
    ) -> Result<Bootstrapped<Self>, RenderError>;
    /// Called once the bootstrap is known (run or restored), before any chain moves.
    fn begin(&self, _boot: &<Self::Integrator as ChainIntegrator>::Boot) {}
    /// Starts `chains` (indices in the whole render, in order), counting their work in `counters`.
    fn start_chains(
        &self,
        driver: &Driver,
        start: &Self::Start,
        chains: &[u64],
        progress: &dyn Progress,
        counters: &mut Counters,
    ) -> Result<Vec<<Self::Integrator as ChainIntegrator>::Unit>, RenderError>;
    /// Checks a chain restored from a state file (untrusted numbers) before it is used.
    fn check_restored(&self, unit: &<Self::Integrator as ChainIntegrator>::Unit) -> Result<(), StateError>;
    /// Empty statistics (a render whose bootstrap found no light).
    fn empty_stats(&self) -> <Self::Integrator as ChainIntegrator>::Stats;
    /// The statistics of the slots `slots` (in slot order) with the chains `units`.
    fn stats(
        &self,
        slots: &[&Self::Slot],
        units: &[<Self::Integrator as ChainIntegrator>::Unit],
    ) -> <Self::Integrator as ChainIntegrator>::Stats;
    /// The slot a resumed run's first slot starts from: a state's statistics.
    fn restore_slot(&self, stats: &<Self::Integrator as ChainIntegrator>::Stats) -> Self::Slot;
    /// Runs `unit`'s segment of pass `pass`; returns the mutations made.
    fn run_segment(
        &self,
        pass: u64,
        unit: &mut <Self::Integrator as ChainIntegrator>::Unit,
        slot: &mut Slot<Self::Slot>,
        progress: &dyn Progress,
    ) -> u64;
    /// Work on the chains between passes (`driver::PassHook`); nothing by default.
    fn between_passes(&self, _edge: PassEdge, _pass: u64, _units: &mut [<Self::Integrator as ChainIntegrator>::Unit]) {}
    /// The normalised image of a pass boundary (previews).
    fn preview(
        &self,
        film: &Accumulator,
        units: &[<Self::Integrator as ChainIntegrator>::Unit],
        slots: &[&Self::Slot],
    ) -> Image;
}

/// The state's part of a chain render (`crate::state`): the bootstrap every chain and the
/// normalisation share, the mutations per chain and pass, the merged statistics, and the chains
/// by their index in the whole render, each written through `UnitState`.
#[derive(Serialize, Deserialize)]
pub struct ChainPart<B, T> {
    pub bootstrap: B,
    pub segment: u64,
    pub stats: T,
    pub units: Vec<(u64, Vec<u8>)>,
}

/// Merges the parts of a render's shards, given in shard order: the first part absorbs the
/// others' statistics (refusing a shard that did not start from the same bootstrap), and the
/// chains are put in chain order, refusing a chain in two shards.
pub fn merge_chain_parts<I: ChainIntegrator>(parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
    let mut merged: Option<ChainPart<I::Boot, I::Stats>> = None;
    for bytes in parts {
        let mut part: ChainPart<I::Boot, I::Stats> = decode(bytes)?;
        match merged.as_mut() {
            None => merged = Some(part),
            Some(m) => {
                if !m.bootstrap.same_as(&part.bootstrap) || m.segment != part.segment {
                    return Err(StateError::Mismatch("the shards did not start from the same bootstrap".into()).into());
                }
                m.stats.absorb(&part.stats);
                m.units.append(&mut part.units);
            }
        }
    }
    let mut merged = merged.ok_or_else(|| StateError::Mismatch("no shard".into()))?;
    merged.units.sort_by_key(|(index, _)| *index);
    if let Some(pair) = merged.units.windows(2).find(|pair| pair[0].0 == pair[1].0) {
        return Err(StateError::Mismatch(format!("chain {} is in two shards: their units overlap", pair[0].0)).into());
    }
    Ok(encode(&merged)?)
}

/// The normalised image, counters and statistics of a chain render's state (a resumed render
/// with nothing left to do, merged shards).
pub fn chain_output_of_state<I: ChainIntegrator>(
    integrator: &I,
    state: &RenderState,
) -> Result<RenderOutput, RenderError> {
    let part: ChainPart<I::Boot, I::Stats> = decode(&state.part)?;
    let units: Vec<I::Unit> = load_units(&part.units)?;
    let film = state_film(state);
    let wall = Duration::try_from_secs_f64(state.wall_time_s).unwrap_or_default();
    let tally = Tally { passes: state.passes_done, segment: part.segment, counters: state.counters.clone(), wall };
    integrator.chain_output(&film, &units, part.stats, &part.bootstrap, tally)
}

/// The film's normalisation for a chain estimator with expected-value splats: b·P/N (docs/mlt.md,
/// "Normalisation"; Veach & Guibas 1997). The chains sample x̄ ∝ f*/b, each of N iterations
/// splats a unit of f*-weight, and pixel j's value is P·∫ 1_j f dμ in the camera's whole-film
/// normalisation, so the film's sums times b·P/N estimate the image. `b` is the normalisation
/// constant of the layer (MMLT, RJMLT: n_d·b_d of depth d), `pixels` the image's P, `iterations`
/// the N of the layer's chains; 0 before any iteration.
pub fn chain_scale(b: f64, pixels: u64, iterations: u64) -> f64 {
    if iterations > 0 {
        b * pixels as f64 / iterations as f64
    } else {
        0.0
    }
}

/// The expected-value splats of Veach & Guibas 1997 (bibliography.md), which every chain here
/// makes: every
/// iteration records both the proposal, with its acceptance probability `a`, and the current
/// state, with 1 − a, whatever the acceptance decides, so that rejected proposals contribute too.
/// Calls `splat(proposal, weight)` for the proposal (`true`) and then the current state, each only
/// with a positive weight.
pub fn expected_value_splats(a: f64, mut splat: impl FnMut(bool, f64)) {
    if a > 0.0 {
        splat(true, a);
    }
    if a < 1.0 {
        splat(false, 1.0 - a);
    }
}

/// The image of `film`, whose `layers` stacked images are estimates of one image whose film sums
/// add (ensemble MLT's pairs): their sums added in layer order, times `scale`. With one layer, the
/// film times `scale`.
pub fn layers_to_image(film: &Accumulator, layers: usize, scale: f64) -> Image {
    let layers = layers.max(1);
    let (width, height) = (film.width, film.height / layers);
    let pixels = width * height;
    let sums = film.sums();
    let image = (0..pixels)
        .map(|i| {
            let mut s = sums[i];
            for layer in 1..layers {
                let t = sums[layer * pixels + i];
                s = [s[0] + t[0], s[1] + t[1], s[2] + t[2]];
            }
            Rgb::new((s[0] * scale) as f32, (s[1] * scale) as f32, (s[2] * scale) as f32)
        })
        .collect();
    Image { width, height, pixels: image }
}

/// The chains as a state keeps them: each one's index in the whole render (`index`) and its bytes.
pub fn save_units<U: UnitState>(units: &[U], index: impl Fn(&U) -> u64) -> Result<Vec<(u64, Vec<u8>)>, StateError> {
    units.iter().map(|u| Ok((index(u), u.save()?))).collect()
}

/// The chains of a state, in its order.
pub fn load_units<U: UnitState>(saved: &[(u64, Vec<u8>)]) -> Result<Vec<U>, StateError> {
    saved.iter().map(|(_, bytes)| U::load(bytes)).collect()
}

/// The counters of a pass boundary: `before` (the bootstrap's and the chains' start) and the
/// slots', merged in slot order.
pub fn boundary_counters<S>(before: &Counters, slots: &[Slot<S>]) -> Counters {
    let mut counters = before.clone();
    for slot in slots {
        counters.merge(&slot.counters);
    }
    counters
}

/// The render-level figures of a chain render's output.
pub struct Tally {
    pub passes: u64,
    /// Mutations per chain and pass.
    pub segment: u64,
    pub counters: Counters,
    pub wall: Duration,
}

/// What a chain render does for its session: the clock (the driver's, read when the render began,
/// so the bootstrap is inside a time budget and the wall time), the wall time of the runs a
/// resumed render continues, the pass schedule of its budget and the states it saves. A shard's
/// state carries no time, so its bytes depend on its chains only.
struct ChainSession<'s> {
    session: &'s Session<'s>,
    clock: Arc<dyn Clock>,
    /// The clock's reading when the render began.
    started: Duration,
    /// Wall time of the runs a resumed render continues.
    earlier: Duration,
    /// Chains of the whole render (a state's `unit_count`).
    chains: u64,
    /// A sample budget's passes: its state is complete after them.
    total_passes: Option<u64>,
}

impl<'s> ChainSession<'s> {
    /// Starts the render's clock. A shard holds the chains whose index it `contains` (every
    /// `count`-th from its index): one whose index is not below `chains` would hold none, render
    /// nothing and say it had succeeded, so it is refused.
    fn new(session: &'s Session<'s>, chains: u64, clock: Arc<dyn Clock>) -> Result<ChainSession<'s>, RenderError> {
        if let Some(shard) = session.shard {
            if shard.index >= chains {
                return Err(RenderError::Limit(format!(
                    "shard {shard} would render nothing: this render has {chains} chains, so it splits into at \
                     most {chains} shards"
                )));
            }
        }
        let started = clock.now();
        Ok(ChainSession { session, clock, started, earlier: Duration::ZERO, chains, total_passes: None })
    }

    /// The state the session resumes and its part, if it resumes one; refused unless its film is
    /// `film_width`×`film_height` and it has the render's chains.
    fn resumed<P: DeserializeOwned>(
        &mut self,
        film_width: u32,
        film_height: u32,
    ) -> Result<Option<(&'s RenderState, P)>, RenderError> {
        let Some(state) = self.session.resume else { return Ok(None) };
        if (state.film_width, state.film_height) != (film_width, film_height) || state.unit_count != self.chains {
            return Err(StateError::Mismatch("the checkpoint's film or chains do not match the scene".into()).into());
        }
        let part = decode(&state.part)?;
        self.earlier = Duration::try_from_secs_f64(state.wall_time_s).unwrap_or_default();
        Ok(Some((state, part)))
    }

    /// The passes of `budget` from pass `next_pass` on, with the progress total: a sample budget's
    /// `mpp` mutations per pixel over `pixels` in passes of `per_pass` mutations (`here` of them
    /// by the chains run here), or a time budget's deadline on the clock, counted from the
    /// render's start, so that the bootstrap and the chains' start took their share.
    fn passes(
        &mut self,
        budget: Budget,
        pixels: u64,
        per_pass: u64,
        here: u64,
        next_pass: u64,
        progress: &dyn Progress,
    ) -> Passes {
        match budget {
            Budget::SamplesPerPixel(mpp) => {
                let n = (mpp * pixels).div_ceil(per_pass.max(1));
                progress.set_total(n.saturating_sub(next_pass) * here);
                self.total_passes = Some(n);
                Passes::Count(n)
            }
            Budget::Seconds(s) => Passes::Seconds(s).counted_from(self.started),
        }
    }

    /// Time this run has taken.
    fn elapsed(&self) -> Duration {
        self.clock.now().saturating_sub(self.started)
    }

    /// Time the render has taken, the runs it continues included.
    fn wall(&self) -> Duration {
        self.elapsed() + self.earlier
    }

    fn is_shard(&self) -> bool {
        self.session.shard.is_some()
    }

    /// `seconds` as a state records them: 0 in a shard.
    fn saved_seconds(&self, seconds: f64) -> f64 {
        if self.is_shard() {
            0.0
        } else {
            seconds
        }
    }

    /// Whether the budget is spent after `passes_done` passes (never for a time budget).
    fn complete_at(&self, passes_done: u64) -> bool {
        self.total_passes.is_some_and(|n| passes_done >= n)
    }

    /// The state of `film` (which it takes), the counters and the integrator's `part` after
    /// `passes_done` passes, `wall` into the render.
    fn state(
        &self,
        film: Accumulator,
        counters: &Counters,
        part: &impl Serialize,
        passes_done: u64,
        complete: bool,
        wall: Duration,
    ) -> Result<RenderState, StateError> {
        Ok(RenderState {
            passes_done,
            unit_count: self.chains,
            film_width: film.width as u32,
            film_height: film.height as u32,
            film: film.into_sums(),
            counters: counters.clone(),
            part: encode(part)?,
            complete,
            interrupted: false,
            wall_time_s: self.saved_seconds(wall.as_secs_f64()),
            units: self.session.shard,
        })
    }

    /// The state part of `boot`, `segment`, `stats` and the chains `units`, as a state records it:
    /// without times in a shard.
    fn part<I: ChainIntegrator>(
        &self,
        boot: &I::Boot,
        segment: u64,
        mut stats: I::Stats,
        units: &[I::Unit],
    ) -> Result<ChainPart<I::Boot, I::Stats>, StateError> {
        let mut bootstrap = boot.clone();
        let seconds = bootstrap.seconds_mut();
        *seconds = self.saved_seconds(*seconds);
        if self.is_shard() {
            stats.clear_times();
        }
        Ok(ChainPart { bootstrap, segment, stats, units: save_units(units, I::unit_index)? })
    }

    /// Hands the state `make` builds at a pass boundary to the session's checkpoint sink, or says
    /// on `progress` why there is none.
    fn checkpoint(&self, progress: &dyn Progress, make: impl FnOnce() -> Result<RenderState, StateError>) {
        let Some(sink) = self.session.checkpoint else { return };
        match make() {
            Ok(state) => sink(state),
            Err(e) => progress.message(&format!("checkpoint not written: {e}")),
        }
    }

    /// The end of a run of `passes` passes (`stopped` early or not): with a `part` (a render
    /// that saves), the state, which takes the film (the film returned is then empty); without,
    /// the film.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        film: Accumulator,
        counters: &Counters,
        part: Option<impl Serialize>,
        passes: u64,
        complete: bool,
        stopped: bool,
        wall: Duration,
    ) -> Result<(Accumulator, Option<RenderState>), StateError> {
        let Some(part) = part else { return Ok((film, None)) };
        let mut state = self.state(film, counters, &part, passes, complete, wall)?;
        state.interrupted = stopped;
        Ok((Accumulator::new(0, 0), Some(state)))
    }
}

/// The chains of the render that `shard` (all without one) holds, in chain order.
fn chains_here<R: ChainRender>(render: &R, shard: Option<Shard>) -> impl Iterator<Item = u64> + '_ {
    (0..render.chains()).filter(move |c| shard.is_none_or(|s| render.in_shard(*c, s)))
}

/// The per-slot states of `slots`, in slot order.
fn slot_refs<S>(slots: &[Slot<S>]) -> Vec<&S> {
    slots.iter().map(|s| &s.state).collect()
}

/// The state part of render `R`.
type PartOf<R> = ChainPart<
    <<R as ChainRender>::Integrator as ChainIntegrator>::Boot,
    <<R as ChainRender>::Integrator as ChainIntegrator>::Stats,
>;

/// What [`run_chains`] returns: the output, the unnormalised film (empty when the state took it)
/// and, with `save`, the state reached.
pub struct ChainRun {
    pub output: RenderOutput,
    pub film: Accumulator,
    pub state: Option<RenderState>,
}

/// The one chain render, for every chain integrator: under `session` (from the start or a state,
/// for all chains or a shard's, stopped early, checkpointed), on `clock`; with `save`, also the
/// state reached. The steps, each the integrator's where it is its own:
/// 1. the bootstrap (`ChainRender::bootstrap`; in a shard never shortened by a time budget, so
///    that every shard has the same) and the start of the chains of the session's shard
///    (`start_chains`), or the chains, statistics and film of the state resumed, each chain checked
///    (`check_restored`);
/// 2. the passes of the budget on the driver: a sample budget's ⌈mpp·P / mutations per pass⌉, a
///    time budget's deadline on the clock from the render's start; each pass runs every chain's
///    segment (`run_segment`), with `between_passes` on either side, previews (`preview`) and
///    checkpoints at the boundaries;
/// 3. the statistics merged in slot order (`stats`), the normalised output
///    (`ChainIntegrator::chain_output`) and the state.
pub fn run_chains<R: ChainRender>(
    render: &R,
    job: &RenderJob,
    progress: &dyn Progress,
    session: &Session,
    save: bool,
    clock: Arc<dyn Clock>,
) -> Result<ChainRun, RenderError> {
    let (width, height) = render.image_size();
    let pixels = width as u64 * height as u64;
    // Mutations per pixel × pixels must not overflow (`Budget::SamplesPerPixel` below).
    crate::integrator::check_budget(job.budget, width, height, "budget")?;
    let (film_width, film_height) = render.film_size()?;
    let driver = Driver::with_clock(job, film_width, film_height, clock.clone())?;
    let mut cs = ChainSession::new(session, render.chains(), clock)?;
    let segment = render.segment();
    let shard = session.shard;
    let integrator = render.integrator();

    // Where the chains start: a saved state, or the bootstrap.
    let mut counters_before = Counters::default();
    let (boot, units, saved_slot, film, next_pass) = match cs.resumed::<PartOf<R>>(film_width, film_height)? {
        Some((state, part)) => {
            let units: Vec<_> = load_units(&part.units)?;
            // The chains the render has here, in chain order: what the passes deal and what an
            // integrator may rely on (ensemble MLT's pairs are runs of consecutive chains).
            if !units.iter().map(R::Integrator::unit_index).eq(chains_here(render, shard)) {
                return Err(
                    StateError::Mismatch("the state's chains are not the render's, in chain order".into()).into()
                );
            }
            for unit in &units {
                render.check_restored(unit)?;
            }
            let saved = (state.counters.clone(), render.restore_slot(&part.stats));
            (part.bootstrap, units, Some(saved), Some(state_film(state)), state.passes_done)
        }
        None => {
            // A shard's bootstrap must be the same in every shard: a time budget may not shorten
            // it there.
            let time_budget = match job.budget {
                Budget::Seconds(s) if shard.is_none() => Some(s),
                _ => None,
            };
            let (boot, boot_counters, start) = render.bootstrap(&driver, progress, time_budget)?;
            counters_before = boot_counters;
            let Some(start) = start else {
                // No light found: a black image, and a complete state.
                let film = Accumulator::new(film_width as usize, film_height as usize);
                let stats = render.empty_stats();
                let tally = Tally { passes: 0, segment, counters: counters_before, wall: cs.elapsed() };
                let output = integrator.chain_output(&film, &[], stats.clone(), &boot, tally)?;
                let part = save.then(|| cs.part::<R::Integrator>(&boot, segment, stats, &[])).transpose()?;
                let (film, state) = cs.finish(film, &output.counters, part, 0, true, false, output.wall_time)?;
                return Ok(ChainRun { output, film, state });
            };
            let chains: Vec<u64> = chains_here(render, shard).collect();
            let units = render.start_chains(&driver, &start, &chains, progress, &mut counters_before)?;
            (boot, units, None, None, 0)
        }
    };
    render.begin(&boot);

    let here = render.mutations_per_pass_of(units.len());
    let passes = cs.passes(job.budget, pixels, render.mutations_per_pass(), here, next_pass, progress);
    progress.message("mutating");
    let preview = |at: &PassBoundary<'_, _, R::Slot>| render.preview(at.film, at.units, &slot_refs(at.slots));
    let checkpoint = |at: &PassBoundary<'_, _, R::Slot>| {
        cs.checkpoint(progress, || {
            let counters = boundary_counters(&counters_before, at.slots);
            let stats = render.stats(&slot_refs(at.slots), at.units);
            let part = cs.part::<R::Integrator>(&boot, segment, stats, at.units)?;
            let done = at.passes_done;
            cs.state(at.film.clone(), &counters, &part, done, cs.complete_at(done), cs.wall())
        })
    };
    let hook = |edge, pass, units: &mut [_]| render.between_passes(edge, pass, units);
    let start = RunStart { units, next_pass, film, saved_slot, passes: PassSet::ALL };
    let out = driver.run_from(
        start,
        passes,
        progress,
        |_| render.new_slot(),
        |item, unit, slot| render.run_segment(item.pass, unit, slot, progress),
        Some(&preview),
        session.control,
        session.checkpoint.is_some().then_some(&checkpoint as &CheckpointHook<'_, _, _>),
        Some(&hook),
    );

    let slots: Vec<&R::Slot> = out.slot_states.iter().collect();
    let stats = render.stats(&slots, &out.units);
    let mut counters = out.counters;
    counters.merge(&counters_before);
    let part = save.then(|| cs.part::<R::Integrator>(&boot, segment, stats.clone(), &out.units)).transpose()?;
    let tally = Tally { passes: out.passes, segment, counters, wall: cs.wall() };
    let output = integrator.chain_output(&out.film, &out.units, stats, &boot, tally)?;
    let complete = cs.complete_at(out.passes);
    let (film, state) =
        cs.finish(out.film, &output.counters, part, out.passes, complete, out.stopped, output.wall_time)?;
    Ok(ChainRun { output, film, state })
}
