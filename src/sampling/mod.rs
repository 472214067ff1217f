//! Warps from uniform numbers to domains, each as a trio `sample_*` / `pdf_*` / `invert_*` side by
//! side; discrete and piecewise-constant distributions; deterministic random streams and the
//! `UniformSource` trait every consumer of explicit uniforms reads from; and the
//! chi-square harness that tests them all (see docs/sampling.md for the table of routines).

/// Test-only: the chi-square harness (behind the `testing` feature, which the test targets enable).
#[cfg(any(test, feature = "testing"))]
pub mod chi2;
mod distribution;
mod rng;
mod sobol;
mod source;
pub mod warp;

pub use distribution::{Distribution1D, Distribution2D};
pub use rng::Rng;
pub use sobol::{PixelSampler, SampleStream, SamplerKind, SobolStream};
pub use source::{ReplaySampler, UniformSource};
pub use warp::*;
