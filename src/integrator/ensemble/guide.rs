//! The complementary ensemble as the guided strategies see it: Y's paths with their tree, the
//! subset Υ of a path, its film spread b_res and α (Sec. 3.1 and 3.4), and the statistics of the
//! guided strategies (guided vs fallback proposals, time in similarity).

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::emlt_settings::EmltSettings;
use super::similarity::{inverse_length2, place, places_similarity, Place};
use super::tree::EnsembleTree;
use crate::integrator::path_space::PathState;

/// Counts of one guided strategy, summed over threads (atomics: sums do not depend on the order,
/// and nothing the image depends on reads them).
#[derive(Debug, Default)]
pub struct GuideCounts {
    /// Proposals made with a guide from Υ.
    pub guided: AtomicU64,
    /// Proposals made by the plain perturbation because |Υ| < 2 (Sec. 3.4).
    pub fallback: AtomicU64,
    /// Proposals rejected because their signature changed (so Υ would differ for the reverse).
    pub signature_changed: AtomicU64,
    /// Nanoseconds spent computing similarity weights (Eq. 8–9).
    pub similarity_ns: AtomicU64,
    /// α of the guided linear proposals (Sec. 3.4): their count, the sum of α in units of 1e-9,
    /// and a histogram over the position of α between α_s and α_l in fifths (the first bin α_s,
    /// the last α_l).
    pub alpha_proposals: AtomicU64,
    pub alpha_nano_sum: AtomicU64,
    pub alpha_bins: [AtomicU64; ALPHA_BINS],
}

/// Bins of `GuideCounts::alpha_bins`.
pub const ALPHA_BINS: usize = 5;

/// The plain-number copy of [`GuideCounts`] for the JSON report and render states.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct GuideReport {
    pub name: String,
    pub guided: u64,
    pub fallback: u64,
    pub signature_changed: u64,
    pub similarity_seconds: f64,
    /// Guided linear proposals and their mean α (0 when none).
    pub alpha_proposals: u64,
    pub alpha_mean: f64,
    /// Proposals by where α is between α_s (first bin) and α_l (last) in fifths.
    pub alpha_histogram: [u64; ALPHA_BINS],
}

impl GuideReport {
    /// Adds another shard's or session's counts of the same strategy (α's mean weighted by the
    /// proposals).
    pub fn absorb(&mut self, other: &GuideReport) {
        let alpha_sum = self.alpha_mean * self.alpha_proposals as f64 + other.alpha_mean * other.alpha_proposals as f64;
        self.guided += other.guided;
        self.fallback += other.fallback;
        self.signature_changed += other.signature_changed;
        self.similarity_seconds += other.similarity_seconds;
        self.alpha_proposals += other.alpha_proposals;
        self.alpha_mean = alpha_sum / self.alpha_proposals.max(1) as f64;
        for (bin, n) in self.alpha_histogram.iter_mut().zip(other.alpha_histogram) {
            *bin += n;
        }
    }
}

impl GuideCounts {
    pub fn report(&self, name: &str) -> GuideReport {
        GuideReport {
            name: name.to_string(),
            guided: self.guided.load(Ordering::Relaxed),
            fallback: self.fallback.load(Ordering::Relaxed),
            signature_changed: self.signature_changed.load(Ordering::Relaxed),
            similarity_seconds: self.similarity_ns.load(Ordering::Relaxed) as f64 * 1e-9,
            alpha_proposals: self.alpha_proposals.load(Ordering::Relaxed),
            alpha_mean: self.alpha_nano_sum.load(Ordering::Relaxed) as f64 * 1e-9
                / self.alpha_proposals.load(Ordering::Relaxed).max(1) as f64,
            alpha_histogram: std::array::from_fn(|b| self.alpha_bins[b].load(Ordering::Relaxed)),
        }
    }

    /// Counts α of one guided linear proposal (Sec. 3.4) for the report.
    pub fn count_alpha(&self, alpha: f64, settings: &EmltSettings) {
        let span = settings.alpha_large - settings.alpha_small;
        let t = if span != 0.0 { (alpha - settings.alpha_small) / span } else { 0.0 };
        // `as` saturates: below α_s to the first bin, beyond α_l to the last.
        let bin = ((t * ALPHA_BINS as f64) as usize).min(ALPHA_BINS - 1);
        self.alpha_proposals.fetch_add(1, Ordering::Relaxed);
        self.alpha_nano_sum.fetch_add((alpha * 1e9).round() as u64, Ordering::Relaxed);
        self.alpha_bins[bin].fetch_add(1, Ordering::Relaxed);
    }

    pub fn add(&self, other: &GuideReport) {
        self.guided.fetch_add(other.guided, Ordering::Relaxed);
        self.fallback.fetch_add(other.fallback, Ordering::Relaxed);
        self.signature_changed.fetch_add(other.signature_changed, Ordering::Relaxed);
        self.similarity_ns.fetch_add((other.similarity_seconds * 1e9) as u64, Ordering::Relaxed);
        self.alpha_proposals.fetch_add(other.alpha_proposals, Ordering::Relaxed);
        let sum = other.alpha_mean * other.alpha_proposals as f64;
        self.alpha_nano_sum.fetch_add((sum * 1e9).round() as u64, Ordering::Relaxed);
        for (bin, n) in self.alpha_bins.iter().zip(other.alpha_histogram) {
            bin.fetch_add(n, Ordering::Relaxed);
        }
    }
}

/// The complementary ensemble Y, fixed while X is updated (the paper's Sec. 3).
pub struct GuideView {
    /// Y's current paths, by their index in Y.
    pub paths: Vec<PathState>,
    pub tree: EnsembleTree,
    pub settings: EmltSettings,
    pub film: (f64, f64),
    /// Every path's vertex places for similarity (`similarity::place`), path after path: Eq. 9
    /// reads these instead of the paths' full vertices (a dense array, so a proposal's M guides
    /// cost M short reads rather than M scattered vertex records).
    places: Vec<Place>,
    /// Where each path's places start in `places` (one more entry than paths: the end).
    place_starts: Vec<u32>,
    /// This view's identity for the weight cache (views are numbered as they are made, so a cache
    /// entry of an earlier view never matches a later one at the same address).
    id: u64,
}

/// Views made so far (`GuideView::id`).
static VIEWS: AtomicU64 = AtomicU64::new(0);

/// The weights of one `GuideView::weights` call with everything they depend on (module
/// `GuideView::weights` docs).
struct CachedWeights {
    view: u64,
    j: usize,
    k: usize,
    subset: Vec<u32>,
    /// The bits of x's places j ..= k.
    x_places: Vec<[u64; 4]>,
    /// The bits of x's 1/L² (`similarity` module docs), which depends on all of x's vertices.
    inv_l2: Option<u64>,
    weights: Rc<Vec<f64>>,
}

/// The last few weight vectors computed on this thread (a Metropolis step computes the weights at
/// x̄ for the proposal and again for T(x̄ → ȳ), and the anisotropic kernels fit twice per step).
#[derive(Default)]
struct WeightCache {
    entries: Vec<CachedWeights>,
    next: usize,
}

/// Entries of the weight cache: a step's proposal and both densities use at most four weight
/// vectors (the anisotropic path perturbation: film and vertex fits at x̄, the same at ȳ).
const WEIGHT_CACHE_ENTRIES: usize = 4;

thread_local! {
    static WEIGHT_CACHE: RefCell<WeightCache> = RefCell::new(WeightCache::default());
}

fn place_bits(p: Place) -> [u64; 4] {
    let [x, y, z] = p.p.to_array().map(f64::to_bits);
    [x, y, z, p.infinite as u64]
}

impl GuideView {
    pub fn new(paths: Vec<PathState>, settings: &EmltSettings, width: u32, height: u32) -> GuideView {
        let refs: Vec<&PathState> = paths.iter().collect();
        let tree = EnsembleTree::build(&refs);
        let mut places = Vec::with_capacity(paths.iter().map(|p| p.len()).sum());
        let mut place_starts = Vec::with_capacity(paths.len() + 1);
        for p in &paths {
            place_starts.push(places.len() as u32);
            places.extend(p.vertices.iter().map(place));
        }
        place_starts.push(places.len() as u32);
        GuideView {
            paths,
            tree,
            settings: settings.clone(),
            film: (width as f64, height as f64),
            places,
            place_starts,
            id: VIEWS.fetch_add(1, Ordering::Relaxed),
        }
    }

    /// Υ of `path` for the offset a proposal drew (`tree` module docs).
    pub fn subset(&self, path: &PathState, offset: u64) -> Vec<u32> {
        self.tree.subset(path, offset, self.settings.subset_size as usize)
    }

    /// b_res of Υ: the area of the bounding box of its members' raster positions over the film's
    /// (Sec. 3.4, "a ratio of the bounding box … to the image plane resolution").
    pub fn b_res(&self, subset: &[u32]) -> f64 {
        let mut lo = glam::DVec2::splat(f64::INFINITY);
        let mut hi = glam::DVec2::splat(f64::NEG_INFINITY);
        for &i in subset {
            let r = self.paths[i as usize].raster.as_dvec2();
            lo = lo.min(r);
            hi = hi.max(r);
        }
        let extent = (hi - lo).max(glam::DVec2::ZERO);
        (extent.x * extent.y) / (self.film.0 * self.film.1)
    }

    /// α of the linear kernels for Υ (Sec. 3.4, `EmltSettings::alpha`).
    pub fn alpha(&self, subset: &[u32]) -> f64 {
        self.settings.alpha(self.b_res(subset))
    }

    /// The places of Y's path `i`.
    fn places_of(&self, i: u32) -> &[Place] {
        let i = i as usize;
        &self.places[self.place_starts[i] as usize..self.place_starts[i + 1] as usize]
    }

    /// The similarity weights S(x̄, v̄, j, k) (Eq. 9) of Υ's members (0 for a path shorter than
    /// k + 1 vertices), timed into `counts` when computed.
    ///
    /// They depend only on this view, Υ, j, k and x's places j ..= k, so a call with the same
    /// inputs on the same thread returns the vector computed before (`WeightCache`: the forward
    /// density T(x̄ → ȳ) refits at x̄ with the proposal's weights); equal inputs give equal weights
    /// to the bit either way, so the cache changes no statistic.
    pub fn weights(&self, x: &PathState, subset: &[u32], j: usize, k: usize, counts: &GuideCounts) -> Rc<Vec<f64>> {
        if k >= x.len() {
            return Rc::new(vec![0.0; subset.len()]);
        }
        let x_places = &x.vertices[j..=k];
        // x̄'s own L (Eq. 8 normalised, `similarity` module docs): the reverse weights w(v | ȳ)
        // are computed from ȳ and so with ȳ's L.
        let inv_l2 = inverse_length2(&x.vertices);
        let inv_l2_bits = inv_l2.map(f64::to_bits);
        let matches = |e: &CachedWeights| {
            e.view == self.id
                && e.j == j
                && e.k == k
                && e.inv_l2 == inv_l2_bits
                && e.subset == subset
                && e.x_places.iter().zip(x_places).all(|(a, b)| *a == place_bits(place(b)))
        };
        WEIGHT_CACHE.with(|cache| {
            let mut cache = cache.borrow_mut();
            if let Some(hit) = cache.entries.iter().find(|e| matches(e)) {
                return hit.weights.clone();
            }
            let start = Instant::now();
            let xp: Vec<Place> = x_places.iter().map(place).collect();
            let fill = |w: &mut Vec<f64>| {
                w.clear();
                w.extend(subset.iter().map(|&i| {
                    let v = self.places_of(i);
                    if k >= v.len() {
                        0.0
                    } else {
                        places_similarity(&xp, &v[j..=k], inv_l2)
                    }
                }));
            };
            let entry = if cache.entries.len() < WEIGHT_CACHE_ENTRIES {
                let mut w = Vec::with_capacity(subset.len());
                fill(&mut w);
                cache.entries.push(CachedWeights {
                    view: self.id,
                    j,
                    k,
                    subset: subset.to_vec(),
                    x_places: Vec::new(),
                    inv_l2: inv_l2_bits,
                    weights: Rc::new(w),
                });
                cache.entries.len() - 1
            } else {
                let at = cache.next;
                cache.next = (at + 1) % WEIGHT_CACHE_ENTRIES;
                let e = &mut cache.entries[at];
                // Reuse the evicted entry's buffer unless a caller still holds it.
                match Rc::get_mut(&mut e.weights) {
                    Some(w) => fill(w),
                    None => {
                        let mut w = Vec::with_capacity(subset.len());
                        fill(&mut w);
                        e.weights = Rc::new(w);
                    }
                }
                e.view = self.id;
                e.j = j;
                e.k = k;
                e.inv_l2 = inv_l2_bits;
                e.subset.clear();
                e.subset.extend_from_slice(subset);
                at
            };
            let e = &mut cache.entries[entry];
            e.x_places.clear();
            e.x_places.extend(xp.iter().map(|&p| place_bits(p)));
            counts.similarity_ns.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
            e.weights.clone()
        })
    }
}

/// The index chosen ∝ `weights` with the uniform `u`, and its probability; None when all are 0.
pub fn choose_weighted(weights: &[f64], u: f64) -> Option<(usize, f64)> {
    let total: f64 = weights.iter().sum();
    if !(total > 0.0) || !total.is_finite() {
        return None;
    }
    let mut target = u * total;
    let mut last = None;
    for (i, &w) in weights.iter().enumerate() {
        if w > 0.0 {
            last = Some(i);
            if target < w {
                return Some((i, w / total));
            }
            target -= w;
        }
    }
    last.map(|i| (i, weights[i] / total))
}

/// The index of the largest weight (the first on ties), if any is positive.
pub fn best_match(weights: &[f64]) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (i, &w) in weights.iter().enumerate() {
        if w > 0.0 && best.is_none_or(|b| w > weights[b]) {
            best = Some(i);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec3};

    use super::*;
    use crate::integrator::bdpt::Vertex;
    use crate::integrator::ensemble::tree::morton;
    use crate::integrator::path_space::{Interaction, PathVertex};
    use crate::spectrum::Rgb;

    /// A path of the vertex types `types`, every vertex at the origin, f = 1.
    fn signature_path(types: &[Interaction]) -> PathState {
        let v = Vertex::camera(Vec3::ZERO, Rgb::ONE);
        PathState {
            vertices: types.iter().map(|&interaction| PathVertex { vertex: v, interaction }).collect(),
            f_star: 1.0,
            ..PathState::default()
        }
    }

    /// A deterministic stream of numbers in [0, 1) for the test's paths.
    struct Stream(u64);

    impl Stream {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 40) as f32) / (1u64 << 24) as f32
        }
    }

    fn vertex(p: Vec3, interaction: Interaction) -> PathVertex {
        PathVertex { vertex: Vertex::camera(p, Rgb::ONE), interaction }
    }

    /// Camera → back wall → floor → the environment, in a room of about half a metre (the Cornell
    /// box in metres), every position times `scale`.
    fn room_path(s: &mut Stream, scale: f32) -> PathState {
        let camera = Vec3::new(0.278, 0.273, -0.8);
        let wall = Vec3::new(0.556 * s.next(), 0.549 * s.next(), 0.559);
        let floor = Vec3::new(0.556 * s.next(), 0.0, 0.559 * s.next());
        let mut sky = vertex(Vec3::ZERO, Interaction::Emitter);
        sky.vertex.infinite = true;
        sky.vertex.dir = Vec3::new(s.next() - 0.5, 1.0, s.next() - 0.5).normalize();
        let mut vertices: Vec<PathVertex> = [camera, wall, floor]
            .into_iter()
            .zip([Interaction::Camera, Interaction::Diffuse, Interaction::Diffuse])
            .map(|(p, i)| vertex(p * scale, i))
            .collect();
        vertices.push(sky);
        PathState { vertices, raster: Vec2::new(64.0 * s.next(), 64.0 * s.next()), f_star: 1.0, ..PathState::default() }
    }

    /// The weights S(x̄, v̄, j, k) of Υ (a whole bucket of 32 guides: the first a copy of x̄ moved by
    /// 2 mm, the others anywhere in the room) for the vertex ranges the guided perturbations use,
    /// in the room scaled by `scale`.
    fn room_weights(scale: f32) -> Vec<Vec<f64>> {
        let mut s = Stream(7);
        let x = room_path(&mut s, scale);
        let mut near = x.clone();
        for v in near.vertices.iter_mut().skip(1).filter(|v| !v.vertex.infinite) {
            v.vertex.p += Vec3::splat(0.002 * scale);
        }
        let guides: Vec<PathState> = std::iter::once(near).chain((1..32).map(|_| room_path(&mut s, scale))).collect();
        let view = GuideView::new(guides, &EmltSettings::default(), 64, 64);
        let subset = view.subset(&x, 0);
        assert_eq!(subset.len(), 32);
        let counts = GuideCounts::default();
        // By guide (Υ is in the bucket's order, `tree` module docs).
        let by_guide = |w: &[f64]| {
            let mut out = vec![0.0; w.len()];
            for (&i, &wi) in subset.iter().zip(w) {
                out[i as usize] = wi;
            }
            out
        };
        RANGES.iter().map(|&(j, k)| by_guide(&view.weights(&x, &subset, j, k, &counts))).collect()
    }

    /// Vertex ranges of Eq. 9 the guided perturbations weigh with: the linear lens (0 ..= 1), the
    /// anisotropic kernels and the caustic (pairs), the environment (2 ..= 3), a whole path.
    const RANGES: [(usize, usize); 5] = [(0, 1), (1, 2), (2, 3), (0, 2), (0, 3)];

    /// Eq. 8 with L (module docs) does not depend on the unit of length: the same room, path and
    /// guides in metres, millimetres and 1/1024 of a metre give the same weights (to the f32
    /// rounding of the vertices). And S still discriminates: in every range the guide next to x̄ has
    /// the largest selection weight, more than 1.03 times the smallest and 1.5 times over the whole
    /// path (measured 1.056 for the linear lens's vertices 0 ..= 1, 1.68 for 0 ..= 3: at the
    /// paper's scale guides across a room of about L are still fairly similar, S = tanh(1/2) at
    /// distance L), which a constant S fails.
    #[test]
    fn similarity_is_unchanged_by_the_unit_of_length_and_discriminates() {
        let metres = room_weights(1.0);
        for scale in [1000.0, 1.0 / 1024.0] {
            for (a, b) in metres.iter().zip(&room_weights(scale)) {
                for (&wa, &wb) in a.iter().zip(b) {
                    assert!((wa - wb).abs() <= 1e-5 * wa.abs().max(1e-12), "scale {scale}: {wa} vs {wb}");
                }
            }
        }
        for (&(j, k), w) in RANGES.iter().zip(&metres) {
            let total: f64 = w.iter().sum();
            let p: Vec<f64> = w.iter().map(|x| x / total).collect();
            let lo = p.iter().copied().fold(f64::INFINITY, f64::min);
            let best = best_match(&p);
            let least = if (j, k) == (0, 3) { 1.5 } else { 1.03 };
            assert!(best == Some(0) && p[0] > least * lo, "vertices {j}..={k}: selection weights {p:?}");
        }
    }

    /// Υ as Sec. 3.4's α needs it: a bucket of 2,048 paths spread uniformly over a 128×128 film,
    /// ordered along the Morton curve, gives slices of M = 32 that are compact patches, so b_res
    /// is mostly below c and α near α_l; in the order of Y's indices every slice spans the film
    /// (b_res ≈ 0.9) and α is α_s. Υ stays the same for any path of the signature.
    #[test]
    fn morton_order_makes_subsets_compact_and_moves_alpha() {
        use Interaction::*;
        let sig = [Camera, Diffuse, Emitter];
        let mut state = 11u64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        };
        let paths: Vec<PathState> = (0..2048)
            .map(|_| PathState { raster: glam::Vec2::new(128.0 * next(), 128.0 * next()), ..signature_path(&sig) })
            .collect();
        let codes: Vec<u64> = paths.iter().map(|p| morton(p.raster)).collect();
        let view = GuideView::new(paths, &EmltSettings::default(), 128, 128);
        let bucket = view.tree.bucket(&signature_path(&sig));
        assert_eq!(bucket.len(), 2048);
        assert!(bucket.windows(2).all(|w| codes[w[0] as usize] <= codes[w[1] as usize]), "not in Morton order");
        let (mut b_res, mut alpha) = (Vec::new(), Vec::new());
        for offset in (0..2048u64).step_by(7) {
            let subset = view.subset(&signature_path(&sig), offset);
            let elsewhere = PathState { raster: glam::Vec2::new(3.0, 120.0), ..signature_path(&sig) };
            assert_eq!(subset, view.subset(&elsewhere, offset), "Υ must not depend on the path's raster");
            b_res.push(view.b_res(&subset));
            alpha.push(view.alpha(&subset));
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let spread = b_res.iter().filter(|&&b| b > 0.1).count() as f64 / b_res.len() as f64;
        let (b_mid, a_mid) = (median(&mut b_res), median(&mut alpha));
        assert!(b_mid < 0.03 && spread < 0.1, "median b_res {b_mid}, share above c {spread}");
        assert!(a_mid > 0.45, "median α {a_mid}");
    }
}
