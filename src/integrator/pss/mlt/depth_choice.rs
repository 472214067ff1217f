//! Which depth an MMLT/RJMLT iteration renders: the depth choice with its floor, the large-step
//! totals behind it and b_d (pooled with the bootstrap's estimate by inverse variance), and the search that starts the chains of a depth the
//! bootstrap missed. A submodule of `mlt` so that it shares the chain types.

use super::{Bootstrap, ChainUnit, Mlt, SlotState, SubChain};
use crate::integrator::bdpt::BdptContext;
use crate::sampling::Distribution1D;
use crate::stats::Counters;

/// Share of the depth choice spread evenly over the depths (MMLT, RJMLT), so that a depth whose b_d
/// estimate is 0 or far too small is still visited: p(d) = (1 − ε)·b̂_d/Σb̂ + ε/D, with b̂_d the
/// chain's estimate (`Mlt::depth_choice`). The MMLT paper (Sec. 4, "Initialization") chooses p(d) ∝
/// b_d and recommends progressive b as "less likely to miss rare bounces when an initial estimate
/// of b_k is zero but b_k > 0"; but with p(d) ∝ b_d alone a depth whose bootstrap b_d is 0 never
/// receives an iteration, so no large step of it ever refines b_d and its light is lost (the door
/// scene with 200 bootstrap paths loses depth 1, b ≈ 5e-4, in 3 of 4 seeds without the floor). The
/// estimator does not depend on p(d): each depth's film is divided by the iterations that depth
/// received (module docs, "Normalisation"), so p(d) only moves effort, and the floor costs at most
/// ε of the iterations on depths that carry no light.
const DEPTH_CHOICE_FLOOR: f64 = 0.1;

/// Per depth: the sum and count of large-step targets.
pub(super) type LargeStepTotals = Vec<(f64, u64)>;

/// Non-zero samples a variance estimate needs before `BEstimate::pooled` trusts it: with fewer
/// the sample variance of a skewed target (most samples 0, a few large) is itself too uncertain
/// (and too often too small) to weigh by, and the estimates are pooled by their sample counts.
const MIN_NONZERO_FOR_WEIGHTS: u64 = 32;

/// The bootstrap's estimate of one depth's b_d, with what progressive b needs to pool it with the
/// render's large steps.
///
/// **Pooling by inverse variance.** The bootstrap's b_d and the large steps' mean are two unbiased
/// estimates of the same b_d, with different variances per sample: a bootstrap sample is a full
/// BDPT sample averaging all n_d techniques, by default with Sobol numbers, a large step one
/// technique with independent numbers. Pooled sample for sample, the large steps, ~9× more numerous
/// at 64 mutations per pixel, outweigh the more precise bootstrap and *raise* the image
/// brightness's spread over seeds (the shipped Cornell box: 0.29% with the bootstrap's b alone,
/// 0.44% MMLT and 0.88% RJMLT pooled; docs/lab/benchmarks-history.md, "MMLT on the shipped Cornell
/// box"). The minimum-variance unbiased combination of two independent unbiased estimates weighs
/// each by the inverse of its variance: b = (b_B/V_B + b_L·n/σ²_L) / (1/V_B + n/σ²_L), with V_B the
/// variance of the bootstrap's mean and σ²_L that of one large step's target. Both are estimated
/// from the bootstrap alone (`variance` honestly even for the Sobol samples where replicates exist,
/// i.e. at depth 0, as an upper bound elsewhere; `large_step_variance` from the full samples'
/// second moments of each technique), so the weights do not depend on the large steps' values:
/// given the bootstrap, the large steps' term stays unbiased. The weights' dependence on the
/// bootstrap's own samples leaves a bias of order 1/N in b_d, below its standard error by a factor
/// √N.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct BEstimate {
    /// b_d: the mean target of the samples.
    pub mean: f64,
    /// Uniform samples behind `mean`, and how many of them had a non-zero target.
    pub samples: u64,
    pub nonzero: u64,
    /// The variance of `mean` (None for fewer than 2 samples).
    pub variance: Option<f64>,
    /// The variance of one large step's target (None for fewer than 2 samples).
    pub large_step_variance: Option<f64>,
}

impl BEstimate {
    /// b_d from the bootstrap and `n` large steps with targets summing to `sum`, by inverse
    /// variance (the type's docs); by sample counts when either variance rests on fewer than
    /// `MIN_NONZERO_FOR_WEIGHTS` non-zero samples (a depth the bootstrap missed or barely saw:
    /// its large steps must be able to bring b_d up from 0).
    pub fn pooled(&self, (sum, n): (f64, u64)) -> f64 {
        if n == 0 {
            return self.mean;
        }
        let large = sum / n as f64;
        match (self.variance, self.large_step_variance) {
            (Some(v), Some(v_large)) if self.nonzero >= MIN_NONZERO_FOR_WEIGHTS => {
                if !(v > 0.0) {
                    self.mean
                } else if !(v_large > 0.0) {
                    large
                } else {
                    let (w_boot, w_large) = (1.0 / v, n as f64 / v_large);
                    (w_boot * self.mean + w_large * large) / (w_boot + w_large)
                }
            }
            _ => (self.mean * self.samples as f64 + sum) / (self.samples + n) as f64,
        }
    }
}

impl Mlt {
    /// Per depth, the sum and count of every large-step target of the chains so far, pooled in
    /// unit order (so not depending on the threads), for b_d.
    pub(super) fn large_step_totals(&self, units: &[ChainUnit]) -> LargeStepTotals {
        let mut totals = vec![(0.0, 0); self.depth_count()];
        for unit in units {
            for (total, own) in totals.iter_mut().zip(&unit.large_steps) {
                total.0 += own.0;
                total.1 += own.1;
            }
        }
        totals
    }

    /// A sub-chain with no non-zero state yet (its depth's bootstrap found no light) takes a large
    /// step: a uniform sample of (ū, u_t) (RJMLT: of (s, ū)), which counts in b_d like every
    /// large step. The first non-zero one becomes the chain's state. Until then nothing is
    /// splatted and no iteration of the depth is counted, so the depth's image (film ÷ iterations)
    /// is an average over states of chains that have found light; what remains is the start-up
    /// bias of a chain started from a uniform sample restricted to f̂ > 0 instead of ∝ f̂, which
    /// vanishes as the chain runs (as does that of the bootstrap's finite resampling), and the
    /// finite-sample effect of stopping each chain's search at its first success on b_d, which
    /// the chain's later large steps dilute: the estimator is consistent.
    pub(super) fn search(
        &self,
        ctx: &BdptContext,
        d: usize,
        chain: &mut SubChain,
        slot: &mut SlotState,
        counters: &mut Counters,
    ) -> f32 {
        chain.sampler.start_iteration_with(true);
        let proposal = self.evaluate(ctx, d, &mut chain.sampler, None, slot, counters);
        counters.samples += 1;
        slot.stats.per_depth[d].search_steps += 1;
        let target = proposal.target;
        if target > 0.0 {
            slot.stats.per_depth[d].searches_found += 1;
            chain.sampler.accept();
            chain.current = proposal;
        } else {
            chain.sampler.reject();
        }
        target
    }

    /// b_d from the bootstrap's estimate and, with progressive b, the large steps' totals
    /// (`BEstimate::pooled`).
    pub(super) fn b_estimate(&self, estimate: &BEstimate, large_steps: (f64, u64)) -> f64 {
        if self.settings.progressive_b {
            estimate.pooled(large_steps)
        } else {
            estimate.mean
        }
    }

    /// The depth choice of a chain's next segment: p(d) = (1 − ε)·b̂_d/Σb̂ + ε/D
    /// (`DEPTH_CHOICE_FLOOR`), with b̂_d the bootstrap's estimate refined, under progressive b, by
    /// the chain's own large steps so far (`own`; the MMLT paper's progressive b_k, Sec. 4
    /// "Initialization", applied to the choice as well as to the normalisation). The choice depends
    /// on the chain alone, never on other chains: a chain renders the same segments in a shard as
    /// in the whole render, and no pass waits for the others' totals. (Render-wide totals would
    /// move effort a little sooner; the estimator does not depend on p(d).)
    /// Depths that cannot be recovered (bootstrap b_d = 0 without progressive b: their image is
    /// scaled by b_d = 0) are never chosen, nor depth 0 when the camera estimator renders it.
    pub(super) fn depth_choice(&self, bootstrap: &Bootstrap, own: &LargeStepTotals) -> Distribution1D {
        let depths = self.depth_count();
        // Depth 0 with the camera estimator is not the chains' (`chains_render`): b_0 leaves the
        // choice, which then spreads over depths ≥ 1 only.
        let b: Vec<f64> = (0..depths)
            .map(|d| if self.chains_render(d) { self.b_estimate(&bootstrap.estimates[d], own[d]) } else { 0.0 })
            .collect();
        let recoverable = |d: usize| self.chains_render(d) && (self.settings.progressive_b || bootstrap.found[d]);
        let recoverable_depths = (0..depths).filter(|&d| recoverable(d)).count().max(1) as f64;
        let total: f64 = b.iter().sum();
        let weights: Vec<f32> = (0..depths)
            .map(|d| {
                let share = if total > 0.0 { b[d] / total } else { 0.0 };
                let floor = if recoverable(d) { DEPTH_CHOICE_FLOOR / recoverable_depths } else { 0.0 };
                ((1.0 - DEPTH_CHOICE_FLOOR) * share + floor) as f32
            })
            .collect();
        Distribution1D::new(&weights)
    }
}

#[cfg(test)]
mod tests {
    use super::{BEstimate, MIN_NONZERO_FOR_WEIGHTS};

    fn estimate(mean: f64, samples: u64, variance: f64, large_step_variance: f64) -> BEstimate {
        BEstimate {
            mean,
            samples,
            nonzero: samples,
            variance: Some(variance),
            large_step_variance: Some(large_step_variance),
        }
    }

    /// Inverse-variance pooling (`BEstimate::pooled`): with the bootstrap's per-sample variance
    /// equal to a large step's it is pooling by sample counts; a bootstrap 100× more
    /// precise than the large steps together gets weight 100/101, where pooling by counts would
    /// give the 900,000 large steps 90% of the weight (the wrong variant: 1.0 + 0.9·(1.1 − 1.0)
    /// = 1.09 here against 1.00099); without enough non-zero samples to trust a variance, or
    /// without large steps, it falls back as documented.
    #[test]
    fn large_steps_are_pooled_by_inverse_variance() {
        let (sum, n) = (1.1 * 900_000.0, 900_000u64);
        // Equal per-sample variances σ² = 4: V_B = σ²/N.
        let equal = estimate(1.0, 100_000, 4.0 / 100_000.0, 4.0);
        let by_counts = (1.0 * 100_000.0 + sum) / 1_000_000.0;
        assert!((equal.pooled((sum, n)) - by_counts).abs() < 1e-12, "{}", equal.pooled((sum, n)));
        // The large steps' mean has variance 4/900,000; the bootstrap's 100× less.
        let precise = estimate(1.0, 100_000, 4.0 / 90_000_000.0, 4.0);
        let expected = (100.0 * 1.0 + 1.0 * 1.1) / 101.0;
        assert!((precise.pooled((sum, n)) - expected).abs() < 1e-12, "{}", precise.pooled((sum, n)));
        assert_eq!(precise.pooled((0.0, 0)), 1.0);
        // Too few non-zero samples: by counts, so a depth the bootstrap missed is recovered.
        let rare = BEstimate { nonzero: MIN_NONZERO_FOR_WEIGHTS - 1, ..precise };
        assert!((rare.pooled((sum, n)) - by_counts).abs() < 1e-12);
        let missed = BEstimate { mean: 0.0, nonzero: 0, variance: Some(0.0), ..precise };
        assert!((missed.pooled((sum, n)) - sum / 1_000_000.0).abs() < 1e-12);
        // A bootstrap without variance (a constant target) is exact.
        let exact = estimate(1.0, 100_000, 0.0, 4.0);
        assert_eq!(exact.pooled((sum, n)), 1.0);
    }
}
