//! `integrator = "pmlt"`: many path-space Markov chains on the render driver.
//!
//! - **Bootstrap** (`pss::bootstrap`, shared with the primary-sample-space methods): `bootstrap`
//!   BDPT samples over the whole film, each from its own stream; a sample's target is Σ_t
//!   luminance(w_t C_t) over its techniques, an unbiased estimate of b = ∫ f* dμ (f* = luminance
//!   of f, the chains' target).
//! - **Start**: chain c draws a bootstrap sample ∝ its target, replays it, and takes one of its
//!   technique paths ∝ luminance(w_t C_t): importance resampling with weight w_t f*/p_t, whose
//!   result is distributed ∝ f* up to the bootstrap's finite size (Veach 1997 Sec. 4's start-up
//!   bias removal by resampling).
//! - **Iterations** ([`step`]): choose a strategy among the suitable ones, propose, accept with
//!   min(1, f*(ȳ)P(ȳ)T(ȳ→x̄) / (f*(x̄)P(x̄)T(x̄→ȳ))) (`strategy` module docs), and splat both
//!   paths with Veach's expected values: ȳ with weight a, x̄ with 1 − a, each as f/f*.
//! - **Normalisation**: the film holds Σ (weight · f/f*) at each path's raster position; the image
//!   is that times b·P/N (P pixels, N iterations of all chains), since the chain samples x̄ ∝ f*/b
//!   and pixel j's value is P·∫ 1_j f dμ in the camera's whole-film normalisation (as PSSMLT's
//!   one-layer image, `pss/mlt.rs`).
//!
//! Units are chains: a chain's state (its random stream and current path) lives in the unit value,
//! as the driver's render model asks, and every stream derives from (seed, chain index), so the
//! image depends on the seed and the chain count only (not on the threads).

use super::bidirectional::{Bidirectional, LengthKernel};
use super::settings::PmltSettings;
use super::state::PathState;
use super::strategy::{Entry, StrategySet};
use super::PathContext;
use crate::film::{Image, SplatBuffer};
use crate::integrator::bdpt::path::full_path;
use crate::integrator::bdpt::{
    connect_all, generate_camera_subpath, generate_light_subpath, BdptContext, ConnectScratch, FilmRegion, Vertex,
};
use crate::integrator::driver::{Driver, PassBoundary, Passes, Slot};
use crate::integrator::pss::bootstrap::run_bootstrap;
use crate::integrator::pss::stats::{MltStats, StrategyStats};
use crate::integrator::{Budget, Integrator, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::{Distribution1D, Rng};
use crate::scene::Scene;
use crate::spectrum::{is_finite, luminance};
use crate::stats::{AcceptanceCount, Counters};

/// Distinguishes the bootstrap's streams (sample i: stream i) from the chains'.
const BOOTSTRAP_SEED_SALT: u64 = 0x9A7B_B007_u64;
/// Distinguishes the chains' streams (chain c: stream c).
const CHAIN_SEED_SALT: u64 = 0x9A7C_C4A1_u64;
/// Draws from the bootstrap a chain may make to find a start path whose f is non-zero (the
/// bootstrap's BDPT contribution and f(x̄) differ only by rounding, e.g. a shadow ray between two
/// vertices a few ulps apart).
const START_ATTEMPTS: usize = 64;

/// Path-space MLT.
#[derive(Clone, Debug)]
pub struct Pmlt {
    pub settings: PmltSettings,
    /// The bidirectional mutation (a value, so that tests can render with a deliberately wrong one).
    pub bidirectional: Bidirectional,
}

/// A chain: its own stream and its current path.
pub struct ChainUnit {
    pub rng: Rng,
    pub current: PathState,
}

/// Per-slot scratch (BDPT subpaths for the bootstrap) and statistics.
struct SlotState {
    camera: Vec<Vertex>,
    light: Vec<Vertex>,
    scratch: ConnectScratch,
    stats: MltStats,
}

/// A render with its unnormalised film (for tests that check the film's bits).
pub struct PmltRun {
    pub output: RenderOutput,
    pub film: crate::film::Accumulator,
}

/// Empty statistics for `max_depth`: per depth, and per strategy of `set`.
pub fn new_stats(max_depth: usize, set: &StrategySet) -> MltStats {
    let mut stats = MltStats::new(&vec![1; max_depth + 1], false, false, false);
    stats.strategies = Some(set.entries.iter().map(|e| StrategyStats::new(e.name(), max_depth + 1)).collect());
    stats
}

/// One Metropolis–Hastings iteration of a chain at `current` (module docs): splats ȳ and x̄ with
/// their expected-value weights into `film`, records the proposal in `stats` (per strategy, per
/// depth of the current path) and counts the state's depth after the step.
pub fn step(
    ctx: &PathContext,
    set: &StrategySet,
    current: &mut PathState,
    rng: &mut Rng,
    stats: &mut MltStats,
    film: &mut SplatBuffer,
    counters: &mut Counters,
) {
    counters.samples += 1;
    let depth = current.depth();
    let chosen = set.choose(ctx, current, rng.uniform_f64());
    let mut a = 0.0f64;
    let mut proposal = None;
    if let Some((i, p_forward)) = chosen {
        let entry = &set.entries[i];
        let strategy = stats.strategies.as_mut().and_then(|s| s.get_mut(i));
        let y = entry.propose(ctx, current, rng, counters);
        match &y {
            None => {
                if let Some(s) = strategy {
                    s.generation_failures += 1;
                }
            }
            Some(y) if y.path.f_star > 0.0 => {
                let p_reverse = set.probability(ctx, &y.path, i);
                let num = y.path.f_star * p_reverse * y.reverse;
                let den = current.f_star * p_forward * y.forward;
                let r = num / den;
                a = if den > 0.0 && r.is_finite() { r.min(1.0) } else { 0.0 };
                if let Some(s) = strategy {
                    s.nonzero_proposals += 1;
                }
            }
            Some(_) => {}
        }
        proposal = y.map(|y| y.path);
    }
    if let Some(y) = proposal.as_ref().filter(|_| a > 0.0) {
        splat(y, a, film);
    }
    if a < 1.0 {
        splat(current, 1.0 - a, film);
    }
    let accepted = a > 0.0 && rng.uniform_f64() < a;
    if let Some((i, _)) = chosen {
        if let Some(s) = stats.strategies.as_mut().and_then(|s| s.get_mut(i)) {
            s.selected += 1;
            s.accepted += accepted as u64;
            s.acceptance_probability_sum += a;
            if let Some(count) = s.per_depth.get_mut(depth) {
                tally(count, accepted);
            }
        }
    }
    if let Some(d) = stats.per_depth.get_mut(depth) {
        tally(&mut d.acceptance, accepted);
    }
    if accepted {
        if let Some(y) = proposal {
            *current = y;
        }
    }
    if let Some(d) = stats.per_depth.get_mut(current.depth()) {
        d.iterations += 1;
    }
}

fn tally(count: &mut AcceptanceCount, accepted: bool) {
    count.proposed += 1;
    if accepted {
        count.accepted += 1.0;
    }
}

/// Splats `path` with expected-value weight `w` as w · f/f* (a zero path splats nothing).
fn splat(path: &PathState, w: f64, film: &mut SplatBuffer) {
    if !(w > 0.0) || !(path.f_star > 0.0) {
        return;
    }
    let value = (path.f * (w / path.f_star)).as_vec3();
    if is_finite(value) {
        film.splat(path.raster, value);
    }
}

impl Pmlt {
    pub fn from_params(params: &toml::Table) -> Result<Pmlt, RenderError> {
        Ok(Pmlt { settings: PmltSettings::from_params(params)?, bidirectional: Bidirectional::default() })
    }

    /// The strategies of the chain (the bidirectional mutation alone, for now).
    pub fn strategies(&self) -> StrategySet {
        StrategySet {
            entries: vec![Box::new(Entry {
                strategy: self.bidirectional,
                kernel: LengthKernel,
                weight: self.settings.bidirectional,
            })],
        }
    }

    fn bdpt_context<'a>(&self, scene: &'a Scene) -> BdptContext<'a> {
        BdptContext::new(scene, usize::MAX, self.settings.mis)
    }

    /// Bootstrap sample `i`: a BDPT sample over the whole film from stream i; returns Σ_t
    /// luminance(w_t C_t). With `paths`, also every technique's complete path with that weight.
    fn bootstrap_sample(
        &self,
        bctx: &BdptContext,
        seed: u64,
        i: u64,
        slot: &mut SlotState,
        counters: &mut Counters,
        mut paths: Option<&mut Vec<(Vec<Vertex>, f32)>>,
    ) -> f32 {
        let max_depth = self.settings.max_depth as usize;
        let mut rng = Rng::new(seed ^ BOOTSTRAP_SEED_SALT, i);
        let raster =
            generate_camera_subpath(bctx, FilmRegion::WholeFilm, &mut rng, max_depth + 2, &mut slot.camera, counters);
        generate_light_subpath(bctx, &mut rng, max_depth + 1, &mut slot.light, counters);
        let mut total = 0.0f32;
        let (light, camera) = (&slot.light, &slot.camera);
        connect_all(bctx, light, camera, raster, max_depth, &mut rng, &mut slot.scratch, counters, |c, _| {
            let w = luminance(c.weighted());
            if w.is_finite() && w > 0.0 {
                total += w;
                if let Some(p) = paths.as_mut() {
                    p.push((full_path(light, camera, c), w));
                }
            }
        });
        if total.is_finite() {
            total
        } else {
            0.0
        }
    }

    fn new_slot(&self, set: &StrategySet) -> SlotState {
        SlotState {
            camera: Vec::new(),
            light: Vec::new(),
            scratch: ConnectScratch::default(),
            stats: new_stats(self.settings.max_depth as usize, set),
        }
    }

    /// The render with its unnormalised film.
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<PmltRun, RenderError> {
        let (width, height) = (scene.camera.width as usize, scene.camera.height as usize);
        let pixels = (width * height) as u64;
        crate::integrator::check_budget(job.budget, scene.camera.width, scene.camera.height, "budget")?;
        let driver = Driver::new(job, scene.camera.width, scene.camera.height)?;
        let render_start = std::time::Instant::now();
        let max_depth = self.settings.max_depth as usize;
        let ctx = PathContext { scene, max_depth };
        let bctx = self.bdpt_context(scene);
        let set = self.strategies();
        let time_budget = match job.budget {
            Budget::Seconds(s) => Some(s),
            Budget::SamplesPerPixel(_) => None,
        };

        let boot = run_bootstrap(
            &driver,
            progress,
            1,
            self.settings.bootstrap,
            time_budget,
            |_| self.new_slot(&set),
            |_, i, slot, counters| self.bootstrap_sample(&bctx, job.seed, i, slot, counters, None),
        );
        let b = boot.b()[0];
        let mut warnings = Vec::new();
        if !(b > 0.0) {
            warnings.push(format!(
                "no bootstrap path ({} BDPT samples) carried light to the camera: the image is black. Check that \
                 emitters are visible from the camera's surroundings, or raise `bootstrap`.",
                boot.paths
            ));
            let mut stats = new_stats(max_depth, &set);
            stats.bootstrap_paths_per_depth = boot.paths;
            stats.bootstrap_seconds = boot.elapsed.as_secs_f64();
            stats.warnings = warnings;
            stats.finish(pixels, &vec![0.0; max_depth + 1], &vec![0.0; max_depth + 1]);
            let output = RenderOutput {
                image: Image::new(width, height),
                layers: Vec::new(),
                counters: boot.counters,
                wall_time: render_start.elapsed(),
                extra_stats: serde_json::to_value(&stats).unwrap_or(serde_json::Value::Null),
            };
            return Ok(PmltRun { output, film: crate::film::Accumulator::new(width, height) });
        }

        // Start every chain from a resampled bootstrap path (module docs).
        let start = Distribution1D::new(&boot.targets[0]);
        let mut init_slot = self.new_slot(&set);
        let mut init_counters = Counters::default();
        let mut candidates = Vec::new();
        let units: Vec<ChainUnit> = (0..self.settings.chains)
            .map(|c| {
                let mut rng = Rng::new(job.seed ^ CHAIN_SEED_SALT, c);
                let mut current = PathState::default();
                for _ in 0..START_ATTEMPTS {
                    let (i, _, _) = start.sample_discrete(rng.uniform());
                    candidates.clear();
                    self.bootstrap_sample(
                        &bctx,
                        job.seed,
                        i as u64,
                        &mut init_slot,
                        &mut init_counters,
                        Some(&mut candidates),
                    );
                    let weights: Vec<f32> = candidates.iter().map(|c| c.1).collect();
                    if weights.is_empty() {
                        continue;
                    }
                    let (k, _, _) = Distribution1D::new(&weights).sample_discrete(rng.uniform());
                    current = PathState::new(&ctx, &candidates[k].0, &mut init_counters);
                    if current.f_star > 0.0 {
                        break;
                    }
                }
                ChainUnit { rng, current }
            })
            .collect();
        let unstarted = units.iter().filter(|u| !(u.current.f_star > 0.0)).count();
        if unstarted > 0 {
            warnings.push(format!(
                "{unstarted} of {} chains found no start path with a non-zero contribution in {START_ATTEMPTS} draws \
                 from the bootstrap; they stay at a zero path (their iterations splat nothing).",
                self.settings.chains
            ));
        }

        // Budget: one pass is about one mutation per pixel over all chains.
        let segment = pixels.div_ceil(self.settings.chains).max(1);
        let per_pass = segment * self.settings.chains;
        let passes = match job.budget {
            Budget::SamplesPerPixel(mpp) => {
                let total = mpp * pixels;
                progress.set_total(total.div_ceil(per_pass) * per_pass);
                Passes::Count(total.div_ceil(per_pass))
            }
            Budget::Seconds(s) => Passes::Seconds((s - render_start.elapsed().as_secs_f64()).max(0.0)),
        };
        progress.message("mutating");
        let scale = |iterations: u64| if iterations > 0 { b * pixels as f64 / iterations as f64 } else { 0.0 };
        let iterations = |slots: &mut dyn Iterator<Item = &MltStats>| -> u64 {
            slots.map(|s| s.per_depth.iter().map(|d| d.iterations).sum::<u64>()).sum()
        };
        let preview = |at: &PassBoundary<'_, ChainUnit, SlotState>| {
            at.film.to_image(scale(iterations(&mut at.slots.iter().map(|s| &s.state.stats))))
        };
        let out = driver.run(
            units,
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
        );

        let mut slots = out.slot_states.into_iter();
        let Some(mut merged) = slots.next() else {
            return Err(RenderError::Settings("no worker ran".into()));
        };
        for s in slots {
            merged.stats.merge(&s.stats);
        }
        let mut stats = merged.stats;
        let n = iterations(&mut std::iter::once(&stats));
        let image = out.film.to_image(scale(n));
        // b per depth: the bootstrap's b split by the chain's share of iterations at each depth
        // (the chain samples depths ∝ their b_d), for the JSON's per-depth entries.
        let b_depth: Vec<f64> =
            stats.per_depth.iter().map(|d| if n > 0 { b * d.iterations as f64 / n as f64 } else { 0.0 }).collect();
        stats.passes = out.passes;
        stats.segment_length = segment;
        stats.bootstrap_paths_per_depth = boot.paths;
        stats.bootstrap_seconds = boot.elapsed.as_secs_f64();
        stats.warnings = warnings;
        stats.finish(pixels, &b_depth, &b_depth);
        let mut counters = out.counters;
        for s in stats.strategies.iter().flatten() {
            counters
                .strategies
                .insert(s.name.clone(), AcceptanceCount { proposed: s.selected, accepted: s.accepted as f64 });
        }
        counters.merge(&boot.counters);
        counters.merge(&init_counters);
        let mut extra = serde_json::to_value(&stats).unwrap_or(serde_json::Value::Null);
        if let Some(map) = extra.as_object_mut() {
            map.insert("b".into(), serde_json::json!(b));
        }
        let output =
            RenderOutput { image, layers: Vec::new(), counters, wall_time: render_start.elapsed(), extra_stats: extra };
        Ok(PmltRun { output, film: out.film })
    }
}

impl Integrator for Pmlt {
    fn name(&self) -> &'static str {
        "pmlt"
    }

    fn settings_json(&self) -> serde_json::Value {
        serde_json::to_value(&self.settings).unwrap_or(serde_json::Value::Null)
    }

    fn render(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<RenderOutput, RenderError> {
        self.render_run(scene, job, progress).map(|run| run.output)
    }
}
