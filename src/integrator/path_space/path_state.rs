//! The path-space state: a path as its vertex list (camera first, emitter last), each vertex with
//! its interaction kind, and the path's raster position and contribution f(x̄), which
//! [`PathState::new`] evaluates from the vertices alone (`contribution::evaluate`).

use glam::{DVec3, Vec2};
use serde::{Deserialize, Serialize};

use super::contribution::evaluate;
use super::PathContext;
use crate::integrator::bdpt::Vertex;
use crate::stats::Counters;

// A path's vertices are their own module, below both the path and its contribution, which
// reads vertices and which `PathState::new` calls.
pub use super::vertex::{material_interaction, with_role, Interaction, PathVertex};

/// A path of the chain: vertices camera first, emitter last; where it lands on the film; its
/// contribution f(x̄) in the module's measure and the chain's scalar target f*(x̄) = luminance(f),
/// both in f64 (`contribution::evaluate` says why).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PathState {
    pub vertices: Vec<PathVertex>,
    pub raster: Vec2,
    pub f: DVec3,
    pub f_star: f64,
}

/// Luminance of an f64 colour (the weights of `spectrum::luminance`).
pub fn luminance64(c: DVec3) -> f64 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

impl PathState {
    /// The path through `vertices` (camera first), with roles assigned and f evaluated (one shadow
    /// ray per edge, counted in `counters`). A non-finite f is a zero path (counted as dropped).
    pub fn new(ctx: &PathContext, vertices: &[Vertex], counters: &mut Counters) -> PathState {
        let n = vertices.len();
        let vertices: Vec<PathVertex> =
            vertices.iter().enumerate().map(|(i, v)| with_role(ctx.scene, *v, i, n)).collect();
        PathState::from_path_vertices(ctx, vertices, counters)
    }

    /// As `new`, for vertices whose roles are already assigned.
    pub fn from_path_vertices(ctx: &PathContext, vertices: Vec<PathVertex>, counters: &mut Counters) -> PathState {
        let (f, raster) = evaluate(ctx, &vertices, counters);
        let f_star = luminance64(f);
        let finite = f_star.is_finite() && f.is_finite();
        if !finite {
            counters.nonfinite_dropped += 1;
        }
        if finite && f_star > 0.0 {
            PathState { vertices, raster, f, f_star }
        } else {
            PathState { vertices, raster, f: DVec3::ZERO, f_star: 0.0 }
        }
    }

    /// Scattering events (vertices − 2), the depth `max_depth` bounds.
    pub fn depth(&self) -> usize {
        self.vertices.len().saturating_sub(2)
    }

    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }
}
