//! The guided anisotropic transition kernel of EMLT (Bashford-Rogers et al. 2021, Sec. 3.2, Eq.
//! 11–12, Fig. 5): a Gaussian fitted to Υ's vertices on the tangent plane of the current vertex,
//! recentred there, sampled and projected onto the scene by a ray from the move's previous vertex.
//! The image-plane version (the same fit on Υ's raster positions) moves the first vertex. Sample,
//! density and the Jacobian of the projection side by side.
//!
//! # The fit (Eq. 11 and the text after it)
//! For the current vertex x_j (position p, geometric normal n) and Υ's vertices v_jⁿ with weights
//! w(n) = S(x̄, vⁿ, j, j + 1)/Σ_k S(x̄, vᵏ, j, j + 1) (Eq. 11), each v_jⁿ is projected orthogonally
//! on the plane through p with normal n, in coordinates uⁿ of an orthonormal basis (s, t) of the
//! plane. The Gaussian's covariance is the **standard weighted estimate** with normalised weights,
//!
//!   μ = Σ w(n) uⁿ,   Σ = Σ w(n) (uⁿ − μ)(uⁿ − μ)ᵀ / (1 − Σ w(n)²),
//!
//! the unbiased estimator with reliability weights. The paper prints μ = (1/M) Σ w(n) v and
//! Σ = 1/(M − 1) Σ w(n)(v − μ)²: with weights already normalised to sum 1, the 1/M would shrink μ
//! towards the origin of world space by M (it is not a mean of the points), and 1/(M − 1) is the
//! unweighted estimator's Bessel factor, which with normalised weights scales Σ by 1/(M − 1)
//! instead of correcting its bias; both are typos for the estimators above (with equal weights
//! they reduce to the sample mean and the sample covariance with 1/(M − 1)).
//! The Gaussian is then **recentred** at p: N(p, Σ) on the plane (Fig. 5(e)); μ is only used for Σ.
//!
//! # Degenerate fits
//! All weights zero, one weight carrying everything (1 − Σw² ≤ `MIN_SPREAD`), a non-finite Σ or
//! one whose eigenvalue ratio det Σ/tr² Σ is below `MIN_EIGEN_RATIO` (Υ's vertices on a line)
//! make the fit degenerate; the kernel is then a von Mises–Fisher distribution of the ray
//! direction about x′_{j−1} → x_j with a high concentration (the paper's fallback;
//! `EmltSettings::fallback_concentration`), per unit solid angle at the ray's origin.
//!
//! # Projection onto the scene and Eq. 12
//! A sample z′ = p + a s + b t of N(p, Σ) is not on the scene: the ray from the move's previous
//! vertex o towards z′ meets the scene at x′_j. Along one ray, a solid angle dω at o is
//! dω = |cos θ_z| dA_z / |z′ − o|² = |cos θ_x| dA_x / |x′ − o|², so the density per unit area at x′ is
//!
//!   K(x̄ → x̄′) = N(z′ | p, Σ) · (|cos θ_x′| / |x′ − o|²) / (|cos θ_z′| / |z′ − o|²)
//!             = N(z′ | p, Σ) · G(x′ ↔ o) / G(z′ ↔ o)
//!
//! (the paper's text after Fig. 6; G's cosine at o is the same for both and cancels).
//! [`plane_to_surface`] is that ratio; the tests check it against a numerical Jacobian of the map
//! z′ ↦ x′. z′ is recovered from x′ as the intersection of the ray o → x′ with the plane, which
//! must lie ahead of o (a direction that does not meet the plane cannot be sampled: density 0).
//!
//! The fit depends on the current path, so the reverse density **refits at ȳ**: its own weights
//! S(ȳ, vⁿ, j, j + 1), its own plane (y_j, n(y_j)) and Σ, and the reverse move's previous vertex as
//! the projection's origin; Eq. 12 is the ratio of the two full densities, which is how the
//! strategies use it (each T is a normalised density, so mixing a Gaussian fit one way with the
//! vMF fallback the other way is still exact).

use glam::{DVec2, DVec3};

use super::directional::Vmf;
use crate::integrator::path_space::reciprocal_kernel::basis;

/// A fit whose weights have 1 − Σw² at or below this (one vertex carries all the weight) is
/// degenerate.
pub const MIN_SPREAD: f64 = 1e-9;
/// A fit whose covariance has det/tr² at or below this (eigenvalue ratio ~1e-8: the points lie on
/// a line) is degenerate.
pub const MIN_EIGEN_RATIO: f64 = 1e-8;

/// A centred 2D Gaussian by its covariance [[a, b], [b, c]] and that matrix's Cholesky factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian2 {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    det: f64,
    /// Cholesky factor L = [[l11, 0], [l21, l22]], Σ = L Lᵀ.
    l: [f64; 3],
}

impl Gaussian2 {
    /// The Gaussian of covariance [[a, b], [b, c]], None when it is degenerate (module docs).
    pub fn from_covariance(a: f64, b: f64, c: f64) -> Option<Gaussian2> {
        let (det, trace) = (a * c - b * b, a + c);
        if !(det.is_finite() && trace.is_finite() && trace > 0.0 && det > MIN_EIGEN_RATIO * trace * trace) {
            return None;
        }
        let l11 = a.sqrt();
        let l21 = b / l11;
        let l22 = (c - l21 * l21).max(0.0).sqrt();
        (l11 > 0.0 && l22 > 0.0).then_some(Gaussian2 { a, b, c, det, l: [l11, l21, l22] })
    }

    /// The weighted covariance of `points` (module docs, "The fit"); None when degenerate.
    /// Non-positive or non-finite weights leave their point out.
    pub fn fit(points: &[DVec2], weights: &[f64]) -> Option<Gaussian2> {
        let usable = |w: f64| w > 0.0 && w.is_finite();
        let total: f64 = weights.iter().filter(|&&w| usable(w)).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let pairs = || points.iter().zip(weights).filter(|(_, &w)| usable(w)).map(move |(p, &w)| (*p, w / total));
        let mean: DVec2 = pairs().map(|(p, w)| p * w).sum();
        let spread = 1.0 - pairs().map(|(_, w)| w * w).sum::<f64>();
        if !(spread > MIN_SPREAD) {
            return None;
        }
        let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
        for (p, w) in pairs() {
            let d = p - mean;
            a += w * d.x * d.x;
            b += w * d.x * d.y;
            c += w * d.y * d.y;
        }
        Gaussian2::from_covariance(a / spread, b / spread, c / spread)
    }

    /// An offset L·n, n a standard normal pair by Box–Muller from `u`.
    pub fn sample_offset(&self, u: [f64; 2]) -> DVec2 {
        let r = (-2.0 * (1.0 - u[0]).ln()).sqrt();
        let phi = std::f64::consts::TAU * u[1];
        let (n0, n1) = (r * phi.cos(), r * phi.sin());
        DVec2::new(self.l[0] * n0, self.l[1] * n0 + self.l[2] * n1)
    }

    /// The density of `sample_offset` producing the offset `d`.
    pub fn density_offset(&self, d: DVec2) -> f64 {
        let q = (self.c * d.x * d.x - 2.0 * self.b * d.x * d.y + self.a * d.y * d.y) / self.det;
        (-0.5 * q).exp() / (std::f64::consts::TAU * self.det.sqrt())
    }
}

/// The point where the ray from `origin` along the unit `dir` meets the plane through `p` with
/// unit normal `n`, with its distance from `origin`; None when the ray is parallel to the plane or
/// meets it behind `origin`.
pub fn ray_plane(origin: DVec3, dir: DVec3, p: DVec3, n: DVec3) -> Option<(DVec3, f64)> {
    let along = (p - origin).dot(n) / dir.dot(n);
    (along > 0.0 && along.is_finite()).then(|| (origin + dir * along, along))
}

/// G(x ↔ o)/G(z ↔ o) of Eq. 12 for the point `z` on a plane of unit normal `n_z` and the point
/// `x` of unit normal `n_x` on the same ray from `origin`: the density per unit plane area at z as
/// a density per unit area at x (module docs). 0 when either cosine vanishes.
pub fn plane_to_surface(origin: DVec3, z: DVec3, n_z: DVec3, x: DVec3, n_x: DVec3) -> f64 {
    let (dz, dx) = (z - origin, x - origin);
    let (lz2, lx2) = (dz.length_squared(), dx.length_squared());
    let cos_z = n_z.dot(dz).abs() / lz2.sqrt();
    let cos_x = n_x.dot(dx).abs() / lx2.sqrt();
    let r = (cos_x / lx2) / (cos_z / lz2);
    if r.is_finite() {
        r
    } else {
        0.0
    }
}

/// |cos θ_x|/|x − o|²: a density per unit solid angle at `origin` as one per unit area at `x`
/// (unit normal `n_x`).
pub fn solid_angle_to_area(origin: DVec3, x: DVec3, n_x: DVec3) -> f64 {
    let d = x - origin;
    let l2 = d.length_squared();
    let r = n_x.dot(d).abs() / (l2 * l2.sqrt());
    if r.is_finite() {
        r
    } else {
        0.0
    }
}

/// The anisotropic kernel at one vertex: the recentred tangent-plane Gaussian, or the vMF fallback
/// about the direction from the move's previous vertex to the current vertex (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VertexKernel {
    Tangent { p: DVec3, n: DVec3, s: DVec3, t: DVec3, gaussian: Gaussian2 },
    Vmf { p: DVec3, kappa: f64 },
}

impl VertexKernel {
    /// The fit at the vertex `p` of unit geometric normal `n` to Υ's vertices `guides` with Eq. 11's
    /// weights (unnormalised: the fit normalises them), `fallback_kappa` the vMF's concentration
    /// when the fit is degenerate.
    pub fn fit(p: DVec3, n: DVec3, guides: &[DVec3], weights: &[f64], fallback_kappa: f64) -> VertexKernel {
        let (s, t) = basis(n);
        let coords: Vec<DVec2> = guides.iter().map(|v| DVec2::new((*v - p).dot(s), (*v - p).dot(t))).collect();
        match Gaussian2::fit(&coords, weights) {
            Some(gaussian) => VertexKernel::Tangent { p, n, s, t, gaussian },
            None => VertexKernel::Vmf { p, kappa: fallback_kappa },
        }
    }

    /// Whether this is the vMF fallback.
    pub fn is_fallback(&self) -> bool {
        matches!(self, VertexKernel::Vmf { .. })
    }

    /// The vMF about `origin` → p.
    fn vmf(origin: DVec3, p: DVec3, kappa: f64) -> Option<Vmf> {
        let axis = (p - origin).normalize();
        axis.is_finite().then_some(Vmf { axis, kappa })
    }

    /// The unit direction from `origin` (the move's previous vertex) of the ray to trace: towards
    /// z′ = p + L·n for the Gaussian, a vMF draw for the fallback.
    pub fn sample_direction(&self, origin: DVec3, u: [f64; 2]) -> Option<DVec3> {
        let dir = match *self {
            VertexKernel::Tangent { p, s, t, gaussian, .. } => {
                let o = gaussian.sample_offset(u);
                (p + s * o.x + t * o.y - origin).normalize()
            }
            VertexKernel::Vmf { p, kappa } => Self::vmf(origin, p, kappa)?.sample(u),
        };
        dir.is_finite().then_some(dir)
    }

    /// The density per unit area at `x` (unit normal `n_x`), the first hit of the ray from `origin`
    /// towards it, of `sample_direction` and the trace (module docs, Eq. 12's K).
    pub fn density_area(&self, origin: DVec3, x: DVec3, n_x: DVec3) -> f64 {
        let dir = (x - origin).normalize();
        if !dir.is_finite() {
            return 0.0;
        }
        match *self {
            VertexKernel::Tangent { p, n, s, t, gaussian } => {
                let Some((z, _)) = ray_plane(origin, dir, p, n) else { return 0.0 };
                let offset = DVec2::new((z - p).dot(s), (z - p).dot(t));
                gaussian.density_offset(offset) * plane_to_surface(origin, z, n, x, n_x)
            }
            VertexKernel::Vmf { p, kappa } => match Self::vmf(origin, p, kappa) {
                Some(v) => v.density(dir) * solid_angle_to_area(origin, x, n_x),
                None => 0.0,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    //! The kernel on an analytic scene (a sphere seen from outside, so that the projection is
    //! oblique and curved): sampling against `density_area` by χ², with the G ratio of Eq. 12
    //! dropped as the wrong variant; the G ratio against a numerical Jacobian of z′ ↦ x′; the
    //! Gaussian's sampling against its density with the off-diagonal term's sign flipped as the
    //! wrong variant; the fit's estimators and degeneracies.

    use super::*;
    use crate::sampling::chi2::{chi2_test, jacobian_det_surface, Chi2Config};
    use crate::sampling::Rng;

    /// χ² tests here that must pass (the Šidák family).
    const CHI2_TESTS: usize = 3;

    const TAU: f64 = std::f64::consts::TAU;

    /// The sphere of the tests: centre and radius.
    const CENTRE: DVec3 = DVec3::new(0.0, 0.0, 0.0);
    const RADIUS: f64 = 1.0;

    /// The first hit of the ray from `o` along the unit `d` with the sphere, and its normal.
    fn hit_sphere(o: DVec3, d: DVec3) -> Option<(DVec3, DVec3)> {
        let oc = o - CENTRE;
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - RADIUS * RADIUS);
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t > 0.0).then(|| {
            let x = o + d * t;
            (x, (x - CENTRE).normalize())
        })
    }

    /// The current vertex, the previous vertex (oblique to the sphere) and the Gaussian fitted to
    /// a spread of weighted guides around it.
    fn setup() -> (DVec3, DVec3, VertexKernel) {
        let p = DVec3::new(0.3, 0.4, 1.0).normalize() * RADIUS;
        let origin = DVec3::new(2.5, -0.5, 2.0);
        let n = (p - CENTRE).normalize();
        let (s, t) = basis(n);
        let guides: Vec<DVec3> = [(0.35, 0.1), (-0.2, 0.05), (0.1, -0.12), (-0.3, -0.02), (0.05, 0.2), (0.25, -0.15)]
            .iter()
            .map(|&(a, b)| (p + s * a + t * b).normalize() * RADIUS)
            .collect();
        let weights = [1.0, 0.7, 0.5, 0.9, 0.3, 0.6];
        let k = VertexKernel::fit(p, n, &guides, &weights, 100.0);
        assert!(!k.is_fallback());
        (p, origin, k)
    }

    /// (cos α, φ) of a point of the sphere about the pole `p` (dA = R² d(cos α) dφ).
    fn sphere_coords(p: DVec3, x: DVec3) -> [f64; 2] {
        let pole = (p - CENTRE).normalize();
        let (s, t) = basis(pole);
        let d = (x - CENTRE).normalize();
        [d.dot(pole), d.dot(t).atan2(d.dot(s)).rem_euclid(TAU)]
    }

    fn sphere_point(p: DVec3, q: [f64; 2]) -> DVec3 {
        let pole = (p - CENTRE).normalize();
        let (s, t) = basis(pole);
        let sin = (1.0 - q[0] * q[0]).max(0.0).sqrt();
        CENTRE + (pole * q[0] + s * (sin * q[1].cos()) + t * (sin * q[1].sin())) * RADIUS
    }

    /// χ² of the hit points of `kernel`'s samples against `density`, over (cos α, φ) about p with
    /// cos α ∈ [0.6, 1] (24 × 16 bins, 200,000 samples); samples that miss the sphere, reach it
    /// where the origin does not see it, or fall outside go to the extra cell.
    fn chi2_on_sphere(
        kernel: &VertexKernel,
        p: DVec3,
        origin: DVec3,
        seed: u64,
        density: impl Fn(DVec3, DVec3) -> f64,
    ) -> crate::sampling::chi2::Chi2Outcome {
        let cfg = Chi2Config {
            res: [24, 16],
            samples: 200_000,
            test_count: CHI2_TESTS,
            quad_eps: 1e-7,
            ..Chi2Config::default()
        };
        chi2_test(
            &cfg,
            [0.6, 1.0],
            [0.0, TAU],
            seed,
            |rng: &mut Rng| {
                let d = kernel.sample_direction(origin, [rng.uniform_f64(), rng.uniform_f64()])?;
                let (x, _) = hit_sphere(origin, d)?;
                Some(sphere_coords(p, x))
            },
            |q| {
                let x = sphere_point(p, q);
                let n_x = (x - CENTRE).normalize();
                // Only the visible cap is reachable: the first hit towards x must be x.
                match hit_sphere(origin, (x - origin).normalize()) {
                    Some((h, _)) if (h - x).length() < 1e-9 => density(x, n_x) * RADIUS * RADIUS,
                    _ => 0.0,
                }
            },
        )
    }

    /// The Gaussian kernel's hit points follow `density_area` (χ² on the sphere, α = 1e-3 over the
    /// module's tests), and so do the vMF fallback's; the density without Eq. 12's G ratio (N(z′)
    /// alone, as if the plane were the scene) is rejected by the same test.
    #[test]
    fn sampling_matches_density_with_the_g_ratio_and_not_without() {
        let (p, origin, k) = setup();
        let right = chi2_on_sphere(&k, p, origin, 11, |x, n_x| k.density_area(origin, x, n_x));
        println!("anisotropic kernel: {}", right.message);
        assert!(right.passed, "{}", right.message);
        let without_g = |x: DVec3, n_x: DVec3| {
            let VertexKernel::Tangent { p, n, .. } = k else { unreachable!() };
            let Some((z, _)) = ray_plane(origin, (x - origin).normalize(), p, n) else { return 0.0 };
            k.density_area(origin, x, n_x) / plane_to_surface(origin, z, n, x, n_x)
        };
        let wrong = chi2_on_sphere(&k, p, origin, 12, without_g);
        println!("anisotropic kernel without the G ratio: {}", wrong.message);
        assert!(!wrong.passed, "the density without Eq. 12's G ratio passed: {}", wrong.message);
        let fallback = VertexKernel::fit(p, (p - CENTRE).normalize(), &[p], &[1.0], 200.0);
        assert!(fallback.is_fallback());
        let vmf = chi2_on_sphere(&fallback, p, origin, 13, |x, n_x| fallback.density_area(origin, x, n_x));
        println!("vMF fallback: {}", vmf.message);
        assert!(vmf.passed, "{}", vmf.message);
    }

    /// Eq. 12's G(x′ ↔ o)/G(z′ ↔ o) is dA_z/dA_x of the map z′ ↦ x′ (plane to sphere along rays
    /// from o), measured by central differences over 200 random plane points: relative error
    /// < 1e-5. Its inverse and the ratio of squared distances alone (cosines dropped) are
    /// rejected (relative errors above 0.2).
    #[test]
    fn g_ratio_matches_a_numerical_jacobian() {
        let (p, origin, k) = setup();
        let VertexKernel::Tangent { n, s, t, .. } = k else { unreachable!() };
        let mut rng = Rng::new(17, 0);
        let (mut worst, mut worst_inverse, mut worst_no_cos) = (0.0f64, 0.0f64, 0.0f64);
        let mut tested = 0;
        while tested < 200 {
            let uv = [rng.uniform_f64() * 0.8 - 0.4, rng.uniform_f64() * 0.8 - 0.4];
            let on_sphere = |q: [f64; 2]| {
                let z = p + s * q[0] + t * q[1];
                hit_sphere(origin, (z - origin).normalize()).map(|(x, _)| x.to_array())
            };
            let Some(x) = on_sphere(uv) else { continue };
            // All four neighbours of the difference stencil must hit the sphere too.
            let h = 1e-6;
            let stencil = [[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]];
            if stencil.iter().any(|d| on_sphere([uv[0] + d[0], uv[1] + d[1]]).is_none()) {
                continue;
            }
            tested += 1;
            let jacobian = jacobian_det_surface(|q| on_sphere(q).expect("checked"), uv, h);
            let expected = 1.0 / jacobian;
            let (x, z) = (DVec3::from_array(x), p + s * uv[0] + t * uv[1]);
            let n_x = (x - CENTRE).normalize();
            let rel = |r: f64| (r - expected).abs() / expected;
            let g = plane_to_surface(origin, z, n, x, n_x);
            worst = worst.max(rel(g));
            worst_inverse = worst_inverse.max(rel(1.0 / g));
            worst_no_cos = worst_no_cos.max(rel((z - origin).length_squared() / (x - origin).length_squared()));
        }
        println!(
            "G ratio vs Jacobian: worst {worst:.2e}; inverse {worst_inverse:.3}; without cosines {worst_no_cos:.3}"
        );
        assert!(worst < 1e-5, "G ratio vs Jacobian: {worst}");
        assert!(worst_inverse > 0.2 && worst_no_cos > 0.2, "wrong variants too close: {worst_inverse} {worst_no_cos}");
    }

    /// `Gaussian2::sample_offset` follows `density_offset` (χ², 20 × 20 bins over ±4 standard
    /// deviations, 200,000 samples) for a correlated covariance; the density with the correlation's
    /// sign flipped is rejected.
    #[test]
    fn gaussian_sampling_matches_its_density() {
        let g = Gaussian2::from_covariance(2.0, 1.2, 1.0).expect("positive definite");
        let flipped = Gaussian2::from_covariance(2.0, -1.2, 1.0).expect("positive definite");
        let cfg = Chi2Config { res: [20, 20], samples: 200_000, test_count: CHI2_TESTS, ..Chi2Config::default() };
        let run = |pdf: &Gaussian2, seed| {
            chi2_test(
                &cfg,
                [-4.0 * 2f64.sqrt(), 4.0 * 2f64.sqrt()],
                [-4.0, 4.0],
                seed,
                |rng: &mut Rng| Some(g.sample_offset([rng.uniform_f64(), rng.uniform_f64()]).to_array()),
                |q| pdf.density_offset(DVec2::from_array(q)),
            )
        };
        let right = run(&g, 21);
        assert!(right.passed, "{}", right.message);
        let wrong = run(&flipped, 22);
        assert!(!wrong.passed, "the flipped correlation passed: {}", wrong.message);
    }

    /// The fit is the standard weighted estimate: with equal weights the sample covariance with
    /// 1/(M − 1); with unequal weights, the reliability-weighted one; it does not depend on where
    /// the points are (only on their spread: it is recentred); and it is degenerate for one point,
    /// collinear points and zero weights.
    #[test]
    fn fit_estimators_and_degeneracies() {
        let pts = [DVec2::new(0.0, 0.0), DVec2::new(2.0, 0.0), DVec2::new(0.0, 1.0), DVec2::new(2.0, 3.0)];
        let g = Gaussian2::fit(&pts, &[1.0; 4]).expect("fit");
        // Sample covariance by hand: mean (1, 1); Σ (dx², dxdy, dy²) = (4, 2, 6); / 3.
        assert!((g.a - 4.0 / 3.0).abs() < 1e-12 && (g.b - 2.0 / 3.0).abs() < 1e-12 && (g.c - 2.0).abs() < 1e-12);
        let w = [1.0, 2.0, 3.0, 4.0];
        let g = Gaussian2::fit(&pts, &w).expect("fit");
        let shifted: Vec<DVec2> = pts.iter().map(|p| *p + DVec2::new(100.0, -40.0)).collect();
        let h = Gaussian2::fit(&shifted, &w).expect("fit");
        assert!((g.a - h.a).abs() < 1e-9 && (g.b - h.b).abs() < 1e-9 && (g.c - h.c).abs() < 1e-9);
        // Weighted by hand: normalised w = (.1, .2, .3, .4), mean (1.2, 1.5), 1 − Σw² = 0.7.
        let (mx, my) = (1.2, 1.5);
        let a: f64 = pts.iter().zip(&w).map(|(p, w)| w / 10.0 * (p.x - mx).powi(2)).sum::<f64>() / 0.7;
        let b: f64 = pts.iter().zip(&w).map(|(p, w)| w / 10.0 * (p.x - mx) * (p.y - my)).sum::<f64>() / 0.7;
        assert!((g.a - a).abs() < 1e-12 && (g.b - b).abs() < 1e-12);
        assert!(Gaussian2::fit(&pts[..1], &[1.0]).is_none());
        assert!(Gaussian2::fit(&pts, &[0.0; 4]).is_none());
        assert!(Gaussian2::fit(&pts, &[1.0, 0.0, 0.0, 0.0]).is_none());
        let line = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(3.0, 3.0)];
        assert!(Gaussian2::fit(&line, &[1.0; 3]).is_none());
    }
}
