//! The portal perturbation (Otsu, Hanika & Dachsbacher 2022, "Portal-Based Path Perturbation for
//! Metropolis Light Transport", Sec. 4; docs/bibliography.md): pivot the
//! first path edge that crosses a portal about its crossing point, so that an edge squeezed through
//! a small opening (a window, a hole) moves freely on both sides of it, where Veach's perturbations,
//! which rotate about a path vertex far from the opening, are mostly occluded (Sec. 3.4, 4.1).
//!
//! # The move (Sec. 4.3 and 4.5)
//! On x̄ = x_0 (pinhole) … x_{n−1} (emitter), find the first edge x_i x_{i+1}, counted from the
//! camera, that crosses a portal, and the crossing p on the nearest portal along it
//! ([`first_crossing`]). The pinhole is a degenerate endpoint (no ray from p can hit it), so the
//! search starts at i = 1, as Sec. 4.5 limits p's range. Then:
//! 1. keep p: T_A(p* | p) = δ(p* − p), the paper's own choice ("Perturbation on the Portal");
//! 2. draw ω* about ω = dir(x_i → x_{i+1}) from the truncated reciprocal kernel (Eq. 5, θ in
//!    [2⁻⁸, 2⁻⁴] rad: `kernel::DirectionKernel`), which keeps ω*·ω > 0 as Sec. 4.5 asks;
//! 3. trace (p, ω*) to x*_{i+1} and (p, −ω*) to x*_i. x*_{i+1} must be an emitter if x_{i+1} was
//!    the path's last vertex (an environment when the forward ray leaves the scene), and a surface
//!    otherwise; x*_i must be a surface;
//! 4. early rejections, by cause in the strategy's statistics ([`Rejection`]): a ray leaves the
//!    scene, a new vertex is specular (its delta lobe cannot meet the kept neighbour), x_{i−1}–x*_i or
//!    x*_{i+1}–x_{i+2} is occluded, or the move is not reversible (below);
//! 5. **reverse consistency**: from x̄* the same strategy must pick the same edge i through the
//!    same portal; a new crossing can appear on x_{i−1} x*_i (or the nearest portal along edge i can
//!    change), and then T(x̄* → x̄) = 0, so the proposal is rejected.
//!
//! Suitability (Sec. 4.5): the path has such an edge, and x_{i−1}, x_i, x_{i+1}, x_{i+2} (where
//! they exist) are not specular: a specular x_{i−1} or x_{i+2} would have to scatter exactly into
//! the moved vertex (f(x̄*) = 0 almost surely), and a specular x_i or x_{i+1} lives in the
//! delta-stripped measure, which this move's density does not speak. Suitability is a function
//! of the path alone, so `StrategySet::probability` evaluates it at both ends of a move.
//!
//! # The acceptance ratio (Sec. 4.4, derived here)
//! Parametrise the edge's two endpoints by the line through them: its crossing p on the portal
//! (area A on the quad) and its direction ω (solid angle σ). The measure of lines is the same
//! in either parametrisation (the étendue identity; Eq. 9's Jacobians are its two halves):
//!
//!   G(x_i, x_{i+1}) dA(x_i) dA(x_{i+1}) = |n·ω| dA(p) dσ(ω),     G = |cos θ_i| |cos θ_{i+1}| / d²
//!
//! (n the portal normal, θ at the geometric normals; with x_{i+1} an environment direction, its
//! measure is σ and G = |cos θ_i|, the cosine at the finite end). So in (p, ω) the target density
//! is f(x̄)·|n·ω| / G(x_i, x_{i+1}), and the proposal there is δ(p* − p)·k(ω* | ω), k the kernel's
//! density per unit solid angle. The δ is the same both ways (the reverse move keeps the same p:
//! the new edge passes through it), and k depends only on the angle between ω and ω* (Eq. 5), so
//! k(ω* | ω) = k(ω | ω*). Metropolis–Hastings' ratio is then
//!
//!   a = f(x̄*) G(x_i, x_{i+1}) |n·ω*| / ( f(x̄) G(x*_i, x*_{i+1}) |n·ω| ),
//!
//! which is what [`PortalPerturbation::transition`] gives the chain, as
//! T(x̄ → x̄*) = k(ω* | ω) · G(x*_i, x*_{i+1}) / |n·ω*| (density per unit area of the moved
//! vertices, the δ left out on both sides). Two differences from the paper as printed:
//! - Eq. 10 simplifies R to f(x̄*)/G(x*_p, x*_{p+1}) for kernels symmetric in *projected* solid
//!   angle at the portal (T_σ⊥ = k/|n·ω|); Eq. 5's kernel is symmetric in solid angle, so the
//!   |n·ω*| / |n·ω| factor stays;
//! - Eq. 3 writes a = l∘R(x̄_i | x̄*) / l∘R(x̄* | x̄_i), upside down relative to its own definition
//!   R(ȳ | x̄) = f(ȳ)/T(ȳ | x̄): the ratio is π(x̄*)T(x̄ | x̄*) / (π(x̄)T(x̄* | x̄)) =
//!   R(x̄* | x̄) / R(x̄ | x̄*), as the chain (`strategy` docs) computes it.
//!
//! Dropping the G terms (the deliberately wrong variant `omit_geometry`, T = k/|n·ω*|) leaves the
//! chain's stationary density off by G(x_i, x_{i+1}), which tests/chains/portal.rs's portal-planes test
//! rejects.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN densities along with zero and negative ones.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::DVec3;

use super::density::{trace, Side};
use super::path_state::{with_role, Interaction, PathState, PathVertex};
use super::reciprocal_kernel::DirectionKernel;
use super::strategy::Strategy;
use super::PathContext;
use crate::geometry::Ray;
use crate::integrator::bdpt::{mutually_visible, Vertex};
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::stats::Counters;

/// The first portal-crossing edge of a path: x_edge x_{edge+1} crosses portal `portal` at `point`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    pub edge: usize,
    pub portal: usize,
    pub point: DVec3,
}

/// The edge x_a → x_b as a ray origin, direction and parameter range (t in (0, 1) for a finite
/// edge; to infinity, with a unit direction, when x_b is an environment direction).
fn edge_ray(a: &Vertex, b: &Vertex) -> (DVec3, DVec3, f64) {
    if b.infinite {
        (a.p.as_dvec3(), (-b.dir).as_dvec3().normalize(), f64::INFINITY)
    } else {
        (a.p.as_dvec3(), (b.p - a.p).as_dvec3(), 1.0)
    }
}

/// The unit direction of the edge x_a → x_b, in f64.
fn edge_direction(a: &Vertex, b: &Vertex) -> DVec3 {
    let (_, d, _) = edge_ray(a, b);
    d.normalize_or_zero()
}

/// The geometric factor of the edge a → b in the path measure (module docs): |cos| at both
/// geometric normals over d², or |cos| at `a` alone when `b` is at infinity.
fn geometry(a: &Vertex, b: &Vertex) -> f64 {
    let dir = edge_direction(a, b);
    let cos_a = a.ng.as_dvec3().dot(dir).abs();
    if b.infinite {
        return cos_a;
    }
    let d2 = (b.p - a.p).as_dvec3().length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    cos_a * b.ng.as_dvec3().dot(dir).abs() / d2
}

/// The portal query (Sec. 4.3): the first edge x_i x_{i+1} with i ≥ 1 (the pinhole cannot be
/// pivoted to, module docs) that crosses a portal, and the nearest crossing along it. None without
/// portals (one `is_empty` test: a scene without portals pays nothing) or crossings.
pub fn first_crossing(scene: &Scene, path: &[PathVertex]) -> Option<Crossing> {
    if scene.portals.is_empty() {
        return None;
    }
    for i in 1..path.len().saturating_sub(1) {
        let (a, b) = (&path[i].vertex, &path[i + 1].vertex);
        if a.infinite {
            return None;
        }
        let (o, d, t_max) = edge_ray(a, b);
        let nearest = scene
            .portals
            .iter()
            .enumerate()
            .filter_map(|(k, portal)| portal.intersect(o, d, t_max).map(|h| (k, h)))
            .min_by(|x, y| x.1.t.total_cmp(&y.1.t));
        if let Some((portal, hit)) = nearest {
            return Some(Crossing { edge: i, portal, point: hit.point });
        }
    }
    None
}

/// Why a portal proposal was rejected before its f was evaluated (the statistics' causes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// The current path has no portal-crossing edge (never, when the chain checks suitability).
    NoCrossing,
    /// A ray from p* left the scene where a surface was needed (or, towards the emitter end, with
    /// no environment to meet).
    Escaped,
    /// x*_{i+1} replaces the path's emitter but is no emitter.
    MissedEmitter,
    /// x*_i or x*_{i+1} is specular.
    Specular,
    /// x_{i−1}–x*_i or x*_{i+1}–x_{i+2} is occluded.
    Occluded,
    /// From x̄* the strategy would pivot another edge or about another portal (T(x̄* → x̄) = 0).
    ReverseInconsistent,
}

impl Rejection {
    pub fn label(self) -> &'static str {
        match self {
            Rejection::NoCrossing => "no_crossing",
            Rejection::Escaped => "escaped",
            Rejection::MissedEmitter => "missed_emitter",
            Rejection::Specular => "specular",
            Rejection::Occluded => "occluded",
            Rejection::ReverseInconsistent => "reverse_inconsistent",
        }
    }
}

/// The portal perturbation (module docs), T_A = δ.
#[derive(Clone, Copy, Debug, Default)]
pub struct PortalPerturbation {
    /// Tests only: leave the geometric factors out of T (a deliberately wrong acceptance ratio,
    /// which the portal-planes agreement test must reject).
    #[cfg(any(test, feature = "testing"))]
    pub omit_geometry: bool,
}

/// A portal proposal's record: the pivoted edge and the portal it crosses. Its own reverse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PortalMove {
    pub edge: usize,
    pub portal: usize,
}

/// Whether x̄'s vertices around the crossing edge allow the move (module docs, "Suitability").
fn movable(path: &[PathVertex], edge: usize) -> bool {
    let lo = edge - 1;
    let hi = (edge + 2).min(path.len() - 1);
    path[lo..=hi].iter().all(|v| v.interaction != Interaction::Specular)
}

impl PortalPerturbation {
    /// The proposal with its record, or the early rejection's cause.
    pub fn propose_or_reject(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &DirectionKernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Result<(PathState, PortalMove), Rejection> {
        let scene = ctx.scene;
        let x = &path.vertices;
        let n = x.len();
        let c = first_crossing(scene, x).ok_or(Rejection::NoCrossing)?;
        let i = c.edge;
        if !movable(x, i) {
            return Err(Rejection::NoCrossing);
        }
        let axis = edge_direction(&x[i].vertex, &x[i + 1].vertex);
        let w = kernel.sample(axis, [rng.uniform_f64(), rng.uniform_f64()]);
        let p = c.point.as_vec3();
        // Towards the emitter end: the camera side's tracing (radiance), which meets the
        // environment when the ray leaves the scene.
        let ahead = trace(scene, &Ray::new(p, w.as_vec3()), Side::Camera, counters).ok_or(Rejection::Escaped)?;
        let last = i + 2 == n;
        if ahead.infinite && !last {
            return Err(Rejection::Escaped);
        }
        if last && ahead.light.is_none() {
            return Err(Rejection::MissedEmitter);
        }
        let behind = trace(scene, &Ray::new(p, (-w).as_vec3()), Side::Camera, counters).ok_or(Rejection::Escaped)?;
        if behind.infinite {
            return Err(Rejection::Escaped);
        }
        let mut y: Vec<PathVertex> = x.clone();
        y[i] = with_role(scene, behind, i, n);
        y[i + 1] = with_role(scene, ahead, i + 1, n);
        if y[i].interaction == Interaction::Specular || y[i + 1].interaction == Interaction::Specular {
            return Err(Rejection::Specular);
        }
        // The two connections the paper checks (x*_i–x*_{i+1} is free: both were traced from p).
        counters.shadow_rays += 1;
        if !mutually_visible(scene, &y[i - 1].vertex, &y[i].vertex) {
            return Err(Rejection::Occluded);
        }
        if !last {
            counters.shadow_rays += 1;
            if !mutually_visible(scene, &y[i + 1].vertex, &y[i + 2].vertex) {
                return Err(Rejection::Occluded);
            }
        }
        match first_crossing(scene, &y) {
            Some(back) if back.edge == i && back.portal == c.portal && movable(&y, i) => {}
            _ => return Err(Rejection::ReverseInconsistent),
        }
        let mv = PortalMove { edge: i, portal: c.portal };
        Ok((PathState::from_path_vertices(ctx, y, counters), mv))
    }
}

impl Strategy for PortalPerturbation {
    type Kernel = DirectionKernel;
    type Move = PortalMove;

    fn name(&self) -> &'static str {
        "portal"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, ctx: &PathContext, path: &PathState) -> bool {
        match first_crossing(ctx.scene, &path.vertices) {
            Some(c) => movable(&path.vertices, c.edge),
            None => false,
        }
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &DirectionKernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, PortalMove)> {
        match self.propose_or_reject(ctx, path, kernel, rng, counters) {
            Ok(proposal) => Some(proposal),
            Err(cause) => {
                counters.early_rejection = Some(cause.label());
                None
            }
        }
    }

    /// T(x̄ → x̄*) = k(ω* | ω) · G(x*_i, x*_{i+1}) / |n·ω*| (module docs; the δ of T_A left out,
    /// being the same both ways).
    fn transition(
        &self,
        ctx: &PathContext,
        kernel: &DirectionKernel,
        from: &PathState,
        to: &PathState,
        mv: &PortalMove,
    ) -> f64 {
        let i = mv.edge;
        if from.len() != to.len() || i == 0 || i + 1 >= to.len() {
            return 0.0;
        }
        let Some(portal) = ctx.scene.portals.get(mv.portal) else { return 0.0 };
        let (a, b) = (&to.vertices[i].vertex, &to.vertices[i + 1].vertex);
        let axis = edge_direction(&from.vertices[i].vertex, &from.vertices[i + 1].vertex);
        let dir = edge_direction(a, b);
        let k = kernel.density(axis, dir);
        let cos = portal.normal().dot(dir).abs();
        if !(k > 0.0) || !(cos > 0.0) {
            return 0.0;
        }
        #[allow(unused_mut)]
        let mut g = geometry(a, b);
        #[cfg(any(test, feature = "testing"))]
        if self.omit_geometry {
            g = 1.0;
        }
        let t = k * g / cos;
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    fn reverse(&self, mv: &PortalMove) -> PortalMove {
        *mv
    }
}
