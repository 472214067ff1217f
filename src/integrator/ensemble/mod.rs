//! Ensemble Metropolis light transport (Bashford-Rogers et al. 2021, "Ensemble Metropolis Light
//! Transport", Sec. 3–3.4): `integrator = "emlt"`.
//!
//! Two ensembles of path-space chains, X and Y, share the path-space MLT machinery of
//! `path_space` (state, contribution f, strategies, the bidirectional mutation). Every path of X is
//! mutated with Y held fixed, using paths of Y as guides for its perturbations; then the ensembles
//! swap roles (Algorithm 1).
//!
//! - `kernel`: the linear guided kernels (the stretch move in R², the great arc on the sphere),
//!   each with sample, density and reverse ratio side by side.
//! - `similarity`: Eq. 8–9, how close a guide path is to the current path.
//! - `tree`: Y indexed by path signature (length and interaction types), and the subset Υ.
//! - `toy` (tests): the ensemble update on a known 2D target.
//! - `settings`, `guide`: the settings (adaptive α); Y as the guided strategies see it.
//! - `linear`: the linear lens and linear caustic perturbations (guided, with the plain fallback).
//! - `render`: Algorithm 1 on the driver.
//! - `anisotropic`, `directional`: the guided anisotropic kernel (Eq. 11–12, with its
//!   image-plane version) and the guided directional (vMF) kernel; `toy_anisotropic` (tests);
//!   the strategies built on them: `anisotropic_path` and `environment`.
pub mod anisotropic;
pub mod anisotropic_path;
pub mod directional;
pub mod emlt_render;
pub mod emlt_settings;
pub mod environment_perturbation;
pub mod guide;
pub mod guided_kernel;
pub mod linear;
pub mod similarity;
#[cfg(test)]
mod toy;
#[cfg(test)]
mod toy_anisotropic;
pub mod tree;
