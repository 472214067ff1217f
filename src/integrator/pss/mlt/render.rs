//! The MLT render: bootstrap, chains, the driver's passes and the normalised output — from the
//! start or from a saved state, for all chains or a shard's. What a state keeps
//! of it is [`MltPart`]: the bootstrap every chain and the normalisation share, the chains
//! themselves (sampler, current path, random stream, large-step totals) and the slots' statistics
//! merged, whose per-depth iteration counts the normalisation divides by.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::{BEstimate, Bootstrap, ChainUnit, Mlt, MltRun, SlotState, SubChain, CHAIN_SEED_SALT};
use super::{PathState, SUBCHAIN_SEED_SALT};
use crate::film::Accumulator;
use crate::integrator::driver::{
    boundary_counters, load_units, merge_chain_parts, merge_slot_states, save_units, state_film, ChainPart,
    ChainSession, CheckpointHook, Driver, PassBoundary, PassSet, RunStart, Slot, Tally,
};
use crate::integrator::pss::bootstrap::{run_bootstrap, run_shared_bootstrap, variance_of_mean};
use crate::integrator::pss::sampler::PssSampler;
use crate::integrator::pss::stats::{MltStats, MoveStats};
use crate::integrator::{Budget, Integrator, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::{Distribution1D, Rng};
use crate::scene::Scene;
use crate::state::{decode, RenderState, Session, StateError};
use crate::stats::{AcceptanceCount, Counters};

/// The bootstrap's outcome: per depth the sum of the targets of `paths` uniform samples, and the
/// warnings it gave. Identical in every shard of a sample-budget render (its streams depend on the
/// seed only), which the merge checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct BootstrapPart {
    sums: Vec<f64>,
    /// Per depth the sum of the squared targets (b_d's standard error in the statistics).
    sums_sq: Vec<f64>,
    /// Per depth the samples with a non-zero target.
    nonzero: Vec<u64>,
    /// Per depth the sum of the samples' second moments of one large step's target (MMLT, RJMLT:
    /// Q_d of `bootstrap_sample`; PSSMLT, whose large steps are its bootstrap samples: `sums_sq`).
    large_step_sums_sq: Vec<f64>,
    /// The sum of the squares of the samples' Σ_{d ≥ 1} n_d·B_d (MMLT, RJMLT: with depth 0's
    /// replicates, the standard error of the bootstrap's image brightness; 0 for PSSMLT).
    indirect_sum_sq: f64,
    /// MMLT, RJMLT: depth 0's replicates (`DIRECT_REPLICATES`), per replicate the sum of its
    /// `paths` targets, and their non-zero samples in all; empty for PSSMLT.
    direct_sums: Vec<f64>,
    direct_nonzero: u64,
    paths: u64,
    /// Wall time (0 in shards, whose bytes depend on their units only).
    seconds: f64,
    warnings: Vec<String>,
}

/// The MLT part of a render state (`crate::state`).
#[derive(Serialize, Deserialize)]
struct MltPart {
    bootstrap: BootstrapPart,
    /// Mutations per chain and pass.
    segment: u64,
    /// The slots' statistics merged (per-depth iterations: the normalisation's divisors).
    stats: MltStats,
    /// The technique count layers, merged (only with `technique_count_layers`).
    count_films: Option<Vec<Vec<Accumulator>>>,
    /// The chains, by their index in the whole render, each written through `UnitState`.
    units: Vec<(u64, Vec<u8>)>,
}

impl ChainPart for MltPart {
    fn units_mut(&mut self) -> &mut Vec<(u64, Vec<u8>)> {
        &mut self.units
    }

    fn absorb(&mut self, other: &MltPart) -> Result<(), StateError> {
        let key = |b: &BootstrapPart| (b.sums.clone(), b.direct_sums.clone(), b.paths);
        let same_bootstrap = key(&self.bootstrap) == key(&other.bootstrap);
        if !same_bootstrap || self.segment != other.segment {
            return Err(StateError::Mismatch("the shards did not start from the same bootstrap".into()));
        }
        self.stats.merge(&other.stats);
        if let (Some(a), Some(b)) = (self.count_films.as_mut(), other.count_films.as_ref()) {
            for (x, y) in a.iter_mut().flatten().zip(b.iter().flatten()) {
                x.merge(y);
            }
        }
        Ok(())
    }
}

impl Integrator for Mlt {
    fn name(&self) -> &'static str {
        self.variant.name()
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
        let part: MltPart = decode(&state.part)?;
        let units: Vec<ChainUnit> = load_units(&part.units)?;
        let film = state_film(state);
        let depths = self.depth_count();
        if !film.height.is_multiple_of(depths) {
            return Err(StateError::Mismatch("the state's film does not hold one layer per depth".into()).into());
        }
        let mut slot = self.new_slot(0, 0);
        slot.stats = part.stats;
        slot.count_films = part.count_films;
        let wall = Duration::try_from_secs_f64(state.wall_time_s).unwrap_or_default();
        let tally = Tally { passes: state.passes_done, segment: part.segment, counters: state.counters.clone(), wall };
        Ok(self.output(&film, &units, slot, &part.bootstrap, tally))
    }

    fn merge_parts(&self, parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
        merge_chain_parts::<MltPart>(parts)
    }
}

/// Per depth, the distribution of the bootstrap's targets the chains start from (`None` for a
/// depth it found no light at).
type StartDistributions = Vec<Option<Distribution1D>>;

/// MMLT, RJMLT: independent replicates of depth 0's own estimate of b_0, each as many camera rays
/// as the bootstrap has samples (`Mlt::direct_sample`; docs/mlt.md, "Depth 0's replicates").
/// Depth 0 (the emitters seen directly) costs one ray per sample where a full BDPT sample at
/// max_depth 16 traces about 33 subpath rays and a shadow ray per technique, and where an emitter
/// is in view it dominates the brightness's variance: its image is an indicator of the emitters'
/// outline on the film, which the bootstrap's Sobol points resolve only at their boundary pixels
/// (the shipped Cornell box: 0.53% relative error for b_0 against 0.16% for the other depths
/// together, 100,000 samples). Eight replicates cut b_0's error by √8 at the cost of 8 camera rays
/// per bootstrap sample, and their spread is an honest estimate of its variance (7 degrees of
/// freedom) where a Sobol sequence's own sample variance overstates it several times.
const DIRECT_REPLICATES: usize = 8;

impl BootstrapPart {
    /// Per depth b_d and its variances (`BEstimate`), and whether the full bootstrap found light
    /// there.
    fn estimates(&self) -> Bootstrap {
        let n = self.paths;
        let estimates = (0..self.sums.len())
            .map(|d| {
                let mean = self.sums[d] / n.max(1) as f64;
                // One large step's variance: its second moment less b_d² (the full bootstrap's).
                let large_step_variance =
                    (n >= 2).then(|| (self.large_step_sums_sq[d] / n as f64 - mean * mean).max(0.0));
                if d == 0 && !self.direct_sums.is_empty() {
                    let r = self.direct_sums.len();
                    let means: Vec<f64> = self.direct_sums.iter().map(|s| s / n.max(1) as f64).collect();
                    let mean = means.iter().sum::<f64>() / r as f64;
                    let spread = means.iter().map(|m| (m - mean) * (m - mean)).sum::<f64>();
                    BEstimate {
                        mean,
                        samples: n * r as u64,
                        nonzero: self.direct_nonzero,
                        variance: (n >= 1 && r >= 2).then(|| spread / (r * (r - 1)) as f64),
                        large_step_variance,
                    }
                } else {
                    BEstimate {
                        mean,
                        samples: n,
                        nonzero: self.nonzero[d],
                        variance: variance_of_mean(self.sums[d], self.sums_sq[d], n),
                        large_step_variance,
                    }
                }
            })
            .collect();
        Bootstrap { estimates, found: self.sums.iter().map(|&s| s > 0.0).collect() }
    }
}

impl Mlt {
    /// The render with the driver's stacked per-depth film (`Integrator::render` keeps only the
    /// output).
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<MltRun, RenderError> {
        self.run_session_film(scene, job, progress, &Session::default(), false).map(|(run, _)| run)
    }

    /// The render under `session`; with `save`, also the state it reached (which then takes the
    /// film, and `MltRun::film` is empty).
    fn run_session_film(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
    ) -> Result<(MltRun, Option<RenderState>), RenderError> {
        let (width, height) = (scene.camera.width as usize, scene.camera.height as usize);
        let pixels = (width * height) as u64;
        let depths = self.depth_count();
        // Mutations per pixel × pixels must not overflow (`Budget::SamplesPerPixel` below).
        crate::integrator::check_budget(job.budget, scene.camera.width, scene.camera.height, "budget")?;
        // The driver's film stacks the depths' images (module docs, "Films and threads"); the
        // driver refuses it beyond 2^32 pixels, and a stack beyond 2^32 rows is reported as that.
        let stacked_height = u32::try_from(height as u64 * depths as u64)
            .map_err(|_| RenderError::FilmTooLarge { width: scene.camera.width, height: u32::MAX })?;
        let driver = Driver::new(job, width as u32, stacked_height)?;
        let rr = if self.settings.rr_depth == u32::MAX { usize::MAX } else { self.settings.rr_depth as usize };
        let ctx = crate::integrator::bdpt::BdptContext::new(scene, rr, self.settings.mis);
        let mut cs = ChainSession::new(session, self.settings.chains)?;
        let segment = pixels.div_ceil(self.settings.chains).max(1);
        let per_pass = segment * self.settings.chains;
        let shard = session.shard;

        // Where the chains start: a saved state, or the bootstrap.
        let mut counters_before = Counters::default();
        let (boot, units, saved_slot, film, next_pass) = match cs.resumed::<MltPart>(width as u32, stacked_height)? {
            Some((state, part)) => {
                let units: Vec<ChainUnit> = load_units(&part.units)?;
                for unit in &units {
                    let counts = (self.depth_count(), self.settings.max_depth as usize + 2);
                    unit.check_restored(scene, counts, width as u32, height as u32)?;
                }
                let mut slot = self.new_slot(width, height);
                slot.stats = part.stats;
                slot.count_films = part.count_films;
                let saved = (state.counters.clone(), slot);
                (part.bootstrap, units, Some(saved), Some(state_film(state)), state.passes_done)
            }
            None => {
                let (boot, boot_counters, dists) = self.bootstrap(&driver, &ctx, job, progress, shard.is_some())?;
                counters_before = boot_counters;
                let Some(dists) = dists else {
                    // No light found: a black image, and a complete state.
                    let film = Accumulator::new(width, height * depths);
                    let tally = Tally { passes: 0, segment, counters: counters_before, wall: cs.elapsed() };
                    let mut empty = self.new_slot(0, 0);
                    empty.count_films = None;
                    let stats = empty.stats.clone();
                    let output = self.output(&film, &[], empty, &boot, tally);
                    let part = MltPart { bootstrap: boot, segment, stats, count_films: None, units: Vec::new() };
                    let (film, state) =
                        cs.finish(film, &output.counters, save.then_some(part), 0, true, false, output.wall_time)?;
                    return Ok((MltRun { output, film }, state));
                };
                let chains = (0..self.settings.chains).filter(|c| shard.is_none_or(|s| s.contains(*c)));
                let mut init_slot = self.new_slot(0, 0);
                let units: Vec<ChainUnit> = chains
                    .map(|c| self.start_chain(c, &dists, &ctx, job.seed, &mut init_slot, &mut counters_before))
                    .collect();
                (boot, units, None, None, 0)
            }
        };

        let passes = cs.passes(job.budget, pixels, per_pass, segment, units.len(), next_pass, progress);
        progress.message("mutating");
        let bootstrap = boot.estimates();
        let preview = |at: &PassBoundary<'_, ChainUnit, SlotState>| {
            let large_steps = self.large_step_totals(at.units);
            let iterations = self.iteration_counts(at.slots.iter().map(|slot| &slot.state));
            self.normalised_image(at.film, &large_steps, &iterations, &bootstrap).0
        };
        let checkpoint = |at: &PassBoundary<'_, ChainUnit, SlotState>| {
            cs.checkpoint(progress, || {
                let counters = boundary_counters(&counters_before, at.slots);
                let mut merged = self.new_slot(0, 0);
                merged.count_films = None;
                for (i, slot) in at.slots.iter().enumerate() {
                    if i == 0 {
                        merged.count_films = slot.state.count_films.clone();
                        merged.stats = slot.state.stats.clone();
                    } else {
                        merge_slot(&mut merged, &slot.state);
                    }
                }
                let boot = BootstrapPart { seconds: cs.saved_seconds(boot.seconds), ..boot.clone() };
                let part = self.part(&boot, segment, &merged, at.units)?;
                let done = at.passes_done;
                cs.state(at.film.clone(), &counters, &part, done, cs.complete_at(done), cs.wall())
            })
        };
        let start = RunStart { units, next_pass, film, saved_slot, passes: PassSet::ALL };
        let out = driver.run_from(
            start,
            passes,
            progress,
            |_| self.new_slot(width, height),
            |_, unit, slot| {
                let Slot { index, state, film, counters } = slot;
                // The unit's own large steps so far: the choice depends on the chain alone.
                let depth_choice = (depths > 1).then(|| self.depth_choice(&bootstrap, &unit.large_steps));
                for _ in 0..segment {
                    let d = depth_choice.as_ref().map_or(0, |c| c.sample_discrete(unit.rng.uniform()).0);
                    let Some(chain) = unit.subchains[d].as_mut() else { continue };
                    if let Some(target) = self.iterate(&ctx, d, chain, &mut unit.rng, state, film, counters) {
                        let depth = &mut state.stats.per_depth[d];
                        depth.large_step_target_sum += target as f64;
                        depth.large_steps += 1;
                        unit.large_steps[d].0 += target as f64;
                        unit.large_steps[d].1 += 1;
                    }
                }
                if *index == 0 {
                    let moves = &state.stats.moves;
                    let (proposed, accepted) = [&moves.large, &moves.small]
                        .into_iter()
                        .chain(moves.jump.as_ref())
                        .fold((0, 0), |(p, a), m| (p + m.proposals, a + m.accepted));
                    progress.message(&format!("acceptance {:.1}%", 100.0 * accepted as f64 / proposed.max(1) as f64));
                }
                segment
            },
            Some(&preview),
            session.control,
            session.checkpoint.is_some().then_some(&checkpoint as &CheckpointHook<'_, _, _>),
        );

        let merged = merge_slot_states(out.slot_states, merge_slot)?;
        let mut counters = out.counters;
        counters.merge(&counters_before);
        let boot_for_state = BootstrapPart { seconds: cs.saved_seconds(boot.seconds), ..boot.clone() };
        let part = save.then(|| self.part(&boot_for_state, segment, &merged, &out.units)).transpose()?;
        let tally = Tally { passes: out.passes, segment, counters, wall: cs.wall() };
        let output = self.output(&out.film, &out.units, merged, &boot, tally);
        let complete = cs.complete_at(out.passes);
        let (film, state) =
            cs.finish(out.film, &output.counters, part, out.passes, complete, out.stopped, output.wall_time)?;
        Ok((MltRun { output, film }, state))
    }

    /// The bootstrap (see the module docs): up to `bootstrap` uniform samples per depth, in
    /// batches over the pool (deterministic: each sample has its own stream). Returns its outcome,
    /// its counters and, unless no sample found light, per depth the distribution of its targets
    /// the chains start from. `same_everywhere` (a shard): a time budget may not shorten it.
    fn bootstrap(
        &self,
        driver: &Driver,
        ctx: &crate::integrator::bdpt::BdptContext,
        job: &RenderJob,
        progress: &dyn Progress,
        same_everywhere: bool,
    ) -> Result<(BootstrapPart, Counters, Option<StartDistributions>), RenderError> {
        let depths = self.depth_count();
        // `bootstrap::run_bootstrap`: under a time budget it takes at most a quarter of the budget
        // (large steps keep refining b during the render, so a shorter bootstrap costs accuracy of
        // the start only, not correctness) — except in a shard, whose bootstrap must be the same
        // in every shard.
        let time_budget = match job.budget {
            Budget::Seconds(s) if !same_everywhere => Some(s),
            _ => None,
        };
        // MMLT and RJMLT push B_d and then Q_d per depth (`bootstrap_sample`).
        let slots = if depths > 1 { 2 * depths } else { 1 };
        let boot = run_shared_bootstrap(
            driver,
            progress,
            slots,
            self.settings.bootstrap,
            time_budget,
            |_| self.new_slot(0, 0),
            |i, slot, counters, out| self.bootstrap_sample(ctx, job.seed, i, slot, counters, out),
        );
        let n_boot = boot.paths;
        let mut counters = boot.counters;
        let mut elapsed = boot.elapsed;
        let mut targets = boot.targets;
        let mut sums = boot.sums;
        let mut sums_sq = boot.sums_sq;
        let large_step_sums_sq = if depths > 1 { sums.split_off(depths) } else { sums_sq.clone() };
        sums_sq.truncate(depths);
        targets.truncate(depths);
        let nonzero = targets.iter().map(|t| t.iter().filter(|&&x| x > 0.0).count() as u64).collect();
        // Per sample Σ_{d ≥ 1} n_d·B_d, the sample's BDPT estimate of the image's luminance less
        // the emitters seen directly (depth 0, which its replicates estimate).
        let indirect_sum_sq = if depths > 1 {
            (0..n_boot as usize)
                .map(|i| {
                    let total: f64 = (1..depths).map(|d| self.technique_count(d) as f64 * targets[d][i] as f64).sum();
                    total * total
                })
                .sum()
        } else {
            0.0
        };
        // Depth 0's replicates, as many camera rays each as the bootstrap took samples.
        let (mut direct_sums, mut direct_nonzero) = (Vec::new(), 0);
        if depths > 1 {
            let replicates = run_bootstrap(
                driver,
                progress,
                DIRECT_REPLICATES,
                n_boot,
                None,
                |_| self.new_slot(0, 0),
                |r, i, slot, counters| self.direct_sample(ctx, job.seed, r, i, slot, counters),
            );
            counters.merge(&replicates.counters);
            elapsed += replicates.elapsed;
            direct_sums = replicates.sums;
            direct_nonzero = replicates.targets.iter().flatten().filter(|&&x| x > 0.0).count() as u64;
        }
        let seconds = elapsed.as_secs_f64();
        let part = |warnings| BootstrapPart {
            sums: sums.clone(),
            sums_sq: sums_sq.clone(),
            nonzero: Vec::clone(&nonzero),
            large_step_sums_sq: large_step_sums_sq.clone(),
            indirect_sum_sq,
            direct_sums: direct_sums.clone(),
            direct_nonzero,
            paths: n_boot,
            seconds,
            warnings,
        };
        let b_total: f64 = sums.iter().map(|s| s / n_boot as f64).sum();
        let mut warnings: Vec<String> = Vec::new();
        if !(b_total > 0.0) {
            warnings.push(format!(
                "no bootstrap path ({} per depth) carried light to the camera: the image is black. Check that \
                 emitters are visible from the camera's surroundings, or raise `bootstrap`.",
                n_boot
            ));
            return Ok((part(warnings), counters, None));
        }
        // Without progressive b a depth's b_d stays the bootstrap's, so a depth it missed cannot
        // be recovered and is not chosen (`depth_choice`); a warning says so.
        if depths > 1 && !self.settings.progressive_b {
            let missed: Vec<usize> = (0..depths).filter(|&d| sums[d] == 0.0).collect();
            if !missed.is_empty() {
                warnings.push(format!(
                    "no bootstrap path ({n_boot} per depth) found light at depth(s) {missed:?}, and without \
                     progressive_b their b_d stays 0: their light is missing from the image. Raise `bootstrap` \
                     or enable `progressive_b`."
                ));
            }
        }
        let dists = targets.iter().zip(&sums).map(|(t, &s)| (s > 0.0).then(|| Distribution1D::new(t))).collect();
        Ok((part(warnings), counters, Some(dists)))
    }

    /// Chain `c`: each sub-chain starts from a bootstrap sample chosen ∝ its target (start-up bias
    /// is negligible this way: the start is distributed as the target up to the bootstrap's finite
    /// sample), reproduced exactly from its stream. Depends on the seed and `c` only, so a shard
    /// starts its chains as the whole render does.
    fn start_chain(
        &self,
        c: u64,
        dists: &StartDistributions,
        ctx: &crate::integrator::bdpt::BdptContext,
        seed: u64,
        init_slot: &mut SlotState,
        counters: &mut Counters,
    ) -> ChainUnit {
        let depths = self.depth_count();
        let mut rng = Rng::new(seed ^ CHAIN_SEED_SALT, c);
        let subchains = (0..depths)
            .map(|d| {
                let own_stream = Rng::new(seed ^ SUBCHAIN_SEED_SALT, c * depths as u64 + d as u64);
                let Some(dist) = dists[d].as_ref() else {
                    // A depth the bootstrap missed: the chain searches from a zero state (only
                    // with progressive b: otherwise the depth is never chosen).
                    let sampler = PssSampler::new(own_stream, self.mutation(), super::STREAM_COUNT);
                    return self.settings.progressive_b.then(|| SubChain { sampler, current: PathState::default() });
                };
                let (i, _, _) = dist.sample_discrete(rng.uniform());
                let (u_technique, u_within) = (rng.uniform(), rng.uniform());
                let (chain, _) =
                    self.start_state(ctx, seed, d, i as u64, u_technique, u_within, own_stream, init_slot, counters);
                Some(chain)
            })
            .collect();
        ChainUnit { index: c, rng, large_steps: vec![(0.0, 0); depths], subchains }
    }

    /// The state's MLT part: the bootstrap, the merged slot, the chains written through
    /// `UnitState`.
    fn part(
        &self,
        boot: &BootstrapPart,
        segment: u64,
        slot: &SlotState,
        units: &[ChainUnit],
    ) -> Result<MltPart, StateError> {
        let (mut stats, count_films) = (slot.stats.clone(), slot.count_films.clone());
        // The slot-order f64 sums depend on the threads; a state's bytes must not (shards).
        for (depth, (sum, _)) in stats.per_depth.iter_mut().zip(self.large_step_totals(units)) {
            depth.large_step_target_sum = sum;
        }
        let units = save_units(units, |u| u.index)?;
        Ok(MltPart { bootstrap: boot.clone(), segment, stats, count_films, units })
    }

    /// The image and statistics of a film with its chains and merged slot: each depth normalised
    /// with the large-step totals pooled in unit order and the depths' iteration counts (integers:
    /// any merge order gives them), so the same for a render, its resumption and its merged shards.
    fn output(
        &self,
        film: &Accumulator,
        units: &[ChainUnit],
        merged: SlotState,
        boot: &BootstrapPart,
        tally: Tally,
    ) -> RenderOutput {
        let pixels = film.width as u64 * (film.height / self.depth_count()) as u64;
        let large_steps = self.large_step_totals(units);
        let iterations = self.iteration_counts(std::iter::once(&merged));
        let bootstrap = boot.estimates();
        let (image, b_final) = self.normalised_image(film, &large_steps, &iterations, &bootstrap);
        let mut layers = Vec::new();
        if let Some(films) = merged.count_films.as_ref() {
            for (d, per_s) in films.iter().enumerate() {
                for (s, f) in per_s.iter().enumerate() {
                    layers.push((format!("count.d{d}.s{s}t{}", d + 2 - s), f.to_image(1.0)));
                }
            }
        }
        let mut stats = merged.stats;
        for (depth, (sum, _)) in stats.per_depth.iter_mut().zip(&large_steps) {
            // The slot-order f64 sum would differ in its last bits between thread counts.
            depth.large_step_target_sum = *sum;
        }
        let b_boot: Vec<f64> = bootstrap.estimates.iter().map(|e| e.mean).collect();
        stats.passes = tally.passes;
        stats.segment_length = tally.segment;
        stats.bootstrap_paths_per_depth = boot.paths;
        stats.bootstrap_seconds = boot.seconds;
        stats.warnings = boot.warnings.clone();
        stats.finish(pixels, &b_boot, &b_final);
        let relative_se = |e: &BEstimate| e.variance.filter(|_| e.mean > 0.0).map(|v| v.sqrt() / e.mean);
        for (depth, e) in stats.per_depth.iter_mut().zip(&bootstrap.estimates) {
            depth.b_bootstrap_relative_se = relative_se(e);
        }
        if self.depth_count() > 1 {
            // Σ_d n_d·b_d: depth 0 from its replicates (independent of the full samples), the
            // other depths from the full samples' per-sample sums.
            let indirect_sum: f64 =
                (1..self.depth_count()).map(|d| self.technique_count(d) as f64 * boot.sums[d]).sum();
            let indirect = indirect_sum / boot.paths.max(1) as f64;
            let indirect_variance = variance_of_mean(indirect_sum, boot.indirect_sum_sq, boot.paths);
            let direct = &bootstrap.estimates[0];
            let total = BEstimate {
                mean: direct.mean + indirect,
                variance: direct.variance.zip(indirect_variance).map(|(a, b)| a + b),
                ..BEstimate::default()
            };
            stats.b_bootstrap_total_relative_se = relative_se(&total);
        }
        let mut counters = tally.counters;
        let strategy = |m: &MoveStats| AcceptanceCount { proposed: m.proposals, accepted: m.accepted as f64 };
        counters.strategies.insert("large_step".to_string(), strategy(&stats.moves.large));
        counters.strategies.insert("small_step".to_string(), strategy(&stats.moves.small));
        if let Some(jump) = stats.moves.jump.as_ref() {
            counters.strategies.insert("technique_jump".to_string(), strategy(jump));
        }
        RenderOutput {
            image,
            layers,
            counters,
            wall_time: tally.wall,
            extra_stats: serde_json::to_value(&stats).unwrap_or(serde_json::Value::Null),
        }
    }
}

/// Adds a slot's statistics and count layers to `merged` (slot order).
fn merge_slot(merged: &mut SlotState, other: &SlotState) {
    if let (Some(m), Some(o)) = (merged.count_films.as_mut(), other.count_films.as_ref()) {
        for (a, b) in m.iter_mut().flatten().zip(o.iter().flatten()) {
            a.merge(b);
        }
    }
    merged.stats.merge(&other.stats);
}

#[cfg(test)]
mod tests {
    use super::BootstrapPart;

    /// b_0 and its variance come from depth 0's replicates: the mean of the replicate means and
    /// their spread / (R(R − 1)), the honest variance of a mean of independent replicates (a
    /// Sobol sequence's own sample variance overstates it); the other depths from the full
    /// samples, variance s²/N; one large step's variance is its second moment less b_d², both from
    /// the full samples.
    #[test]
    fn bootstrap_estimates_take_depth_0_from_its_replicates() {
        let n = 100u64;
        let part = BootstrapPart {
            sums: vec![50.0, 20.0],
            sums_sq: vec![50.0, 20.0 * 1.5],
            nonzero: vec![50, 40],
            large_step_sums_sq: vec![50.0, 36.0],
            indirect_sum_sq: 0.0,
            // Replicate means 0.40, 0.44, 0.48, 0.52, 0.56, 0.60, 0.64, 0.68: mean 0.54.
            direct_sums: (0..8).map(|r| 40.0 + 4.0 * r as f64).collect(),
            direct_nonzero: 432,
            paths: n,
            seconds: 0.0,
            warnings: Vec::new(),
        };
        let b = part.estimates();
        let d0 = b.estimates[0];
        assert!((d0.mean - 0.54).abs() < 1e-12, "{d0:?}");
        assert_eq!((d0.samples, d0.nonzero), (800, 432));
        let spread: f64 = (0..8).map(|r| (0.40 + 0.04 * r as f64 - 0.54f64).powi(2)).sum();
        assert!((d0.variance.expect("variance") - spread / 56.0).abs() < 1e-15, "{d0:?}");
        // A large step's variance from the full samples' own moments (Q_0/N − (Σ B_0/N)²).
        assert!((d0.large_step_variance.expect("variance") - (0.5 - 0.5 * 0.5)).abs() < 1e-12);
        let d1 = b.estimates[1];
        assert!((d1.mean - 0.2).abs() < 1e-12);
        let s2 = (30.0 - 100.0 * 0.04) / 99.0;
        assert!((d1.variance.expect("variance") - s2 / 100.0).abs() < 1e-15, "{d1:?}");
        assert!((d1.large_step_variance.expect("variance") - (0.36 - 0.04)).abs() < 1e-12);
        assert_eq!(b.found, vec![true, true]);
    }
}
