//! PSSMLT, MMLT and RJMLT on the chain runner (`integrator::driver::run_chains`): what is theirs
//! in a render — the bootstrap (per depth, with depth 0's replicates), the chains' start (every
//! sub-chain from a bootstrap sample), their segment (a depth chosen per iteration, Kelemen
//! mutations, RJMLT's jumps), the statistics and the per-depth normalisation. What a state keeps
//! of it is a `ChainPart` of [`BootstrapPart`] (the bootstrap every chain and the normalisation
//! share), [`MltStats`] with the technique count layers ([`MltTally`]: the slots' statistics
//! merged, whose per-depth iteration counts the normalisation divides by) and the chains
//! themselves (sampler, current path, random stream, large-step totals).

use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use super::{BEstimate, Bootstrap, ChainUnit, Mlt, MltRun, SlotState, SubChain, CHAIN_SEED_SALT};
use super::{PathState, SUBCHAIN_SEED_SALT};
use crate::film::{Accumulator, Image};
use crate::integrator::bdpt::BdptContext;
use crate::integrator::driver::bootstrap::{run_bootstrap, run_shared_bootstrap, variance_of_mean};
use crate::integrator::driver::{
    run_chains, ChainBootstrap, ChainEngine, ChainIntegrator, ChainRender, ChainRun, ChainStats, Clock, Driver, Slot,
    Tally, WallClock,
};
use crate::integrator::pss::mlt_settings::MltSettings;
use crate::integrator::pss::mlt_stats::{MltStats, MoveStats};
use crate::integrator::pss::sampler::PssSampler;
use crate::integrator::{Plugin, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::{Distribution1D, Rng};
use crate::scene::Scene;
use crate::state::{Session, StateError};
use crate::stats::{AcceptanceCount, Counters};

/// The bootstrap's outcome: per depth the sum of the targets of `paths` uniform samples, and the
/// warnings it gave. Identical in every shard of a sample-budget render (its streams depend on the
/// seed only), which the merge checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BootstrapPart {
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

impl ChainBootstrap for BootstrapPart {
    fn same_as(&self, other: &BootstrapPart) -> bool {
        let key = |b: &BootstrapPart| (b.sums.clone(), b.direct_sums.clone(), b.paths);
        key(self) == key(other)
    }
    fn seconds_mut(&mut self) -> &mut f64 {
        &mut self.seconds
    }
}

/// The MLT statistics of a render state: the slots' merged.
#[derive(Clone, Serialize, Deserialize)]
pub struct MltTally {
    /// Per-depth iterations: the normalisation's divisors.
    stats: MltStats,
    /// The technique count layers, merged (only with `technique_count_layers`).
    count_films: Option<Vec<Vec<Accumulator>>>,
}

impl ChainStats for MltTally {
    fn absorb(&mut self, other: &MltTally) {
        self.stats.merge(&other.stats);
        if let (Some(a), Some(b)) = (self.count_films.as_mut(), other.count_films.as_ref()) {
            for (x, y) in a.iter_mut().flatten().zip(b.iter().flatten()) {
                x.merge(y);
            }
        }
    }
}

impl ChainIntegrator for Mlt {
    type Unit = ChainUnit;
    type Boot = BootstrapPart;
    type Stats = MltTally;

    fn unit_index(unit: &ChainUnit) -> u64 {
        unit.index
    }

    fn chain_output(
        &self,
        film: &Accumulator,
        units: &[ChainUnit],
        stats: MltTally,
        boot: &BootstrapPart,
        tally: Tally,
    ) -> Result<RenderOutput, RenderError> {
        if !film.height.is_multiple_of(self.depth_count()) {
            return Err(StateError::Mismatch("the state's film does not hold one layer per depth".into()).into());
        }
        let mut slot = self.new_slot(0, 0);
        slot.stats = stats.stats;
        slot.count_films = stats.count_films;
        Ok(self.output(film, units, slot, boot, tally))
    }

    fn run_on_clock(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: &Session,
        save: bool,
        clock: Arc<dyn Clock>,
    ) -> Result<ChainRun, RenderError> {
        run_chains(&MltRender::new(self, scene, job), job, progress, session, save, clock)
    }
}

impl Plugin for Mlt {
    type Engine = ChainEngine;
    type Settings = MltSettings;

    fn plugin_name(&self) -> &'static str {
        self.variant.name()
    }

    fn settings(&self) -> &MltSettings {
        &self.settings
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
        let render = MltRender::new(self, scene, job);
        let run = run_chains(&render, job, progress, &Session::default(), false, Arc::new(WallClock::new()))?;
        Ok(MltRun { output: run.output, film: run.film })
    }

    /// The bootstrap (see the module docs): up to `bootstrap` uniform samples per depth, in
    /// batches over the pool (deterministic: each sample has its own stream). Returns its outcome,
    /// its counters and, unless no sample found light, per depth the distribution of its targets
    /// the chains start from. `bootstrap::run_bootstrap`: under a time budget of `time_budget`
    /// seconds it takes at most a quarter of the budget (large steps keep refining b during the
    /// render, so a shorter bootstrap costs accuracy of the start only, not correctness); the
    /// runner gives a shard none, since its bootstrap must be the same in every shard.
    fn bootstrap(
        &self,
        driver: &Driver,
        ctx: &BdptContext,
        seed: u64,
        progress: &dyn Progress,
        time_budget: Option<f64>,
    ) -> Result<(BootstrapPart, Counters, Option<StartDistributions>), RenderError> {
        let depths = self.depth_count();
        // MMLT and RJMLT push B_d and then Q_d per depth (`bootstrap_sample`).
        let slots = if depths > 1 { 2 * depths } else { 1 };
        let boot = run_shared_bootstrap(
            driver,
            progress,
            slots,
            self.settings.bootstrap,
            time_budget,
            |_| self.new_slot(0, 0),
            |i, slot, counters, out| self.bootstrap_sample(ctx, seed, i, slot, counters, out),
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
                |r, i, slot, counters| self.direct_sample(ctx, seed, r, i, slot, counters),
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
        ctx: &BdptContext,
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

/// One PSSMLT, MMLT or RJMLT render of a scene (`ChainRender`).
struct MltRender<'a> {
    mlt: &'a Mlt,
    scene: &'a Scene,
    ctx: BdptContext<'a>,
    seed: u64,
    /// The bootstrap's per-depth estimates, once known (`ChainRender::begin`): the depth choice
    /// and the normalisation read them.
    bootstrap: OnceLock<Bootstrap>,
}

impl<'a> MltRender<'a> {
    fn new(mlt: &'a Mlt, scene: &'a Scene, job: &RenderJob) -> MltRender<'a> {
        let rr = if mlt.settings.rr_depth == u32::MAX { usize::MAX } else { mlt.settings.rr_depth as usize };
        let ctx = BdptContext::new(scene, rr, mlt.settings.mis);
        MltRender { mlt, scene, ctx, seed: job.seed, bootstrap: OnceLock::new() }
    }

    fn size(&self) -> (usize, usize) {
        (self.scene.camera.width as usize, self.scene.camera.height as usize)
    }

    fn estimates(&self) -> &Bootstrap {
        self.bootstrap.get_or_init(|| Bootstrap { estimates: Vec::new(), found: Vec::new() })
    }
}

impl ChainRender for MltRender<'_> {
    type Integrator = Mlt;
    type Slot = SlotState;
    type Start = StartDistributions;

    fn integrator(&self) -> &Mlt {
        self.mlt
    }

    fn image_size(&self) -> (u32, u32) {
        (self.scene.camera.width, self.scene.camera.height)
    }

    /// The depths' images stacked (module docs, "Films and threads"); the driver refuses a film
    /// beyond 2^32 pixels, and a stack beyond 2^32 rows is reported as that.
    fn film_size(&self) -> Result<(u32, u32), RenderError> {
        let (width, height) = self.image_size();
        let stacked = u32::try_from(height as u64 * self.mlt.depth_count() as u64)
            .map_err(|_| RenderError::FilmTooLarge { width, height: u32::MAX })?;
        Ok((width, stacked))
    }

    fn chains(&self) -> u64 {
        self.mlt.settings.chains
    }

    /// One pass is about one mutation per pixel over all chains.
    fn segment(&self) -> u64 {
        let (w, h) = self.size();
        ((w * h) as u64).div_ceil(self.chains()).max(1)
    }

    fn new_slot(&self) -> SlotState {
        let (w, h) = self.size();
        self.mlt.new_slot(w, h)
    }

    fn bootstrap(
        &self,
        driver: &Driver,
        progress: &dyn Progress,
        time_budget: Option<f64>,
    ) -> Result<(BootstrapPart, Counters, Option<StartDistributions>), RenderError> {
        self.mlt.bootstrap(driver, &self.ctx, self.seed, progress, time_budget)
    }

    fn begin(&self, boot: &BootstrapPart) {
        let _ = self.bootstrap.set(boot.estimates());
    }

    fn start_chains(
        &self,
        _driver: &Driver,
        dists: &StartDistributions,
        chains: &[u64],
        _progress: &dyn Progress,
        counters: &mut Counters,
    ) -> Result<Vec<ChainUnit>, RenderError> {
        let mut init_slot = self.mlt.new_slot(0, 0);
        Ok(chains
            .iter()
            .map(|&c| self.mlt.start_chain(c, dists, &self.ctx, self.seed, &mut init_slot, counters))
            .collect())
    }

    fn check_restored(&self, unit: &ChainUnit) -> Result<(), StateError> {
        let (w, h) = self.image_size();
        unit.check_restored(self.scene, (self.mlt.depth_count(), self.mlt.settings.max_depth as usize + 2), w, h)
    }

    fn empty_stats(&self) -> MltTally {
        MltTally { stats: self.mlt.new_slot(0, 0).stats, count_films: None }
    }

    fn stats(&self, slots: &[&SlotState], units: &[ChainUnit]) -> MltTally {
        let mut stats = slots.first().map(|s| s.stats.clone()).unwrap_or_default();
        let mut count_films = slots.first().and_then(|s| s.count_films.clone());
        for slot in slots.iter().skip(1) {
            stats.merge(&slot.stats);
            if let (Some(m), Some(o)) = (count_films.as_mut(), slot.count_films.as_ref()) {
                for (a, b) in m.iter_mut().flatten().zip(o.iter().flatten()) {
                    a.merge(b);
                }
            }
        }
        // The slot-order f64 sums depend on the threads; a state's bytes must not (shards).
        for (depth, (sum, _)) in stats.per_depth.iter_mut().zip(self.mlt.large_step_totals(units)) {
            depth.large_step_target_sum = sum;
        }
        MltTally { stats, count_films }
    }

    fn restore_slot(&self, stats: &MltTally) -> SlotState {
        let mut slot = self.new_slot();
        slot.stats = stats.stats.clone();
        slot.count_films = stats.count_films.clone();
        slot
    }

    fn run_segment(
        &self,
        _pass: u64,
        unit: &mut ChainUnit,
        slot: &mut Slot<SlotState>,
        progress: &dyn Progress,
    ) -> u64 {
        let Slot { index, state, film, counters } = slot;
        let segment = self.segment();
        let depths = self.mlt.depth_count();
        // The unit's own large steps so far: the choice depends on the chain alone.
        let depth_choice = (depths > 1).then(|| self.mlt.depth_choice(self.estimates(), &unit.large_steps));
        for _ in 0..segment {
            let d = depth_choice.as_ref().map_or(0, |c| c.sample_discrete(unit.rng.uniform()).0);
            let Some(chain) = unit.subchains[d].as_mut() else { continue };
            if let Some(target) = self.mlt.iterate(&self.ctx, d, chain, &mut unit.rng, state, film, counters) {
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
    }

    fn preview(&self, film: &Accumulator, units: &[ChainUnit], slots: &[&SlotState]) -> Image {
        let large_steps = self.mlt.large_step_totals(units);
        let iterations = self.mlt.iteration_counts(slots.iter().copied());
        self.mlt.normalised_image(film, &large_steps, &iterations, self.estimates()).0
    }
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
