//! Primary-sample-space MLT (Kelemen et al. 2002; MMLT paper Alg. 1) and Multiplexed MLT
//! (Hachisuka et al. 2014, Alg. 2), sharing one chain driver, one bootstrap, one splat path and
//! one statistics type. They differ only in how a primary-sample state maps to contributions:
//!
//! - **PSSMLT**: the camera and light subpaths of the state are combined with every BDPT technique
//!   (Alg. 1, COMBINE); the target is the luminance of the sum of the MIS-weighted contributions.
//! - **MMLT**: one chain per path depth d (d scattering events, d + 2 vertices); an extra primary
//!   coordinate u_t picks one of the n_d = d + 2 techniques, s = ⌊n_d·u_t⌋ light vertices and
//!   t = n_d − s camera vertices, connected only at their endpoints (Sec. 4, "Path Generation");
//!   the target is the luminance of that one MIS-weighted contribution ŵ_t Ĉ_t (Eq. 20).
//!
//! # Normalisation
//! With b_d = ∫ f̂_d over the (ū, u_t) unit cube (estimated by a bootstrap of uniform samples), a
//! chain of depth d samples (ū, u_t) ∝ f̂_d, and the pixel j of the depth-d image is
//!   I_j = n_d · b_d · P · E_π[ 1_j(raster) · ŵ_t C_t / f̂_d ],
//! where P is the pixel count (the film position is uniform over the whole film) and n_d the
//! number of techniques u_t spreads over (the paper's factor k+2, Sec. 4 "Accumulation"). Each
//! depth's splats go to their own image (see "Films and threads"), divided at the end by the
//! number of iterations that depth received; this equals the paper's 1/p(k) scaling in expectation
//! and lets b_d be refined from the large steps (uniform samples) during the render without
//! re-weighting earlier splats.
//! PSSMLT is the special case of one "depth" with n = 1.
//!
//! # Reversible-jump MLT
//! **RJMLT** (Bitterli et al. 2017) keeps MMLT's per-depth chains, target and normalisation but
//! moves the technique out of the primary samples: the state is (s, ū) with s an integer that small
//! steps never change. Each iteration is a large step (s and ū resampled uniformly, so the
//! bootstrap and b_d are MMLT's), a small step of ū under the fixed technique, or a technique jump
//! (Sec. 4 and the final algorithm of Sec. 6.2): choose j with probability w_j(x̄) of the current
//! path x̄, invert x̄ into the primary samples technique j would have used (`inverse.rs`), evaluate
//! that state and accept with Eq. 38/43 (`jump.rs`), which is 1 up to rounding when the inverse
//! reproduces x̄. A path that cannot be inverted, or whose inverse does not reproduce it, is
//! rejected and counted.
//!
//! # Films and threads
//! The depths' images are layers of the driver's one film: depth d is rows [d·H, (d+1)·H) of a
//! W × (H·D) film (one layer for PSSMLT), written through the chain unit's `SplatBuffer`, which
//! the driver applies in unit order (`integrator::driver`). The normalisation reads that film, the
//! large-step totals summed over the units in unit order (b_d) and the depths' iteration counts
//! (integers), at output and for previews alike; each chain's depth choice reads its own totals
//! (`depth_choice`), so chains never depend on each other. So the image, bit for bit, depends on the
//! seed and the chain count, not on the thread count. The technique count layers (a debug output,
//! off by default) stay per slot, merged in slot order: they hold integer counts (sums of 1.0,
//! exact in f64 below 2^53), which any merge order gives bit for bit.
//! The cost is memory: a pass (about one mutation per pixel) holds all its splats until it ends,
//! 16 bytes each, the proposal's and, when a < 1, the current state's: MMLT and RJMLT about two
//! per mutation (66 MB a pass at 1920×1080), PSSMLT one per contributing technique of both, so
//! several times that. The one film is W·H·D·24 bytes, where the per-slot films were that per
//! thread.
//!
//! # Expected values
//! Each iteration splats the proposal with weight a and the current state with 1 − a (Veach's
//! expected values), so rejected proposals still contribute.

use glam::Vec2;
use serde::{Deserialize, Serialize};

use super::inverse::{invert_technique, same_path, InversionFailure};
use super::jump::{jump_acceptance, JumpSide};
use super::mlt_settings::{MltSettings, MltVariant};
use super::mlt_stats::{MltStats, MoveKind};
use super::sampler::{MutationSettings, PssSampler};
use crate::film::{Accumulator, Image, SplatBuffer};
use crate::integrator::bdpt::path::full_path;
use crate::integrator::bdpt::{
    connect_all, evaluate_technique, generate_camera_subpath, generate_light_subpath, BdptContext, ConnectScratch,
    FilmRegion, Vertex,
};
use crate::integrator::driver::{chain_scale, expected_value_splats};
use crate::integrator::{RenderError, RenderOutput};
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::spectrum::{is_finite, luminance, Rgb};
use crate::state::StateError;
use crate::stats::{AcceptanceCount, Counters};

mod bootstrap_sample;
mod depth_choice;
mod mlt_render;
use bootstrap_sample::{technique_target, PrimarySource};
use depth_choice::{BEstimate, LargeStepTotals};

/// Primary-sample streams: camera subpath, light subpath, connection, technique (MMLT's u_t).
const CAMERA_STREAM: usize = 0;
const LIGHT_STREAM: usize = 1;
const CONNECTION_STREAM: usize = 2;
const TECHNIQUE_STREAM: usize = 3;
const STREAM_COUNT: usize = 4;

/// Distinguishes the bootstrap's random streams from the render's.
const BOOTSTRAP_SEED_SALT: u64 = 0xB007_5742_u64;
/// Distinguishes the streams of depth 0's replicates (`DIRECT_REPLICATES`) from the bootstrap's.
const DIRECT_SEED_SALT: u64 = 0xD14E_C700_0000_0000_u64;
/// Distinguishes the chains' own streams (depth choice, acceptance) from the bootstrap's.
const CHAIN_SEED_SALT: u64 = 0xC4A1_0000_u64;
/// Distinguishes the sub-chains' mutation streams (stream c·D + d for chain c, depth d) from the
/// bootstrap's: chains that start from the same bootstrap sample must then mutate independently.
const SUBCHAIN_SEED_SALT: u64 = 0x5EA2_C400_u64;

/// PSSMLT, MMLT or RJMLT.
#[derive(Clone, Debug)]
pub struct Mlt {
    pub variant: MltVariant,
    pub settings: MltSettings,
}

/// One contribution of a state to the film.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
struct Splat {
    raster: Vec2,
    value: Rgb,
}

impl ChainUnit {
    /// Checks a unit restored from a state file (untrusted numbers) before it is used: the
    /// sub-chains the integrator has (`depths`), each sampler's ranges, splats on the
    /// `width`×`height` film with finite values, and an RJMLT path whose vertices are finite and
    /// name materials and lights the scene has (its vertices become rays and lookups), and a
    /// technique `s` (light vertices) of at most `max_vertices`.
    fn check_restored(
        &self,
        scene: &Scene,
        (depths, max_vertices): (usize, usize),
        width: u32,
        height: u32,
    ) -> Result<(), StateError> {
        let bad = |what: String| StateError::Mismatch(format!("chain {} of the state: {what}", self.index));
        if self.subchains.len() != depths {
            return Err(bad(format!("{} sub-chains where the integrator has {depths}", self.subchains.len())));
        }
        for sub in self.subchains.iter().flatten() {
            sub.sampler.check_restored(STREAM_COUNT).map_err(bad)?;
            let c = &sub.current;
            let on_film = |r: Vec2| r.x >= 0.0 && r.y >= 0.0 && r.x < width as f32 && r.y < height as f32;
            let values_ok = c.splats.iter().all(|s| on_film(s.raster) && s.value.is_finite())
                && c.target.is_finite()
                && c.target >= 0.0
                && c.unweighted.is_finite()
                && c.weights.iter().all(|w| w.is_finite());
            if !values_ok {
                return Err(bad("a current state with values out of range".into()));
            }
            let vertex_ok = |v: &Vertex| v.is_valid_in(scene);
            // MMLT keeps no path (only its technique); RJMLT's technique indexes its path.
            let s_ok = c.s <= max_vertices && (c.path.is_empty() || c.s <= c.path.len());
            if !s_ok || !c.path.iter().all(vertex_ok) {
                return Err(bad("a current path that is not a path of this scene".into()));
            }
        }
        Ok(())
    }
}

/// The contributions of one primary-sample state and its scalar target.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct PathState {
    splats: Vec<Splat>,
    target: f32,
    /// MMLT, RJMLT: the technique (light vertices) of the state.
    s: usize,
    /// RJMLT: the complete path (camera first) and every technique's MIS weight for it (index =
    /// light vertices), for the next technique jump. Empty for a zero-contribution state.
    path: Vec<Vertex>,
    weights: Vec<f32>,
    /// RJMLT: luminance of the technique's unweighted estimate C = f(x̄)/p(x̄) of the path.
    unweighted: f32,
    /// Technique paths this state evaluated (PSSMLT: every (s, t) combination of its subpaths;
    /// MMLT, RJMLT: one) and how many of them contributed.
    paths_evaluated: u32,
    paths_nonzero: u32,
}

/// The bootstrap's result as the normalisation and the depth choice read it.
struct Bootstrap {
    /// Per depth slot: b_d and what pooling it with the large steps needs.
    estimates: Vec<BEstimate>,
    /// Per depth slot: whether a sample of the full bootstrap found light there, so that chains
    /// start from it (depth 0's replicates start no chains).
    found: Vec<bool>,
}

/// A chain for one depth (MMLT) or for all depths (PSSMLT). A sub-chain of a depth the bootstrap
/// missed starts with a zero-target state and searches (`Mlt::search`) until a large step finds
/// its first non-zero state.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct SubChain {
    sampler: PssSampler,
    current: PathState,
}

/// A Markov chain unit: its own random stream (depth choice, acceptance) and its sub-chains. All
/// of it is saved in checkpoints and shards (`crate::state::UnitState`, through serde).
#[derive(Serialize, Deserialize)]
pub struct ChainUnit {
    /// The chain's index in the whole render (a shard holds some of the chains).
    index: u64,
    rng: Rng,
    /// Per depth: sum and count of this unit's large-step targets so far, for the depth choice.
    large_steps: LargeStepTotals,
    /// Indexed by depth for MMLT and RJMLT (None only where the depth is never chosen:
    /// bootstrap b_d = 0 without progressive b); one entry for PSSMLT.
    subchains: Vec<Option<SubChain>>,
}

/// Per-slot scratch buffers and statistics. The image is not here: it is in the driver's film,
/// written through each chain unit's buffer (module docs, "Films and threads").
struct SlotState {
    camera: Vec<Vertex>,
    light: Vec<Vertex>,
    scratch: ConnectScratch,
    /// MMLT and RJMLT with count layers (a debug output, off by default): per (depth, s) an image
    /// of state counts, merged in slot order (integer sums, exact in f64: the order does not show).
    count_films: Option<Vec<Vec<Accumulator>>>,
    stats: MltStats,
}

/// What [`Mlt::render_run`] produced.
pub struct MltRun {
    pub output: RenderOutput,
    /// The driver's film of unnormalised splat sums, every chain unit applied in unit order: a
    /// width × (height · D) film whose rows [d·height, (d+1)·height) are depth d's image (D = 1
    /// for PSSMLT). Each depth is normalised by its own b_d / iterations at output.
    pub film: Accumulator,
}

impl Mlt {
    pub fn from_params(variant: MltVariant, params: &toml::Table) -> Result<Mlt, RenderError> {
        Ok(Mlt { variant, settings: MltSettings::from_params(variant, params)? })
    }

    fn depth_count(&self) -> usize {
        match self.variant {
            MltVariant::Pssmlt => 1,
            MltVariant::Mmlt | MltVariant::Rjmlt => self.settings.max_depth as usize + 1,
        }
    }

    /// Number of techniques the state's u_t spreads over at depth slot `d`: n_d = d + 2, except
    /// at depth 0 where (s, t) = (1, 1) is not a BDPT technique (the MIS weights of the others
    /// already sum to 1 without it), leaving only s = 0, t = 2.
    fn technique_count(&self, d: usize) -> usize {
        match self.variant {
            MltVariant::Pssmlt => 1,
            MltVariant::Mmlt | MltVariant::Rjmlt if d == 0 => 1,
            MltVariant::Mmlt | MltVariant::Rjmlt => d + 2,
        }
    }

    fn mutation(&self) -> MutationSettings {
        MutationSettings {
            large_step_probability: self.settings.large_step_probability,
            small_step: self.settings.small_step(),
        }
    }

    /// Maps the sampler's current proposal to its contributions (the state's path). `technique`
    /// fixes the number of light vertices (RJMLT's small steps and jumps); otherwise MMLT and
    /// RJMLT read it from the technique stream.
    fn evaluate<P: PrimarySource>(
        &self,
        ctx: &BdptContext,
        d: usize,
        sampler: &mut P,
        technique: Option<usize>,
        slot: &mut SlotState,
        counters: &mut Counters,
    ) -> PathState {
        let mut state = PathState::default();
        let max_depth = self.settings.max_depth as usize;
        match self.variant {
            MltVariant::Pssmlt => {
                sampler.start_stream(CAMERA_STREAM);
                let raster = generate_camera_subpath(
                    ctx,
                    FilmRegion::WholeFilm,
                    sampler,
                    max_depth + 2,
                    &mut slot.camera,
                    counters,
                );
                sampler.start_stream(LIGHT_STREAM);
                generate_light_subpath(ctx, sampler, max_depth + 1, &mut slot.light, counters);
                sampler.start_stream(CONNECTION_STREAM);
                let splats = &mut state.splats;
                state.paths_evaluated = techniques_of_subpaths(slot.light.len(), slot.camera.len(), max_depth);
                connect_all(
                    ctx,
                    &slot.light,
                    &slot.camera,
                    raster,
                    max_depth,
                    sampler,
                    &mut slot.scratch,
                    counters,
                    |c, counters| {
                        let value = c.weighted();
                        if is_finite(value) {
                            splats.push(Splat { raster: c.raster, value });
                        } else {
                            counters.nonfinite_dropped += 1;
                        }
                    },
                );
            }
            MltVariant::Mmlt | MltVariant::Rjmlt => {
                // Alg. 2: t = ⌊n·u_t⌋ in the paper's numbering; here s = ⌊n·u_t⌋ light vertices
                // and t = n − s camera vertices (t ≥ 1: a pinhole cannot be hit).
                let n = self.technique_count(d);
                let s = match technique {
                    Some(s) => s.min(n - 1),
                    None => {
                        sampler.start_stream(TECHNIQUE_STREAM);
                        ((sampler.next_1d() * n as f32) as usize).min(n - 1)
                    }
                };
                state.paths_evaluated = 1;
                let rjmlt = self.variant == MltVariant::Rjmlt;
                let t = d + 2 - s;
                state.s = s;
                sampler.start_stream(CAMERA_STREAM);
                let raster =
                    generate_camera_subpath(ctx, FilmRegion::WholeFilm, sampler, t, &mut slot.camera, counters);
                sampler.start_stream(LIGHT_STREAM);
                slot.light.clear();
                if s > 0 {
                    generate_light_subpath(ctx, sampler, s, &mut slot.light, counters);
                }
                sampler.start_stream(CONNECTION_STREAM);
                if slot.camera.len() >= t && slot.light.len() >= s {
                    if let Some(c) = evaluate_technique(
                        ctx,
                        &slot.light,
                        &slot.camera,
                        s,
                        t,
                        raster,
                        sampler,
                        &mut slot.scratch,
                        counters,
                        if rjmlt { Some(&mut state.weights) } else { None },
                    ) {
                        if technique_target(&c, counters) > 0.0 {
                            state.splats.push(Splat { raster: c.raster, value: c.weighted() });
                            if rjmlt {
                                state.path = full_path(&slot.light, &slot.camera, &c);
                                state.unweighted = luminance(c.contribution);
                            }
                        }
                    }
                }
            }
        }
        state.paths_nonzero = state.splats.len() as u32;
        let target: f32 = state.splats.iter().map(|s| luminance(s.value)).sum();
        state.target = if target.is_finite() && target > 0.0 { target } else { 0.0 };
        if state.target == 0.0 {
            state.splats.clear();
            state.path.clear();
            state.weights.clear();
        }
        state
    }

    fn new_slot(&self, width: usize, height: usize) -> SlotState {
        let depths = self.depth_count();
        SlotState {
            camera: Vec::new(),
            light: Vec::new(),
            scratch: ConnectScratch::default(),
            count_films: (self.settings.technique_count_layers && self.variant != MltVariant::Pssmlt)
                .then(|| (0..depths).map(|d| vec![Accumulator::new(width, height); self.technique_count(d)]).collect()),
            stats: MltStats::new(
                &(0..depths).map(|d| self.technique_count(d)).collect::<Vec<_>>(),
                self.variant != MltVariant::Pssmlt,
                self.variant == MltVariant::Mmlt,
                self.variant == MltVariant::Rjmlt,
            ),
        }
    }

    /// The image of the driver's stacked per-depth film (module docs, "Normalisation"): depth d
    /// (rows [d·H, (d+1)·H)) scaled by n_d · b_d · P / (iterations of depth d), with b_d from the
    /// bootstrap and, with `progressive_b`, the large steps so far (`large_steps`, pooled in unit
    /// order; `BEstimate::pooled`). Returns the b_d used. Serves the final image and the previews during the render
    /// alike.
    fn normalised_image(
        &self,
        film: &Accumulator,
        large_steps: &LargeStepTotals,
        iterations: &[u64],
        bootstrap: &Bootstrap,
    ) -> (Image, Vec<f64>) {
        let depths = self.depth_count();
        let (width, height) = (film.width, film.height / depths);
        let pixels = width * height;
        let mut total = vec![[0.0f64; 3]; pixels];
        let mut b = Vec::with_capacity(depths);
        for d in 0..depths {
            let b_d = self.b_estimate(&bootstrap.estimates[d], large_steps[d]);
            b.push(b_d);
            if iterations[d] == 0 {
                continue;
            }
            // n_d · b_d is depth d's normalisation constant (its n_d techniques share the film).
            let scale = chain_scale(self.technique_count(d) as f64 * b_d, pixels as u64, iterations[d]);
            let layer = &film.sums()[d * pixels..(d + 1) * pixels];
            for (t, s) in total.iter_mut().zip(layer) {
                t[0] += s[0] * scale;
                t[1] += s[1] * scale;
                t[2] += s[2] * scale;
            }
        }
        let pixels = total.iter().map(|s| Rgb::new(s[0] as f32, s[1] as f32, s[2] as f32)).collect();
        (Image { width, height, pixels }, b)
    }

    /// Per depth, the iterations the slots ran (integer sums: any order gives them).
    fn iteration_counts<'s>(&self, slots: impl Iterator<Item = &'s SlotState>) -> Vec<u64> {
        let mut iterations = vec![0; self.depth_count()];
        for slot in slots {
            for (n, depth) in iterations.iter_mut().zip(&slot.stats.per_depth) {
                *n += depth.iterations;
            }
        }
        iterations
    }

    /// One Metropolis iteration of sub-chain `d`: a large or small step of the primary samples
    /// (all methods), or for RJMLT, with probability `jump_probability`, a technique jump. Returns
    /// the proposal's target if it was a large step (a uniform sample, for b_d).
    #[allow(clippy::too_many_arguments)]
    fn iterate(
        &self,
        ctx: &BdptContext,
        d: usize,
        chain: &mut SubChain,
        rng: &mut Rng,
        slot: &mut SlotState,
        film: &mut SplatBuffer,
        counters: &mut Counters,
    ) -> Option<f32> {
        if !(chain.current.target > 0.0) {
            return Some(self.search(ctx, d, chain, slot, counters));
        }
        let (large, jump) = if self.variant == MltVariant::Rjmlt {
            let u = rng.uniform() as f64;
            let large = u < self.settings.large_step_probability;
            (large, !large && u < self.settings.large_step_probability + self.settings.jump_probability)
        } else {
            chain.sampler.start_iteration();
            (chain.sampler.is_large_step(), false)
        };
        let (proposal, a) = if jump {
            match self.propose_jump(ctx, d, chain, rng, slot, counters) {
                Some(p) => p,
                None => {
                    // The jump chose the current technique: the state stays, and it is splatted.
                    self.splat(d, &chain.current, 1.0, film);
                    slot.stats.per_depth[d].iterations += 1;
                    self.count_technique_state(d, &chain.current, slot);
                    return None;
                }
            }
        } else {
            if self.variant == MltVariant::Rjmlt {
                chain.sampler.start_iteration_with(large);
            }
            // RJMLT's small steps keep the technique; its large steps draw one uniformly.
            let technique = (self.variant == MltVariant::Rjmlt && !large).then_some(chain.current.s);
            let proposal = self.evaluate(ctx, d, &mut chain.sampler, technique, slot, counters);
            // Eq. 20 (and Alg. 1): a = target(proposal) / target(current). A current state of
            // zero target (only possible before any light was found) accepts any proposal.
            let cur = chain.current.target;
            let a = if cur > 0.0 {
                (proposal.target / cur).min(1.0)
            } else if proposal.target > 0.0 {
                1.0
            } else {
                0.0
            };
            (proposal, a)
        };
        counters.samples += 1;
        let large_step_target = large.then_some(proposal.target);
        // Weights in f64 and back: a is an f32, so a and 1 − a come back as the f32 values.
        expected_value_splats(a as f64, |is_proposal, w| {
            self.splat(d, if is_proposal { &proposal } else { &chain.current }, w as f32, film)
        });
        let accepted = rng.uniform() < a;
        let kind = if jump {
            MoveKind::Jump
        } else if large {
            MoveKind::Large
        } else {
            MoveKind::Small
        };
        if let Some(moves) = slot.stats.moves.get_mut(kind) {
            moves.proposals += 1;
            moves.accepted += accepted as u64;
            moves.nonzero_proposals += (proposal.target > 0.0) as u64;
            moves.paths_evaluated += proposal.paths_evaluated as u64;
            moves.paths_nonzero += proposal.paths_nonzero as u64;
        }
        let tally = |count: &mut AcceptanceCount| {
            count.proposed += 1;
            if accepted {
                count.accepted += 1.0;
            }
        };
        let depth = &mut slot.stats.per_depth[d];
        depth.iterations += 1;
        tally(&mut depth.acceptance);
        match kind {
            MoveKind::Jump => depth.jumps.as_mut().into_iter().for_each(tally),
            MoveKind::Small => {
                tally(&mut depth.small_steps);
                if proposal.s != chain.current.s {
                    depth.technique_change.as_mut().into_iter().for_each(tally);
                }
            }
            MoveKind::Large => {}
        }
        if accepted {
            chain.sampler.accept();
            chain.current = proposal;
        } else {
            chain.sampler.reject();
        }
        self.count_technique_state(d, &chain.current, slot);
        large_step_target
    }

    /// Splats `state`'s contributions with weight `w` / target (Veach's expected values) to depth
    /// `d`'s layer of the unit's buffer (rows [d·H, (d+1)·H) of the stacked film).
    fn splat(&self, d: usize, state: &PathState, w: f32, film: &mut SplatBuffer) {
        if !(w > 0.0) || !(state.target > 0.0) {
            return;
        }
        let w = w / state.target;
        let layer_height = film.height / self.depth_count();
        for sp in &state.splats {
            // A target near the smallest f32 can make the expected-value weight overflow: no
            // non-finite value may reach the film (the splat's own value was checked when made).
            let value = sp.value * w;
            if is_finite(value) {
                film.splat_in_layer(sp.raster, d, layer_height, value);
            }
        }
    }

    /// MMLT and RJMLT: which technique the chain's state has (the paper's Fig. 5).
    fn count_technique_state(&self, d: usize, current: &PathState, slot: &mut SlotState) {
        if self.variant == MltVariant::Pssmlt {
            return;
        }
        if let Some(count) =
            slot.stats.per_depth[d].technique_state_counts.as_mut().and_then(|counts| counts.get_mut(current.s))
        {
            count.iterations += 1;
        }
        if let (Some(films), Some(sp)) = (slot.count_films.as_mut(), current.splats.first()) {
            films[d][current.s].splat(sp.raster, Rgb::ONE);
        }
    }

    /// RJMLT's technique jump (Bitterli et al. 2017, final algorithm of Sec. 6.2): choose j with
    /// probability w_j(x̄) of the current path x̄; write S_j⁻¹(x̄) into the sampler as a new
    /// iteration; evaluate that state; return it with its acceptance min(1, r) of Eq. 38/43.
    /// `None` when j is the current technique (the state does not change and no iteration is
    /// started). A failed inverse, or one that does not reproduce x̄, gives a zero-target proposal
    /// with acceptance 0.
    fn propose_jump(
        &self,
        ctx: &BdptContext,
        d: usize,
        chain: &mut SubChain,
        rng: &mut Rng,
        slot: &mut SlotState,
        counters: &mut Counters,
    ) -> Option<(PathState, f32)> {
        let current = &chain.current;
        let i = current.s;
        let n = self.technique_count(d);
        // T(i → j) = w_j(x̄) (Eq. 33), over the techniques this depth's chain can be in.
        let weight = |s: usize| current.weights.get(s).copied().filter(|w| w.is_finite() && *w > 0.0).unwrap_or(0.0);
        let total: f32 = (0..n).map(weight).sum();
        if !(current.target > 0.0) || current.path.is_empty() || !(total > 0.0) {
            return None;
        }
        let mut u = rng.uniform() * total;
        let mut j = i;
        for s in 0..n {
            let w = weight(s);
            if w > 0.0 {
                j = s;
                if u < w {
                    break;
                }
                u -= w;
            }
        }
        if j == i {
            slot.stats.jumps.iter_mut().for_each(|j| j.to_same_technique += 1);
            return None;
        }
        chain.sampler.start_iteration_with(false);
        // A failed jump still proposed one technique path (for the effective path ratio).
        let rejected = PathState { s: j, paths_evaluated: 1, ..PathState::default() };
        let inverse = match invert_technique(ctx.scene, &current.path, j, rng) {
            Ok(inverse) => inverse,
            Err(failure) => {
                let k = InversionFailure::ALL.iter().position(|f| *f == failure).unwrap_or(0);
                slot.stats.jumps.iter_mut().for_each(|j| j.inversion_failures[k] += 1);
                return Some((rejected, 0.0));
            }
        };
        for (stream, values) in
            [(CAMERA_STREAM, &inverse.camera), (LIGHT_STREAM, &inverse.light), (CONNECTION_STREAM, &inverse.connection)]
        {
            for (position, &value) in values.iter().enumerate() {
                chain.sampler.put(stream, position, value);
            }
        }
        let proposal = self.evaluate(ctx, d, &mut chain.sampler, Some(j), slot, counters);
        if !(proposal.target > 0.0) || !same_path(&proposal.path, &current.path) {
            slot.stats.jumps.iter_mut().for_each(|j| j.path_mismatches += 1);
            return Some((rejected, 0.0));
        }
        // Eq. 38 with Eq. 43. By Eq. 44 each step's |J[g⁻¹]| / T(t) is that step's full (mixture)
        // density, so over an inverse walk |J[S⁻¹]| / T = p(x̄), the technique's path density, and
        // only the ratio p_j(x̄) / p_i(x̄) enters. It is taken from the two techniques' own unweighted
        // estimates of the shared path, C = f(x̄)/p(x̄), which the walks compute exactly: the MIS
        // recurrence's densities are not a substitute, since across specular chains it drops the
        // chains' Jacobians (delta densities count as 1; the weights stay valid, but w_j/w_i is then
        // not p_j/p_i). The ratio is 1 up to rounding whenever the regenerated path is x̄.
        let density_ratio = current.unweighted as f64 / proposal.unweighted as f64;
        let current_side = JumpSide {
            target: current.target as f64,
            technique_choice: weight(j) as f64,
            inverse_jacobian: 1.0,
            branch_choice: 1.0,
        };
        let proposal_side = JumpSide {
            target: proposal.target as f64,
            technique_choice: proposal.weights.get(i).copied().unwrap_or(0.0) as f64,
            inverse_jacobian: density_ratio,
            branch_choice: 1.0,
        };
        let r = jump_acceptance(&current_side, &proposal_side);
        let deviation = (r - 1.0).abs();
        if let Some(jumps) = slot.stats.jumps.as_mut() {
            jumps.ratio_max_deviation = jumps.ratio_max_deviation.max(deviation);
            jumps.ratio_off += (deviation > 1e-3) as u64;
        }
        Some((proposal, r.min(1.0) as f32))
    }
}

/// Number of BDPT techniques (s, t) `connect_all` evaluates on subpaths of these lengths: t ≥ 1,
/// s + t − 2 ≤ max_depth, not (1, 1).
fn techniques_of_subpaths(light: usize, camera: usize, max_depth: usize) -> u32 {
    let mut n = 0;
    for t in 1..=camera {
        for s in 0..=light {
            let depth = (s + t) as isize - 2;
            if !(s == 1 && t == 1) && depth >= 0 && depth as usize <= max_depth {
                n += 1;
            }
        }
    }
    n
}
