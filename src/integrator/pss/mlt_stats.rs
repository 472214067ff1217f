//! The statistics of the Markov chain integrators (`pssmlt`, `mmlt`, `rjmlt`), typed: every worker
//! slot accumulates one [`MltStats`], the slots are combined by [`MltStats::merge`] in slot order,
//! [`MltStats::finish`] derives the rates, and serde writes the result as the render's
//! `integrator_stats` JSON (tests/chains/mlt.rs, scripts/bench-mlt.sh and scripts/fig4_table.py read it by
//! these field names). A new statistic is one field here, plus its line in `merge`.

use serde::{Deserialize, Serialize, Serializer};

use super::inverse::InversionFailure;
use crate::stats::AcceptanceCount;

/// The kind of a proposal, for the per-move-type statistics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKind {
    Large,
    Small,
    Jump,
}

/// Proposals of one move type (large step, small step, technique jump), with the same measures for
/// all three integrators so that they are comparable.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct MoveStats {
    /// Proposals made (a jump that chose the current technique proposes nothing and is counted in
    /// `JumpStats::to_same_technique` instead).
    pub proposals: u64,
    /// Proposals accepted (the Metropolis coin, not the expected-value weight).
    pub accepted: u64,
    /// Proposals whose target (luminance of the state's contribution) is non-zero.
    pub nonzero_proposals: u64,
    /// Technique paths the proposals evaluated: PSSMLT evaluates every (s, t) connection of its
    /// two subpaths, MMLT and RJMLT one technique, a technique jump one (also when its inverse
    /// fails or regenerates another path: that proposal is one path that contributed nothing).
    pub paths_evaluated: u64,
    /// Of those, the paths with a non-zero contribution.
    pub paths_nonzero: u64,
    /// Derived by `finish`: accepted / proposals (null without proposals).
    pub acceptance: Option<f64>,
    /// Derived by `finish`: the effective path ratio, paths_nonzero / paths_evaluated (the share of
    /// evaluated technique paths that carried light; null without proposals).
    pub effective_path_ratio: Option<f64>,
}

impl MoveStats {
    pub fn merge(&mut self, o: &MoveStats) {
        self.proposals += o.proposals;
        self.accepted += o.accepted;
        self.nonzero_proposals += o.nonzero_proposals;
        self.paths_evaluated += o.paths_evaluated;
        self.paths_nonzero += o.paths_nonzero;
    }

    fn finish(&mut self) {
        self.acceptance = ratio(self.accepted, self.proposals);
        self.effective_path_ratio = ratio(self.paths_nonzero, self.paths_evaluated);
    }
}

/// Per move type. `jump` is null except for RJMLT.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct MoveTypes {
    pub large: MoveStats,
    pub small: MoveStats,
    pub jump: Option<MoveStats>,
}

impl MoveTypes {
    pub fn get_mut(&mut self, kind: MoveKind) -> Option<&mut MoveStats> {
        match kind {
            MoveKind::Large => Some(&mut self.large),
            MoveKind::Small => Some(&mut self.small),
            MoveKind::Jump => self.jump.as_mut(),
        }
    }

    fn all(&self) -> impl Iterator<Item = &MoveStats> {
        [&self.large, &self.small].into_iter().chain(self.jump.as_ref())
    }
}

/// Iterations with technique (s, t) as the chain's state (MMLT paper, Fig. 5).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct TechniqueCount {
    pub s: usize,
    pub t: usize,
    pub iterations: u64,
}

/// One path depth's chains (PSSMLT: the one chain over all depths).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct DepthStats {
    /// Scattering events; null for PSSMLT.
    pub depth: Option<usize>,
    /// Set by `finish`: b_d from the bootstrap alone, and the b_d the image was normalised with.
    pub b_bootstrap: f64,
    pub b: f64,
    /// The relative standard error of `b_bootstrap` (its uniform samples' spread; null when the
    /// bootstrap found no light at the depth). PSSMLT's one chain and path-space MLT leave it null.
    pub b_bootstrap_relative_se: Option<f64>,
    /// Iterations of the depth's chains (what its film is divided by).
    pub iterations: u64,
    /// Large steps of sub-chains still searching for their first non-zero state (a depth the
    /// bootstrap missed; not iterations), and how many searches found one.
    pub search_steps: u64,
    pub searches_found: u64,
    /// Large steps (searches included) and the sum of their targets: the render's uniform
    /// samples of the depth, which refine b_d under progressive b.
    pub large_steps: u64,
    pub large_step_target_sum: f64,
    /// All proposals of the depth; serialised as the acceptance rate.
    #[serde(serialize_with = "rate_or_zero")]
    pub acceptance: AcceptanceCount,
    /// Small steps (RJMLT paper Fig. 4 (a)); serialised as the rate, null without any.
    #[serde(rename = "small_step_acceptance", serialize_with = "rate_or_null")]
    pub small_steps: AcceptanceCount,
    /// MMLT: small steps whose proposal has another technique (Fig. 4 (b)); null otherwise.
    #[serde(serialize_with = "proposals_and_rate")]
    pub technique_change: Option<AcceptanceCount>,
    /// RJMLT: technique jumps to another technique (Fig. 4 (c)); null otherwise.
    #[serde(serialize_with = "proposals_and_rate")]
    pub jumps: Option<AcceptanceCount>,
    /// MMLT, RJMLT: per technique s, iterations with it as the state; null for PSSMLT.
    pub technique_state_counts: Option<Vec<TechniqueCount>>,
}

impl DepthStats {
    fn merge(&mut self, o: &DepthStats) {
        self.iterations += o.iterations;
        self.search_steps += o.search_steps;
        self.searches_found += o.searches_found;
        self.large_steps += o.large_steps;
        self.large_step_target_sum += o.large_step_target_sum;
        self.acceptance.merge(&o.acceptance);
        self.small_steps.merge(&o.small_steps);
        merge_option(&mut self.technique_change, &o.technique_change, AcceptanceCount::merge);
        merge_option(&mut self.jumps, &o.jumps, AcceptanceCount::merge);
        merge_option(&mut self.technique_state_counts, &o.technique_state_counts, |a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                x.iterations += y.iterations;
            }
        });
    }
}

/// RJMLT's technique jumps over all depths.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct JumpStats {
    /// Derived by `finish` from the per-depth jumps: jumps to another technique and their
    /// acceptance (null without any).
    pub proposals: u64,
    pub acceptance: Option<f64>,
    /// Jumps that chose the current technique (nothing changes).
    pub to_same_technique: u64,
    /// Inverses that failed, by `InversionFailure::ALL` order; serialised by failure name.
    #[serde(serialize_with = "failures_by_name")]
    pub inversion_failures: [u64; 5],
    /// Inverses whose regenerated path is not the current one.
    pub path_mismatches: u64,
    /// Valid jumps whose ratio r of Eq. 38/43 was off 1 by more than 1e-3, and the largest |r − 1|.
    /// A diagnostic of rounding only: r's density ratio comes from the two techniques' own f/p of
    /// the same path, so r is 1 by construction whatever the Jacobians; the Jacobians are checked
    /// against BDPT's densities by `pss/inverse.rs`'s tests, not by these figures.
    #[serde(rename = "ratio_off_by_more_than_1e-3")]
    pub ratio_off: u64,
    pub ratio_max_deviation: f64,
}

impl JumpStats {
    fn merge(&mut self, o: &JumpStats) {
        self.to_same_technique += o.to_same_technique;
        for (a, b) in self.inversion_failures.iter_mut().zip(&o.inversion_failures) {
            *a += b;
        }
        self.path_mismatches += o.path_mismatches;
        self.ratio_off += o.ratio_off;
        self.ratio_max_deviation = self.ratio_max_deviation.max(o.ratio_max_deviation);
    }
}

/// Path-space MLT: the proposals of one mutation strategy (`integrator::path_space`), so that
/// every strategy a render ran says how often it was chosen, how often it produced a path and how
/// often that path was taken.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct StrategyStats {
    pub name: String,
    /// Iterations that chose the strategy (among the strategies suitable for the current path).
    pub selected: u64,
    /// Of those, the proposals that failed before a path existed (a ray escaped, a sample failed,
    /// the new path would be too long): rejected without an evaluation.
    pub generation_failures: u64,
    /// Proposals with a non-zero contribution f(ȳ) (the rest are rejected: a = 0).
    pub nonzero_proposals: u64,
    /// Proposals accepted (the Metropolis coin), and the sum of their acceptance probabilities
    /// (what expected-value splatting weights the proposals by).
    pub accepted: u64,
    pub acceptance_probability_sum: ProbabilitySum,
    /// Per depth (scattering events) of the current path: the strategy's proposals and their
    /// acceptance; serialised as proposals and rate.
    #[serde(serialize_with = "per_depth_counts")]
    pub per_depth: Vec<AcceptanceCount>,
    /// Of the generation failures, those whose strategy named a cause (`Counters::early_rejection`),
    /// by cause: e.g. the portal perturbation's "occluded" or "reverse_inconsistent".
    #[serde(default)]
    pub early_rejections: std::collections::BTreeMap<String, u64>,
    /// Derived by `finish`: accepted / selected and the mean acceptance probability (null without
    /// selections).
    pub acceptance: Option<f64>,
    pub mean_acceptance_probability: Option<f64>,
}

/// A sum of probabilities (values in [0, 1]) held exactly as an integer count of 2^-64, so that
/// the slots' sums merge to the same bits however the chains were dealt to threads: the last bits
/// of an f64 sum depend on the grouping, and a state's bytes must not depend on the threads
/// (`crate::state`; pmlt's shards differed with 1 and 2 threads when this was an f64). Each value
/// added is rounded to the nearest 2^-64 (an error of at most 2^-65 each, below f64's own spacing
/// at every probability above 2^-12); u128 holds 2^64 values of 1. The JSON report shows the f64
/// it stands for, a state file (bincode) the integer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProbabilitySum(u128);

impl ProbabilitySum {
    const ONE: f64 = 18_446_744_073_709_551_616.0; // 2^64

    pub fn value(&self) -> f64 {
        self.0 as f64 / Self::ONE
    }
}

impl std::ops::AddAssign<f64> for ProbabilitySum {
    fn add_assign(&mut self, p: f64) {
        // p · 2^64 is exact (a power-of-two scale); `as` saturates, and sends a NaN to 0.
        self.0 += (p.clamp(0.0, 1.0) * Self::ONE).round() as u128;
    }
}

impl std::ops::AddAssign for ProbabilitySum {
    fn add_assign(&mut self, o: ProbabilitySum) {
        self.0 += o.0;
    }
}

impl Serialize for ProbabilitySum {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            s.serialize_f64(self.value())
        } else {
            s.serialize_u128(self.0)
        }
    }
}

impl<'de> Deserialize<'de> for ProbabilitySum {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() {
            let mut sum = ProbabilitySum::default();
            sum += f64::deserialize(d)?;
            Ok(sum)
        } else {
            u128::deserialize(d).map(ProbabilitySum)
        }
    }
}

impl StrategyStats {
    pub fn new(name: &str, depths: usize) -> StrategyStats {
        StrategyStats {
            name: name.to_string(),
            per_depth: vec![AcceptanceCount::default(); depths],
            ..Default::default()
        }
    }

    fn merge(&mut self, o: &StrategyStats) {
        self.selected += o.selected;
        self.generation_failures += o.generation_failures;
        self.nonzero_proposals += o.nonzero_proposals;
        self.accepted += o.accepted;
        self.acceptance_probability_sum += o.acceptance_probability_sum;
        for (a, b) in self.per_depth.iter_mut().zip(&o.per_depth) {
            a.merge(b);
        }
        for (cause, n) in &o.early_rejections {
            *self.early_rejections.entry(cause.clone()).or_default() += n;
        }
    }

    /// The strategy's proposals as a move type (for the render-wide totals).
    fn as_moves(&self) -> MoveStats {
        MoveStats {
            proposals: self.selected,
            accepted: self.accepted,
            nonzero_proposals: self.nonzero_proposals,
            paths_evaluated: self.selected,
            paths_nonzero: self.nonzero_proposals,
            ..MoveStats::default()
        }
    }
}

/// Everything a PSSMLT, MMLT or RJMLT render reports besides the image and the shared counters.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct MltStats {
    /// Derived by `finish`: proposals over all depths and move types, and per pixel.
    pub mutations: u64,
    pub mutations_per_pixel: f64,
    /// Set by the render: driver passes, iterations per chain and pass, uniform bootstrap samples
    /// per depth and the bootstrap's wall time.
    pub passes: u64,
    pub segment_length: u64,
    pub bootstrap_paths_per_depth: u64,
    pub bootstrap_seconds: f64,
    /// MMLT, RJMLT: the relative standard error of the bootstrap's Σ_d n_d·b_d (the image's
    /// luminance when b is the bootstrap's), from its samples' spread; null for PSSMLT, path-space
    /// MLT, and a bootstrap without light.
    pub b_bootstrap_total_relative_se: Option<f64>,
    /// Derived by `finish`, over all proposals: acceptance, effective path ratio (non-zero
    /// technique paths / evaluated; see `MoveStats`), share of proposals with a non-zero target,
    /// and technique paths evaluated.
    pub acceptance: f64,
    pub effective_path_ratio: f64,
    pub nonzero_proposal_ratio: f64,
    pub technique_paths_evaluated: u64,
    /// Per move type: the same measures for the three integrators.
    pub moves: MoveTypes,
    /// RJMLT only.
    pub jumps: Option<JumpStats>,
    /// Path-space MLT only: per mutation strategy (null for the primary-sample-space methods,
    /// whose `moves` are then zero: a path-space proposal is neither a large nor a small step).
    pub strategies: Option<Vec<StrategyStats>>,
    pub per_depth: Vec<DepthStats>,
    pub warnings: Vec<String>,
}

impl MltStats {
    /// Empty statistics with the shape of the method: per-depth entries (with `techniques[d]`
    /// techniques each when `per_technique`), technique-change counts for MMLT, jump counts for
    /// RJMLT.
    pub fn new(techniques: &[usize], per_technique: bool, mmlt: bool, rjmlt: bool) -> MltStats {
        let depths = techniques.len();
        let per_depth = techniques
            .iter()
            .enumerate()
            .map(|(d, &n)| DepthStats {
                depth: (depths > 1).then_some(d),
                technique_change: mmlt.then(AcceptanceCount::default),
                jumps: rjmlt.then(AcceptanceCount::default),
                technique_state_counts: per_technique
                    .then(|| (0..n).map(|s| TechniqueCount { s, t: d + 2 - s, iterations: 0 }).collect()),
                ..DepthStats::default()
            })
            .collect();
        MltStats {
            moves: MoveTypes { jump: rjmlt.then(MoveStats::default), ..MoveTypes::default() },
            jumps: rjmlt.then(JumpStats::default),
            per_depth,
            ..MltStats::default()
        }
    }

    /// Adds another slot's counts (the derived and the render-level fields are left alone).
    pub fn merge(&mut self, o: &MltStats) {
        for (a, b) in self.per_depth.iter_mut().zip(&o.per_depth) {
            a.merge(b);
        }
        self.moves.large.merge(&o.moves.large);
        self.moves.small.merge(&o.moves.small);
        merge_option(&mut self.moves.jump, &o.moves.jump, MoveStats::merge);
        merge_option(&mut self.jumps, &o.jumps, JumpStats::merge);
        merge_option(&mut self.strategies, &o.strategies, |a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                x.merge(y);
            }
        });
    }

    /// Derives the rates and totals from the merged counts, with the b_d of the image.
    pub fn finish(&mut self, pixels: u64, b_bootstrap: &[f64], b: &[f64]) {
        for (d, depth) in self.per_depth.iter_mut().enumerate() {
            depth.b_bootstrap = b_bootstrap[d];
            depth.b = b[d];
        }
        self.moves.large.finish();
        self.moves.small.finish();
        if let Some(jump) = self.moves.jump.as_mut() {
            jump.finish();
        }
        let mut all = MoveStats::default();
        for m in self.moves.all() {
            all.merge(m);
        }
        for strategy in self.strategies.iter_mut().flatten() {
            all.merge(&strategy.as_moves());
            strategy.acceptance = ratio(strategy.accepted, strategy.selected);
            strategy.mean_acceptance_probability =
                (strategy.selected > 0).then(|| strategy.acceptance_probability_sum.value() / strategy.selected as f64);
        }
        self.mutations = all.proposals;
        self.mutations_per_pixel = all.proposals as f64 / pixels.max(1) as f64;
        self.acceptance = ratio(all.accepted, all.proposals).unwrap_or(0.0);
        self.effective_path_ratio = ratio(all.paths_nonzero, all.paths_evaluated).unwrap_or(0.0);
        self.nonzero_proposal_ratio = ratio(all.nonzero_proposals, all.proposals).unwrap_or(0.0);
        self.technique_paths_evaluated = all.paths_evaluated;
        if let Some(jumps) = self.jumps.as_mut() {
            let mut total = AcceptanceCount::default();
            for j in self.per_depth.iter().filter_map(|d| d.jumps.as_ref()) {
                total.merge(j);
            }
            jumps.proposals = total.proposed;
            jumps.acceptance = (total.proposed > 0).then(|| total.rate());
        }
    }
}

fn ratio(a: u64, b: u64) -> Option<f64> {
    (b > 0).then(|| a as f64 / b as f64)
}

fn merge_option<T>(a: &mut Option<T>, b: &Option<T>, merge: impl Fn(&mut T, &T)) {
    if let (Some(a), Some(b)) = (a.as_mut(), b.as_ref()) {
        merge(a, b);
    }
}

// The JSON report shows rates and names; a state file (bincode, not human-readable) keeps the
// counts themselves, which the derived `Deserialize` reads back.
fn rate_or_zero<S: Serializer>(a: &AcceptanceCount, s: S) -> Result<S::Ok, S::Error> {
    if !s.is_human_readable() {
        return a.serialize(s);
    }
    s.serialize_f64(a.rate())
}

fn rate_or_null<S: Serializer>(a: &AcceptanceCount, s: S) -> Result<S::Ok, S::Error> {
    if !s.is_human_readable() {
        return a.serialize(s);
    }
    (a.proposed > 0).then(|| a.rate()).serialize(s)
}

fn proposals_and_rate<S: Serializer>(a: &Option<AcceptanceCount>, s: S) -> Result<S::Ok, S::Error> {
    if !s.is_human_readable() {
        return a.serialize(s);
    }
    #[derive(Serialize)]
    struct ProposalsAndRate {
        proposals: u64,
        acceptance: Option<f64>,
    }
    a.map(|a| ProposalsAndRate { proposals: a.proposed, acceptance: (a.proposed > 0).then(|| a.rate()) }).serialize(s)
}

fn per_depth_counts<S: Serializer>(counts: &[AcceptanceCount], s: S) -> Result<S::Ok, S::Error> {
    // A state file (bincode) keeps the counts themselves, so that they deserialise (pmlt's part).
    if !s.is_human_readable() {
        return counts.serialize(s);
    }
    #[derive(Serialize)]
    struct ProposalsAndRate {
        proposals: u64,
        acceptance: Option<f64>,
    }
    s.collect_seq(
        counts
            .iter()
            .map(|a| ProposalsAndRate { proposals: a.proposed, acceptance: (a.proposed > 0).then(|| a.rate()) }),
    )
}

fn failures_by_name<S: Serializer>(counts: &[u64; 5], s: S) -> Result<S::Ok, S::Error> {
    if !s.is_human_readable() {
        return counts.serialize(s);
    }
    s.collect_map(InversionFailure::ALL.iter().map(|f| f.name()).zip(counts))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The JSON keys and shape the tests and scripts read, and a merge that adds counts.
    /// Probability sums merge to the same bits in any grouping (an f64 sum of these values does
    /// not: ((0.1 + 0.2) + 0.3) ≠ (0.1 + (0.2 + 0.3)) in f64), and read back from a state's bytes.
    #[test]
    fn probability_sums_do_not_depend_on_the_grouping() {
        let values = [0.1, 0.2, 0.3, 0.7, 1.0, 1e-9, 0.999_999];
        let sum_of = |vs: &[f64]| {
            let mut s = ProbabilitySum::default();
            for &v in vs {
                s += v;
            }
            s
        };
        let all = sum_of(&values);
        for split in 1..values.len() {
            let mut parts = sum_of(&values[..split]);
            parts += sum_of(&values[split..]);
            assert_eq!(parts, all, "split at {split}");
        }
        assert!((all.value() - values.iter().sum::<f64>()).abs() < 1e-14);
        assert_ne!((0.1f64 + 0.2) + 0.3, 0.1 + (0.2 + 0.3), "the f64 counterexample");
        let bytes = crate::state::encode(&all).expect("encode");
        assert_eq!(crate::state::decode::<ProbabilitySum>(&bytes).expect("decode"), all);
    }

    #[test]
    fn merged_statistics_serialise_with_the_keys_the_readers_use() {
        let mut a = MltStats::new(&[1, 3], true, false, true);
        a.per_depth[1].iterations = 3;
        a.per_depth[1].jumps = Some(AcceptanceCount { proposed: 4, accepted: 2.0 });
        a.moves.small =
            MoveStats { proposals: 10, accepted: 5, paths_evaluated: 10, paths_nonzero: 8, ..MoveStats::default() };
        let mut b = a.clone();
        if let Some(j) = b.jumps.as_mut() {
            j.ratio_max_deviation = 0.5;
        }
        a.merge(&b);
        a.finish(4, &[0.0, 1.0], &[0.5, 2.0]);
        let json = serde_json::to_value(&a).expect("serialises");
        assert_eq!(json["per_depth"][1]["iterations"], 6);
        assert_eq!(json["per_depth"][1]["b"], 2.0);
        assert_eq!(json["per_depth"][1]["jumps"]["proposals"], 8);
        assert_eq!(json["per_depth"][0]["small_step_acceptance"], serde_json::Value::Null);
        assert_eq!(json["per_depth"][0]["technique_change"], serde_json::Value::Null);
        assert_eq!(json["per_depth"][1]["technique_state_counts"][2]["t"], 1);
        assert_eq!(json["jumps"]["proposals"], 8);
        assert_eq!(json["jumps"]["ratio_max_deviation"], 0.5);
        assert!(json["jumps"]["inversion_failures"].as_object().is_some_and(|m| m.len() == 5));
        assert_eq!(json["jumps"]["ratio_off_by_more_than_1e-3"], 0);
        assert_eq!(json["mutations"], 20);
        assert_eq!(json["moves"]["small"]["effective_path_ratio"], 0.8);
        assert_eq!(json["moves"]["large"]["acceptance"], serde_json::Value::Null);
        assert_eq!(json["effective_path_ratio"], 0.8);
    }
}
