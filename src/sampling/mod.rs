//! Warps from uniform numbers to domains, each as a trio `sample_*` / `pdf_*` / `invert_*` side by
//! side; discrete and piecewise-constant distributions; deterministic random streams.

mod distribution;
mod rng;

pub use distribution::{Distribution1D, Distribution2D};
pub use rng::Rng;
