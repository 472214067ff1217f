//! The guided directional transition kernel of EMLT (Bashford-Rogers et al. 2021, Sec. 3.2, "Guided
//! Directional Transition Kernels", Fig. 6): a von Mises–Fisher (vMF) distribution on S² whose
//! concentration is fitted to the weighted directions from a base vertex to Υ's vertices,
//! **recentred** on the current direction. Also the vMF the anisotropic kernel falls back to when
//! its fit is degenerate (`anisotropic` module docs). Sample and density side by side.
//!
//! # The vMF
//! p(ω | μ, κ) = κ / (2π (1 − e^{−2κ})) · e^{κ (μ·ω − 1)} per unit solid angle, sampled by inverting
//! the CDF of cos θ: cos θ = 1 + ln(1 − (1 − u)(1 − e^{−2κ}))/κ (Wenzel Jakob's note on the vMF),
//! written with `ln_1p` and `exp_m1` so that it neither overflows for large κ nor cancels for
//! small κ, and with 1 − μ·ω computed as |μ − ω|²/2 (exact for small angles).
//!
//! # The fit
//! With unit directions ω_n and weights w_n (Eq. 11's similarities, normalised by their sum), the
//! mean resultant length is R̄ = |Σ w_n ω_n| and κ is Banerjee et al.'s (2005) approximation of
//! the maximum-likelihood estimate, κ̂ = R̄(3 − R̄²)/(1 − R̄²), refined by Newton's method to the
//! exact estimate, the root of coth κ − 1/κ = R̄. The fitted mean direction is
//! discarded: the paper recentres the distribution on the current direction, so only κ is kept.
//! The fit depends on the current path (its weights and its base vertex), so the reverse move refits
//! at ȳ: the kernel is **not** symmetric, and the acceptance uses both full densities.
//!
//! A fit is degenerate when fewer than two directions carry positive finite weight (one direction
//! has no spread to measure): the kernel then uses the fallback concentration. κ is clamped to
//! [`KAPPA_MIN`, `KAPPA_MAX`] (a finite κ for directions that coincide to rounding, and a proper
//! density for Υ spread over the sphere); the clamp is part of the fit, so both directions of a
//! move apply it identically.

use glam::DVec3;

use crate::integrator::path_space::reciprocal_kernel::basis;

/// The smallest concentration a fit returns (≈ uniform on the sphere).
pub const KAPPA_MIN: f64 = 1e-6;
/// The largest concentration a fit returns (angles of ~3e-4 rad, far above f64's resolution of
/// directions).
pub const KAPPA_MAX: f64 = 1e7;

/// A von Mises–Fisher distribution on the unit sphere (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vmf {
    /// The mean direction (unit).
    pub axis: DVec3,
    /// The concentration κ > 0.
    pub kappa: f64,
}

impl Vmf {
    /// −(1 − e^{−2κ}) = expm1(−2κ): the normalisation's factor without cancellation.
    fn one_minus_exp(&self) -> f64 {
        -(-2.0 * self.kappa).exp_m1()
    }

    /// A direction by inversion of cos θ's CDF (u[0]) and a uniform azimuth (u[1]).
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let k = self.kappa;
        // 1 − cos θ = −ln(1 − (1 − u)(1 − e^{−2κ}))/κ ∈ [0, 2].
        let one_minus_cos = (-(-(1.0 - u[0]) * self.one_minus_exp()).ln_1p() / k).clamp(0.0, 2.0);
        let cos_t = 1.0 - one_minus_cos;
        let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let phi = std::f64::consts::TAU * u[1];
        let (s, t) = basis(self.axis);
        (s * (sin_t * phi.cos()) + t * (sin_t * phi.sin()) + self.axis * cos_t).normalize()
    }

    /// The density of `sample` producing the unit `dir`, per unit solid angle.
    pub fn density(&self, dir: DVec3) -> f64 {
        let one_minus_cos = 0.5 * (self.axis - dir).length_squared();
        let k = self.kappa;
        k / (std::f64::consts::TAU * self.one_minus_exp()) * (-k * one_minus_cos).exp()
    }
}

/// κ̂ of the weighted unit `directions` (module docs, "The fit"), clamped to [KAPPA_MIN,
/// KAPPA_MAX]; None when the fit is degenerate (fewer than two positive finite weights).
pub fn fit_concentration(directions: &[DVec3], weights: &[f64]) -> Option<f64> {
    let usable = |w: f64| w > 0.0 && w.is_finite();
    if weights.iter().filter(|&&w| usable(w)).count() < 2 {
        return None;
    }
    let total: f64 = weights.iter().filter(|&&w| usable(w)).sum();
    let resultant: DVec3 =
        directions.iter().zip(weights).filter(|(_, &w)| usable(w)).map(|(d, &w)| *d * (w / total)).sum();
    let r = resultant.length().min(1.0);
    if !r.is_finite() {
        return None;
    }
    Some(concentration_of_resultant(r))
}

/// The maximum-likelihood κ of a vMF on S² whose mean resultant length is `r`: the root of
/// A(κ) = coth κ − 1/κ = r, clamped to [KAPPA_MIN, KAPPA_MAX]. Started from Banerjee et al.'s
/// approximation r(3 − r²)/(1 − r²) (5% high at κ = 5, which the tests saw) and refined by
/// Newton's method, A′(κ) = 1 − A² − 2A/κ; above κ = 20, coth κ = 1 to 1e-17 and the root is
/// 1/(1 − r) exactly.
fn concentration_of_resultant(r: f64) -> f64 {
    if !(r < 1.0 - 1.0 / 20.0) {
        let kappa = 1.0 / (1.0 - r);
        return if kappa.is_finite() { kappa.clamp(KAPPA_MIN, KAPPA_MAX) } else { KAPPA_MAX };
    }
    let a = |k: f64| 1.0 / k.tanh() - 1.0 / k;
    let mut kappa = (r * (3.0 - r * r) / ((1.0 - r) * (1.0 + r))).max(KAPPA_MIN);
    for _ in 0..20 {
        let ak = a(kappa);
        let slope = 1.0 - ak * ak - 2.0 * ak / kappa;
        if !(slope > 0.0) {
            break;
        }
        let next = (kappa - (ak - r) / slope).max(0.5 * kappa);
        if (next - kappa).abs() <= 1e-12 * kappa {
            kappa = next;
            break;
        }
        kappa = next;
    }
    kappa.clamp(KAPPA_MIN, KAPPA_MAX)
}

/// The guided directional kernel at one path: a vMF recentred on the current direction with κ
/// fitted to Υ's weighted directions, or `fallback_kappa` when that fit is degenerate.
pub fn guided_vmf(current: DVec3, directions: &[DVec3], weights: &[f64], fallback_kappa: f64) -> Vmf {
    let kappa = fit_concentration(directions, weights).unwrap_or(fallback_kappa);
    Vmf { axis: current, kappa }
}

#[cfg(test)]
mod tests {
    //! The vMF's sampling against its density (χ² over the sphere, a wrong κ rejected), the fit's
    //! recovery of a known κ, and the recentring.

    use super::*;
    use crate::sampling::chi2::{chi2_sphere, Chi2Config};
    use crate::sampling::Rng;

    /// χ² tests here that must pass (the Šidák family).
    const CHI2_TESTS: usize = 3;

    fn cfg() -> Chi2Config {
        Chi2Config { res: [40, 20], samples: 200_000, test_count: CHI2_TESTS, ..Chi2Config::default() }
    }

    /// `Vmf::sample` follows `Vmf::density` for a broad (κ = 2) and a concentrated (κ = 60)
    /// distribution (χ² over (cos θ, φ), 40 × 20 equal-area bins, 200,000 samples, α = 1e-3 over
    /// the module's tests); the concentrated one binned about its own axis would put all its mass
    /// in a few bins, so its axis is the pole. A density with κ/2 is rejected.
    #[test]
    fn vmf_sampling_matches_its_density() {
        for (seed, vmf) in [
            (1, Vmf { axis: DVec3::new(0.3, -0.4, 0.2).normalize(), kappa: 2.0 }),
            (2, Vmf { axis: DVec3::Z, kappa: 60.0 }),
        ] {
            let out = chi2_sphere(
                &cfg(),
                seed,
                |rng: &mut Rng| Some(vmf.sample([rng.uniform_f64(), rng.uniform_f64()]).as_vec3()),
                |w| vmf.density(w.as_dvec3()),
            );
            assert!(out.passed, "κ = {}: {}", vmf.kappa, out.message);
        }
        let vmf = Vmf { axis: DVec3::new(0.3, -0.4, 0.2).normalize(), kappa: 2.0 };
        let half = Vmf { kappa: 1.0, ..vmf };
        let wrong = chi2_sphere(
            &cfg(),
            3,
            |rng: &mut Rng| Some(vmf.sample([rng.uniform_f64(), rng.uniform_f64()]).as_vec3()),
            |w| half.density(w.as_dvec3()),
        );
        assert!(!wrong.passed, "a density with κ/2 passed: {}", wrong.message);
        // Extreme concentrations stay finite and normalised at the axis.
        for kappa in [KAPPA_MIN, KAPPA_MAX] {
            let v = Vmf { axis: DVec3::Y, kappa };
            let d = v.sample([0.5, 0.25]);
            assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-12 && v.density(d).is_finite());
        }
    }

    /// The fit recovers κ from 20,000 equally weighted draws of a vMF (κ = 5 and 50: within 3%;
    /// Banerjee's approximation alone gave 5.25 for κ = 5),
    /// ignores the samples' mean direction (the kernel is recentred on `current`), and is
    /// degenerate for a single weighted direction.
    #[test]
    fn fit_recovers_the_concentration_and_recentres() {
        let mut rng = Rng::new(5, 0);
        for r in [0.01, 0.3, 0.8, 0.9, 0.96, 0.999] {
            let k = concentration_of_resultant(r);
            assert!((1.0 / k.tanh() - 1.0 / k - r).abs() < 1e-9, "R̄ = {r}: κ = {k}");
        }
        for kappa in [5.0, 50.0] {
            let v = Vmf { axis: DVec3::new(1.0, 2.0, -0.5).normalize(), kappa };
            let dirs: Vec<DVec3> = (0..20_000).map(|_| v.sample([rng.uniform_f64(), rng.uniform_f64()])).collect();
            let w = vec![1.0; dirs.len()];
            let fit = fit_concentration(&dirs, &w).expect("a fit");
            assert!((fit / kappa - 1.0).abs() < 0.03, "κ = {kappa}: fitted {fit}");
            let current = DVec3::X;
            assert_eq!(guided_vmf(current, &dirs, &w, 1e4).axis, current);
        }
        assert_eq!(fit_concentration(&[DVec3::X, DVec3::Y], &[1.0, 0.0]), None);
        assert_eq!(guided_vmf(DVec3::X, &[DVec3::X], &[1.0], 123.0).kappa, 123.0);
        assert_eq!(fit_concentration(&[DVec3::X, DVec3::X], &[1.0, 1.0]), Some(KAPPA_MAX));
    }
}
