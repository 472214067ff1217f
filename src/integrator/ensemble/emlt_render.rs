//! `integrator = "emlt"`: Algorithm 1 of the paper on the path-space chain, run by the chain
//! runner (`integrator::driver::run_chains`) as pmlt is.
//!
//! - **Bootstrap and ensembles** (Sec. 3.4): pmlt's BDPT bootstrap estimates b; the 2|X| chains
//!   of a pair (X = its chains 0 … |X| − 1, Y the rest) are started by resampling it, exactly as
//!   pmlt starts its chains (`path_space::chain`), each chain with its own stream from (seed, chain
//!   index). A render has K = `pairs` independent pairs (1 by default): pair k's chains are chains
//!   2|X|·k … 2|X|·(k + 1) − 1 of the render, so each pair has its own streams.
//! - **Iterations** (Algorithm 1): a pass of the runner is a half-iteration of every pair: every
//!   chain of X takes `it` = max(1, ⌊W·H/(|X| + |Y|)⌋) steps of pmlt's Metropolis–Hastings
//!   `step` (the paper's ⌊W·H/(|X|+|Y|)⌋ is 0 for images smaller than the ensembles) with the
//!   strategies bidirectional, linear lens, linear caustic, linear multi-chain, anisotropic path and
//!   environment (`EmltSettings::perturbations` switches them), the guided ones reading Y (its
//!   paths and its tree, built before the pass, `tree`); after the pass X and Y swap (pass p's X
//!   is the first half of each pair's chains when p is even). X's chains run in parallel on the
//!   driver as its units, Y fixed: the complementary split that keeps the parallel update valid
//!   (`toy` module docs). Splats are pmlt's expected values, pair k's into its own layer k of the
//!   film.
//! - **Normalisation**: as pmlt, b·P/N (`driver::chain_scale`), N the iterations of all chains of
//!   all pairs, applied to the pairs' layers added in pair order: the pairs' mean.
//! - **Sessions**: a pass boundary is a swap, where every chain is a path-space chain's state
//!   (stream and path), so checkpoints, resume and shards are the runner's. A shard `k/N` renders
//!   the pairs k, k + N, …; its film holds only their layers, so the shards' films add up (with
//!   zeros elsewhere, which adds nothing) to the K-pair render's film bit for bit.
//!
//! Determinism: a chain's proposals read only its own stream, its path and its pair's Y (fixed
//! during the half-iteration); the driver applies the chains' splats in chain order. So the image
//! depends on the seed and the settings only, not on the thread count.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, RwLock};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::anisotropic_path::{AnisotropicPath, GuideContext};
use super::emlt_settings::EmltSettings;
use super::environment_perturbation::EnvironmentPerturbation;
use super::guide::{GuideCounts, GuideReport, GuideView};
use super::linear::{GuidedKernel, LinearCaustic, LinearLens, LinearMultiChain};
use crate::film::{Accumulator, Image};
use crate::integrator::bdpt::BdptContext;
use crate::integrator::driver::{
    chain_scale, layers_to_image, run_chains, ChainEngine, ChainIntegrator, ChainRender, ChainRun, ChainStats, Clock,
    Driver, PassEdge, Passes, Slot, Tally,
};
use crate::integrator::path_space::bidirectional::{Bidirectional, LengthKernel};
use crate::integrator::path_space::caustic::CausticKernel;
use crate::integrator::path_space::chain::{new_stats, step, ChainUnit, SlotState};
use crate::integrator::path_space::multichain::MultiChainKernel;
use crate::integrator::path_space::pmlt_render::{
    iterations, merged_stats, path_output, report_acceptance, BootstrapPart, PmltStats,
};
use crate::integrator::path_space::reciprocal_kernel::RasterKernel;
use crate::integrator::path_space::{Entry, PathContext, Pmlt, PmltSettings, StrategySet};
use crate::integrator::{Plugin, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::Distribution1D;
use crate::scene::Scene;
use crate::state::{Session, Shard, StateError};
use crate::stats::Counters;

/// The guided strategies with counts: linear lens, linear caustic, linear multi-chain, anisotropic
/// path (whose counts are per fit: Gaussian fits as guided, degenerate ones as fallbacks) and
/// environment.
const GUIDED_STRATEGIES: usize = 5;

/// Ensemble MLT (module docs).
#[derive(Clone, Debug, Default)]
pub struct Emlt {
    pub settings: EmltSettings,
    /// The linear lens perturbation (a value, so that tests can render with a deliberately wrong
    /// one).
    pub linear_lens: LinearLens,
    /// The anisotropic path perturbation (a value for the same reason).
    pub anisotropic_path: AnisotropicPath,
    /// The linear caustic perturbation (a value for the same reason).
    pub linear_caustic: LinearCaustic,
    /// The bidirectional mutation (a value for the same reason).
    pub bidirectional: Bidirectional,
}

/// The ensemble part of the JSON statistics.
#[derive(Debug, Default, Serialize)]
pub struct EnsembleReport {
    pub ensemble_size: u64,
    /// K, the independent X/Y pairs.
    pub pairs: u64,
    pub iterations_per_swap: u64,
    pub swaps: u64,
    pub tree_rebuild_seconds: f64,
    /// Signatures (buckets) in the last tree built (the largest over the pairs).
    pub signatures: u64,
    pub guided: Vec<GuideReport>,
    /// Guided proposals over all proposals of the guided strategies (guided + fallback).
    pub guided_share: f64,
}

impl Emlt {
    pub fn from_params(params: &toml::Table) -> Result<Emlt, RenderError> {
        Ok(Emlt { settings: EmltSettings::from_params(params)?, ..Emlt::default() })
    }

    /// The pmlt whose bootstrap and chain start this render shares.
    fn pmlt(&self) -> Pmlt {
        let s = &self.settings;
        let settings = PmltSettings {
            max_depth: s.max_depth,
            bootstrap: s.bootstrap,
            chains: 2 * s.ensemble_size * s.pairs,
            mis: s.mis,
            bidirectional: s.bidirectional,
            ..PmltSettings::default()
        };
        Pmlt {
            settings,
            bidirectional: Bidirectional::default(),
            lens: Default::default(),
            caustic: Default::default(),
            portal: Default::default(),
        }
    }

    /// The strategies of a half-iteration, the guided ones reading `view`.
    fn strategies(
        &self,
        scene: &Scene,
        view: &Arc<GuideView>,
        counts: &[Arc<GuideCounts>; GUIDED_STRATEGIES],
    ) -> StrategySet {
        let camera = &scene.camera;
        let raster = RasterKernel::veach(camera.width, camera.height);
        let s = &self.settings;
        // The ablation switch (`EmltSettings::perturbations`) zeroes the weights it turns off.
        let weights = s.guided_weights();
        StrategySet {
            entries: vec![
                Box::new(Entry { strategy: self.bidirectional, kernel: LengthKernel, weight: s.bidirectional }),
                Box::new(Entry {
                    strategy: self.linear_lens,
                    kernel: GuidedKernel { view: view.clone(), plain: raster, counts: counts[0].clone() },
                    weight: weights[0],
                }),
                Box::new(Entry {
                    strategy: self.linear_caustic,
                    kernel: GuidedKernel {
                        view: view.clone(),
                        plain: CausticKernel::from_lens(&raster, camera),
                        counts: counts[1].clone(),
                    },
                    weight: weights[1],
                }),
                Box::new(Entry {
                    strategy: LinearMultiChain { lens: self.linear_lens },
                    kernel: GuidedKernel {
                        view: view.clone(),
                        plain: MultiChainKernel::new(raster),
                        counts: counts[2].clone(),
                    },
                    weight: weights[2],
                }),
                Box::new(Entry {
                    strategy: self.anisotropic_path,
                    kernel: GuideContext { view: view.clone(), counts: counts[3].clone() },
                    weight: weights[3],
                }),
                Box::new(Entry {
                    strategy: EnvironmentPerturbation { kernel: s.environment_kernel },
                    kernel: GuideContext { view: view.clone(), counts: counts[4].clone() },
                    weight: weights[4],
                }),
            ],
        }
    }
}

/// emlt's statistics in a state: pmlt's, the guided strategies' counts (in `GUIDED_NAMES`
/// order) and the trees'.
#[derive(Clone, Serialize, Deserialize)]
pub struct EmltStats {
    path: PmltStats,
    guided: Vec<GuideReport>,
    tree_rebuild_seconds: f64,
    /// Signatures in the last trees built (the largest over the pairs).
    signatures: u64,
}

impl ChainStats for EmltStats {
    fn absorb(&mut self, other: &EmltStats) {
        self.path.absorb(&other.path);
        for (a, b) in self.guided.iter_mut().zip(&other.guided) {
            a.absorb(b);
        }
        self.tree_rebuild_seconds += other.tree_rebuild_seconds;
        self.signatures = self.signatures.max(other.signatures);
    }

    fn clear_times(&mut self) {
        self.tree_rebuild_seconds = 0.0;
        for g in &mut self.guided {
            g.similarity_seconds = 0.0;
        }
    }
}

/// The guided strategies' names in the statistics, in the order of their counts.
const GUIDED_NAMES: [&str; GUIDED_STRATEGIES] =
    ["linear_lens", "linear_caustic", "linear_multi_chain", "anisotropic_path", "environment"];

impl ChainIntegrator for Emlt {
    type Unit = ChainUnit;
    type Boot = BootstrapPart;
    type Stats = EmltStats;

    fn unit_index(unit: &ChainUnit) -> u64 {
        unit.index
    }

    fn chain_output(
        &self,
        film: &Accumulator,
        _units: &[ChainUnit],
        stats: EmltStats,
        boot: &BootstrapPart,
        tally: Tally,
    ) -> Result<RenderOutput, RenderError> {
        let pairs = self.settings.pairs as usize;
        if !film.height.is_multiple_of(pairs) {
            return Err(
                StateError::Mismatch("the state's film does not hold one layer per ensemble pair".into()).into()
            );
        }
        let pixels = film.width as u64 * (film.height / pairs) as u64;
        let image = |n| layers_to_image(film, pairs, chain_scale(boot.b(), pixels, n));
        let (passes, segment) = (tally.passes, tally.segment);
        let e = self.settings.ensemble_size;
        let mut output = path_output(image, pixels, stats.path, boot, 2 * e * self.settings.pairs, tally);
        let (g, f) = stats.guided.iter().fold((0, 0), |(g, f), r| (g + r.guided, f + r.fallback));
        let report = EnsembleReport {
            ensemble_size: e,
            pairs: self.settings.pairs,
            iterations_per_swap: segment,
            swaps: passes,
            tree_rebuild_seconds: stats.tree_rebuild_seconds,
            signatures: stats.signatures,
            guided: stats.guided,
            guided_share: if g + f > 0 { g as f64 / (g + f) as f64 } else { 0.0 },
        };
        if let Some(map) = output.extra_stats.as_object_mut() {
            map.insert("ensemble".into(), serde_json::to_value(&report).unwrap_or(serde_json::Value::Null));
        }
        Ok(output)
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
        if let Some(shard) = session.shard.filter(|s| s.index >= self.settings.pairs) {
            return Err(StateError::Mismatch(format!(
                "emlt shard {shard} would hold none of the render's {} ensemble pairs: emlt is sharded by pairs, \
                 so shard it at most `pairs` ways (--set pairs=N)",
                self.settings.pairs
            ))
            .into());
        }
        run_chains(&EmltRender::new(self, scene, job, session.shard), job, progress, session, save, clock)
    }
}

impl Plugin for Emlt {
    type Engine = ChainEngine;
    type Settings = EmltSettings;

    fn plugin_name(&self) -> &'static str {
        "emlt"
    }

    fn settings(&self) -> &EmltSettings {
        &self.settings
    }
}

/// One emlt render of a scene (`ChainRender`; module docs).
struct EmltRender<'a> {
    emlt: &'a Emlt,
    /// The pmlt whose bootstrap, chain start and slots this render shares.
    pmlt: Pmlt,
    scene: &'a Scene,
    ctx: PathContext<'a>,
    bctx: BdptContext<'a>,
    /// A set over an empty view: the names and order of the statistics.
    names: StrategySet,
    counts: [Arc<GuideCounts>; GUIDED_STRATEGIES],
    seed: u64,
    shard: Option<Shard>,
    /// |X| = |Y|.
    e: u64,
    /// Steps per chain of X and half-iteration.
    it: u64,
    /// During a pass: per pair of the render here (in pair order), Y's view and the strategies
    /// reading it (`between_passes` builds them before the pass and takes them apart after).
    guides: RwLock<Vec<(Arc<GuideView>, StrategySet)>>,
    /// Seconds in tree builds, and the largest signature count of the last trees.
    trees: Mutex<(f64, u64)>,
    /// Chains that found no start path: counted at their start, or restored from a state.
    unstarted: AtomicU64,
    /// The bootstrap's b, once known, for previews.
    boot_b: OnceLock<f64>,
}

impl<'a> EmltRender<'a> {
    fn new(emlt: &'a Emlt, scene: &'a Scene, job: &RenderJob, shard: Option<Shard>) -> EmltRender<'a> {
        let pmlt = emlt.pmlt();
        let (width, height) = (scene.camera.width, scene.camera.height);
        let counts: [Arc<GuideCounts>; GUIDED_STRATEGIES] = Default::default();
        let empty = Arc::new(GuideView::new(Vec::new(), &emlt.settings, width, height));
        let names = emlt.strategies(scene, &empty, &counts);
        let e = emlt.settings.ensemble_size;
        EmltRender {
            emlt,
            ctx: PathContext { scene, max_depth: emlt.settings.max_depth as usize },
            bctx: pmlt.bdpt_context(scene),
            pmlt,
            scene,
            names,
            counts,
            seed: job.seed,
            shard,
            e,
            it: (width as u64 * height as u64 / (2 * e)).max(1),
            guides: RwLock::new(Vec::new()),
            trees: Mutex::new((0.0, 0)),
            unstarted: AtomicU64::new(0),
            boot_b: OnceLock::new(),
        }
    }

    fn pairs(&self) -> u64 {
        self.emlt.settings.pairs
    }

    /// Where Y starts in a pair's chains at pass `pass`: X is the first half at even passes.
    fn y_offset(&self, pass: u64) -> usize {
        if pass.is_multiple_of(2) {
            self.e as usize
        } else {
            0
        }
    }
}

impl ChainRender for EmltRender<'_> {
    type Integrator = Emlt;
    type Slot = SlotState;
    type Start = Distribution1D;

    fn integrator(&self) -> &Emlt {
        self.emlt
    }

    fn image_size(&self) -> (u32, u32) {
        (self.scene.camera.width, self.scene.camera.height)
    }

    /// One layer per pair.
    fn film_size(&self) -> Result<(u32, u32), RenderError> {
        let (width, height) = self.image_size();
        let stacked = u32::try_from(height as u64 * self.pairs())
            .map_err(|_| RenderError::FilmTooLarge { width, height: u32::MAX })?;
        Ok((width, stacked))
    }

    fn chains(&self) -> u64 {
        2 * self.e * self.pairs()
    }

    fn segment(&self) -> u64 {
        self.it
    }

    /// Only X's chains move in a pass: half of every pair's.
    fn mutations_per_pass(&self) -> u64 {
        self.it * self.e * self.pairs()
    }

    fn mutations_per_pass_of(&self, units: usize) -> u64 {
        self.it * (units as u64 / 2)
    }

    /// A shard holds whole pairs.
    fn in_shard(&self, chain: u64, shard: Shard) -> bool {
        shard.contains(chain / (2 * self.e))
    }

    fn new_slot(&self) -> SlotState {
        self.pmlt.new_slot(&self.names)
    }

    fn bootstrap(
        &self,
        driver: &Driver,
        progress: &dyn Progress,
        time_budget: Option<f64>,
    ) -> Result<(BootstrapPart, Counters, Option<Distribution1D>), RenderError> {
        Ok(self.pmlt.run_path_bootstrap(driver, progress, &self.bctx, self.seed, &self.names, time_budget))
    }

    fn begin(&self, boot: &BootstrapPart) {
        let _ = self.boot_b.set(boot.b());
    }

    /// Every chain of the pairs here, started in parallel (one driver pass whose units are the
    /// chains; a chain's start depends on the seed and its index only).
    fn start_chains(
        &self,
        driver: &Driver,
        start: &Distribution1D,
        chains: &[u64],
        progress: &dyn Progress,
        counters: &mut Counters,
    ) -> Result<Vec<ChainUnit>, RenderError> {
        let init: Vec<(u64, Option<ChainUnit>)> = chains.iter().map(|&c| (c, None)).collect();
        let started = driver.run(
            init,
            Passes::Count(1),
            progress,
            |_| self.new_slot(),
            |_, (c, unit), slot| {
                let mut candidates = Vec::new();
                let Slot { state, counters, .. } = slot;
                let (ctx, bctx) = (&self.ctx, &self.bctx);
                *unit = Some(self.pmlt.start_chain(*c, start, ctx, bctx, self.seed, state, counters, &mut candidates));
                0
            },
            None,
        );
        counters.merge(&started.counters);
        let units: Vec<ChainUnit> = started.units.into_iter().filter_map(|(_, u)| u).collect();
        let unstarted = units.iter().filter(|u| !(u.current.f_star > 0.0)).count() as u64;
        self.unstarted.store(unstarted, Ordering::Relaxed);
        Ok(units)
    }

    fn check_restored(&self, unit: &ChainUnit) -> Result<(), StateError> {
        unit.check_restored(&self.ctx, self.chains())
    }

    fn empty_stats(&self) -> EmltStats {
        EmltStats {
            path: PmltStats { unstarted: 0, stats: new_stats(self.ctx.max_depth, &self.names) },
            guided: GUIDED_NAMES
                .iter()
                .map(|name| GuideReport { name: name.to_string(), ..GuideReport::default() })
                .collect(),
            tree_rebuild_seconds: 0.0,
            signatures: 0,
        }
    }

    fn stats(&self, slots: &[&SlotState], _units: &[ChainUnit]) -> EmltStats {
        let (tree_rebuild_seconds, signatures) = *self.trees.lock().unwrap_or_else(|e| e.into_inner());
        EmltStats {
            path: PmltStats { unstarted: self.unstarted.load(Ordering::Relaxed), stats: merged_stats(slots) },
            guided: self.counts.iter().zip(GUIDED_NAMES).map(|(c, name)| c.report(name)).collect(),
            tree_rebuild_seconds,
            signatures,
        }
    }

    fn restore_slot(&self, stats: &EmltStats) -> SlotState {
        self.unstarted.store(stats.path.unstarted, Ordering::Relaxed);
        for (counts, saved) in self.counts.iter().zip(&stats.guided) {
            counts.add(saved);
        }
        *self.trees.lock().unwrap_or_else(|e| e.into_inner()) = (stats.tree_rebuild_seconds, stats.signatures);
        let mut slot = self.new_slot();
        slot.stats = stats.path.stats.clone();
        slot
    }

    /// `it` steps of a chain of X, with its pair's strategies; a chain of Y waits.
    fn run_segment(&self, pass: u64, unit: &mut ChainUnit, slot: &mut Slot<SlotState>, progress: &dyn Progress) -> u64 {
        let pair = unit.index / (2 * self.e);
        let in_x = (unit.index % (2 * self.e) < self.e) == pass.is_multiple_of(2);
        if !in_x {
            return 0;
        }
        let guides = self.guides.read().unwrap_or_else(|e| e.into_inner());
        // The pair's place among the pairs here: a shard k/N holds pairs k, k + N, ...
        let here = self.shard.map_or(pair, |s| pair / s.count) as usize;
        let Some((_, set)) = guides.get(here) else { return 0 };
        let Slot { index, state, film, counters } = slot;
        for _ in 0..self.it {
            step(&self.ctx, set, &mut unit.current, &mut unit.rng, &mut state.stats, film, pair as usize, counters);
        }
        if *index == 0 {
            report_acceptance(&state.stats, progress);
        }
        self.it
    }

    /// Before a pass, every pair's tree over its Y (Algorithm 1, line 12: Y's paths move into the
    /// view the guided strategies read); after it, Y's paths back into their chains.
    fn between_passes(&self, edge: PassEdge, pass: u64, units: &mut [ChainUnit]) {
        let e = self.e as usize;
        let y = self.y_offset(pass)..self.y_offset(pass) + e;
        let (width, height) = self.image_size();
        let mut guides = self.guides.write().unwrap_or_else(|e| e.into_inner());
        match edge {
            PassEdge::Before => {
                let started = Instant::now();
                let mut signatures = 0;
                for pair in units.chunks_mut(2 * e) {
                    let paths = pair[y.clone()].iter_mut().map(|u| std::mem::take(&mut u.current)).collect();
                    let view = Arc::new(GuideView::new(paths, &self.emlt.settings, width, height));
                    signatures = signatures.max(view.tree.signatures() as u64);
                    let set = self.emlt.strategies(self.scene, &view, &self.counts);
                    guides.push((view, set));
                }
                let mut trees = self.trees.lock().unwrap_or_else(|e| e.into_inner());
                *trees = (trees.0 + started.elapsed().as_secs_f64(), signatures);
            }
            PassEdge::After => {
                for ((view, set), pair) in std::mem::take(&mut *guides).into_iter().zip(units.chunks_mut(2 * e)) {
                    // The set's kernels hold the view: dropped, it is the view's only owner.
                    drop(set);
                    let paths = Arc::try_unwrap(view).map(|v| v.paths).unwrap_or_else(|v| v.paths.clone());
                    for (unit, path) in pair[y.clone()].iter_mut().zip(paths) {
                        unit.current = path;
                    }
                }
            }
        }
    }

    fn preview(&self, film: &Accumulator, _units: &[ChainUnit], slots: &[&SlotState]) -> Image {
        let n: u64 = slots.iter().map(|s| iterations(&s.stats)).sum();
        let (w, h) = self.image_size();
        let b = self.boot_b.get().copied().unwrap_or(0.0);
        layers_to_image(film, self.pairs() as usize, chain_scale(b, w as u64 * h as u64, n))
    }
}
