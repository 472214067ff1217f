//! The image integrators, materials, scenes, accelerators, metrics and the native libraries: agreement, golden hashes, extremes.
//!
//! One test binary for these modules: each binary links the whole library, and on two cores
//! linking dominated the suite's build when every file was its own binary.

#[path = "../common/mod.rs"]
mod common;

mod accel;
mod bdpt;
mod crosscheck;
mod extremes;
mod ffi;
mod golden;
mod import;
mod materials;
mod metrics;
mod pt;
mod scene;
