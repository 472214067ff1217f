//! The strategy interface every path-space mutation implements (docs/architecture.md, "The
//! path-space family"), and the set of strategies a chain chooses from.
//!
//! A strategy has `suitable`, `propose` and `transition` side by side: `transition(x̄, ȳ, change)`
//! is the density (in the module's measure) with which `propose` from x̄ makes that change and
//! produces ȳ, computed from the two paths and the change's record, so that the reverse density is
//! the same function called the other way with the reverse change. The kernel
//! (the distributions a strategy draws its changes from: deletion and addition lengths for the
//! bidirectional mutation; direction, lens or stretch kernels for the perturbations of issues
//! 14–16) is a separate value, handed to both.
//!
//! Selection: strategy i has a weight w_i; at path x̄ its effective weight is w_i, or, for a
//! perturbation, w_i / m(x̄) with m(x̄) the number of perturbations suitable at x̄ (so that with
//! equal weights the perturbations split their share equally among the suitable ones, the ensemble
//! paper's setting: bidirectional 1/3, perturbations 2/3), and it is chosen with probability
//! P_i(x̄) = w_i(x̄) / Σ_{j suitable at x̄} w_j(x̄), renormalised over the strategies suitable for x̄
//! (the portal paper, Sec. 4.5). P_i enters the acceptance both ways,
//!   a = min(1, f*(ȳ) P_i(ȳ) T_i(ȳ→x̄) / (f*(x̄) P_i(x̄) T_i(x̄→ȳ))),
//! since the reverse move must choose the same strategy at ȳ, whose suitable set may differ.

use super::path_state::PathState;
use super::PathContext;
use crate::sampling::Rng;
use crate::stats::Counters;

/// A path-space mutation strategy with its kernel type.
pub trait Strategy: Send + Sync {
    /// The distributions the strategy draws from (a separate value, see the module docs).
    type Kernel: Send + Sync;
    /// What a proposal records of the change it made (the bidirectional mutation: which vertices
    /// it deleted and how many it added), so that the reverse density is that of the reverse change.
    /// Where a deterministic step (a specular bounce) regenerates a vertex bit for bit, several
    /// changes can turn x̄ into the same ȳ; the record keeps each change paired with its own
    /// reverse, which is what detailed balance needs (Metropolis–Hastings with the change as an
    /// auxiliary choice; Mitsuba's `MutationRecord` does the same).
    type Move: Copy + Send + Sync;

    /// The name in the statistics (`integrator_stats.strategies[].name`).
    fn name(&self) -> &'static str;

    /// Whether the strategy can produce a change of `path` (and so is offered at it).
    fn suitable(&self, ctx: &PathContext, path: &PathState) -> bool;

    /// Whether the strategy is a perturbation: perturbations share their weight equally among
    /// those suitable at a path (the module docs, "Selection"); other strategies (the
    /// bidirectional mutation) keep theirs.
    fn is_perturbation(&self) -> bool {
        false
    }

    /// A proposal from `path`, with f evaluated, and the change that made it; None when the
    /// generation fails before a complete path exists (a ray leaves the scene, a sample fails): a
    /// rejection.
    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &Self::Kernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, Self::Move)>;

    /// T(from → to) by the change `mv`: the density of `propose` from `from` making that change and
    /// producing `to`, in the module's measure (0 when it cannot). The reverse density is the same
    /// function, T(to → from) = `transition(to, from, reverse(mv))`.
    fn transition(
        &self,
        ctx: &PathContext,
        kernel: &Self::Kernel,
        from: &PathState,
        to: &PathState,
        mv: &Self::Move,
    ) -> f64;

    /// The change that undoes `mv` (from the proposal back to the path it came from).
    fn reverse(&self, mv: &Self::Move) -> Self::Move;
}

/// A proposal with its transition densities both ways, for the chain's acceptance.
pub struct Proposed {
    pub path: PathState,
    /// T(x̄ → ȳ) and T(ȳ → x̄); both 0 when f(ȳ) = 0 (the proposal is rejected without them).
    pub forward: f64,
    pub reverse: f64,
}

/// A strategy, its kernel and its selection weight: one entry of a chain's strategy set.
pub struct Entry<S: Strategy> {
    pub strategy: S,
    pub kernel: S::Kernel,
    pub weight: f64,
}

/// The object-safe face of an [`Entry`], so that a chain holds strategies of different types.
pub trait Mutation: Send + Sync {
    fn name(&self) -> &'static str;
    fn weight(&self) -> f64;
    fn is_perturbation(&self) -> bool;
    fn suitable(&self, ctx: &PathContext, path: &PathState) -> bool;
    /// A proposal from `path` with T both ways (computed only when f(ȳ) > 0).
    fn propose(&self, ctx: &PathContext, path: &PathState, rng: &mut Rng, counters: &mut Counters) -> Option<Proposed>;
}

impl<S: Strategy> Mutation for Entry<S> {
    fn name(&self) -> &'static str {
        self.strategy.name()
    }
    fn weight(&self) -> f64 {
        self.weight
    }
    fn is_perturbation(&self) -> bool {
        self.strategy.is_perturbation()
    }
    fn suitable(&self, ctx: &PathContext, path: &PathState) -> bool {
        self.strategy.suitable(ctx, path)
    }
    fn propose(&self, ctx: &PathContext, path: &PathState, rng: &mut Rng, counters: &mut Counters) -> Option<Proposed> {
        let (y, mv) = self.strategy.propose(ctx, path, &self.kernel, rng, counters)?;
        let (forward, reverse) = if y.f_star > 0.0 {
            let back = self.strategy.reverse(&mv);
            (
                self.strategy.transition(ctx, &self.kernel, path, &y, &mv),
                self.strategy.transition(ctx, &self.kernel, &y, path, &back),
            )
        } else {
            (0.0, 0.0)
        };
        Some(Proposed { path: y, forward, reverse })
    }
}

/// The strategies a chain chooses from, in a fixed order (the statistics' order).
pub struct StrategySet {
    pub entries: Vec<Box<dyn Mutation>>,
}

impl StrategySet {
    /// The effective weights w_i(path) (module docs, "Selection"), 0 where a strategy is not suitable.
    pub fn weights(&self, ctx: &PathContext, path: &PathState) -> Vec<f64> {
        let mut w: Vec<f64> = self
            .entries
            .iter()
            .map(|e| if e.weight() > 0.0 && e.suitable(ctx, path) { e.weight() } else { 0.0 })
            .collect();
        let perturbations = self.entries.iter().zip(&w).filter(|(e, &w)| e.is_perturbation() && w > 0.0).count();
        for (e, w) in self.entries.iter().zip(w.iter_mut()) {
            if e.is_perturbation() {
                *w /= perturbations.max(1) as f64;
            }
        }
        w
    }

    /// P_i(path): strategy i's effective weight over the total at `path` (0 when i is not
    /// suitable there).
    pub fn probability(&self, ctx: &PathContext, path: &PathState, i: usize) -> f64 {
        let w = self.weights(ctx, path);
        let total: f64 = w.iter().sum();
        if total > 0.0 {
            w.get(i).copied().unwrap_or(0.0) / total
        } else {
            0.0
        }
    }

    /// Chooses a strategy for `path` with the uniform `u`: its index and P_i(path). None when no
    /// strategy is suitable.
    pub fn choose(&self, ctx: &PathContext, path: &PathState, u: f64) -> Option<(usize, f64)> {
        let weights = self.weights(ctx, path);
        let total: f64 = weights.iter().sum();
        if !(total > 0.0) {
            return None;
        }
        let mut target = u * total;
        let mut last = None;
        for (i, &w) in weights.iter().enumerate() {
            if w > 0.0 {
                last = Some(i);
                if target < w {
                    return Some((i, w / total));
                }
                target -= w;
            }
        }
        last.map(|i| (i, weights[i] / total))
    }
}
