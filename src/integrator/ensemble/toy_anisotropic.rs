//! The ensemble update with the guided anisotropic kernel on a known 2D target: each walker of one
//! ensemble proposes from a Gaussian fitted to a subset Υ of the complementary ensemble, weighted
//! by Eq. 8's similarity to the walker and recentred on it (`anisotropic` module docs: in the
//! plane there is no projection, so the kernel is the fit itself); the walkers' histogram must
//! match the target. Why the complementary split keeps the parallel update valid and why the χ²
//! bound is exact (every walker starts as an exact draw, so a correct update keeps all final states
//! independent draws of the target) is in `toy`'s module docs; the same argument holds here.
//!
//! The target is a curved ridge: a guide subset near a walker lies along the ridge, so the fitted
//! covariance turns with the walker's position, and the kernel is far from symmetric. The reverse
//! density must therefore be the fit **at the proposal** (its own weights, its own Σ); the wrong
//! variant reuses the current walker's fit for the reverse, which makes the ratio of the kernels 1.

use glam::DVec2;

use super::anisotropic::Gaussian2;
use super::similarity::point_similarity;
use super::toy::{chi2_against, run_ensembles};
use crate::sampling::chi2::Chi2Outcome;
use crate::sampling::Rng;

/// The ridge y ≈ 2 + 0.15 (x − 4)², Gaussian across it (σ 0.3) and along x (σ 2), truncated to
/// [0, 8]² (unnormalised).
fn target(p: DVec2) -> f64 {
    if !(p.x >= 0.0 && p.x <= 8.0 && p.y >= 0.0 && p.y <= 8.0) {
        return 0.0;
    }
    let (u, v) = ((p.x - 4.0) / 2.0, (p.y - 2.0 - 0.15 * (p.x - 4.0).powi(2)) / 0.3);
    (-0.5 * (u * u + v * v)).exp()
}

/// An exact draw of the target: x, then y given x, rejected outside the square.
fn draw_target(rng: &mut Rng) -> DVec2 {
    loop {
        let x = 4.0 + 2.0 * rng.standard_normal();
        let p = DVec2::new(x, 2.0 + 0.15 * (x - 4.0).powi(2) + 0.3 * rng.standard_normal());
        if target(p) > 0.0 {
            return p;
        }
    }
}

/// Which update the test runs.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Variant {
    Correct,
    /// The reverse density with the current walker's fit instead of the proposal's refit.
    ReuseForwardFit,
}

/// |Υ| in the toy.
const M: usize = 16;

/// The isotropic fallback's covariance when the fit is degenerate (the plane's analogue of the
/// vMF fallback).
const FALLBACK_VARIANCE: f64 = 0.25;

/// The kernel at `p`: the weighted fit to `subset`, or the isotropic fallback.
fn fit_at(p: DVec2, subset: &[DVec2]) -> Gaussian2 {
    let w: Vec<f64> = subset.iter().map(|v| point_similarity(p.extend(0.0), v.extend(0.0))).collect();
    Gaussian2::fit(subset, &w)
        .unwrap_or_else(|| Gaussian2::from_covariance(FALLBACK_VARIANCE, 0.0, FALLBACK_VARIANCE).expect("isotropic"))
}

/// One walker's update with Υ the M walkers of `others` from an offset drawn from its own stream.
fn update(x: DVec2, others: &[DVec2], variant: Variant, rng: &mut Rng) -> DVec2 {
    let offset = (rng.uniform_f64() * others.len() as f64) as usize;
    let subset: Vec<DVec2> = (0..M).map(|i| others[(offset + i) % others.len()]).collect();
    let forward = fit_at(x, &subset);
    let y = x + forward.sample_offset([rng.uniform_f64(), rng.uniform_f64()]);
    let fy = target(y);
    if !(fy > 0.0) {
        rng.uniform_f64();
        return x;
    }
    let reverse = match variant {
        Variant::Correct => fit_at(y, &subset),
        Variant::ReuseForwardFit => forward,
    };
    let ratio = reverse.density_offset(x - y) / forward.density_offset(y - x);
    let a = (fy * ratio / target(x)).min(1.0);
    if rng.uniform_f64() < a {
        y
    } else {
        x
    }
}

/// `runs` independent pairs of ensembles of `n` walkers, `sweeps` half-iterations each
/// (`toy::run_ensembles`); every walker's final state.
fn run(variant: Variant, runs: u64, n: usize, sweeps: usize) -> Vec<DVec2> {
    run_ensembles(0xA215, (runs, n, sweeps), draw_target, |x, guides, rng| update(x, guides, variant, rng))
}

fn chi2_of(states: &[DVec2]) -> Chi2Outcome {
    chi2_against(states, target)
}

/// 8 independent pairs of ensembles of 4,096 walkers, 40 half-iterations (20 updates per walker):
/// the 65,536 final states against the target by χ² on 16 × 16 bins (significance 1e-3; exact, see
/// the module docs). The variant that reuses the current walker's fit for the reverse density
/// must fail the same test.
#[test]
fn anisotropic_toy_ensemble_matches_its_target_and_reusing_the_forward_fit_does_not() {
    let (runs, n, sweeps) = (8, 4096, 40);
    let good = chi2_of(&run(Variant::Correct, runs, n, sweeps));
    println!("anisotropic toy ensemble, correct: {}", good.message);
    assert!(good.passed, "{}", good.message);
    let wrong = chi2_of(&run(Variant::ReuseForwardFit, runs, n, sweeps));
    println!("anisotropic toy ensemble, reusing x̄'s fit: statistic {:.1}, p = {:.3e}", wrong.statistic, wrong.p_value);
    assert!(!wrong.passed, "reusing the forward fit passed: {}", wrong.message);
}
