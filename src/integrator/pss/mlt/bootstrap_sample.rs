//! The MLT bootstrap's samples and the chains' start from them.
//!
//! **One full BDPT sample for every depth.** MMLT's b_d = ∫ f̂_d over the (ū, u_t) cube (MMLT paper
//! Sec. 4, "Initialization", which allows estimating it "using bidirectional path tracing"). With
//! u_t uniform, f̂_d averaged over u_t is (1/n_d)·Σ_s lum(w_{s,t} C_{s,t}(ū)) over the n_d techniques
//! of depth d. So one BDPT sample — a camera subpath of max_depth + 2 vertices, a light subpath of
//! max_depth + 1 and every technique (s, t) between them, each with its MIS weight — gives every
//! depth's b_d an estimate at once, B_d = (1/n_d)·Σ_s lum(w_{s,t} C_{s,t}), where one sample per
//! depth on one technique would take 100,000 paths per depth × 17 depths at max_depth 16. Each
//! technique of the sample sees uniform primary samples, so each B_d is unbiased.
//!
//! **Primary samples that a chain can replay.** A bootstrap sample reads its camera, light and
//! connection numbers from streams of its own ([`BootstrapSource`]), each read from its start, and
//! each technique reads the connection stream from its first number (as an MMLT state's one
//! technique does). A camera subpath of t vertices then reads a prefix of what the full subpath
//! read, so the state (ū, u_t) with those numbers and a u_t that selects s evaluates to exactly the
//! technique's target lum(w_{s,t} C_{s,t}) within the full sample: the bootstrap's weights are the
//! MMLT targets of the states they stand for (`start_state`, checked by
//! `start_states_reproduce_their_bootstrap_targets`).
//!
//! **Starting ∝ the target.** A depth-d chain picks sample i with probability B_{i,d}/Σ_j B_{j,d},
//! then technique s of it with probability lum(w_s C_s)/(n_d·B_{i,d}): (i, s) is chosen
//! ∝ lum(w_s C_s) = f̂_d(ū_i, u_t ∈ s), the importance resampling of the stratified candidates
//! {(ū_i, s)} by the MMLT target; u_t is then drawn uniformly within s's interval [s/n_d, (s+1)/n_d),
//! which is its distribution under the target given s (the target depends on u_t only through s).
//!
//! **Sobol or independent numbers** (`bootstrap_sampler`). The bootstrap's samples are
//! independent of each other in either case and the chains' large steps stay independent
//! proposals; the Sobol bootstrap (the default) reads each stream from one Owen-scrambled Sobol
//! sequence over the whole film (`SobolStream::of_sequence`), which stratifies the film position
//! and the first vertices' numbers across the samples and so lowers b_d's error at equal samples
//! (docs/mlt.md, "The bootstrap").

use super::{
    Mlt, PathState, SlotState, SubChain, BOOTSTRAP_SEED_SALT, CAMERA_STREAM, CONNECTION_STREAM, DIRECT_SEED_SALT,
    LIGHT_STREAM, STREAM_COUNT, TECHNIQUE_STREAM,
};
use crate::integrator::bdpt::{
    evaluate_technique, generate_camera_subpath, generate_light_subpath, BdptContext, FilmRegion, TechniqueSample,
};
use crate::integrator::pss::mlt_settings::MltVariant;
use crate::integrator::pss::sampler::PssSampler;
use crate::sampling::{Rng, SamplerKind, SobolStream, UniformSource};
use crate::spectrum::{is_finite, luminance};
use crate::stats::Counters;

/// What `Mlt::evaluate` reads primary samples from: a chain's sampler or a bootstrap sample.
pub(super) trait PrimarySource: UniformSource {
    /// Subsequent reads come from `stream`, starting at its first number.
    fn start_stream(&mut self, stream: usize);
}

impl PrimarySource for PssSampler {
    fn start_stream(&mut self, stream: usize) {
        PssSampler::start_stream(self, stream);
    }
}

/// One stream of a bootstrap sample.
enum StreamSource {
    Independent(Rng),
    Sobol(SobolStream),
}

/// The primary samples of bootstrap sample `index`: per stream an independent random stream or
/// one stream of the bootstrap's Sobol sequence, each restarted from its first number by
/// `start_stream`; with `record`, every number read is kept by (stream, position) for the chain
/// that starts from the sample.
pub(super) struct BootstrapSource {
    kind: SamplerKind,
    /// The sample's key: the render seed with the bootstrap's salt.
    key: u64,
    index: u64,
    current: StreamSource,
    stream: usize,
    position: usize,
    recorded: Option<Vec<Vec<f32>>>,
}

impl BootstrapSource {
    pub(super) fn new(kind: SamplerKind, seed: u64, index: u64, record: bool) -> BootstrapSource {
        Self::keyed(kind, seed ^ BOOTSTRAP_SEED_SALT, index, record)
    }

    /// Sample `index` of replicate `replicate` of depth 0's own estimate (`Mlt::direct_sample`):
    /// streams keyed apart from the full bootstrap's and from the other replicates', so each
    /// replicate is an independently scrambled Sobol sequence (or independent numbers).
    pub(super) fn direct_replicate(kind: SamplerKind, seed: u64, replicate: usize, index: u64) -> BootstrapSource {
        let key = seed ^ DIRECT_SEED_SALT ^ ((replicate as u64 + 1) << 40);
        Self::keyed(kind, key, index, false)
    }

    fn keyed(kind: SamplerKind, key: u64, index: u64, record: bool) -> BootstrapSource {
        let current = Self::stream_source(kind, key, index, 0);
        let recorded = record.then(|| vec![Vec::new(); STREAM_COUNT]);
        BootstrapSource { kind, key, index, current, stream: 0, position: 0, recorded }
    }

    fn stream_source(kind: SamplerKind, key: u64, index: u64, stream: usize) -> StreamSource {
        match kind {
            SamplerKind::Independent => {
                StreamSource::Independent(Rng::new(key, index * STREAM_COUNT as u64 + stream as u64))
            }
            SamplerKind::Sobol => StreamSource::Sobol(SobolStream::of_sequence(key, stream as u32, index)),
        }
    }

    fn record(&mut self, value: f32) {
        if let Some(streams) = self.recorded.as_mut() {
            let values = &mut streams[self.stream];
            if self.position < values.len() {
                // A restarted stream reads the same numbers again.
                values[self.position] = value;
            } else {
                values.push(value);
            }
        }
        self.position += 1;
    }

    /// The numbers read so far, per stream in reading order (empty without `record`).
    pub(super) fn recorded(&self) -> &[Vec<f32>] {
        self.recorded.as_deref().unwrap_or(&[])
    }
}

impl UniformSource for BootstrapSource {
    fn next_1d(&mut self) -> f32 {
        let v = match &mut self.current {
            StreamSource::Independent(rng) => rng.uniform(),
            StreamSource::Sobol(s) => s.next_1d(),
        };
        self.record(v);
        v
    }

    fn next_n<const N: usize>(&mut self) -> [f32; N] {
        // Sobol reads a block from one stratified set (`SobolStream::next_n`); the chain replays
        // the numbers one by one in the same order.
        let u: [f32; N] = match &mut self.current {
            StreamSource::Independent(rng) => rng.next_n(),
            StreamSource::Sobol(s) => s.next_n(),
        };
        for v in u {
            self.record(v);
        }
        u
    }
}

impl PrimarySource for BootstrapSource {
    fn start_stream(&mut self, stream: usize) {
        self.current = Self::stream_source(self.kind, self.key, self.index, stream);
        self.stream = stream;
        self.position = 0;
    }
}

/// A technique's MMLT target, lum(w_{s,t} C_{s,t}) (Eq. 20), as `Mlt::evaluate` computes it: 0 for a
/// non-finite contribution (counted as dropped) or a non-positive luminance.
pub(super) fn technique_target(c: &TechniqueSample, counters: &mut Counters) -> f32 {
    let value = c.weighted();
    if !is_finite(value) {
        counters.nonfinite_dropped += 1;
        return 0.0;
    }
    let target = luminance(value);
    if target.is_finite() && target > 0.0 {
        target
    } else {
        0.0
    }
}

impl Mlt {
    /// Bootstrap sample `index`: pushes one target per depth slot to `out`. PSSMLT: the state's
    /// target (all techniques of its subpaths, Alg. 1). MMLT and RJMLT: per depth d the full BDPT
    /// sample's B_d = (1/n_d)·Σ_s lum(w_{s,t} C_{s,t}) (module docs), whose mean is b_d, and then
    /// per depth Q_d = (1/n_d)·Σ_s lum(w_{s,t} C_{s,t})², whose mean is the second moment of one
    /// large step's target (s uniform, ū uniform): what pooling b_d with the large steps weighs
    /// them by (`mlt::BEstimate`).
    pub(super) fn bootstrap_sample(
        &self,
        ctx: &BdptContext,
        seed: u64,
        index: u64,
        slot: &mut SlotState,
        counters: &mut Counters,
        out: &mut Vec<f32>,
    ) {
        let mut source = BootstrapSource::new(self.settings.bootstrap_sampler, seed, index, false);
        if self.variant == MltVariant::Pssmlt {
            out.push(self.evaluate(ctx, 0, &mut source, None, slot, counters).target);
            return;
        }
        let depths = self.depth_count();
        let first = out.len();
        out.resize(first + 2 * depths, 0.0);
        self.for_each_technique(ctx, &mut source, 0, depths - 1, slot, counters, |d, _, target| {
            out[first + d] += target;
            out[first + depths + d] += target * target;
        });
        for d in 0..depths {
            let n = self.technique_count(d) as f32;
            out[first + d] /= n;
            out[first + depths + d] /= n;
        }
    }

    /// MMLT and RJMLT: sample `index` of replicate `replicate` of depth 0's own estimate of b_0,
    /// the emitters seen directly: a camera ray and its emission (the one technique s = 0, t = 2,
    /// as a depth-0 state evaluates it), from streams of the replicate's own (module docs of
    /// `mlt`, "Depth 0's replicates").
    pub(super) fn direct_sample(
        &self,
        ctx: &BdptContext,
        seed: u64,
        replicate: usize,
        index: u64,
        slot: &mut SlotState,
        counters: &mut Counters,
    ) -> f32 {
        let mut source = BootstrapSource::direct_replicate(self.settings.bootstrap_sampler, seed, replicate, index);
        self.evaluate(ctx, 0, &mut source, Some(0), slot, counters).target
    }

    /// Generates the bootstrap sample's subpaths for depths up to `top` (a camera subpath of
    /// top + 2 vertices, a light subpath of top + 1) and calls `sink(d, s, target)` for every
    /// technique of the depths `bottom ..= top` that the subpaths reach, the connection stream read
    /// from its start for each (as a chain state's one technique reads it).
    #[allow(clippy::too_many_arguments)]
    fn for_each_technique(
        &self,
        ctx: &BdptContext,
        source: &mut BootstrapSource,
        bottom: usize,
        top: usize,
        slot: &mut SlotState,
        counters: &mut Counters,
        mut sink: impl FnMut(usize, usize, f32),
    ) {
        source.start_stream(CAMERA_STREAM);
        let raster = generate_camera_subpath(ctx, FilmRegion::WholeFilm, source, top + 2, &mut slot.camera, counters);
        source.start_stream(LIGHT_STREAM);
        generate_light_subpath(ctx, source, top + 1, &mut slot.light, counters);
        for d in bottom..=top {
            for s in 0..self.technique_count(d) {
                let t = d + 2 - s;
                if slot.camera.len() < t || slot.light.len() < s {
                    continue;
                }
                source.start_stream(CONNECTION_STREAM);
                let light = &slot.light;
                let camera = &slot.camera;
                if let Some(c) =
                    evaluate_technique(ctx, light, camera, s, t, raster, source, &mut slot.scratch, counters, None)
                {
                    let target = technique_target(&c, counters);
                    if target > 0.0 {
                        sink(d, s, target);
                    }
                }
            }
        }
    }

    /// The state a chain of depth slot `d` starts from, given bootstrap sample `index` (chosen
    /// ∝ its target): MMLT and RJMLT choose the technique s ∝ its target with `u_technique` and
    /// draw u_t within s's interval with `u_within` (module docs); PSSMLT takes the sample's
    /// state. The numbers the sample read are installed in a fresh sampler drawing its mutations
    /// from `mutations`, and the state is evaluated from them. Returns the sub-chain and the
    /// bootstrap's target for the chosen state (which the state's own target reproduces).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn start_state(
        &self,
        ctx: &BdptContext,
        seed: u64,
        d: usize,
        index: u64,
        u_technique: f32,
        u_within: f32,
        mutations: Rng,
        slot: &mut SlotState,
        counters: &mut Counters,
    ) -> (SubChain, f32) {
        let mut source = BootstrapSource::new(self.settings.bootstrap_sampler, seed, index, true);
        let n = self.technique_count(d);
        let (s, expected) = if self.variant == MltVariant::Pssmlt {
            (0, self.evaluate(ctx, 0, &mut source, None, slot, counters).target)
        } else {
            let mut targets = vec![0.0f32; n];
            self.for_each_technique(ctx, &mut source, d, d, slot, counters, |_, s, target| targets[s] = target);
            let total: f32 = targets.iter().sum();
            let mut u = u_technique * total;
            let mut chosen = 0;
            for (s, &w) in targets.iter().enumerate() {
                if w > 0.0 {
                    chosen = s;
                    if u < w {
                        break;
                    }
                    u -= w;
                }
            }
            (chosen, targets[chosen])
        };
        let mut sampler = PssSampler::new(mutations, self.mutation(), STREAM_COUNT);
        sampler.start_iteration_with(true);
        for (stream, values) in source.recorded().iter().enumerate() {
            for (position, &value) in values.iter().enumerate() {
                sampler.put(stream, position, value);
            }
        }
        if self.variant != MltVariant::Pssmlt {
            sampler.put(TECHNIQUE_STREAM, 0, technique_coordinate(s, n, u_within));
        }
        let current: PathState = self.evaluate(ctx, d, &mut sampler, None, slot, counters);
        sampler.accept();
        (SubChain { sampler, current }, expected)
    }
}

/// A technique-stream value u_t that selects technique `s` of `n` (s = ⌊n·u_t⌋, `Mlt::evaluate`),
/// uniform within its interval by `u`; the interval's midpoint if rounding would leave it.
fn technique_coordinate(s: usize, n: usize, u: f32) -> f32 {
    let selects = |v: f32| (0.0..1.0).contains(&v) && ((v * n as f32) as usize).min(n - 1) == s;
    let v = (s as f32 + u) / n as f32;
    if selects(v) {
        v
    } else {
        (s as f32 + 0.5) / n as f32
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::integrator::pss::mlt_settings::MltSettings;

    fn load(name: &str) -> crate::scene::Scene {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(format!("{name}.toml"));
        crate::scene::load_scene(&file, None).expect("scene").scene
    }

    /// Every u_t the start installs selects its technique, at the ends of the interval too.
    #[test]
    fn technique_coordinates_select_their_technique() {
        for n in 1..40 {
            for s in 0..n {
                for u in [0.0, 1e-7, 0.5, 1.0 - f32::EPSILON, 0.999_999_9] {
                    let v = technique_coordinate(s, n, u);
                    assert!((0.0..1.0).contains(&v) && ((v * n as f32) as usize).min(n - 1) == s, "{s}/{n} at {u}");
                }
            }
        }
    }

    /// A chain's start state is the bootstrap sample's technique it was chosen for: replayed from
    /// the numbers the sample read, with a u_t selecting the chosen s, the state's own target
    /// (`Mlt::evaluate`, what the chain's acceptance divides by) equals the target the bootstrap
    /// weighed it with, lum(w_{s,t} C_{s,t}) within the full BDPT sample (module docs). This is
    /// what makes the start ∝ the MMLT target rather than ∝ some other weight: it holds only if
    /// every technique reads the connection stream from its start, a shorter subpath reads a
    /// prefix of the longer one's numbers, and the MIS weight of (s, t) does not depend on the
    /// vertices beyond s and t. Checked for MMLT and RJMLT, both samplers, every depth up to 10 and
    /// every technique of 60 samples per depth (chosen by sweeping u_technique), on a diffuse, a
    /// glossy and a specular (glass) scene; the bootstrap sample's B_d must also be the mean of the
    /// depth's technique targets. Wrong variant (measured, then reverted): the connection stream
    /// read on across techniques, as BDPT's `connect_all` reads it, fails at the first sample
    /// (Cornell box, depth 2: B_d 0.006315 against its techniques' 0.006555 as a state reads them).
    #[test]
    fn start_states_reproduce_their_bootstrap_targets() {
        let (mut checked, mut per_technique) = (0u32, std::collections::BTreeSet::new());
        for name in ["cornell-box", "cornell-glossy", "cornell-glass"] {
            let scene = load(name);
            for variant in [MltVariant::Mmlt, MltVariant::Rjmlt] {
                for sampler in [SamplerKind::Sobol, SamplerKind::Independent] {
                    let settings = MltSettings { max_depth: 10, bootstrap_sampler: sampler, ..MltSettings::default() };
                    let mlt = Mlt { variant, settings };
                    let ctx = BdptContext::new(&scene, usize::MAX, mlt.settings.mis);
                    let mut slot = mlt.new_slot(0, 0);
                    let mut counters = Counters::default();
                    for index in 0..60u64 {
                        let mut b = Vec::new();
                        mlt.bootstrap_sample(&ctx, 7, index, &mut slot, &mut counters, &mut b);
                        assert_eq!(b.len(), 2 * mlt.depth_count());
                        for (d, &b_d) in b[..mlt.depth_count()].iter().enumerate() {
                            let n = mlt.technique_count(d);
                            // The depth's techniques from subpaths generated for depth d only.
                            let mut targets = vec![0.0f32; n];
                            let mut source = BootstrapSource::new(sampler, 7, index, false);
                            mlt.for_each_technique(&ctx, &mut source, d, d, &mut slot, &mut counters, |_, s, w| {
                                targets[s] = w
                            });
                            let mean = targets.iter().map(|&w| w as f64).sum::<f64>() / n as f64;
                            assert!(
                                (mean - b_d as f64).abs() <= 1e-6 * mean.max(1e-30),
                                "{name} {variant:?} sample {index} depth {d}: B_d {b_d} vs the techniques' mean {mean}"
                            );
                            let total: f32 = targets.iter().sum();
                            let mut before = 0.0f32;
                            for (s, &w) in targets.iter().enumerate() {
                                if w > 0.0 {
                                    // A u_technique inside s's share of the cumulative weights.
                                    let u = (before + 0.5 * w) / total;
                                    let mutations = Rng::new(1, index);
                                    let (chain, expected) = mlt.start_state(
                                        &ctx,
                                        7,
                                        d,
                                        index,
                                        u,
                                        0.37,
                                        mutations,
                                        &mut slot,
                                        &mut counters,
                                    );
                                    let got = chain.current.target;
                                    assert_eq!((chain.current.s, expected), (s, w), "{name} {variant:?} depth {d}");
                                    assert!(
                                        (got - w).abs() <= 1e-5 * w,
                                        "{name} {variant:?} {sampler:?} sample {index} depth {d} s {s}: state target \
                                         {got}, bootstrap's {w}"
                                    );
                                    checked += 1;
                                    per_technique.insert((d, s));
                                }
                                before += w;
                            }
                        }
                    }
                }
            }
        }
        println!("{checked} start states checked, {} techniques (d, s)", per_technique.len());
        assert!(checked > 8000, "only {checked} non-zero start states");
        // Every technique of every depth, light tracing (t = 1) included, was a start somewhere,
        // except s = 0 beyond depth 0 (a camera subpath that hits the small lamp after bouncing).
        let missing: Vec<(usize, usize)> = (0..=10usize)
            .flat_map(|d| (0..if d == 0 { 1 } else { d + 2 }).map(move |s| (d, s)))
            .filter(|ds| !per_technique.contains(ds))
            .collect();
        println!("techniques never a start: {missing:?}");
        assert!(missing.iter().all(|&(d, s)| s == 0 && d >= 1), "{missing:?}");
    }
}
