//! The bootstrap every Markov chain integrator starts from (PSSMLT, MMLT, RJMLT and path-space MLT):
//! up to `requested` independent samples per depth slot, each evaluated by the integrator's own
//! `sample(depth, index, ...)` from a stream of its own (so a chain can later replay the sample it
//! starts from exactly), run in batches over the driver's pool. The mean target per depth is the
//! normalisation b_d (MMLT paper Sec. 4, "Initialization"; Veach 1997 Sec. 4 for path space), and
//! the targets are kept so that chains can be started ∝ target.

use std::time::Duration;

use crate::integrator::driver::{Driver, Passes};
use crate::integrator::Progress;
use crate::stats::Counters;

/// Bootstrap samples per batch (a work unit of the driver).
pub const BATCH: u64 = 4096;
/// Under a time budget, the bootstrap takes at most this share of it (after one batch per depth,
/// which always runs): the chains matter more than a precise start.
pub const BOOTSTRAP_SHARE: f64 = 0.25;

/// What a bootstrap produced.
pub struct BootstrapRun {
    /// Per depth slot, the target of every sample in sample order.
    pub targets: Vec<Vec<f32>>,
    /// Per depth slot, the sum of the targets (f64, summed in sample order).
    pub sums: Vec<f64>,
    /// Per depth slot, the sum of the squared targets (the same order): b_d's standard error.
    pub sums_sq: Vec<f64>,
    /// Samples per depth slot actually taken (≤ `requested` under a time budget).
    pub paths: u64,
    pub counters: Counters,
    pub elapsed: Duration,
}

/// The variance of a mean of `n` samples with sum `sum` and sum of squares `sum_sq`, s²/n with the
/// unbiased sample variance s² (as for independent samples); `None` for n < 2.
pub fn variance_of_mean(sum: f64, sum_sq: f64, n: u64) -> Option<f64> {
    if n < 2 {
        return None;
    }
    let n = n as f64;
    let mean = sum / n;
    Some(((sum_sq - n * mean * mean) / (n - 1.0)).max(0.0) / n)
}

impl BootstrapRun {
    /// b_d of every depth slot: the mean target.
    pub fn b(&self) -> Vec<f64> {
        self.sums.iter().map(|s| s / self.paths.max(1) as f64).collect()
    }
}

/// Runs the bootstrap: `depths` slots of up to `requested` samples each; `sample(d, i, state,
/// counters)` evaluates sample `i` of slot `d` and returns its target. The first round runs one
/// batch per slot; under a time budget of `time_budget` seconds the remaining rounds are capped so
/// that the bootstrap takes at most `BOOTSTRAP_SHARE` of it. Deterministic for a sample budget:
/// every sample has its own stream and the batches are merged in order.
pub fn run_bootstrap<S: Send + Sync>(
    driver: &Driver,
    progress: &dyn Progress,
    depths: usize,
    requested: u64,
    time_budget: Option<f64>,
    init_slot: impl Fn(usize) -> S,
    sample: impl Fn(usize, u64, &mut S, &mut Counters) -> f32 + Sync,
) -> BootstrapRun {
    run_batches(driver, progress, depths, 1, requested, time_budget, init_slot, |d, i, state, counters, out| {
        out.push(sample(d, i, state, counters))
    })
}

/// A bootstrap whose every sample feeds all `depths` slots at once (MMLT and RJMLT: one full BDPT
/// sample gives every depth's b_d its estimate, see `pss::mlt`): up to `requested` samples, each
/// pushing one target per slot (slot order) through `sample(i, state, counters, out)`. The time
/// budget and determinism are `run_bootstrap`'s; `paths` is the number of samples, each counted
/// once in every slot.
pub fn run_shared_bootstrap<S: Send + Sync>(
    driver: &Driver,
    progress: &dyn Progress,
    depths: usize,
    requested: u64,
    time_budget: Option<f64>,
    init_slot: impl Fn(usize) -> S,
    sample: impl Fn(u64, &mut S, &mut Counters, &mut Vec<f32>) + Sync,
) -> BootstrapRun {
    run_batches(driver, progress, 1, depths, requested, time_budget, init_slot, |_, i, state, counters, out| {
        sample(i, state, counters, out)
    })
}

/// The bootstrap's batches over `keys` independent sample sequences of up to `requested` samples,
/// each sample pushing `width` targets: the result has `keys · width` slots (key-major).
#[allow(clippy::too_many_arguments)]
fn run_batches<S: Send + Sync>(
    driver: &Driver,
    progress: &dyn Progress,
    keys: usize,
    width: usize,
    requested: u64,
    time_budget: Option<f64>,
    init_slot: impl Fn(usize) -> S,
    sample: impl Fn(usize, u64, &mut S, &mut Counters, &mut Vec<f32>) + Sync,
) -> BootstrapRun {
    progress.message("bootstrap");
    let batches_per_key = requested.div_ceil(BATCH);
    let run_batches = |rounds: std::ops::Range<u64>| {
        let batches: Vec<(usize, u64, Vec<f32>)> =
            (0..keys).flat_map(|k| rounds.clone().map(move |b| (k, b, Vec::new()))).collect();
        driver.run(
            batches,
            Passes::Count(1),
            progress,
            &init_slot,
            |_, (k, b, targets), slot| {
                let start = *b * BATCH;
                let end = (start + BATCH).min(requested);
                targets.reserve((end - start) as usize * width);
                for i in start..end {
                    sample(*k, i, &mut slot.state, &mut slot.counters, targets);
                }
                0
            },
            None,
        )
    };
    let first = run_batches(0..1);
    let rounds = match time_budget {
        Some(s) => {
            let round = first.elapsed.as_secs_f64().max(1e-6);
            let affordable = ((BOOTSTRAP_SHARE * s - round) / round).floor().max(0.0) as u64;
            batches_per_key.min(1 + affordable)
        }
        None => batches_per_key,
    };
    let rest = run_batches(1..rounds);
    let paths = requested.min(rounds * BATCH);
    let mut counters = first.counters;
    counters.merge(&rest.counters);
    let elapsed = first.elapsed + rest.elapsed;
    let mut targets: Vec<Vec<f32>> = vec![Vec::with_capacity(paths as usize); keys * width];
    for (k, _, t) in first.units.into_iter().chain(rest.units) {
        assert_eq!(t.len() % width, 0, "a bootstrap sample pushed other than {width} targets");
        for (j, &x) in t.iter().enumerate() {
            targets[k * width + j % width].push(x);
        }
    }
    let sums = targets.iter().map(|t| t.iter().map(|&x| x as f64).sum()).collect();
    let sums_sq = targets.iter().map(|t| t.iter().map(|&x| x as f64 * x as f64).sum()).collect();
    BootstrapRun { targets, sums, sums_sq, paths, counters, elapsed }
}

#[cfg(test)]
mod tests {
    use super::variance_of_mean;

    /// Samples 1, 2, 3: mean 2, s² = 1, variance of the mean 1/3; none from one sample.
    #[test]
    fn variance_of_a_small_sample_mean() {
        let v = variance_of_mean(6.0, 14.0, 3).expect("defined");
        assert!((v - 1.0 / 3.0).abs() < 1e-12, "{v}");
        assert_eq!(variance_of_mean(1.0, 1.0, 1), None);
    }
}
