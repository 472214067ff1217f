//! The linear guided transition kernels of EMLT (Bashford-Rogers et al. 2021, Sec. 3.2): the stretch
//! move in R² (Goodman & Weare 2010) and its extension along a great arc of the sphere. Each has
//! `sample`, `density` and `reverse_ratio` side by side.
//!
//! # The stretch move
//! Given the current point x and a guide v (a point of a path of the complementary ensemble), the
//! proposal is x′ = v + λ(x − v) with λ drawn from g(c) ∝ 1/√c on [1/a, a], a = 1 + α. g satisfies
//! g(1/c) = c·g(c), and the reverse move from x′ with the same guide needs λ′ = 1/λ. Written as a
//! deterministic map of (x, λ) to (x′, 1/λ) (Green's reversible jump), the ratio of the kernels is
//!
//!   K(x′→x)/K(x→x′) = g(1/λ)/g(λ) · |∂(x′, λ′)/∂(x, λ)| = λ · (λ² · 1/λ²) = λ   in R²
//!
//! (λ^{n−1} in Rⁿ: Goodman & Weare's Eq. 7). The tests check this against a numerical Jacobian.
//!
//! # The great-arc (linear hemispherical) kernel
//! With current direction ω₁ and guide direction ω₂ at angle ψ = ∠(ω₁, ω₂), the proposal moves ω₁
//! along the great arc through ω₂ to the angle ψ′ = λψ from ω₂: a slerp from ω₂ towards ω₁ by λ,
//!
//!   ω′ = [sin((1 − λ)ψ) ω₂ + sin(λψ) ω₁] / sin ψ.
//!
//! The paper prints the angles as (ω₁·ω₂)λ and (ω₁·ω₂)(1 − λ): a typo, the angle ψ = acos(ω₁·ω₂)
//! belongs there (the tests show the printed form does not sample the stated density). In polar
//! coordinates about ω₂, dω = sin ψ dψ dφ and the move keeps φ, so
//!
//!   K(ω′→ω)/K(ω→ω′) = g(1/λ)/g(λ) · |∂(ω′, λ′)/∂(ω, λ)| = λ · (λ sin ψ′/sin ψ) · 1/λ² = sin ψ′ / sin ψ,
//!
//! which tends to λ for small angles (the flat case). The paper's Eq. 10 prints the inverse,
//! sin ψ / sin ψ′ (→ 1/λ): the tests show a numerical Jacobian contradicts it. A move whose ψ or
//! ψ′ is below `ARC_MIN_ANGLE` (ω₁ and the guide coincide: the arc is undefined) or whose ψ′
//! reaches π (the arc would wrap past the antipode) fails; both conditions are symmetric in the
//! forward and reverse moves, so a failure never has an accepted reverse.

use glam::{DVec2, DVec3};

/// Angles below this (radians) leave the great arc undefined: such moves fail (module docs).
pub const ARC_MIN_ANGLE: f64 = 1e-9;

/// The stretch move's λ distribution g(c) ∝ 1/√c on [1/(1+α), 1+α] (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StretchKernel {
    pub alpha: f64,
}

impl StretchKernel {
    /// a = 1 + α, the upper end of λ's range.
    fn a(&self) -> f64 {
        1.0 + self.alpha
    }

    /// ∫ c^{−1/2} over [1/a, a] = 2(√a − 1/√a): g's normalisation.
    fn norm(&self) -> f64 {
        let s = self.a().sqrt();
        2.0 * (s - 1.0 / s)
    }

    /// λ by inversion of g's CDF, 2(√λ − 1/√a)/norm: √λ = 1/√a + u(√a − 1/√a).
    pub fn sample_lambda(&self, u: f64) -> f64 {
        let s = self.a().sqrt();
        let r = 1.0 / s + u * (s - 1.0 / s);
        r * r
    }

    /// g(λ): density of `sample_lambda` (0 outside [1/a, a]).
    pub fn density_lambda(&self, lambda: f64) -> f64 {
        let a = self.a();
        // A relative tolerance at the ends: 1/a and a computed from a sampled λ round by an ulp.
        let tol = 1e-12;
        if !(lambda >= (1.0 / a) * (1.0 - tol) && lambda <= a * (1.0 + tol)) {
            return 0.0;
        }
        1.0 / (self.norm() * lambda.sqrt())
    }

    /// The uniform that `sample_lambda` maps to λ (None outside the range).
    pub fn invert_lambda(&self, lambda: f64) -> Option<f64> {
        if !(self.density_lambda(lambda) > 0.0) {
            return None;
        }
        let s = self.a().sqrt();
        Some(((lambda.sqrt() - 1.0 / s) / (s - 1.0 / s)).clamp(0.0, 1.0))
    }

    /// The stretch of `x` about the guide `v` by λ = `sample_lambda(u)`: (x′, λ).
    pub fn sample(&self, x: DVec2, guide: DVec2, u: f64) -> (DVec2, f64) {
        let lambda = self.sample_lambda(u);
        (guide + lambda * (x - guide), lambda)
    }

    /// The λ that maps `x` to `to` about `guide` (None when `to` is not on the ray from the guide
    /// through x, or λ is outside the range): what the reverse density needs.
    pub fn lambda_of(&self, x: DVec2, guide: DVec2, to: DVec2) -> Option<f64> {
        let (d, e) = (x - guide, to - guide);
        let (dl, el) = (d.length(), e.length());
        if !(dl > 0.0) || (d.perp_dot(e)).abs() > 1e-9 * dl * el.max(dl) || d.dot(e) <= 0.0 {
            return None;
        }
        let lambda = el / dl;
        (self.density_lambda(lambda) > 0.0).then_some(lambda)
    }

    /// K(x′→x)/K(x→x′) for the stretch by λ in R² (module docs): λ.
    pub fn reverse_ratio(&self, lambda: f64) -> f64 {
        lambda
    }
}

/// The great-arc kernel (module docs): λ from `stretch`, then ψ′ = λψ about the guide direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GreatArcKernel {
    pub stretch: StretchKernel,
}

/// The angle between two unit vectors, by atan2 of the cross and dot products (exact for small
/// angles, where acos of a dot product near 1 loses half its digits).
pub fn angle_between(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

impl GreatArcKernel {
    /// The slerp from the unit `guide` towards the unit `current` by `lambda`: the direction at
    /// angle λψ from the guide on the great arc through both (module docs). None when ψ or λψ is
    /// below `ARC_MIN_ANGLE` or λψ ≥ π.
    pub fn arc_point(current: DVec3, guide: DVec3, lambda: f64) -> Option<DVec3> {
        let psi = angle_between(current, guide);
        let psi_new = lambda * psi;
        if !(psi >= ARC_MIN_ANGLE && (ARC_MIN_ANGLE..std::f64::consts::PI).contains(&psi_new)) {
            return None;
        }
        let s = psi.sin();
        let w = (guide * ((1.0 - lambda) * psi).sin() + current * psi_new.sin()) / s;
        let w = w.normalize();
        w.is_finite().then_some(w)
    }

    /// A proposal ω′ from `current` guided by `guide` (unit vectors), with its λ.
    pub fn sample(&self, current: DVec3, guide: DVec3, u: f64) -> Option<(DVec3, f64)> {
        let lambda = self.stretch.sample_lambda(u);
        Self::arc_point(current, guide, lambda).map(|w| (w, lambda))
    }

    /// Density of the angle ψ′ from the guide that `sample` produces from a current direction at
    /// angle `psi`: g(ψ′/ψ)/ψ per radian along the arc (the move is singular across it).
    pub fn density_along_arc(&self, psi: f64, psi_new: f64) -> f64 {
        if !(psi >= ARC_MIN_ANGLE && psi_new < std::f64::consts::PI) {
            return 0.0;
        }
        self.stretch.density_lambda(psi_new / psi) / psi
    }

    /// K(ω′→ω)/K(ω→ω′) = sin ψ′ / sin ψ (module docs; the paper's Eq. 10 inverted), ψ and ψ′ the
    /// angles of `current` and `proposed` from `guide`; 0 when the move is not a valid arc move.
    pub fn reverse_ratio(&self, current: DVec3, guide: DVec3, proposed: DVec3) -> f64 {
        let (psi, psi_new) = (angle_between(current, guide), angle_between(proposed, guide));
        if !(psi >= ARC_MIN_ANGLE && psi_new >= ARC_MIN_ANGLE) {
            return 0.0;
        }
        psi_new.sin() / psi.sin()
    }
}

#[cfg(test)]
mod tests {
    //! χ² of each kernel's sampling against its density, and its reverse ratio against a numerical
    //! Jacobian of the move written as a map (x, λ) ↦ (x′, 1/λ), each with a wrong variant rejected.

    use super::*;
    use crate::sampling::chi2::{chi2_1d, jacobian_det_surface, Chi2Config};
    use crate::sampling::Rng;

    /// Two χ² tests here must pass (the wrong variants must fail): the Šidák family.
    const CHI2_TESTS: usize = 2;

    fn cfg() -> Chi2Config {
        Chi2Config { res: [40, 1], samples: 200_000, test_count: CHI2_TESTS, ..Chi2Config::default() }
    }

    /// The distance ratio |x′ − v|/|x − v| of `StretchKernel::sample` follows g (χ², 40 bins,
    /// 200,000 samples); a uniform density on the same range is rejected by the same test
    /// (asserted: p < α).
    #[test]
    fn stretch_sampling_matches_its_density() {
        let k = StretchKernel { alpha: 1.5 };
        let (x, v) = (DVec2::new(0.3, -1.2), DVec2::new(2.0, 0.5));
        let range = [1.0 / 2.5, 2.5];
        let sampler = |rng: &mut Rng| {
            let (to, lambda) = k.sample(x, v, rng.uniform_f64());
            assert_eq!(k.lambda_of(x, v, to).map(|l| (l - lambda).abs() < 1e-9), Some(true));
            Some((to - v).length() / (x - v).length())
        };
        let out = chi2_1d(&cfg(), range, 1, sampler, |l| k.density_lambda(l));
        assert!(out.passed, "{}", out.message);
        let wrong = chi2_1d(&cfg(), range, 1, sampler, |_| 1.0 / (range[1] - range[0]));
        assert!(!wrong.passed, "a uniform λ density passed: {}", wrong.message);
        for u in [0.0, 0.3, 0.999] {
            let l = k.sample_lambda(u);
            assert!((k.invert_lambda(l).expect("in range") - u).abs() < 1e-12);
        }
    }

    /// The angle ψ′ of `GreatArcKernel::sample` from the guide follows g(ψ′/ψ)/ψ, and ω′ stays on
    /// the great circle through ω₁ and ω₂ (χ², 40 bins). The paper's printed slerp (angles
    /// (ω₁·ω₂)λ) is rejected by the same test (asserted: p < α).
    #[test]
    fn great_arc_sampling_matches_its_density() {
        let k = GreatArcKernel { stretch: StretchKernel { alpha: 0.5 } };
        let w1 = DVec3::new(0.2, 0.3, 0.9).normalize();
        let w2 = DVec3::new(-0.5, 0.1, 0.6).normalize();
        let psi = angle_between(w1, w2);
        let normal = w1.cross(w2).normalize();
        let range = [psi / 1.5, psi * 1.5];
        let sampler = |rng: &mut Rng| {
            let (w, _) = k.sample(w1, w2, rng.uniform_f64())?;
            assert!(w.dot(normal).abs() < 1e-9, "off the great circle");
            Some(angle_between(w, w2))
        };
        let out = chi2_1d(&cfg(), range, 2, sampler, |p| k.density_along_arc(psi, p));
        assert!(out.passed, "{}", out.message);
        // The printed form: sin((ω₁·ω₂)λ) ω₁ / sin(ω₁·ω₂) + sin((ω₁·ω₂)(1−λ)) ω₂ / sin(ω₁·ω₂).
        let printed = |rng: &mut Rng| {
            let lambda = k.stretch.sample_lambda(rng.uniform_f64());
            let c = w1.dot(w2);
            let w = (w1 * (c * lambda).sin() + w2 * (c * (1.0 - lambda)).sin()) / c.sin();
            Some(angle_between(w.normalize(), w2))
        };
        let wrong = chi2_1d(&cfg(), range, 2, printed, |p| k.density_along_arc(psi, p));
        assert!(!wrong.passed, "the printed slerp passed: {}", wrong.message);
    }

    /// |det| of a 3×3 matrix given by columns.
    fn det3(c: [[f64; 3]; 3]) -> f64 {
        let [a, b, d] = c;
        (a[0] * (b[1] * d[2] - b[2] * d[1]) - b[0] * (a[1] * d[2] - a[2] * d[1]) + d[0] * (a[1] * b[2] - a[2] * b[1]))
            .abs()
    }

    /// The stretch's ratio λ equals g(1/λ)/g(λ) · |∂(x′, λ′)/∂(x, λ)| with the 3×3 Jacobian of
    /// (x, λ) ↦ (v + λ(x − v), 1/λ) by central differences (relative error < 1e-6 over 200 random
    /// moves). Dropping λ (ratio 1) and Rⁿ's exponent for n = 3 (λ²) are rejected: their relative
    /// errors reach |λ − 1|/λ ≥ 0.15 at these α.
    #[test]
    fn stretch_ratio_matches_a_numerical_jacobian() {
        let k = StretchKernel { alpha: 0.5 };
        let mut rng = Rng::new(3, 0);
        let (mut worst, mut worst_drop, mut worst_cube) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..200 {
            let v = DVec2::new(rng.uniform_f64() * 4.0 - 2.0, rng.uniform_f64() * 4.0 - 2.0);
            let x = DVec2::new(rng.uniform_f64() * 4.0 - 2.0, rng.uniform_f64() * 4.0 - 2.0);
            let lambda = k.sample_lambda(rng.uniform_f64());
            let map = |p: [f64; 3]| {
                let to = v + p[2] * (DVec2::new(p[0], p[1]) - v);
                [to.x, to.y, 1.0 / p[2]]
            };
            let h = 1e-6;
            let p = [x.x, x.y, lambda];
            let cols: [[f64; 3]; 3] = std::array::from_fn(|axis| {
                let (mut up, mut down) = (p, p);
                up[axis] += h;
                down[axis] -= h;
                let (a, b) = (map(up), map(down));
                std::array::from_fn(|i| (a[i] - b[i]) / (2.0 * h))
            });
            let expected = k.density_lambda(1.0 / lambda) / k.density_lambda(lambda) * det3(cols);
            let rel = |r: f64| (r - expected).abs() / expected;
            worst = worst.max(rel(k.reverse_ratio(lambda)));
            worst_drop = worst_drop.max(rel(1.0));
            worst_cube = worst_cube.max(rel(lambda * lambda));
        }
        assert!(worst < 1e-6, "stretch ratio vs Jacobian: {worst}");
        assert!(worst_drop > 0.15 && worst_cube > 0.15, "wrong variants too close: {worst_drop} {worst_cube}");
    }

    /// The great arc's ratio sin ψ′/sin ψ equals g(1/λ)/g(λ) · J_ω · |∂λ′/∂λ|, J_ω the solid-angle
    /// Jacobian of ω ↦ ω′ at fixed λ measured by central differences through a spherical chart
    /// (relative error < 1e-5 over 200 random moves, ψ up to ~2.5 rad). The paper's Eq. 10 as
    /// printed (sin ψ/sin ψ′) and the flat ratio λ are rejected (relative errors above 0.2).
    #[test]
    fn great_arc_ratio_matches_a_numerical_jacobian() {
        let k = GreatArcKernel { stretch: StretchKernel { alpha: 0.5 } };
        let mut rng = Rng::new(4, 0);
        let chart = |p: [f64; 2]| {
            let (st, ct) = p[0].sin_cos();
            DVec3::new(st * p[1].cos(), st * p[1].sin(), ct)
        };
        let (mut worst, mut worst_printed, mut worst_flat) = (0.0f64, 0.0f64, 0.0f64);
        let mut tested = 0;
        while tested < 200 {
            let guide = chart([rng.uniform_f64() * 2.5 + 0.3, rng.uniform_f64() * 6.0]);
            let p = [rng.uniform_f64() * 2.5 + 0.3, rng.uniform_f64() * 6.0];
            let current = chart(p);
            let lambda = k.stretch.sample_lambda(rng.uniform_f64());
            let Some(proposed) = GreatArcKernel::arc_point(current, guide, lambda) else { continue };
            tested += 1;
            let h = 1e-6;
            let moved = |q: [f64; 2]| {
                let w = GreatArcKernel::arc_point(chart(q), guide, lambda).expect("nearby move");
                [w.x, w.y, w.z]
            };
            let as_array = |q: [f64; 2]| chart(q).to_array();
            let j_omega = jacobian_det_surface(moved, p, h) / jacobian_det_surface(as_array, p, h);
            let expected =
                k.stretch.density_lambda(1.0 / lambda) / k.stretch.density_lambda(lambda) * j_omega / (lambda * lambda);
            let rel = |r: f64| (r - expected).abs() / expected;
            let psi = (angle_between(current, guide), angle_between(proposed, guide));
            worst = worst.max(rel(k.reverse_ratio(current, guide, proposed)));
            worst_printed = worst_printed.max(rel(psi.0.sin() / psi.1.sin()));
            worst_flat = worst_flat.max(rel(lambda));
        }
        assert!(worst < 1e-5, "great-arc ratio vs Jacobian: {worst}");
        assert!(worst_printed > 0.2 && worst_flat > 0.2, "wrong variants too close: {worst_printed} {worst_flat}");
    }
}
