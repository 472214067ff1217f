//! The linear guided perturbations (the paper's Sec. 3.3): the linear lens, linear caustic and linear
//! multi-chain perturbations, each Veach's perturbation (`path_space::lens`, `path_space::caustic`,
//! `path_space::multichain`) with its isotropic kernel replaced by a linear kernel about a guide
//! from Υ, and the plain perturbation as the fallback when |Υ| < 2 (Sec. 3.4).
//!
//! # Guide choice is part of the kernel
//! - Linear lens: the guide v is drawn from Υ with weight w(v | x̄) = S(x̄, v, 0, k)/Σ S (Eq. 9, k the
//!   first non-specular vertex); the reverse move redoes the choice from ȳ, so T includes w(v | x̄)
//!   and the reverse T includes w(v | ȳ): their ratio is in the acceptance. The linear multi-chain
//!   perturbation chooses its guide the same way (`LinearMultiChain`).
//! - Linear caustic: the guide is Υ's best match to the pivot and the first specular vertex
//!   (S(x̄, v, j − 1, j)); T is 0 unless v is the best match of the path the move leaves, so a
//!   move to a ȳ whose best match is another path is rejected (its reverse could not choose v).
//!
//! # Υ is the same both ways
//! Υ depends on the path's signature and an offset the proposal draws from the chain's stream
//! independently of the path (`tree` module docs); the move records the offset, and a proposal
//! whose signature changed is rejected (`transition` returns 0), so the reverse move sees the same
//! Υ, the same α and the same branch (guided or fallback).
//!
//! # Densities
//! The linear kernels are singular (a move stays on a line or great arc), and the density of the
//! forward and reverse moves share the same delta across the line, which we leave out of both:
//! - stretch on the film about the guide's raster position v: T_px = w · g(λ) / (|x − v| |y − v|)
//!   (polar coordinates about v: area = s ds dφ), whose reverse ratio is λ · w(v | ȳ)/w(v | x̄)
//!   (`kernel` module docs); then, as the lens perturbation, to solid angle at the pinhole and
//!   through the retrace to area (`raster_to_solid_angle`, `retrace_jacobian`);
//! - great arc at the caustic pivot about ω₂ = pivot → guide's vertex j − 1: T_ω = g(λ)/(ψ sin ψ′)
//!   (dω = sin ψ dψ dφ), whose reverse ratio is sin ψ′/sin ψ; then through the retrace to area.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use super::guide::{best_match, choose_weighted, GuideCounts, GuideView};
use super::guided_kernel::{angle_between, GreatArcKernel, StretchKernel};
use super::tree::same_signature;
use crate::integrator::path_space::caustic::{caustic_pivot, Caustic, CausticKernel};
use crate::integrator::path_space::lens::{lens_chain_end, offset_raster, raster_to_solid_angle, Lens};
use crate::integrator::path_space::multichain::{
    self, further_chains_density, retrace_further_chains, MultiChain, MultiChainKernel,
};
use crate::integrator::path_space::reciprocal_kernel::RasterKernel;
#[cfg(any(test, feature = "testing"))]
use crate::integrator::path_space::retrace::retrace_measure_factor;
use crate::integrator::path_space::retrace::{retrace, retrace_jacobian};
use crate::integrator::path_space::{PathContext, PathState, PathVertex, Strategy};
use crate::sampling::Rng;
use crate::stats::Counters;

/// The context of a guided strategy: the complementary ensemble, the plain kernel of its fallback,
/// and its counts.
pub struct GuidedKernel<K> {
    pub view: Arc<GuideView>,
    pub plain: K,
    pub counts: Arc<GuideCounts>,
}

impl<K: Send + Sync> GuidedKernel<K> {
    /// The frame every guided proposal shares (Sec. 3.4): Υ from the chain's own offset; with
    /// fewer than two paths in it the plain perturbation `plain`, else `guided` with Υ; a proposal
    /// whose signature changed is rejected, since the reverse move must see the same Υ.
    fn propose_with<P: Strategy<Kernel = K, Move = ()>>(
        &self,
        plain: P,
        ctx: &PathContext,
        path: &PathState,
        rng: &mut Rng,
        counters: &mut Counters,
        guided: impl FnOnce(&[u32], u64, &mut Rng, &mut Counters) -> Option<(PathState, GuidedMove)>,
    ) -> Option<(PathState, GuidedMove)> {
        let offset = rng.next_u64();
        let subset = self.view.subset(path, offset);
        let (y, mv) = if subset.len() < 2 {
            self.counts.fallback.fetch_add(1, Ordering::Relaxed);
            let (y, ()) = plain.propose(ctx, path, &self.plain, rng, counters)?;
            (y, GuidedMove::Fallback { offset })
        } else {
            self.counts.guided.fetch_add(1, Ordering::Relaxed);
            guided(&subset, offset, rng, counters)?
        };
        if !same_signature(path, &y) {
            self.counts.signature_changed.fetch_add(1, Ordering::Relaxed);
            return None;
        }
        Some((y, mv))
    }

    /// The density of `propose_with`'s move `mv`: the same Υ (from `from` and the recorded
    /// offset), the plain perturbation's density for a fallback, `guided(Υ, guide)` otherwise; 0
    /// where the move could not have been made or the density is not finite.
    fn transition_with<P: Strategy<Kernel = K, Move = ()>>(
        &self,
        plain: P,
        ctx: &PathContext,
        from: &PathState,
        to: &PathState,
        mv: &GuidedMove,
        guided: impl FnOnce(&[u32], u32) -> f64,
    ) -> f64 {
        if !same_signature(from, to) {
            return 0.0;
        }
        let subset = self.view.subset(from, mv.offset());
        let t = match *mv {
            GuidedMove::Fallback { .. } if subset.len() >= 2 => 0.0,
            GuidedMove::Fallback { .. } => plain.transition(ctx, &self.plain, from, to, &()),
            GuidedMove::Guided { .. } if subset.len() < 2 => 0.0,
            GuidedMove::Guided { guide, .. } => guided(&subset, guide),
        };
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }
}

/// What a guided proposal recorded: Υ's offset and, when guided, the guide (its index in Y).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GuidedMove {
    Guided { offset: u64, guide: u32 },
    Fallback { offset: u64 },
}

impl GuidedMove {
    fn offset(&self) -> u64 {
        match *self {
            GuidedMove::Guided { offset, .. } | GuidedMove::Fallback { offset } => offset,
        }
    }
}

/// The position of `guide` in `subset` (None when Υ does not hold it).
fn position(subset: &[u32], guide: u32) -> Option<usize> {
    subset.iter().position(|&i| i == guide)
}

/// The linear lens perturbation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct LinearLens {
    /// Tests only: leave the selection ratio out (T without w(v | ·)), a deliberately wrong variant.
    #[cfg(any(test, feature = "testing"))]
    pub omit_selection: bool,
    /// Tests only: leave g(λ) out of T, so that the reverse ratio λ drops out of the acceptance (the
    /// toy test's first wrong variant, on the film).
    #[cfg(any(test, feature = "testing"))]
    pub omit_lambda: bool,
}

impl LinearLens {
    /// w(guide | path) for Υ = `subset` (Eq. 9 weights normalised), or None when 0.
    fn selection(
        &self,
        view: &GuideView,
        path: &PathState,
        subset: &[u32],
        at: usize,
        k: usize,
        counts: &GuideCounts,
    ) -> Option<f64> {
        #[cfg(any(test, feature = "testing"))]
        if self.omit_selection {
            return Some(1.0);
        }
        let w = view.weights(path, subset, 0, k, counts);
        let total: f64 = w.iter().sum();
        let p = w[at] / total;
        (p > 0.0 && p.is_finite()).then_some(p)
    }

    /// The guided move on the film shared by the linear lens and linear multi-chain perturbations
    /// (Sec. 3.3): a guide v drawn from Υ = `subset` with weight S(x̄, v, 0, k)/Σ S (k the end of
    /// the lens chain), then the stretch of the raster position about v's. Returns the guide and
    /// the new raster position (None when it leaves the film).
    fn sample_film(
        &self,
        ctx: &PathContext,
        kernel: &GuidedKernel<impl Send + Sync>,
        path: &PathState,
        subset: &[u32],
        k: usize,
        rng: &mut Rng,
    ) -> Option<(u32, glam::Vec2)> {
        let view = &kernel.view;
        let w = view.weights(path, subset, 0, k, &kernel.counts);
        let (at, _) = choose_weighted(&w, rng.uniform_f64())?;
        let guide = subset[at];
        let v = view.paths[guide as usize].raster.as_dvec2();
        let stretch = StretchKernel { alpha: view.alpha(subset) };
        kernel.counts.count_alpha(stretch.alpha, &view.settings);
        let (r, _) = stretch.sample(path.raster.as_dvec2(), v, rng.uniform_f64());
        Some((guide, offset_raster(ctx, path.raster, r - path.raster.as_dvec2())?))
    }

    /// The density per pixel² of `sample_film` moving `from`'s raster position to `to`'s with
    /// `guide` (module docs, "Densities"): w(v | x̄) · g(λ) / (|x − v| |y − v|); 0 when Υ does not
    /// hold the guide or its weight is 0.
    fn film_density(
        &self,
        kernel: &GuidedKernel<impl Send + Sync>,
        from: &PathState,
        to: &PathState,
        subset: &[u32],
        guide: u32,
        k: usize,
    ) -> f64 {
        let view = &kernel.view;
        let Some(at) = position(subset, guide) else { return 0.0 };
        let Some(w) = self.selection(view, from, subset, at, k, &kernel.counts) else { return 0.0 };
        let v = view.paths[guide as usize].raster.as_dvec2();
        let (s_from, s_to) = ((from.raster.as_dvec2() - v).length(), (to.raster.as_dvec2() - v).length());
        let stretch = StretchKernel { alpha: view.alpha(subset) };
        #[allow(unused_mut)]
        let mut g = stretch.density_lambda(s_to / s_from);
        #[cfg(any(test, feature = "testing"))]
        if self.omit_lambda && g > 0.0 {
            g = 1.0;
        }
        w * g / (s_from * s_to)
    }
}

impl Strategy for LinearLens {
    type Kernel = GuidedKernel<RasterKernel>;
    type Move = GuidedMove;

    fn name(&self) -> &'static str {
        "linear_lens"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        lens_chain_end(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &Self::Kernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, GuidedMove)> {
        kernel.propose_with(Lens::default(), ctx, path, rng, counters, |subset, offset, rng, counters| {
            let x = &path.vertices;
            let k = lens_chain_end(x)?;
            let (guide, raster) = self.sample_film(ctx, kernel, path, subset, k, rng)?;
            let ray = ctx.scene.camera.ray_through(raster);
            let new = retrace(ctx, x, 0, k, &x[0].vertex, ray.d, counters)?;
            let vertices: Vec<PathVertex> =
                x[..1].iter().copied().chain(new).chain(x[k + 1..].iter().copied()).collect();
            Some((PathState::from_path_vertices(ctx, vertices, counters), GuidedMove::Guided { offset, guide }))
        })
    }

    fn transition(
        &self,
        ctx: &PathContext,
        kernel: &Self::Kernel,
        from: &PathState,
        to: &PathState,
        mv: &GuidedMove,
    ) -> f64 {
        kernel.transition_with(Lens::default(), ctx, from, to, mv, |subset, guide| {
            let Some(k) = lens_chain_end(&from.vertices) else { return 0.0 };
            let t_px = self.film_density(kernel, from, to, subset, guide, k);
            raster_to_solid_angle(ctx, to, t_px) * retrace_jacobian(ctx.scene, &to.vertices, 0, k)
        })
    }

    fn reverse(&self, mv: &GuidedMove) -> GuidedMove {
        *mv
    }
}

/// The linear caustic perturbation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct LinearCaustic {
    /// Tests only: T without the retrace's refraction measure factors Π h, in the guided move and
    /// in its fallback (`Caustic::omit_refraction_measure`), the deliberately wrong variant the
    /// agreement tests on scenes whose Π h ≠ 1 must reject.
    #[cfg(any(test, feature = "testing"))]
    pub omit_refraction_measure: bool,
}

impl LinearCaustic {
    /// Veach's caustic perturbation, the fallback, with this strategy's wrong variant.
    fn plain(&self) -> Caustic {
        #[allow(unused_mut)]
        let mut caustic = Caustic::default();
        #[cfg(any(test, feature = "testing"))]
        {
            caustic.omit_refraction_measure = self.omit_refraction_measure;
        }
        caustic
    }

    /// ω₁ (pivot → vertex j − 1 of `path`) and ω₂ (pivot → the guide's vertex j − 1).
    fn directions(path: &PathState, guide: &PathState, j: usize) -> (glam::DVec3, glam::DVec3) {
        let pivot = &path.vertices[j].vertex;
        let w1 = pivot.dir_to(&path.vertices[j - 1].vertex).as_dvec3();
        let w2 = pivot.dir_to(&guide.vertices[j - 1].vertex).as_dvec3();
        (w1, w2)
    }
}

impl Strategy for LinearCaustic {
    type Kernel = GuidedKernel<CausticKernel>;
    type Move = GuidedMove;

    fn name(&self) -> &'static str {
        "linear_caustic"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        caustic_pivot(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &Self::Kernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, GuidedMove)> {
        let view = &kernel.view;
        kernel.propose_with(self.plain(), ctx, path, rng, counters, |subset, offset, rng, counters| {
            let x = &path.vertices;
            let j = caustic_pivot(x)?;
            let w = view.weights(path, subset, j - 1, j, &kernel.counts);
            let guide = subset[best_match(&w)?];
            let (w1, w2) = Self::directions(path, &view.paths[guide as usize], j);
            let arc = GreatArcKernel { stretch: StretchKernel { alpha: view.alpha(subset) } };
            kernel.counts.count_alpha(arc.stretch.alpha, &view.settings);
            let (dir, _) = arc.sample(w1, w2, rng.uniform_f64())?;
            let new = retrace(ctx, x, j, 1, &x[j].vertex, dir.as_vec3(), counters)?;
            let vertices: Vec<PathVertex> =
                x[..1].iter().copied().chain(new.into_iter().rev()).chain(x[j..].iter().copied()).collect();
            Some((PathState::from_path_vertices(ctx, vertices, counters), GuidedMove::Guided { offset, guide }))
        })
    }

    fn transition(
        &self,
        ctx: &PathContext,
        kernel: &Self::Kernel,
        from: &PathState,
        to: &PathState,
        mv: &GuidedMove,
    ) -> f64 {
        let view = &kernel.view;
        kernel.transition_with(self.plain(), ctx, from, to, mv, |subset, guide| {
            let Some(j) = caustic_pivot(&from.vertices) else { return 0.0 };
            if caustic_pivot(&to.vertices) != Some(j) {
                return 0.0;
            }
            // The best match of the path the move leaves must be the guide (module docs).
            let w = view.weights(from, subset, j - 1, j, &kernel.counts);
            if best_match(&w).map(|b| subset[b]) != Some(guide) {
                return 0.0;
            }
            let g_path = &view.paths[guide as usize];
            let (w1, w2) = Self::directions(from, g_path, j);
            let (w1_to, _) = Self::directions(to, g_path, j);
            let (psi, psi_new) = (angle_between(w1, w2), angle_between(w1_to, w2));
            let stretch = StretchKernel { alpha: view.alpha(subset) };
            let g = stretch.density_lambda(psi_new / psi);
            let t_omega = g / (psi * psi_new.sin());
            #[allow(unused_mut)]
            let mut t = t_omega * retrace_jacobian(ctx.scene, &to.vertices, j, 1);
            #[cfg(any(test, feature = "testing"))]
            if self.omit_refraction_measure {
                t /= retrace_measure_factor(ctx.scene, &to.vertices, j, 1);
            }
            t
        })
    }

    fn reverse(&self, mv: &GuidedMove) -> GuidedMove {
        *mv
    }
}

/// The linear multi-chain perturbation (Sec. 3.3): Veach's multi-chain perturbation
/// (`path_space::multichain`) with its lens offset replaced by the linear lens's guided stretch on
/// the film (guide drawn ∝ S(x̄, v, 0, k), k the end of the lens chain, "in the same way as the
/// Linear Lens Perturbation"); each further specular chain is then retraced from its new pivot
/// after Veach's direction perturbation (`retrace_further_chains`), until the path reconnects to
/// its light subpath. The paper guides only the image-plane step; its "deterministic connection to
/// the next specular subpath" is read as the retrace of each further chain, whose pivot direction
/// must still move for the chain to follow the moved pivot (keeping x_{p+1} fixed would make the
/// reverse move impossible unless y_{p+1} = x_{p+1}, which a retrace reaches only by chance).
///
/// Density: the linear lens's film density (`LinearLens::film_density`, with its selection ratio),
/// to solid angle at the pinhole and through the lens chain's retrace, times the further chains'
/// densities (`further_chains_density`), as Veach's multi-chain; the fallback (|Υ| < 2) is Veach's
/// multi-chain perturbation itself.
#[derive(Clone, Copy, Debug, Default)]
pub struct LinearMultiChain {
    /// The guided film move (its test-only wrong variants included).
    pub lens: LinearLens,
}

impl Strategy for LinearMultiChain {
    type Kernel = GuidedKernel<MultiChainKernel>;
    type Move = GuidedMove;

    fn name(&self) -> &'static str {
        "linear_multi_chain"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        multichain::chains(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &Self::Kernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, GuidedMove)> {
        kernel.propose_with(MultiChain, ctx, path, rng, counters, |subset, offset, rng, counters| {
            let x = &path.vertices;
            let chains = multichain::chains(x)?;
            let (guide, raster) = self.lens.sample_film(ctx, kernel, path, subset, chains[0].1, rng)?;
            let ray = ctx.scene.camera.ray_through(raster);
            let mut y: Vec<PathVertex> = x[..1].to_vec();
            y.extend(retrace(ctx, x, 0, chains[0].1, &x[0].vertex, ray.d, counters)?);
            retrace_further_chains(ctx, x, &chains, &kernel.plain.direction, &mut y, rng, counters)?;
            Some((PathState::from_path_vertices(ctx, y, counters), GuidedMove::Guided { offset, guide }))
        })
    }

    fn transition(
        &self,
        ctx: &PathContext,
        kernel: &Self::Kernel,
        from: &PathState,
        to: &PathState,
        mv: &GuidedMove,
    ) -> f64 {
        kernel.transition_with(MultiChain, ctx, from, to, mv, |subset, guide| {
            let (x, y) = (&from.vertices, &to.vertices);
            let Some(cx) = multichain::chains(x) else { return 0.0 };
            if multichain::chains(y).as_ref() != Some(&cx) {
                return 0.0;
            }
            let k = cx[0].1;
            let t_px = self.lens.film_density(kernel, from, to, subset, guide, k);
            raster_to_solid_angle(ctx, to, t_px)
                * retrace_jacobian(ctx.scene, y, 0, k)
                * further_chains_density(ctx.scene, x, y, &cx, &kernel.plain.direction)
        })
    }

    fn reverse(&self, mv: &GuidedMove) -> GuidedMove {
        *mv
    }
}
