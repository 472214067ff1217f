//! The Markov chain integrators' statistical tests: agreement with path tracing and committed references, power-checked, and their deliberately wrong variants.
//!
//! One test binary for these modules: each binary links the whole library, and on two cores
//! linking dominated the suite's build when every file was its own binary.

#[path = "../common/mod.rs"]
mod common;

mod emlt;
mod emlt_part2;
mod mlt;
mod pmlt;
mod portal;
mod refraction;
