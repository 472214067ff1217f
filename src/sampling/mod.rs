//! Warps from uniform numbers to domains, each as a trio `sample_*` / `pdf_*` / `invert_*` side by
//! side; discrete and piecewise-constant distributions; deterministic random streams; and the
//! chi-square harness that tests them all (see docs/sampling.md for the table of routines).

pub mod chi2;
mod distribution;
mod rng;
pub mod warp;

pub use distribution::{Distribution1D, Distribution2D};
pub use rng::Rng;
pub use warp::*;
