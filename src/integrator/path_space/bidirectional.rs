//! Veach's bidirectional mutation (Veach & Guibas 1997, Sec. 5.3; Veach's thesis Sec. 11.4.2):
//! delete a subpath, regrow it from both ends, connect. It changes the path's length and any
//! vertex, and deleting the whole path (all but the pinhole) regenerates it from scratch, which
//! makes the chain ergodic.
//!
//! # The move
//! Extend the path x_0 (pinhole) … x_{n−1} (emitter) by a "supernode" x_n behind the emitter (Veach's
//! and Mitsuba's convention), so that deleting the emitter vertex is deleting an edge like any
//! other: the extended path has K = n edges.
//! 1. Deletion: k_d ∈ [1, K] edges with p_d(k_d) ∝ 1/4, 1/2, 2^−k_d for k_d = 1, 2, ≥ 3 (Veach's
//!    thesis Sec. 11.4.2.1: short deletions favoured, removing one vertex most often), then the
//!    first kept vertex l uniform in [0, K − k_d]; m = l + k_d. Kept: x_0 … x_l and x_m … x_{n−1}
//!    (nothing of the emitter end when m = n). The pinhole is never deleted: its position is fixed.
//! 2. Addition: k_a edges, k_a − 1 new vertices, with p_a(k_a) ∝ 2^−|k_a − k_d| over the lengths
//!    that keep the new path between 2 and max_depth + 2 vertices (n′ = n − k_d + k_a), never
//!    k_d = k_a = 1 (that would reconnect the same vertices). Then the split: s′ uniform in
//!    [0, k_a − 1] new vertices grown from the emitter end (from x_m by its BSDF or emission, or from
//!    a new emitter sample when m = n) and t′ = k_a − 1 − s′ from the camera end (from x_l by its
//!    BSDF, or a uniform film position when l = 0), each by the sampler BDPT uses there.
//! 3. Connection: the two ends are joined by an edge that no sampling traced; f(ȳ) (visibility
//!    included) decides whether it carries light. With s′ = 0 and m = n the camera walk's last
//!    vertex must itself be on an emitter (BDPT's s = 0 technique).
//!
//! # The transition density
//! For x̄ → ȳ with kept prefix x_0 … x_l and kept suffix (Veach 1997, Sec. 5.3, and the thesis'
//! Eq. 11.5):
//!
//!   T(x̄ → ȳ) = p_d(k_d | n) · 1/(n − k_d + 1) · p_a(k_a | k_d, n) · Σ_{s′=0}^{k_a−1} (1/k_a) · p_{s′,t′}(z_1 … z_{k_a−1})
//!
//! where p_{s′,t′} is the product of the area densities of generating the new vertices z that way:
//! t′ of them from the camera side in order, s′ from the emitter side in order, zero if the split's
//! connection would end at a specular vertex. An emitter-side step through a refraction carries
//! the measure factor h = η_a² |cos θ_a| / (η_b² |cos θ_b|) of the `density` module docs (the
//! walk generates the camera-side direction, f strips the δ of the light-side one). The sum is over every split because ȳ does not
//! record which one produced it: all of them could have. The cut (l, k_d, k_a) is the proposal's
//! record (`Strategy::Move`), and the reverse density T(ȳ → x̄) is the same function for the
//! reverse cut (l, k_a, k_d): the deleted vertices of x̄ are the "new" ones of the reverse move.
//! The cut cannot be read off the two paths: a walk through a specular vertex regenerates the next
//! vertex bit for bit, so a longer cut can give the same ȳ as a shorter one, and pairing each cut
//! with its own reverse is what keeps detailed balance. The densities are in the delta-stripped measure of the module docs;
//! every edge a walk traced carries its G in both f and T, so in f(ȳ)/T(x̄→ȳ) only the connection
//! edge's G remains, as in BDPT's unweighted contribution C = f/p.
//!
//! Mitsuba 0.6's `mut_bidir.cpp` is the public reference for the conventions (its Q() sums the
//! splits' 1/luminance(f/p), the same sum written as f/T); its length distributions differ (a
//! desired total length, then the deletion), ours are Veach's.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN densities along with zero and negative ones.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::density::{
    density_emitted, density_emitter, density_next, sample_emitter, sample_next, trace_emitted, Side,
};
use super::path_state::{PathState, PathVertex};
use super::strategy::Strategy;
use super::PathContext;
use crate::integrator::bdpt::{Vertex, VertexKind};
use crate::sampling::Rng;
use crate::stats::Counters;

/// The bidirectional mutation's kernel: the deletion and addition length distributions.
#[derive(Clone, Copy, Debug, Default)]
pub struct LengthKernel;

impl LengthKernel {
    fn deletion_weight(kd: usize) -> f64 {
        match kd {
            1 => 0.25,
            2 => 0.5,
            k => 0.5f64.powi(k as i32),
        }
    }

    /// p_d(k_d | n): the probability of deleting k_d of the extended path's K = n edges.
    pub fn deletion_pmf(&self, kd: usize, n: usize) -> f64 {
        if kd == 0 || kd > n {
            return 0.0;
        }
        let total: f64 = (1..=n).map(Self::deletion_weight).sum();
        Self::deletion_weight(kd) / total
    }

    /// Draws k_d with `u`.
    pub fn sample_deletion(&self, n: usize, u: f64) -> usize {
        let total: f64 = (1..=n).map(Self::deletion_weight).sum();
        let mut target = u * total;
        for kd in 1..=n {
            let w = Self::deletion_weight(kd);
            if target < w {
                return kd;
            }
            target -= w;
        }
        n
    }

    /// The added edge counts allowed after deleting k_d of n vertices' K = n edges.
    fn addition_range(kd: usize, n: usize, max_vertices: usize) -> std::ops::RangeInclusive<usize> {
        let lo = (2 + kd).saturating_sub(n).max(if kd == 1 { 2 } else { 1 });
        let hi = (max_vertices + kd).saturating_sub(n);
        lo..=hi
    }

    fn addition_weight(ka: usize, kd: usize) -> f64 {
        0.5f64.powi((ka as i32 - kd as i32).abs())
    }

    /// p_a(k_a | k_d, n) for paths of at most `max_vertices` vertices.
    pub fn addition_pmf(&self, ka: usize, kd: usize, n: usize, max_vertices: usize) -> f64 {
        let range = Self::addition_range(kd, n, max_vertices);
        if !range.contains(&ka) {
            return 0.0;
        }
        let total: f64 = range.map(|j| Self::addition_weight(j, kd)).sum();
        Self::addition_weight(ka, kd) / total
    }

    /// Draws k_a with `u`; None when no length is allowed.
    pub fn sample_addition(&self, kd: usize, n: usize, max_vertices: usize, u: f64) -> Option<usize> {
        let range = Self::addition_range(kd, n, max_vertices);
        let total: f64 = range.clone().map(|j| Self::addition_weight(j, kd)).sum();
        if !(total > 0.0) {
            return None;
        }
        let mut target = u * total;
        let mut last = None;
        for ka in range {
            let w = Self::addition_weight(ka, kd);
            last = Some(ka);
            if target < w {
                return Some(ka);
            }
            target -= w;
        }
        last
    }
}

/// Veach's bidirectional mutation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct Bidirectional {
    /// Tests only: leave split `s′ = omit_split` out of the sum of `transition` (a deliberately
    /// wrong T, which the χ² test must reject).
    #[cfg(any(test, feature = "testing"))]
    pub omit_split: Option<usize>,
    /// Tests only: leave the addition-length probability out of T (a deliberately wrong T, which the
    /// path-length and agreement tests must reject).
    #[cfg(any(test, feature = "testing"))]
    pub omit_addition_pmf: bool,
    /// Tests only: leave the emitter-side walks' refraction measure factors h out of T (`density`
    /// module docs), the deliberately wrong variant the agreement tests on scenes whose Π h ≠ 1
    /// must reject.
    #[cfg(any(test, feature = "testing"))]
    pub omit_refraction_measure: bool,
}

/// The change a bidirectional proposal made (its `Strategy::Move`): it kept x_0 … x_l, deleted
/// k_d edges (so the kept suffix starts at m = l + k_d; m = n: the emitter end was regrown from a
/// new emitter sample) and added k_a edges. The reverse change keeps the same vertices and swaps
/// k_d and k_a.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cut {
    pub l: usize,
    pub kd: usize,
    pub ka: usize,
}

/// `v` in the role of a vertex a walk continues from: the pinhole, an emitter point that starts an
/// emitter-side walk, or a surface that scatters.
fn as_role(v: &PathVertex, kind: VertexKind) -> Vertex {
    let mut v = v.vertex;
    v.kind = kind;
    v
}

impl Bidirectional {
    /// p_{s′,t′} of generating `y`'s new vertices (those between y_l and y_{m′}, m′ = l + k_a) with
    /// s′ from the emitter side and the rest from the camera side.
    pub fn split_density(ctx: &PathContext, y: &[PathVertex], cut: Cut, s: usize) -> f64 {
        let scene = ctx.scene;
        let n = y.len();
        let (l, ka) = (cut.l, cut.ka);
        let m = l + ka;
        let t = ka - 1 - s;
        // The connection: camera end y_{l+t}, emitter end y_{l+t+1} (none when the camera walk's
        // last vertex is the path's emitter: s′ = 0 and m = n).
        let c = &y[l + t];
        if c.vertex.infinite && l + t + 1 < n {
            return 0.0;
        }
        if l + t + 1 < n {
            if !c.connectible() || !y[l + t + 1].connectible() {
                return 0.0;
            }
        } else if c.vertex.light.is_none() {
            return 0.0;
        }
        let mut density = 1.0f64;
        // Camera side: y_{l+1} … y_{l+t}, each from its predecessor.
        for j in l + 1..=l + t {
            let from = &y[j - 1].vertex;
            let prev = (j >= 2).then(|| &y[j - 2].vertex);
            density *= density_next(scene, from, prev, &y[j].vertex, Side::Camera);
            if !(density > 0.0) {
                return 0.0;
            }
        }
        // Emitter side: y_{m−1} down to y_{l+t+1}.
        for (step, j) in (l + t + 1..m).rev().enumerate() {
            let next = &y[j].vertex;
            let d = if m == n {
                // A new emitter vertex (y_{n−1}), then its emitted ray, then BSDF samples.
                match step {
                    0 => density_emitter(scene, next),
                    1 => density_emitted(scene, &y[n - 1].vertex, next),
                    _ => density_next(scene, &y[j + 1].vertex, Some(&y[j + 2].vertex), next, Side::Light),
                }
            } else {
                let prev = (j + 2 < n).then(|| &y[j + 2].vertex);
                density_next(scene, &y[j + 1].vertex, prev, next, Side::Light)
            };
            density *= d;
            if !(density > 0.0) {
                return 0.0;
            }
        }
        density
    }

    /// Σ over the splits of (1/k_a) · p_{s′,t′}, every split but the wrong variant's `omit_split`.
    fn split_sum(&self, ctx: &PathContext, y: &[PathVertex], cut: Cut) -> f64 {
        #[cfg(any(test, feature = "testing"))]
        let omit = self.omit_split;
        #[cfg(not(any(test, feature = "testing")))]
        let omit: Option<usize> = None;
        let density = |s: usize| {
            #[allow(unused_mut)]
            let mut d = Self::split_density(ctx, y, cut, s);
            #[cfg(any(test, feature = "testing"))]
            if self.omit_refraction_measure && d > 0.0 {
                d /= Self::emitter_side_measure(ctx, y, cut, s);
            }
            d
        };
        (0..cut.ka).filter(|&s| Some(s) != omit).map(density).sum::<f64>() / cut.ka as f64
    }

    /// The wrong variant's divisor: Π h over the emitter-side steps of split s′ that continue
    /// from a surface vertex (those `split_density` takes from `density_next` with `Side::Light`).
    #[cfg(any(test, feature = "testing"))]
    fn emitter_side_measure(ctx: &PathContext, y: &[PathVertex], cut: Cut, s: usize) -> f64 {
        let (n, m) = (y.len(), cut.l + cut.ka);
        // y_j is generated from y_{j+1}, a surface exactly when j + 2 < n (else the emitter).
        (m - s..m)
            .filter(|&j| j + 2 < n)
            .map(|j| {
                super::density::light_step_measure_factor(ctx.scene, &y[j + 1].vertex, &y[j].vertex, &y[j + 2].vertex)
            })
            .product()
    }

    /// Grows `t` vertices from the camera end (`x_l` with its predecessor) and `s` from the emitter
    /// end (`x_m`, or a new emitter sample when m = n): the new vertices in path order, or None
    /// when a walk fails (a ray leaves the scene, a sample fails, or a camera walk meets the
    /// environment before its end).
    #[allow(clippy::too_many_arguments)]
    fn grow(
        ctx: &PathContext,
        x: &[PathVertex],
        l: usize,
        m: usize,
        t: usize,
        s: usize,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<Vec<Vertex>> {
        let scene = ctx.scene;
        let n = x.len();
        let mut camera: Vec<Vertex> = Vec::with_capacity(t);
        let mut cur = as_role(&x[l], if l == 0 { VertexKind::Camera } else { VertexKind::Surface });
        let mut prev = (l >= 1).then(|| as_role(&x[l - 1], VertexKind::Surface));
        for j in 0..t {
            let next = sample_next(scene, &cur, prev.as_ref(), Side::Camera, rng, counters)?;
            // Only the path's last vertex may be at infinity (the environment as its emitter).
            if next.infinite && !(j + 1 == t && s == 0 && m == n) {
                return None;
            }
            camera.push(next);
            prev = Some(cur);
            cur = next;
        }
        let mut light: Vec<Vertex> = Vec::with_capacity(s);
        if s > 0 {
            let (mut cur, mut prev) = if m == n {
                let (mut emitter, ray) = sample_emitter(scene, rng)?;
                emitter.kind = VertexKind::Light;
                light.push(emitter);
                if s == 1 {
                    return Some(camera.into_iter().chain(light.into_iter().rev()).collect());
                }
                let next = trace_emitted(scene, &ray, counters)?;
                light.push(next);
                (next, Some(emitter))
            } else {
                let kind = if m + 1 == n { VertexKind::Light } else { VertexKind::Surface };
                (as_role(&x[m], kind), (m + 1 < n).then(|| as_role(&x[m + 1], VertexKind::Surface)))
            };
            while light.len() < s {
                let next = sample_next(scene, &cur, prev.as_ref(), Side::Light, rng, counters)?;
                light.push(next);
                prev = Some(cur);
                cur = next;
            }
        }
        Some(camera.into_iter().chain(light.into_iter().rev()).collect())
    }
}

impl Strategy for Bidirectional {
    type Kernel = LengthKernel;
    type Move = Cut;

    fn name(&self) -> &'static str {
        "bidirectional"
    }

    /// Every path: the mutation can always delete and regrow.
    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        path.len() >= 2
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &LengthKernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, Cut)> {
        let x = &path.vertices;
        let n = x.len();
        let max_vertices = ctx.max_depth + 2;
        let kd = kernel.sample_deletion(n, rng.uniform_f64());
        let l = ((rng.uniform_f64() * (n - kd + 1) as f64) as usize).min(n - kd);
        let m = l + kd;
        let ka = kernel.sample_addition(kd, n, max_vertices, rng.uniform_f64())?;
        let s = ((rng.uniform_f64() * ka as f64) as usize).min(ka - 1);
        let t = ka - 1 - s;
        let new = Self::grow(ctx, x, l, m, t, s, rng, counters)?;
        let vertices: Vec<Vertex> =
            x[..=l].iter().map(|v| v.vertex).chain(new).chain(x[m.min(n)..].iter().map(|v| v.vertex)).collect();
        Some((PathState::new(ctx, &vertices, counters), Cut { l, kd, ka }))
    }

    fn transition(&self, ctx: &PathContext, kernel: &LengthKernel, from: &PathState, to: &PathState, cut: &Cut) -> f64 {
        let cut = *cut;
        let n = from.len();
        if cut.kd == 0 || cut.ka == 0 || cut.l + cut.kd > n || to.len() + cut.kd != n + cut.ka {
            return 0.0;
        }
        let max_vertices = ctx.max_depth + 2;
        let position = 1.0 / (n - cut.kd + 1) as f64;
        #[allow(unused_mut)]
        let mut addition = kernel.addition_pmf(cut.ka, cut.kd, n, max_vertices);
        #[cfg(any(test, feature = "testing"))]
        if self.omit_addition_pmf {
            addition = 1.0;
        }
        let t = kernel.deletion_pmf(cut.kd, n) * position * addition * self.split_sum(ctx, &to.vertices, cut);
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    fn reverse(&self, cut: &Cut) -> Cut {
        Cut { l: cut.l, kd: cut.ka, ka: cut.kd }
    }
}
