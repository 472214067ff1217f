//! pmlt on the chain runner (`integrator::driver::run_chains`): what is pmlt's own in a render —
//! its bootstrap (one BDPT sample per path, b = the mean of their targets), its chains' start
//! (resampled bootstrap paths) and Metropolis–Hastings steps (`chain::step`), its statistics and
//! its output (the film times b·P/N, `driver::chain_scale`). What a state keeps of it is a
//! `ChainPart` of [`BootstrapPart`] (b's sum, shared by every chain and the normalisation),
//! [`PmltStats`] (the slots' statistics merged, whose iteration counts the normalisation divides
//! by) and the chains (random stream and current path with its f and f*, written through
//! `UnitState`). Ensemble MLT shares the bootstrap, the start and the output (`ensemble::emlt_render`).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use super::chain::{new_stats, step, ChainUnit, Pmlt, PmltRun, SlotState};
use super::{PathContext, PmltSettings, StrategySet};
use crate::film::{Accumulator, Image};
use crate::integrator::bdpt::BdptContext;
use crate::integrator::driver::bootstrap::run_bootstrap;
use crate::integrator::driver::{
    chain_scale, run_chains, ChainBootstrap, ChainEngine, ChainIntegrator, ChainRender, ChainRun, ChainStats, Clock,
    Driver, Slot, Tally, WallClock,
};
use crate::integrator::pss::mlt_stats::MltStats;
use crate::integrator::{Plugin, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::Distribution1D;
use crate::scene::Scene;
use crate::state::{Session, StateError};
use crate::stats::{AcceptanceCount, Counters};

/// The bootstrap's outcome: the sum of the targets of `paths` BDPT samples (b = sum / paths).
/// Identical in every shard of a sample-budget render (its streams depend on the seed only), which
/// the merge checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BootstrapPart {
    sum: f64,
    paths: u64,
    /// Wall time (0 in shards, whose bytes depend on their units only).
    seconds: f64,
}

impl BootstrapPart {
    pub(crate) fn b(&self) -> f64 {
        self.sum / self.paths.max(1) as f64
    }
}

impl ChainBootstrap for BootstrapPart {
    fn same_as(&self, other: &BootstrapPart) -> bool {
        (self.sum, self.paths) == (other.sum, other.paths)
    }
    fn seconds_mut(&mut self) -> &mut f64 {
        &mut self.seconds
    }
}

/// pmlt's statistics in a state.
#[derive(Clone, Serialize, Deserialize)]
pub struct PmltStats {
    /// Chains of the state that found no start path (for the warning; summed by the merge).
    pub(crate) unstarted: u64,
    /// The slots' statistics merged (per depth and per strategy; the iterations are the
    /// normalisation's divisor).
    pub(crate) stats: MltStats,
}

impl ChainStats for PmltStats {
    fn absorb(&mut self, other: &PmltStats) {
        // Per depth and per strategy: counts add (`MltStats::merge`).
        self.stats.merge(&other.stats);
        self.unstarted += other.unstarted;
    }
}

impl ChainIntegrator for Pmlt {
    type Unit = ChainUnit;
    type Boot = BootstrapPart;
    type Stats = PmltStats;

    fn unit_index(unit: &ChainUnit) -> u64 {
        unit.index
    }

    fn chain_output(
        &self,
        film: &Accumulator,
        _units: &[ChainUnit],
        stats: PmltStats,
        boot: &BootstrapPart,
        tally: Tally,
    ) -> Result<RenderOutput, RenderError> {
        let pixels = film.width as u64 * film.height as u64;
        let image = |n| film.to_image(chain_scale(boot.b(), pixels, n));
        Ok(path_output(image, pixels, stats, boot, self.settings.chains, tally))
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
        run_chains(&PmltRender::new(self, scene, job), job, progress, session, save, clock)
    }
}

impl Plugin for Pmlt {
    type Engine = ChainEngine;
    type Settings = PmltSettings;

    fn plugin_name(&self) -> &'static str {
        "pmlt"
    }

    fn settings(&self) -> &PmltSettings {
        &self.settings
    }
}

impl Pmlt {
    /// The render with its unnormalised film (for tests that check the film's bits).
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<PmltRun, RenderError> {
        let render = PmltRender::new(self, scene, job);
        let run = run_chains(&render, job, progress, &Session::default(), false, Arc::new(WallClock::new()))?;
        Ok(PmltRun { output: run.output, film: run.film })
    }

    /// The bootstrap (module docs): up to `bootstrap` BDPT samples over the pool, at most
    /// `time_budget` seconds of them; its outcome, counters and, unless it found no light, the
    /// distribution of its targets the chains start from. `set` names the slots' statistics.
    pub(crate) fn run_path_bootstrap(
        &self,
        driver: &Driver,
        progress: &dyn Progress,
        bctx: &BdptContext,
        seed: u64,
        set: &StrategySet,
        time_budget: Option<f64>,
    ) -> (BootstrapPart, Counters, Option<Distribution1D>) {
        let run = run_bootstrap(
            driver,
            progress,
            1,
            self.settings.bootstrap,
            time_budget,
            |_| self.new_slot(set),
            |_, i, slot, counters| self.bootstrap_sample(bctx, seed, i, slot, counters, None),
        );
        let boot = BootstrapPart { sum: run.sums[0], paths: run.paths, seconds: run.elapsed.as_secs_f64() };
        let start = (boot.b() > 0.0).then(|| Distribution1D::new(&run.targets[0]));
        (boot, run.counters, start)
    }
}

/// One pmlt render of a scene (`ChainRender`).
struct PmltRender<'a> {
    pmlt: &'a Pmlt,
    ctx: PathContext<'a>,
    bctx: BdptContext<'a>,
    set: StrategySet,
    seed: u64,
    /// Chains that found no start path: counted at their start, or restored from a state.
    unstarted: AtomicU64,
    /// The bootstrap's b, once known (`ChainRender::begin`), for previews.
    boot_b: OnceLock<f64>,
}

impl<'a> PmltRender<'a> {
    fn new(pmlt: &'a Pmlt, scene: &'a Scene, job: &RenderJob) -> PmltRender<'a> {
        PmltRender {
            pmlt,
            ctx: PathContext { scene, max_depth: pmlt.settings.max_depth as usize },
            bctx: pmlt.bdpt_context(scene),
            set: pmlt.strategies(scene),
            seed: job.seed,
            unstarted: AtomicU64::new(0),
            boot_b: OnceLock::new(),
        }
    }
}

impl ChainRender for PmltRender<'_> {
    type Integrator = Pmlt;
    type Slot = SlotState;
    type Start = Distribution1D;

    fn integrator(&self) -> &Pmlt {
        self.pmlt
    }

    fn image_size(&self) -> (u32, u32) {
        (self.ctx.scene.camera.width, self.ctx.scene.camera.height)
    }

    fn film_size(&self) -> Result<(u32, u32), RenderError> {
        Ok(self.image_size())
    }

    fn chains(&self) -> u64 {
        self.pmlt.settings.chains
    }

    /// One pass is about one mutation per pixel over all chains.
    fn segment(&self) -> u64 {
        let (w, h) = self.image_size();
        (w as u64 * h as u64).div_ceil(self.chains()).max(1)
    }

    fn new_slot(&self) -> SlotState {
        self.pmlt.new_slot(&self.set)
    }

    fn bootstrap(
        &self,
        driver: &Driver,
        progress: &dyn Progress,
        time_budget: Option<f64>,
    ) -> Result<(BootstrapPart, Counters, Option<Distribution1D>), RenderError> {
        Ok(self.pmlt.run_path_bootstrap(driver, progress, &self.bctx, self.seed, &self.set, time_budget))
    }

    fn begin(&self, boot: &BootstrapPart) {
        let _ = self.boot_b.set(boot.b());
    }

    /// The chains from resampled bootstrap paths (`chain` docs), one after another.
    fn start_chains(
        &self,
        _driver: &Driver,
        start: &Distribution1D,
        chains: &[u64],
        _progress: &dyn Progress,
        counters: &mut Counters,
    ) -> Result<Vec<ChainUnit>, RenderError> {
        let mut init_slot = self.new_slot();
        let mut candidates = Vec::new();
        let units: Vec<ChainUnit> = chains
            .iter()
            .map(|&c| {
                let (ctx, bctx, slot) = (&self.ctx, &self.bctx, &mut init_slot);
                self.pmlt.start_chain(c, start, ctx, bctx, self.seed, slot, counters, &mut candidates)
            })
            .collect();
        let unstarted = units.iter().filter(|u| !(u.current.f_star > 0.0)).count() as u64;
        self.unstarted.store(unstarted, Ordering::Relaxed);
        Ok(units)
    }

    fn check_restored(&self, unit: &ChainUnit) -> Result<(), StateError> {
        unit.check_restored(&self.ctx, self.chains())
    }

    fn empty_stats(&self) -> PmltStats {
        PmltStats { unstarted: 0, stats: new_stats(self.ctx.max_depth, &self.set) }
    }

    fn stats(&self, slots: &[&SlotState], _units: &[ChainUnit]) -> PmltStats {
        PmltStats { unstarted: self.unstarted.load(Ordering::Relaxed), stats: merged_stats(slots) }
    }

    fn restore_slot(&self, stats: &PmltStats) -> SlotState {
        self.unstarted.store(stats.unstarted, Ordering::Relaxed);
        let mut slot = self.new_slot();
        slot.stats = stats.stats.clone();
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
        for _ in 0..segment {
            step(&self.ctx, &self.set, &mut unit.current, &mut unit.rng, &mut state.stats, film, 0, counters);
        }
        if *index == 0 {
            report_acceptance(&state.stats, progress);
        }
        segment
    }

    fn preview(&self, film: &Accumulator, _units: &[ChainUnit], slots: &[&SlotState]) -> Image {
        let n: u64 = slots.iter().map(|s| iterations(&s.stats)).sum();
        let (w, h) = self.image_size();
        let b = self.boot_b.get().copied().unwrap_or(0.0);
        film.to_image(chain_scale(b, w as u64 * h as u64, n))
    }
}

/// The slots' statistics merged in slot order.
pub(crate) fn merged_stats(slots: &[&SlotState]) -> MltStats {
    let mut merged = slots.first().map(|s| s.stats.clone()).unwrap_or_default();
    for slot in slots.iter().skip(1) {
        merged.merge(&slot.stats);
    }
    merged
}

/// Shows the acceptance of `stats` (a slot's) on the progress line.
pub(crate) fn report_acceptance(stats: &MltStats, progress: &dyn Progress) {
    let (p, a) = stats.strategies.iter().flatten().fold((0, 0), |(p, a), s| (p + s.selected, a + s.accepted));
    progress.message(&format!("acceptance {:.1}%", 100.0 * a as f64 / p.max(1) as f64));
}

/// Iterations of all chains in `stats` (every depth).
pub(crate) fn iterations(stats: &MltStats) -> u64 {
    stats.per_depth.iter().map(|d| d.iterations).sum()
}

/// The output of a path-space chain render (pmlt, emlt): `image(N)` the film normalised for N
/// iterations of all chains (an integer: any merge order gives it, so the same for a render, its
/// resumption and its merged shards), the statistics with b per depth, the warnings, and the
/// per-strategy acceptance in the counters. `chains` is the render's chain count.
pub(crate) fn path_output(
    image: impl FnOnce(u64) -> Image,
    pixels: u64,
    stats: PmltStats,
    boot: &BootstrapPart,
    chains: u64,
    tally: Tally,
) -> RenderOutput {
    let PmltStats { unstarted, mut stats } = stats;
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
            "{unstarted} of {chains} chains found no start path with a non-zero contribution in {} draws from the \
             bootstrap; they stay at a zero path (their iterations splat nothing).",
            super::chain::START_ATTEMPTS
        ));
    }
    let n = iterations(&stats);
    let image = image(n);
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
