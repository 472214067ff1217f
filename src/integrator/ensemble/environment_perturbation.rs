//! The environment perturbation (Bashford-Rogers et al. 2021, Sec. 3.3, Fig. 11): for a path that
//! ends at the environment (a vertex at infinity) from a non-specular surface vertex x_{n−2} (the
//! first non-specular vertex from the light), perturb the direction ω = x_{n−2} → environment with
//! a guided kernel and trace it again from x_{n−2}: the ray must leave the scene, and the path's
//! other vertices are kept.
//!
//! # Kernels (`EmltSettings::environment_kernel`)
//! - `directional` (default): the guided directional kernel (`directional`), a vMF about ω with κ
//!   fitted to Υ's environment directions weighted by Eq. 11 (S(x̄, vⁿ, n − 2, n − 1), the
//!   environment vertices compared by direction, `similarity` module docs); refitted at ȳ for the
//!   reverse. T(x̄ → ȳ) = vMF_x̄(ω_ȳ) per unit solid angle, the environment vertex's measure.
//! - `hemispherical`: the linear hemispherical (great-arc) kernel (`kernel`) about a guide
//!   direction ω₂ chosen from Υ ∝ the same weights: T = w(v | x̄) g(ψ′/ψ)/(ψ sin ψ′), with the
//!   selection probability redone at ȳ for the reverse, and the singular delta across the arc
//!   left out of both directions (`linear` module docs; the reverse ratio sin ψ′/sin ψ follows).
//!
//! With |Υ| < 2 (or a degenerate directional fit) both fall back to the vMF about ω with the
//! fallback concentration, recorded in the move so the reverse uses the same branch (Υ is the same
//! both ways: the offset is recorded and a signature change is rejected, `tree` module docs).

use std::rc::Rc;
use std::sync::atomic::Ordering;

use glam::DVec3;

use super::anisotropic_path::GuideContext;
use super::directional::{guided_vmf, Vmf};
use super::emlt_settings::EnvironmentKernel;
use super::guide::choose_weighted;
use super::guided_kernel::{angle_between, GreatArcKernel, StretchKernel};
use super::tree::same_signature;
use crate::integrator::path_space::retrace::retrace;
use crate::integrator::path_space::{Interaction, PathContext, PathState, PathVertex, Strategy};
use crate::sampling::Rng;
use crate::stats::Counters;

/// The index of x_{n−2}, if the perturbation is suitable for `path`: the last vertex at infinity,
/// x_{n−2} a diffuse or glossy surface point (not the camera).
pub fn environment_base(path: &[PathVertex]) -> Option<usize> {
    let n = path.len();
    if n < 3 || !path[n - 1].vertex.infinite {
        return None;
    }
    matches!(path[n - 2].interaction, Interaction::Diffuse | Interaction::Glossy).then_some(n - 2)
}

/// The direction from x_{n−2} to the environment.
fn env_direction(path: &PathState) -> DVec3 {
    let n = path.len();
    path.vertices[n - 2].vertex.dir_to(&path.vertices[n - 1].vertex).as_dvec3().normalize()
}

/// What a proposal recorded: Υ's offset, and the guide of the hemispherical kernel (`None` for the
/// directional kernel and for the fallback, which `fallback` tells apart).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EnvironmentMove {
    pub offset: u64,
    pub guide: Option<u32>,
    pub fallback: bool,
}

/// The environment perturbation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct EnvironmentPerturbation {
    pub kernel: EnvironmentKernel,
}

impl EnvironmentPerturbation {
    /// The weights of Υ's members for `path` and their environment directions.
    fn weighted_directions(guide: &GuideContext, path: &PathState, subset: &[u32]) -> (Rc<Vec<f64>>, Vec<DVec3>) {
        let j = path.len() - 2;
        let w = guide.view.weights(path, subset, j, j + 1, &guide.counts);
        let dirs = subset.iter().map(|&i| env_direction(&guide.view.paths[i as usize])).collect();
        (w, dirs)
    }

    /// The vMF of the directional kernel (or the fallback) at `path`.
    fn vmf(guide: &GuideContext, path: &PathState, subset: &[u32], fallback: bool) -> Vmf {
        let kappa = guide.view.settings.fallback_concentration;
        let current = env_direction(path);
        if fallback {
            return Vmf { axis: current, kappa };
        }
        let (w, dirs) = Self::weighted_directions(guide, path, subset);
        guided_vmf(current, &dirs, &w, kappa)
    }

    fn arc(guide: &GuideContext, subset: &[u32]) -> GreatArcKernel {
        GreatArcKernel { stretch: StretchKernel { alpha: guide.view.alpha(subset) } }
    }
}

impl Strategy for EnvironmentPerturbation {
    type Kernel = GuideContext;
    type Move = EnvironmentMove;

    fn name(&self) -> &'static str {
        "environment"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        environment_base(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        guide: &GuideContext,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, EnvironmentMove)> {
        let x = &path.vertices;
        let base = environment_base(x)?;
        let offset = rng.next_u64();
        let subset = guide.view.subset(path, offset);
        let fallback = subset.len() < 2;
        guide.count_fit(fallback);
        let (dir, mv) = match self.kernel {
            EnvironmentKernel::Hemispherical if !fallback => {
                let (w, dirs) = Self::weighted_directions(guide, path, &subset);
                let (at, _) = choose_weighted(&w, rng.uniform_f64())?;
                let (dir, _) = Self::arc(guide, &subset).sample(env_direction(path), dirs[at], rng.uniform_f64())?;
                (dir, EnvironmentMove { offset, guide: Some(subset[at]), fallback })
            }
            _ => {
                let vmf = Self::vmf(guide, path, &subset, fallback);
                (vmf.sample([rng.uniform_f64(), rng.uniform_f64()]), EnvironmentMove { offset, guide: None, fallback })
            }
        };
        let env = retrace(ctx, x, base, base + 1, &x[base].vertex, dir.as_vec3(), counters)?;
        let vertices: Vec<PathVertex> = x[..=base].iter().copied().chain(env).collect();
        let y = PathState::from_path_vertices(ctx, vertices, counters);
        if !same_signature(path, &y) {
            guide.counts.signature_changed.fetch_add(1, Ordering::Relaxed);
            return None;
        }
        Some((y, mv))
    }

    fn transition(
        &self,
        _ctx: &PathContext,
        guide: &GuideContext,
        from: &PathState,
        to: &PathState,
        mv: &EnvironmentMove,
    ) -> f64 {
        if !same_signature(from, to) || environment_base(&from.vertices).is_none() {
            return 0.0;
        }
        let subset = guide.view.subset(from, mv.offset);
        if mv.fallback != (subset.len() < 2) {
            return 0.0;
        }
        let to_dir = env_direction(to);
        let t = match (self.kernel, mv.guide) {
            (EnvironmentKernel::Hemispherical, Some(g)) if !mv.fallback => {
                let Some(at) = subset.iter().position(|&i| i == g) else { return 0.0 };
                let (w, dirs) = Self::weighted_directions(guide, from, &subset);
                let total: f64 = w.iter().sum();
                let select = w[at] / total;
                let (psi, psi_new) = (angle_between(env_direction(from), dirs[at]), angle_between(to_dir, dirs[at]));
                let g = Self::arc(guide, &subset).density_along_arc(psi, psi_new);
                select * g / psi_new.sin()
            }
            (EnvironmentKernel::Hemispherical, None) if !mv.fallback => 0.0,
            _ => Self::vmf(guide, from, &subset, mv.fallback).density(to_dir),
        };
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    fn reverse(&self, mv: &EnvironmentMove) -> EnvironmentMove {
        *mv
    }
}
