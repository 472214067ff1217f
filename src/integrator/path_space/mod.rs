//! Path-space Metropolis light transport (Veach & Guibas 1997; the portal paper's Sec. 3 and the
//! ensemble paper's Sec. 2.3 summarise it): Markov chains whose state is a light path itself,
//! mutated vertex by vertex. `integrator = "pmlt"` runs many such chains started from a BDPT
//! bootstrap (`chain`); the bidirectional mutation (`bidirectional`) is its global strategy, Veach's
//! lens, caustic and multi-chain perturbations (`lens`, `caustic`, `multichain`, with the truncated
//! reciprocal kernels of `kernel` and the specular-chain retrace of `retrace`) its local ones, and
//! the portal perturbation (`portal`, Otsu et al. 2022) and the ensemble-guided kernels
//! (`integrator::ensemble`, Bashford-Rogers et al. 2021) are further strategies on the same chain
//! (`strategy`).
//!
//! # State
//! A path x̄ = x_0 … x_{n−1} is its vertex list, pinhole first and emitter last (`state`): each
//! vertex with position, geometric normal and shading frame, material or emitter, and interaction
//! kind (camera, diffuse, glossy, specular, emitter), plus the raster position where its first
//! edge meets the film and its contribution f(x̄). An environment emitter is a vertex at infinity:
//! its direction, measured in solid angle.
//!
//! # Measure (used everywhere in this module)
//! The path measure is the product of the area measures of x_1 … x_{n−1} (solid angle for a vertex
//! at infinity); the pinhole is a fixed point and contributes no measure. Specular vertices follow
//! BDPT's **delta-stripped convention**: a specular vertex x_i contributes F/|cos θ_i| to f (the
//! lobe's weight over the cosine towards x_{i+1}, so that f_s·|cos| = F) and its lobe's selection
//! probability to a transition density in place of a directional density; every edge's geometric
//! factor is in both f and T, so edges a mutation traced cancel in f/T and only its connection
//! edges remain, as in BDPT's C = f/p. So f and T are densities with respect to the same
//! (delta-stripped) measure and their ratio in the acceptance is well defined. The measure of the
//! image is the whole film: pixel j's value is P·∫ 1_j(x̄) f(x̄) dμ(x̄) (P pixels), as BDPT's
//! whole-film sampling of primary-sample-space MLT normalises it.
//!
//! The δ of a specular vertex is stripped with respect to the solid angle of its direction towards
//! the light (towards x_{i+1}). A step that generates the direction towards the camera from the one
//! towards the light (an emitter-side walk of the bidirectional mutation, a retrace towards the
//! camera) carries the other δ, so at a refraction its density is converted by the measure factor
//! h = η_a² |cos θ_a| / (η_b² |cos θ_b|) (`density` module docs, "Light-direction steps through a
//! refraction"); reflections and steps towards the light need none.
//!
//! # Contribution
//! `contribution::evaluate` computes f(x̄) from the vertices alone, visibility included, for every
//! proposal of every strategy: there is one f.

pub mod bidirectional;
pub mod caustic;
pub mod chain;
pub mod contribution;
pub mod density;
pub mod lens;
pub mod multichain;
pub mod path_state;
#[cfg(test)]
mod perturb_tests;
pub mod pmlt_render;
pub mod pmlt_settings;
pub mod portal_perturbation;
pub mod reciprocal_kernel;
pub mod retrace;
pub mod strategy;
#[cfg(test)]
mod tests;
pub mod trace;
pub mod vertex;

pub use chain::{Pmlt, PmltRun};
pub use path_state::{Interaction, PathState, PathVertex};
pub use pmlt_settings::PmltSettings;
pub use reciprocal_kernel::{DirectionKernel, RasterKernel};
pub use strategy::{Entry, Mutation, Strategy, StrategySet};

use crate::scene::Scene;

/// What every strategy and the contribution function need: the scene and the longest path allowed
/// (`max_depth` scattering events, max_depth + 2 vertices).
#[derive(Clone, Copy)]
pub struct PathContext<'a> {
    pub scene: &'a Scene,
    pub max_depth: usize,
}
