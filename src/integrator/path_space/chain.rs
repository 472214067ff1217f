//! `integrator = "pmlt"`: many path-space Markov chains on the render driver.
//!
//! - **Bootstrap** (`driver::bootstrap`, shared with the primary-sample-space methods): `bootstrap`
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
use super::caustic::{Caustic, CausticKernel};
use super::lens::Lens;
use super::multichain::{MultiChain, MultiChainKernel};
use super::path_state::PathState;
use super::pmlt_settings::PmltSettings;
use super::portal_perturbation::PortalPerturbation;
use super::reciprocal_kernel::DirectionKernel;
use super::strategy::{Entry, Mutation, StrategySet};
use super::PathContext;
use serde::{Deserialize, Serialize};

use crate::film::SplatBuffer;
use crate::integrator::bdpt::path::full_path;
use crate::integrator::bdpt::{
    connect_all, generate_camera_subpath, generate_light_subpath, BdptContext, ConnectScratch, FilmRegion, Vertex,
};
use crate::integrator::driver::expected_value_splats;
use crate::integrator::pss::mlt_stats::{MltStats, StrategyStats};
use crate::integrator::{RenderError, RenderOutput};
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
pub(super) const START_ATTEMPTS: usize = 64;

/// Path-space MLT.
#[derive(Clone, Debug)]
pub struct Pmlt {
    pub settings: PmltSettings,
    /// The bidirectional mutation (a value, so that tests can render with a deliberately wrong one).
    pub bidirectional: Bidirectional,
    /// The lens and caustic perturbations (values for the same reason).
    pub lens: Lens,
    pub caustic: Caustic,
    /// The portal perturbation (likewise a value, for its wrong variant).
    pub portal: PortalPerturbation,
}

/// A chain: its own stream and its current path (with its f and f*), all of which a state saves
/// (`crate::state::UnitState`, through serde; `pmlt_render`).
#[derive(Serialize, Deserialize)]
pub struct ChainUnit {
    /// The chain's index in the whole render (a shard holds some of the chains).
    pub index: u64,
    pub rng: Rng,
    pub current: PathState,
}

impl ChainUnit {
    /// Checks a chain restored from a state file (untrusted numbers) before it is used: its index
    /// is one of the render's `chains`, and its current path has at most `max_depth` + 2 vertices,
    /// each valid in the scene (`Vertex::is_valid_in`: its vertices become rays and lookups), a
    /// raster position on the film and a finite, non-negative f and f*.
    pub fn check_restored(&self, ctx: &PathContext, chains: u64) -> Result<(), crate::state::StateError> {
        let bad = |what: &str| crate::state::StateError::Mismatch(format!("chain {} of the state: {what}", self.index));
        if self.index >= chains {
            return Err(bad(&format!("an index beyond the render's {chains} chains")));
        }
        let c = &self.current;
        if c.vertices.len() > ctx.max_depth + 2 || !c.vertices.iter().all(|v| v.vertex.is_valid_in(ctx.scene)) {
            return Err(bad("a current path that is not a path of this scene"));
        }
        let camera = &ctx.scene.camera;
        let on_film = c.raster.x >= 0.0
            && c.raster.y >= 0.0
            && c.raster.x <= camera.width as f32
            && c.raster.y <= camera.height as f32;
        let f_ok = c.f.is_finite() && c.f.min_element() >= 0.0 && c.f_star.is_finite() && c.f_star >= 0.0;
        if !(on_film && f_ok) {
            return Err(bad("a current path with values out of range"));
        }
        Ok(())
    }
}

/// Per-slot scratch (BDPT subpaths for the bootstrap) and statistics.
pub(crate) struct SlotState {
    camera: Vec<Vertex>,
    light: Vec<Vertex>,
    scratch: ConnectScratch,
    pub(crate) stats: MltStats,
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
/// their expected-value weights into `film`'s image `layer` (`SplatBuffer::splat_in_layer`; 0 for
/// a film of one image), records the proposal in `stats` (per strategy, per
/// depth of the current path) and counts the state's depth after the step.
#[allow(clippy::too_many_arguments)]
pub fn step(
    ctx: &PathContext,
    set: &StrategySet,
    current: &mut PathState,
    rng: &mut Rng,
    stats: &mut MltStats,
    film: &mut SplatBuffer,
    layer: usize,
    counters: &mut Counters,
) {
    counters.samples += 1;
    let film = &mut Layer { film, layer, height: ctx.scene.camera.height as usize };
    let depth = current.depth();
    let chosen = set.choose(ctx, current, rng.uniform_f64());
    let mut a = 0.0f64;
    let mut proposal = None;
    if let Some((i, p_forward)) = chosen {
        let entry = &set.entries[i];
        let strategy = stats.strategies.as_mut().and_then(|s| s.get_mut(i));
        counters.early_rejection = None;
        let y = entry.propose(ctx, current, rng, counters);
        let cause = counters.early_rejection.take();
        match &y {
            None => {
                if let Some(s) = strategy {
                    s.generation_failures += 1;
                    if let Some(cause) = cause {
                        *s.early_rejections.entry(cause.to_string()).or_default() += 1;
                    }
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
    expected_value_splats(a, |is_proposal, w| match (is_proposal, proposal.as_ref()) {
        (true, Some(y)) => splat(y, w, film),
        (true, None) => {}
        (false, _) => splat(current, w, film),
    });
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

/// One image of a film of stacked images.
struct Layer<'a> {
    film: &'a mut SplatBuffer,
    layer: usize,
    height: usize,
}

/// Splats `path` with expected-value weight `w` as w · f/f* (a zero path splats nothing).
fn splat(path: &PathState, w: f64, film: &mut Layer) {
    if !(w > 0.0) || !(path.f_star > 0.0) {
        return;
    }
    let value = (path.f * (w / path.f_star)).as_vec3();
    if is_finite(value) {
        film.film.splat_in_layer(path.raster, film.layer, film.height, value);
    }
}

impl Pmlt {
    pub fn from_params(params: &toml::Table) -> Result<Pmlt, RenderError> {
        Ok(Pmlt {
            settings: PmltSettings::from_params(params)?,
            bidirectional: Bidirectional::default(),
            lens: Lens::default(),
            caustic: Caustic::default(),
            portal: PortalPerturbation::default(),
        })
    }

    /// The strategies of the chain for `scene` (its film sets the lens kernel's range unless the
    /// settings do, `PmltSettings::lens_kernel`): the bidirectional mutation and Veach's
    /// perturbations, in the statistics' order. A weight of 0 leaves a strategy out.
    pub fn strategies(&self, scene: &Scene) -> StrategySet {
        let s = &self.settings;
        let lens = s.lens_kernel(scene.camera.width, scene.camera.height);
        let mut entries: Vec<Box<dyn Mutation>> =
            vec![Box::new(Entry { strategy: self.bidirectional, kernel: LengthKernel, weight: s.bidirectional })];
        if s.lens > 0.0 {
            entries.push(Box::new(Entry { strategy: self.lens, kernel: lens, weight: s.lens }));
        }
        if s.caustic > 0.0 {
            let kernel = CausticKernel::from_lens(&lens, &scene.camera);
            entries.push(Box::new(Entry { strategy: self.caustic, kernel, weight: s.caustic }));
        }
        if s.portal > 0.0 {
            // Offered only at paths that cross a portal (`portal` docs).
            entries.push(Box::new(Entry {
                strategy: self.portal,
                kernel: DirectionKernel::default(),
                weight: s.portal,
            }));
        }
        if s.multi_chain > 0.0 {
            let kernel = MultiChainKernel::new(lens);
            entries.push(Box::new(Entry { strategy: MultiChain, kernel, weight: s.multi_chain }));
        }
        StrategySet { entries }
    }

    pub(crate) fn bdpt_context<'a>(&self, scene: &'a Scene) -> BdptContext<'a> {
        BdptContext::new(scene, usize::MAX, self.settings.mis)
    }

    /// Bootstrap sample `i`: a BDPT sample over the whole film from stream i; returns Σ_t
    /// luminance(w_t C_t). With `paths`, also every technique's complete path with that weight.
    pub(crate) fn bootstrap_sample(
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

    pub(crate) fn new_slot(&self, set: &StrategySet) -> SlotState {
        SlotState {
            camera: Vec::new(),
            light: Vec::new(),
            scratch: ConnectScratch::default(),
            stats: new_stats(self.settings.max_depth as usize, set),
        }
    }

    /// Chain `c`: its stream, and a start path resampled from the bootstrap (module docs), drawn
    /// again up to `START_ATTEMPTS` times while its f is zero. Depends on the seed and `c` only,
    /// so a shard starts its chains as the whole render does.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn start_chain(
        &self,
        c: u64,
        start: &Distribution1D,
        ctx: &PathContext,
        bctx: &BdptContext,
        seed: u64,
        slot: &mut SlotState,
        counters: &mut Counters,
        candidates: &mut Vec<(Vec<Vertex>, f32)>,
    ) -> ChainUnit {
        let mut rng = Rng::new(seed ^ CHAIN_SEED_SALT, c);
        let mut current = PathState::default();
        for _ in 0..START_ATTEMPTS {
            let (i, _, _) = start.sample_discrete(rng.uniform());
            candidates.clear();
            self.bootstrap_sample(bctx, seed, i as u64, slot, counters, Some(&mut *candidates));
            let weights: Vec<f32> = candidates.iter().map(|c| c.1).collect();
            if weights.is_empty() {
                continue;
            }
            let (k, _, _) = Distribution1D::new(&weights).sample_discrete(rng.uniform());
            current = PathState::new(ctx, &candidates[k].0, counters);
            if current.f_star > 0.0 {
                break;
            }
        }
        ChainUnit { index: c, rng, current }
    }
}
