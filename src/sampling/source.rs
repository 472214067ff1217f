//! Sources of uniform numbers for code that takes its randomness explicitly (every sampling
//! routine takes its uniforms as arguments, docs/architecture.md "Sampling"):
//! one trait that independent sampling (`Rng`), a prescribed list (`ReplaySampler`) and Markov
//! chains over primary samples (`integrator::pss::PssSampler`) all implement, so the same subpath
//! code runs under each. A source reads one stream in order; which coordinate means what (the
//! per-vertex dimension blocks) is the reader's layout, not the source's.

use super::Rng;

/// A source of uniform numbers in [0, 1), read in order.
pub trait UniformSource {
    fn next_1d(&mut self) -> f32;
    fn next_2d(&mut self) -> [f32; 2] {
        [self.next_1d(), self.next_1d()]
    }
    /// The next `N` numbers, in order.
    fn next_n<const N: usize>(&mut self) -> [f32; N]
    where
        Self: Sized,
    {
        let mut u = [0.0; N];
        for x in &mut u {
            *x = self.next_1d();
        }
        u
    }
    /// Runs `f` on the numbers of branch `k` ≥ 1 of a path split at a vertex (`pt`'s
    /// `first_bounce_paths`). Here: this source itself, read on after the branch before it; a
    /// source with streams of its own (`SampleStream`'s Sobol points) gives each branch one.
    fn with_branch<R>(&mut self, k: u32, f: impl FnOnce(&mut Self) -> R) -> R
    where
        Self: Sized,
    {
        let _ = k;
        f(self)
    }
}

impl UniformSource for Rng {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        self.uniform()
    }
}

/// A recorded or prescribed list of numbers (tests, replays, inverted samples); past its end it
/// reads 0.5 so that a short list still yields a deterministic result.
#[derive(Clone, Debug, Default)]
pub struct ReplaySampler {
    pub values: Vec<f32>,
    pub position: usize,
}

impl UniformSource for ReplaySampler {
    fn next_1d(&mut self) -> f32 {
        let v = self.values.get(self.position).copied().unwrap_or(0.5);
        self.position += 1;
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replay_reads_its_values_in_order_then_one_half() {
        let mut s = ReplaySampler { values: vec![0.25, 0.75, 0.125], position: 0 };
        assert_eq!(s.next_2d(), [0.25, 0.75]);
        assert_eq!(s.next_n::<3>(), [0.125, 0.5, 0.5]);
        assert_eq!(s.position, 5);
    }

    #[test]
    fn rng_source_is_the_rng_stream() {
        let (mut a, mut b) = (Rng::new(7, 3), Rng::new(7, 3));
        let from_source: [f32; 4] = a.next_n();
        let direct = [b.uniform(), b.uniform(), b.uniform(), b.uniform()];
        assert_eq!(from_source, direct);
    }
}
