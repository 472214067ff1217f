//! Veach's multi-chain perturbation (Veach & Guibas 1997 Sec. 5.4.3): for paths whose first pair
//! of adjacent non-specular vertices comes after two or more specular chains (read from the camera:
//! E S* D S+ D … with the lens chain E S* D possibly empty of specular vertices), a lens
//! perturbation moves the raster position and retraces the first chain to x_k; then each following
//! chain x_{p+1} … x_m (specular up to a non-specular x_m) is retraced from the new x_p after
//! turning the direction the path left x_p by with a truncated reciprocal kernel (θ ∈ [1e-4°, 0.1°],
//! as Mitsuba 0.6's `mut_mchain.cpp` and the ensemble paper's implementation), until x_m is the
//! emitter or x_{m+1} is non-specular, where the path reconnects.
//!
//! # Transition density
//! In the delta-stripped area measure of the retraced vertices (path_space module docs): the lens
//! perturbation's T for the first chain (`lens`), times, per following chain from pivot p,
//! p_θ(ω_y | ω_x) per unit solid angle at y_p, with ω_x the direction x_p → x_{p+1} and ω_y the
//! direction y_p → y_{p+1}, times the chain's Π |cos θ_next|/d² (`retrace_jacobian`). Each factor
//! is symmetric between x̄ and ȳ except the traced edges' G and the camera's, which are in f too;
//! each pivot's |cos θ| stays in the acceptance through f (its projected solid angle), as for the
//! caustic perturbation.

use super::lens::{offset_raster, raster_to_solid_angle};
use super::path_state::{Interaction, PathState, PathVertex};
use super::reciprocal_kernel::{DirectionKernel, RasterKernel};
use super::retrace::{first_non_specular, retrace, retrace_jacobian};
use super::strategy::Strategy;
use super::PathContext;
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::stats::Counters;

/// The multi-chain perturbation's kernels: the lens offset and the direction kernel at each
/// further chain's pivot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultiChainKernel {
    pub lens: RasterKernel,
    pub direction: DirectionKernel,
}

impl MultiChainKernel {
    /// The public implementations' direction range, 1e-4° to 0.1°, with the lens kernel `lens`.
    pub fn new(lens: RasterKernel) -> MultiChainKernel {
        MultiChainKernel {
            lens,
            direction: DirectionKernel { theta_min: 1e-4f64.to_radians(), theta_max: 0.1f64.to_radians() },
        }
    }
}

/// The multi-chain perturbation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct MultiChain;

/// The chains of `path` the multi-chain perturbation retraces, as (start, end) vertex indices: the
/// lens chain (0, k) first, then (p, m) per further chain; None when it is not suitable (fewer than
/// two chains before a connectible pair, or a chain ending at infinity).
pub fn chains(path: &[PathVertex]) -> Option<Vec<(usize, usize)>> {
    let n = path.len();
    let k = first_non_specular(path)?;
    if k + 1 >= n || path[k + 1].interaction != Interaction::Specular {
        return None;
    }
    let mut out = vec![(0, k)];
    let mut p = k;
    loop {
        let m = (p + 1..n).find(|&i| path[i].interaction != Interaction::Specular)?;
        if path[m].vertex.infinite || path[p].interaction == Interaction::Emitter {
            return None;
        }
        out.push((p, m));
        if m + 1 == n || path[m + 1].connectible() {
            return Some(out);
        }
        p = m;
    }
}

/// The multi-chain perturbation after its lens chain: `y` holds the new vertices 0 ..= k of the
/// lens chain (`chains[0]`); per further chain (p, m), the direction x_p → x_{p+1} turned by
/// `direction` is retraced from the new y_p to y_m; then the rest of `x` is appended. None when a
/// retrace fails. Shared with the ensemble's linear multi-chain perturbation, which guides only the
/// lens chain.
pub fn retrace_further_chains(
    ctx: &PathContext,
    x: &[PathVertex],
    chains: &[(usize, usize)],
    direction: &DirectionKernel,
    y: &mut Vec<PathVertex>,
    rng: &mut Rng,
    counters: &mut Counters,
) -> Option<()> {
    for &(p, m) in &chains[1..] {
        let axis = x[p].vertex.dir_to(&x[p + 1].vertex).as_dvec3();
        let dir = direction.sample(axis, [rng.uniform_f64(), rng.uniform_f64()]).as_vec3();
        let origin = y[p].vertex;
        y.extend(retrace(ctx, x, p, m, &origin, dir, counters)?);
    }
    let last = chains[chains.len() - 1].1;
    y.extend(x[last + 1..].iter().copied());
    Some(())
}

/// The density of [`retrace_further_chains`] turning `x` into `y` (module docs): per further chain
/// (p, m), p_θ(ω_y | ω_x) at y_p times the chain's retrace Jacobian.
pub fn further_chains_density(
    scene: &Scene,
    x: &[PathVertex],
    y: &[PathVertex],
    chains: &[(usize, usize)],
    direction: &DirectionKernel,
) -> f64 {
    chains[1..]
        .iter()
        .map(|&(p, m)| {
            let axis = x[p].vertex.dir_to(&x[p + 1].vertex).as_dvec3();
            let dir = y[p].vertex.dir_to(&y[p + 1].vertex).as_dvec3();
            direction.density(axis, dir) * retrace_jacobian(scene, y, p, m)
        })
        .product()
}

impl Strategy for MultiChain {
    type Kernel = MultiChainKernel;
    type Move = ();

    fn name(&self) -> &'static str {
        "multi_chain"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        chains(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &MultiChainKernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, ())> {
        let x = &path.vertices;
        let chains = chains(x)?;
        let offset = kernel.lens.sample([rng.uniform_f64(), rng.uniform_f64()]);
        let raster = offset_raster(ctx, path.raster, offset)?;
        let ray = ctx.scene.camera.ray_through(raster);
        let mut y: Vec<PathVertex> = x[..1].to_vec();
        y.extend(retrace(ctx, x, 0, chains[0].1, &x[0].vertex, ray.d, counters)?);
        retrace_further_chains(ctx, x, &chains, &kernel.direction, &mut y, rng, counters)?;
        Some((PathState::from_path_vertices(ctx, y, counters), ()))
    }

    fn transition(
        &self,
        ctx: &PathContext,
        kernel: &MultiChainKernel,
        from: &PathState,
        to: &PathState,
        _: &(),
    ) -> f64 {
        let (x, y) = (&from.vertices, &to.vertices);
        let Some(cx) = chains(x) else { return 0.0 };
        if y.len() != x.len() || chains(y).as_ref() != Some(&cx) {
            return 0.0;
        }
        let offset = (to.raster - from.raster).as_dvec2();
        let (_, k) = cx[0];
        let t = raster_to_solid_angle(ctx, to, kernel.lens.density(offset))
            * retrace_jacobian(ctx.scene, y, 0, k)
            * further_chains_density(ctx.scene, x, y, &cx, &kernel.direction);
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    fn reverse(&self, _: &()) {}
}
