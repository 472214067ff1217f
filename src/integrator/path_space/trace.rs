//! One chain's image-plane trajectory, for the portal paper's Fig. 4c/d: the raster position of
//! chain 0's current path every `every` mutations, and the integrated autocorrelation time of its
//! y coordinate (how many mutations the chain needs per independent image-plane sample). Used by
//! `docs/lab/scripts/bench-portals.sh` through `examples/pmlt-trace.rs`; the render itself never traces.

use glam::Vec2;

use super::chain::{step, Pmlt};
use super::PathContext;
use crate::film::SplatBuffer;
use crate::integrator::RenderError;
use crate::sampling::Distribution1D;
use crate::scene::Scene;
use crate::stats::Counters;

/// Chain 0's raster positions (normalised to [0, 1]², y down as on the film) after every `every`-th
/// of `mutations` mutations, started as the render starts it (the same bootstrap and resampling,
/// run on one thread).
pub fn raster_trace(
    pmlt: &Pmlt,
    scene: &Scene,
    seed: u64,
    mutations: u64,
    every: u64,
) -> Result<Vec<Vec2>, RenderError> {
    let ctx = PathContext { scene, max_depth: pmlt.settings.max_depth as usize };
    let bctx = pmlt.bdpt_context(scene);
    let set = pmlt.strategies(scene);
    let mut slot = pmlt.new_slot(&set);
    let mut counters = Counters::default();
    let targets: Vec<f32> = (0..pmlt.settings.bootstrap)
        .map(|i| pmlt.bootstrap_sample(&bctx, seed, i, &mut slot, &mut counters, None))
        .collect();
    if !targets.iter().any(|t| *t > 0.0) {
        return Err(RenderError::Settings("no bootstrap path carried light: nothing to trace".into()));
    }
    let start = Distribution1D::new(&targets);
    let mut candidates = Vec::new();
    let mut unit = pmlt.start_chain(0, &start, &ctx, &bctx, seed, &mut slot, &mut counters, &mut candidates);
    let mut film = SplatBuffer::new(scene.camera.width as usize, scene.camera.height as usize);
    let size = Vec2::new(scene.camera.width as f32, scene.camera.height as f32);
    let every = every.max(1);
    let mut trace = Vec::with_capacity((mutations / every) as usize);
    for k in 1..=mutations {
        step(&ctx, &set, &mut unit.current, &mut unit.rng, &mut slot.stats, &mut film, 0, &mut counters);
        if k % every == 0 {
            trace.push(unit.current.raster / size);
        }
    }
    Ok(trace)
}

/// The integrated autocorrelation time τ = 1 + 2 Σ_{k≥1} ρ(k) of `xs`, in units of its spacing,
/// with Sokal's automatic window (the smallest M with M ≥ 5 τ(M); Sokal 1997, "Monte Carlo
/// methods in statistical mechanics", Sec. 3). A constant series (a chain that never moved) has
/// τ = ∞; None for fewer than 4 points.
pub fn integrated_autocorrelation_time(xs: &[f64]) -> Option<f64> {
    let n = xs.len();
    if n < 4 {
        return None;
    }
    let mean = xs.iter().sum::<f64>() / n as f64;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
    if !(var > 0.0) {
        return Some(f64::INFINITY);
    }
    let rho = |k: usize| (0..n - k).map(|i| (xs[i] - mean) * (xs[i + k] - mean)).sum::<f64>() / (n as f64 * var);
    let mut tau = 1.0;
    for m in 1..n / 2 {
        tau += 2.0 * rho(m);
        if m as f64 >= 5.0 * tau {
            return Some(tau);
        }
    }
    // No window fits: the series is too short for its correlation; report what it reached.
    Some(tau)
}

#[cfg(test)]
mod tests {
    use super::integrated_autocorrelation_time;
    use crate::sampling::Rng;

    /// An AR(1) series x_{k+1} = φ x_k + noise has τ = (1 + φ)/(1 − φ): 1 for white noise, 19 for
    /// φ = 0.9. 100,000 points give the estimate within ~6% (one standard error, Sokal's τ·√(2(2M+1)/n)
    /// with the window M ≈ 5τ), so the 20% bound is over 3 standard errors.
    #[test]
    fn autocorrelation_time_of_ar1_series() {
        for (phi, expected) in [(0.0, 1.0), (0.9, 19.0)] {
            let mut rng = Rng::new(5, 0);
            let mut x = 0.0f64;
            let xs: Vec<f64> = (0..100_000)
                .map(|_| {
                    let noise = (rng.uniform_f64() - 0.5) * 12f64.sqrt();
                    x = phi * x + noise;
                    x
                })
                .collect();
            let tau = integrated_autocorrelation_time(&xs).expect("tau");
            assert!((tau / expected - 1.0).abs() < 0.2, "φ = {phi}: τ = {tau}, expected {expected}");
        }
        assert_eq!(integrated_autocorrelation_time(&[1.0; 10]), Some(f64::INFINITY));
    }
}
