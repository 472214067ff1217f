//! Primary-sample-space Markov chain methods: the shared Kelemen sampler, PSSMLT, MMLT and RJMLT.

pub mod inverse;
pub mod jump;
pub mod mlt;
pub mod mlt_settings;
pub mod mlt_stats;
pub mod sampler;
/// Test-only: the 1D reversible-jump validation chains (behind the `testing` feature).
#[cfg(any(test, feature = "testing"))]
pub mod validation_1d;

pub use sampler::{MutationSettings, PssSampler, SmallStep};
