//! plexus: a physically based renderer for difficult light transport.
//!
//! See docs/architecture.md for the architecture. Module boundaries: `accel` answers
//! ray queries (Embree or the in-house BVH), `geometry` holds rays and hits, `sampling` holds every
//! warp with its pdf and inverse, `scene` parses and builds scenes, `camera`/`material`/`light`
//! sample and evaluate, `film` accumulates and writes images, `job` says what a render is asked to
//! do and may use (budget, limits, memory, run control) below everything that renders,
//! `integrator` holds light transport,
//! `stats` and `metrics` measure, `bench` times the accelerators and the path tracer, `process`
//! says what plexus does to its own process (transparent huge pages, flush-to-zero) and why.

pub mod accel;
pub mod bench;
pub mod camera;
pub mod film;
pub mod geometry;
pub mod input_file;
pub mod integrator;
pub mod interrupt;
pub mod job;
pub mod light;
pub mod material;
pub mod metrics;
mod prefetch;
pub mod process;
pub mod sampling;
pub mod scene;
pub mod spectrum;
pub mod state;
pub mod stats;
pub mod texture;
