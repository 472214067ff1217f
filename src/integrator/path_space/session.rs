//! The pmlt render: bootstrap, chains, the driver's passes and the normalised output — from the
//! start or from a saved state, for all chains or a shard's, as the MLT family's
//! (`pss/mlt/render.rs`). `Integrator::render` is this path with no session. What a state keeps of
//! it is [`PmltPart`]: the bootstrap's sum (b, shared by every chain and the normalisation), the
//! chains (random stream and current path with its f and f*, written through `UnitState`) and the
//! slots' statistics merged, whose iteration counts the normalisation divides by.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::chain::{new_stats, step, ChainUnit, Pmlt, PmltRun, SlotState};
use super::PathContext;
use crate::film::Accumulator;
use crate::integrator::driver::{
    boundary_counters, load_units, merge_chain_parts, merge_slot_states, save_units, state_film, ChainPart,
    ChainSession, CheckpointHook, Driver, PassBoundary, PassSet, RunStart, Slot, Tally,
};
use crate::integrator::pss::bootstrap::run_bootstrap;
use crate::integrator::pss::stats::MltStats;
use crate::integrator::{Budget, Integrator, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::Distribution1D;
use crate::scene::Scene;
use crate::state::{decode, RenderState, Session, StateError};
use crate::stats::{AcceptanceCount, Counters};

/// The bootstrap's outcome: the sum of the targets of `paths` BDPT samples (b = sum / paths).
/// Identical in every shard of a sample-budget render (its streams depend on the seed only), which
/// the merge checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct BootstrapPart {
    sum: f64,
    paths: u64,
    /// Wall time (0 in shards, whose bytes depend on their units only).
    seconds: f64,
}

impl BootstrapPart {
    fn b(&self) -> f64 {
        self.sum / self.paths.max(1) as f64
    }
}

/// The pmlt part of a render state (`crate::state`).
#[derive(Serialize, Deserialize)]
struct PmltPart {
    bootstrap: BootstrapPart,
    /// Mutations per chain and pass.
    segment: u64,
    /// Chains of the state that found no start path (for the warning; summed by the merge).
    unstarted: u64,
    /// The slots' statistics merged (per depth and per strategy; the iterations are the
    /// normalisation's divisor).
    stats: MltStats,
    /// The chains, by their index in the whole render, each written through `UnitState`.
    units: Vec<(u64, Vec<u8>)>,
}

impl ChainPart for PmltPart {
    fn units_mut(&mut self) -> &mut Vec<(u64, Vec<u8>)> {
        &mut self.units
    }

    fn absorb(&mut self, other: &PmltPart) -> Result<(), StateError> {
        let same_bootstrap = (self.bootstrap.sum, self.bootstrap.paths) == (other.bootstrap.sum, other.bootstrap.paths);
        if !same_bootstrap || self.segment != other.segment {
            return Err(StateError::Mismatch("the shards did not start from the same bootstrap".into()));
        }
        // Per depth and per strategy: counts add (`MltStats::merge`).
        self.stats.merge(&other.stats);
        self.unstarted += other.unstarted;
        Ok(())
    }
}

impl Integrator for Pmlt {
    fn name(&self) -> &'static str {
        "pmlt"
    }

    fn settings_json(&self) -> serde_json::Value {
        serde_json::to_value(&self.settings).unwrap_or(serde_json::Value::Null)
    }

    fn run_session(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(RenderOutput, Option<RenderState>), RenderError> {
        self.run_session_film(scene, job, progress, session, save).map(|(run, state)| (run.output, state))
    }

    fn output_of_state(&self, state: &RenderState) -> Result<RenderOutput, RenderError> {
        let part: PmltPart = decode(&state.part)?;
        let film = state_film(state);
        let wall = Duration::try_from_secs_f64(state.wall_time_s).unwrap_or_default();
        let tally = Tally { passes: state.passes_done, segment: part.segment, counters: state.counters.clone(), wall };
        Ok(self.output(&film, part.stats, &part.bootstrap, part.unstarted, tally))
    }

    fn merge_parts(&self, parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        merge_chain_parts::<PmltPart>(parts)
    }
}

impl Pmlt {
    /// The render with its unnormalised film (for tests that check the film's bits).
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<PmltRun, RenderError> {
        self.run_session_film(scene, job, progress, &Session::default(), false).map(|(run, _)| run)
    }

    /// The render under `session`; with `save`, also the state it reached (which then takes the
    /// film, and `PmltRun::film` is empty).
    fn run_session_film(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(PmltRun, Option<RenderState>), RenderError> {
        let (width, height) = (scene.camera.width as usize, scene.camera.height as usize);
        let pixels = (width * height) as u64;
        crate::integrator::check_budget(job.budget, scene.camera.width, scene.camera.height, "budget")?;
        let driver = Driver::new(job, scene.camera.width, scene.camera.height)?;
        let mut cs = ChainSession::new(session, self.settings.chains)?;
        let max_depth = self.settings.max_depth as usize;
        let ctx = PathContext { scene, max_depth };
        let bctx = self.bdpt_context(scene);
        let set = self.strategies(scene);
        // Budget: one pass is about one mutation per pixel over all chains.
        let segment = pixels.div_ceil(self.settings.chains).max(1);
        let per_pass = segment * self.settings.chains;
        let shard = session.shard;

        // Where the chains start: a saved state, or the bootstrap.
        let mut counters_before = Counters::default();
        let (boot, unstarted, units, saved_slot, film, next_pass) =
            match cs.resumed::<PmltPart>(scene.camera.width, scene.camera.height)? {
                Some((state, part)) => {
                    let units: Vec<ChainUnit> = load_units(&part.units)?;
                    let mut slot = self.new_slot(&set);
                    slot.stats = part.stats;
                    let saved = (state.counters.clone(), slot);
                    (part.bootstrap, part.unstarted, units, Some(saved), Some(state_film(state)), state.passes_done)
                }
                None => {
                    // A shard's bootstrap must be the same in every shard: a time budget may not
                    // shorten it there.
                    let time_budget = match job.budget {
                        Budget::Seconds(s) if shard.is_none() => Some(s),
                        _ => None,
                    };
                    let run = run_bootstrap(
                        &driver,
                        progress,
                        1,
                        self.settings.bootstrap,
                        time_budget,
                        |_| self.new_slot(&set),
                        |_, i, slot, counters| self.bootstrap_sample(&bctx, job.seed, i, slot, counters, None),
                    );
                    counters_before = run.counters;
                    let boot = BootstrapPart { sum: run.sums[0], paths: run.paths, seconds: run.elapsed.as_secs_f64() };
                    if !(boot.b() > 0.0) {
                        // No light found: a black image, and a complete state.
                        let film = Accumulator::new(width, height);
                        let stats = new_stats(max_depth, &set);
                        let tally = Tally { passes: 0, segment, counters: counters_before, wall: cs.elapsed() };
                        let output = self.output(&film, stats.clone(), &boot, 0, tally);
                        let part = PmltPart { bootstrap: boot, segment, unstarted: 0, stats, units: Vec::new() };
                        let (film, state) =
                            cs.finish(film, &output.counters, save.then_some(part), 0, true, false, output.wall_time)?;
                        return Ok((PmltRun { output, film }, state));
                    }
                    // Start the chains (of the shard) from resampled bootstrap paths (`chain` docs).
                    let start = Distribution1D::new(&run.targets[0]);
                    let mut init_slot = self.new_slot(&set);
                    let mut candidates = Vec::new();
                    let units: Vec<ChainUnit> = (0..self.settings.chains)
                        .filter(|c| shard.is_none_or(|s| s.contains(*c)))
                        .map(|c| {
                            let (seed, slot) = (job.seed, &mut init_slot);
                            self.start_chain(c, &start, &ctx, &bctx, seed, slot, &mut counters_before, &mut candidates)
                        })
                        .collect();
                    let unstarted = units.iter().filter(|u| !(u.current.f_star > 0.0)).count() as u64;
                    (boot, unstarted, units, None, None, 0)
                }
            };

        let passes = cs.passes(job.budget, pixels, per_pass, segment, units.len(), next_pass, progress);
        progress.message("mutating");
        let b = boot.b();
        let preview = |at: &PassBoundary<'_, ChainUnit, SlotState>| {
            let n: u64 = at.slots.iter().map(|s| iterations(&s.state.stats)).sum();
            at.film.to_image(scale(b, pixels, n))
        };
        let checkpoint = |at: &PassBoundary<'_, ChainUnit, SlotState>| {
            cs.checkpoint(progress, || {
                let counters = boundary_counters(&counters_before, at.slots);
                let mut stats = new_stats(max_depth, &set);
                for (i, slot) in at.slots.iter().enumerate() {
                    if i == 0 {
                        stats = slot.state.stats.clone();
                    } else {
                        stats.merge(&slot.state.stats);
                    }
                }
                let boot = BootstrapPart { seconds: cs.saved_seconds(boot.seconds), ..boot.clone() };
                let part = self.part(&boot, segment, unstarted, stats, at.units)?;
                let done = at.passes_done;
                cs.state(at.film.clone(), &counters, &part, done, cs.complete_at(done), cs.wall())
            })
        };
        let start = RunStart { units, next_pass, film, saved_slot, passes: PassSet::ALL };
        let out = driver.run_from(
            start,
            passes,
            progress,
            |_| self.new_slot(&set),
            |_, unit, slot| {
                let Slot { index, state, film, counters } = slot;
                for _ in 0..segment {
                    step(&ctx, &set, &mut unit.current, &mut unit.rng, &mut state.stats, film, counters);
                }
                if *index == 0 {
                    let (p, a) = state
                        .stats
                        .strategies
                        .iter()
                        .flatten()
                        .fold((0, 0), |(p, a), s| (p + s.selected, a + s.accepted));
                    progress.message(&format!("acceptance {:.1}%", 100.0 * a as f64 / p.max(1) as f64));
                }
                segment
            },
            Some(&preview),
            session.control,
            session.checkpoint.is_some().then_some(&checkpoint as &CheckpointHook<'_, _, _>),
        );

        let merged = merge_slot_states(out.slot_states, |m, s| m.stats.merge(&s.stats))?;
        let mut counters = out.counters;
        counters.merge(&counters_before);
        let boot_for_state = BootstrapPart { seconds: cs.saved_seconds(boot.seconds), ..boot.clone() };
        let part = save
            .then(|| self.part(&boot_for_state, segment, unstarted, merged.stats.clone(), &out.units))
            .transpose()?;
        let tally = Tally { passes: out.passes, segment, counters, wall: cs.wall() };
        let output = self.output(&out.film, merged.stats, &boot, unstarted, tally);
        let complete = cs.complete_at(out.passes);
        let (film, state) =
            cs.finish(out.film, &output.counters, part, out.passes, complete, out.stopped, output.wall_time)?;
        Ok((PmltRun { output, film }, state))
    }

    /// The state's pmlt part: the bootstrap, the merged statistics, the chains written through
    /// `UnitState`.
    fn part(
        &self,
        boot: &BootstrapPart,
        segment: u64,
        unstarted: u64,
        stats: MltStats,
        units: &[ChainUnit],
    ) -> Result<PmltPart, StateError> {
        let units = save_units(units, |u| u.index)?;
        Ok(PmltPart { bootstrap: boot.clone(), segment, unstarted, stats, units })
    }

    /// The image and statistics of a film with the merged statistics: the film times b·P/N (`chain`
    /// docs), N the iterations of all chains (an integer: any merge order gives it), so the same
    /// for a render, its resumption and its merged shards.
    fn output(
        &self,
        film: &Accumulator,
        mut stats: MltStats,
        boot: &BootstrapPart,
        unstarted: u64,
        tally: Tally,
    ) -> RenderOutput {
        let pixels = film.width as u64 * film.height as u64;
        let b = boot.b();
        let mut warnings = Vec::new();
        if !(b > 0.0) {
            warnings.push(format!(
                "no bootstrap path ({} BDPT samples) carried light to the camera: the image is black. Check that \
                 emitters are visible from the camera's surroundings, or raise `bootstrap`.",
                boot.paths
            ));
        }
        if unstarted > 0 {
            warnings.push(format!(
                "{unstarted} of {} chains found no start path with a non-zero contribution in {} draws from the \
                 bootstrap; they stay at a zero path (their iterations splat nothing).",
                self.settings.chains,
                super::chain::START_ATTEMPTS
            ));
        }
        let n = iterations(&stats);
        let image = film.to_image(scale(b, pixels, n));
        // b per depth: the bootstrap's b split by the chains' share of iterations at each depth
        // (the chains sample depths ∝ their b_d), for the JSON's per-depth entries.
        let b_depth: Vec<f64> =
            stats.per_depth.iter().map(|d| if n > 0 { b * d.iterations as f64 / n as f64 } else { 0.0 }).collect();
        stats.passes = tally.passes;
        stats.segment_length = tally.segment;
        stats.bootstrap_paths_per_depth = boot.paths;
        stats.bootstrap_seconds = boot.seconds;
        stats.warnings = warnings;
        stats.finish(pixels, &b_depth, &b_depth);
        let mut counters = tally.counters;
        for s in stats.strategies.iter().flatten() {
            counters
                .strategies
                .insert(s.name.clone(), AcceptanceCount { proposed: s.selected, accepted: s.accepted as f64 });
        }
        let mut extra = serde_json::to_value(&stats).unwrap_or(serde_json::Value::Null);
        if let (Some(map), true) = (extra.as_object_mut(), b > 0.0) {
            map.insert("b".into(), serde_json::json!(b));
        }
        RenderOutput { image, layers: Vec::new(), counters, wall_time: tally.wall, extra_stats: extra }
    }
}

/// Iterations of all chains in `stats` (every depth).
fn iterations(stats: &MltStats) -> u64 {
    stats.per_depth.iter().map(|d| d.iterations).sum()
}

/// The film's normalisation b·P/N (`chain` docs); 0 before any iteration.
fn scale(b: f64, pixels: u64, iterations: u64) -> f64 {
    if iterations > 0 {
        b * pixels as f64 / iterations as f64
    } else {
        0.0
    }
}
