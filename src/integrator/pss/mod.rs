//! Primary-sample-space Markov chain methods: the shared Kelemen sampler, PSSMLT, MMLT and RJMLT.

pub mod sampler;

pub use sampler::{MutationSettings, PssSampler};
