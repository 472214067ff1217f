//! Which depth an MMLT/RJMLT iteration renders: the depth choice with its floor, the large-step
//! totals behind it and b_d, and the search that starts the chains of a depth the
//! bootstrap missed (issue 12). A submodule of `mlt` so that it shares the chain types.

use super::{Bootstrap, ChainUnit, Mlt, SlotState, SubChain};
use crate::integrator::bdpt::BdptContext;
use crate::sampling::Distribution1D;
use crate::stats::Counters;

/// Share of the depth choice spread evenly over the depths (MMLT, RJMLT), so that a depth whose
/// b_d estimate is 0 or far too small is still visited: p(d) = (1 − ε)·b̂_d/Σb̂ + ε/D, with b̂_d
/// the chain's estimate (`Mlt::depth_choice`). The MMLT paper (Sec. 4,
/// "Initialization") chooses p(d) ∝ b_d and recommends progressive b as "less likely to miss rare
/// bounces when an initial estimate of b_k is zero but b_k > 0"; but with p(d) ∝ b_d alone a depth
/// whose bootstrap b_d is 0 never receives an iteration, so no large step of it ever refines b_d
/// and its light is lost (issue 12: the door scene with 200 bootstrap paths lost depth 1,
/// b ≈ 5e-4, in 3 of 4 seeds). The estimator does not depend on p(d): each depth's film is divided
/// by the iterations that depth received (module docs, "Normalisation"), so p(d) only moves
/// effort, and the floor costs at most ε of the iterations on depths that carry no light.
const DEPTH_CHOICE_FLOOR: f64 = 0.1;

/// Per depth: the sum and count of large-step targets.
pub(super) type LargeStepTotals = Vec<(f64, u64)>;

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

    /// The depth choice of a chain's next segment: p(d) = (1 − ε)·b̂_d/Σb̂ + ε/D
    /// (`DEPTH_CHOICE_FLOOR`), with b̂_d the bootstrap's estimate refined, under progressive b, by
    /// the chain's own large steps so far (`own`; the MMLT paper's progressive b_k, Sec. 4
    /// "Initialization", applied to the choice as well as to the normalisation). The choice depends
    /// on the chain alone, never on other chains: a chain renders the same segments in a shard as
    /// in the whole render (issue 21), and no pass waits for the others' totals. (The render-wide
    /// totals it once pooled move effort a little sooner; the estimator does not depend on p(d).)
    /// Depths that cannot be recovered (bootstrap b_d = 0 without progressive b: their image is
    /// scaled by b_d = 0) are never chosen.
    pub(super) fn depth_choice(&self, bootstrap: &Bootstrap, own: &LargeStepTotals) -> Distribution1D {
        let depths = self.depth_count();
        let b: Vec<f64> = (0..depths)
            .map(|d| {
                if self.settings.progressive_b {
                    let (sum, n) = own[d];
                    (bootstrap.sums[d] + sum) / (bootstrap.paths + n) as f64
                } else {
                    bootstrap.sums[d] / bootstrap.paths as f64
                }
            })
            .collect();
        let recoverable = |d: usize| self.settings.progressive_b || bootstrap.sums[d] > 0.0;
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
