//! Russian roulette for the path tracer: the survival probability (the throughput rule scaled by
//! `rr_scale`, refraction's radiance compression undone) and one roll of it.

use crate::spectrum::Rgb;

/// Probability that Russian roulette lets a path with throughput `beta` continue, `eta_scale` being
/// the product of η² over its refractions and `scale` the setting `rr_scale`:
/// q = min(1, scale · max component of beta · eta_scale).
///
/// Undoing the 1/η² that refraction applies in radiance transport (Veach 1997 Sec. 5.2) keeps a
/// path inside glass from being killed for a compression that the exit undoes (×η² again): without
/// it a path inside η = 1.5 survives each roll with q ≈ 1/2.25 ≈ 0.44 (pbrt-v4 `etaScale`,
/// `PathIntegrator::Li`, Sec. 13.1.5).
///
/// Why scale the throughput rule (scale 1: pbrt-v4 and Mitsuba 3) by 2. A roll with survival q at a
/// vertex of throughput β, whose remaining path would add β·F, adds β²·E[F²]·(1/q − 1) to the
/// sample's variance V and saves (1 − q)·c of its cost C, c being that remaining path's cost.
/// The efficiency 1/(V·C) is largest where the two relative changes balance, d(ln V)/dq = −d(ln C)/dq:
/// q = β·√(E[F²]·C / (V·c)) (the efficiency-optimal factor of Rath et al. 2022, "EARS:
/// Efficiency-Aware Russian Roulette and Splitting", derived here for a single roll). The
/// throughput rule is this with √(E[F²]·C/(V·c)) = 1; but a roll saves only the remaining path's
/// cost c, a fraction of the whole sample's C that has already been paid (camera ray, first bounces),
/// so the factor is above 1 unless the remaining path is far less noisy than the sample. Measured
/// on eleven scenes (docs/lab/benchmarks-history.md, "Russian roulette's survival scale"),
/// efficiency per ray rose at scales 2 and 4 alike (a plateau): 25–31% on the door and the torus,
/// 6–10% on the Cornell scenes, −1% to +4% (within noise) on the rest; 2 is the plateau's cheapest
/// point. A survivor is reweighted by 1/q; it carries at most 1/scale of a fresh path's throughput,
/// and `max_depth` bounds the paths that never roll.
pub fn roulette_survival(beta: Rgb, eta_scale: f32, scale: f32) -> f32 {
    let m = scale * (beta * eta_scale).max_element();
    // `!(m < 1)` also sends a NaN to "no roll"; `li` drops non-finite throughputs before rolling.
    if !(m < 1.0) {
        1.0
    } else {
        m.max(0.0)
    }
}

/// One roll of Russian roulette with the uniform `u`: the reweighted throughput beta / q if the
/// path survives (u < q, probability q = `roulette_survival`), `None` if it ends. The expected
/// reweighted throughput is q · beta/q = beta, so the estimator stays unbiased.
pub fn russian_roulette(beta: Rgb, eta_scale: f32, scale: f32, u: f32) -> Option<Rgb> {
    let q = roulette_survival(beta, eta_scale, scale);
    if q >= 1.0 {
        return Some(beta);
    }
    (u < q).then(|| beta / q)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::material::{Material, TransportMode};

    /// A path whose throughput (η² undone) is ≥ 1 in some channel is never rolled: it survives
    /// whatever the uniform. A capped rule, survival = min(max βᵢ, 0.95), fails this with
    /// q = 0.95 for β = 1.
    #[test]
    fn roulette_never_rolls_a_throughput_of_one_or_more() {
        for beta in [Rgb::ONE, Rgb::new(1.0, 0.2, 0.1), Rgb::new(0.0, 3.0, 0.0), Rgb::splat(40.0)] {
            for scale in [1.0, 2.0] {
                assert_eq!(roulette_survival(beta, 1.0, scale), 1.0, "{beta:?}");
                assert_eq!(russian_roulette(beta, 1.0, scale, 0.999_999), Some(beta), "{beta:?}");
            }
        }
        // 0.5 inside glass (η² = 2.25 accumulated) is 1.125 without the compression: no roll.
        assert_eq!(roulette_survival(Rgb::splat(0.5), 2.25, 1.0), 1.0);
    }

    /// `rr_scale` multiplies the throughput rule's survival and is capped at 1: throughput 0.2 is
    /// kept with 0.2 at scale 1 and 0.4 at scale 2; 0.6 is not rolled at scale 2. A survivor at
    /// scale 2 carries half a fresh path's throughput (β/q = 1/2 in its largest channel).
    #[test]
    fn roulette_scale_multiplies_the_survival() {
        let beta = Rgb::new(0.2, 0.1, 0.05);
        assert!((roulette_survival(beta, 1.0, 1.0) - 0.2).abs() < 1e-7);
        assert!((roulette_survival(beta, 1.0, 2.0) - 0.4).abs() < 1e-7);
        assert_eq!(roulette_survival(Rgb::splat(0.6), 1.0, 2.0), 1.0);
        assert_eq!(russian_roulette(beta, 1.0, 2.0, 0.45), None);
        let survivor = russian_roulette(beta, 1.0, 2.0, 0.35).expect("u < q = 0.4 survives");
        assert!((survivor.max_element() - 0.5).abs() < 1e-6, "{survivor:?}");
    }

    /// Refracting into η = 1.5 divides the radiance throughput by 2.25; the η² the sample record
    /// reports undoes it, so a camera path that has only entered glass survives with q = 1 (the
    /// rule without the η² factor gives q = 0.444), a diffuse bounce of albedo 0.5 inside gives
    /// q = 0.5 (without it: 0.222), and leaving the glass restores both factors to 1.
    #[test]
    fn roulette_undoes_the_radiance_compression_of_refraction() {
        let glass = Material::Dielectric { ior: 1.5 };
        let mut beta = Rgb::ONE;
        let mut eta_scale = 1.0f32;
        let bounce = |wo: Vec3, beta: &mut Rgb, eta_scale: &mut f32| {
            // u[0] = 0.99 is past F ≈ 0.04 at normal incidence: the refraction lobe.
            let bs = glass.sample(wo, [0.99, 0.5, 0.5], TransportMode::Radiance).expect("refracts");
            assert_eq!(bs.lobe as usize, crate::material::DIELECTRIC_REFRACT);
            *beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
            *eta_scale *= bs.eta * bs.eta;
        };
        bounce(Vec3::Z, &mut beta, &mut eta_scale);
        assert!((beta.max_element() - 1.0 / 2.25).abs() < 1e-5, "entering compresses: {beta:?}");
        let q = roulette_survival(beta, eta_scale, 1.0);
        assert!((q - 1.0).abs() < 1e-5, "inside glass q = {q}");
        let q_half = roulette_survival(beta * 0.5, eta_scale, 1.0);
        assert!((q_half - 0.5).abs() < 1e-5, "albedo 0.5 inside glass: q = {q_half}");
        bounce(-Vec3::Z, &mut beta, &mut eta_scale);
        assert!((beta - Rgb::ONE).abs().max_element() < 1e-5 && (eta_scale - 1.0).abs() < 1e-5);
        assert!((roulette_survival(beta, eta_scale, 1.0) - 1.0).abs() < 1e-5);
    }

    /// E[reweighted throughput] = β for every β and η² state: over the midpoint grid u_k =
    /// (k + ½)/N the number of survivors differs from N·q by at most 1, so each channel's mean of
    /// survivor/β is within 1/(N q) of 1 (q ≥ 8.9e-4 here: ≤ 1.2e-2 at N = 10⁵), plus f32
    /// rounding of β/q (≤ 1e-6). A reweighting by 1/max βᵢ (forgetting η²) fails this: measured
    /// 2.25 at β = (0.4, 0.3, 0.1), η² = 2.25 (bound 1.2e-5). The scale-2 cases (half those
    /// throughputs, so that every one still rolls) catch a reweighting that forgets the scale.
    #[test]
    fn roulette_keeps_the_expected_weight() {
        const N: usize = 100_000;
        let betas = [Rgb::new(0.4, 0.3, 0.1), Rgb::new(0.2, 0.05, 0.2), Rgb::new(1e-3, 2e-3, 5e-4)];
        for (beta, scale) in betas.into_iter().flat_map(|b| [(b, 1.0f32), (b * 0.5, 2.0)]) {
            for eta_scale in [1.0f32, 2.25, 1.0 / 2.25] {
                let q = roulette_survival(beta, eta_scale, scale);
                assert!(q > 0.0 && q < 1.0, "{beta:?} {eta_scale}: q = {q}");
                let mut sum = [0.0f64; 3];
                for k in 0..N {
                    let u = ((k as f64 + 0.5) / N as f64) as f32;
                    if let Some(b) = russian_roulette(beta, eta_scale, scale, u) {
                        for (c, s) in sum.iter_mut().enumerate() {
                            *s += b[c] as f64;
                        }
                    }
                }
                let bound = 1.0 / (N as f64 * q as f64) + 1e-6;
                for (c, s) in sum.iter().enumerate() {
                    let ratio = s / N as f64 / beta[c] as f64;
                    assert!(
                        (ratio - 1.0).abs() <= bound,
                        "{beta:?} η² {eta_scale} channel {c}: {ratio} (bound {bound})"
                    );
                }
            }
        }
    }
}
