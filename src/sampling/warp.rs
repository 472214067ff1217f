//! Warps from the unit square to disks, hemispheres, spheres, cones and triangles, each as a trio
//! `sample_*` / `pdf_*` / `invert_*`.
//!
//! Every `invert_*` is the exact inverse of its `sample_*` wherever the map is injective (the
//! "inversion method" of the RJMLT paper, Sec. 6): its Jacobian determinant is the pdf, so an
//! inverted sample costs nothing in the acceptance ratio (Eq. 29). An inverse returns `None` for a
//! point the sampler cannot produce (a direction in the wrong hemisphere or outside the cone, a point
//! off the disk or the triangle) and clamps its result into [0, 1).
//!
//! Conventions: directions are unit vectors in a local frame with +z the pole (normal); `u` are
//! uniforms in [0, 1); the pdfs are densities per unit solid angle (directions), per unit area
//! (disk), or per unit barycentric area (triangle: 2 on the reference triangle).

// `!(x > 0.0)` is deliberate throughout: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

use glam::{Vec2, Vec3};

/// The largest `f32` below 1: inverses clamp into [0, ONE_MINUS_EPSILON] so that a round trip never
/// produces 1.0, which samplers do not accept.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Clamps an inverted uniform into [0, 1) (NaN becomes 0, so garbage never leaves an inverse).
#[inline]
pub fn clamp_unit(u: f32) -> f32 {
    if u.is_nan() {
        0.0
    } else {
        u.clamp(0.0, ONE_MINUS_EPSILON)
    }
}

/// Tolerance on "is this point inside the domain" in the inverses: points that a forward map
/// produced in f32 can lie a few ulps outside (e.g. |d|² = 1 + 1e-7 after normalisation).
const DOMAIN_TOLERANCE: f32 = 1e-5;

/// Azimuth φ/(2π) of (x, y) in [0, 1): the inverse of φ = 2π u. The seam φ = 0 is the one point where
/// u = 0 and u → 1 give the same direction, so round trips there are exact only modulo 1.
#[inline]
fn azimuth_to_unit(x: f32, y: f32) -> f32 {
    let mut u = y.atan2(x) * (0.5 * FRAC_1_PI);
    if u < 0.0 {
        u += 1.0;
    }
    clamp_unit(u)
}

// ---------------------------------------------------------------------------------------------
// Concentric disk (Shirley & Chiu 1997)
// ---------------------------------------------------------------------------------------------

/// Uniform point on the unit disk by Shirley and Chiu's concentric mapping. It maps the square's
/// concentric squares onto the disk's concentric circles, so unlike the polar map (r = √u0, φ = 2πu1)
/// it has no seam: its inverse is continuous everywhere and exact up to rounding (the centre, a
/// single point, is the only place where the map is not locally injective).
#[inline]
pub fn sample_uniform_disk_concentric(u: [f32; 2]) -> Vec2 {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if a.abs() > b.abs() { (a, FRAC_PI_4 * (b / a)) } else { (b, FRAC_PI_2 - FRAC_PI_4 * (a / b)) };
    let (s, c) = theta.sin_cos();
    Vec2::new(r * c, r * s)
}

/// Density of `sample_uniform_disk_concentric` per unit area: 1/π on the disk, 0 outside.
#[inline]
pub fn pdf_uniform_disk_concentric(p: Vec2) -> f32 {
    if p.length_squared() <= 1.0 {
        FRAC_1_PI
    } else {
        0.0
    }
}

/// Inverse of `sample_uniform_disk_concentric`; `None` off the disk.
///
/// In the wedge |x| ≥ |y| the forward map is p = a·(cos θ, sin θ) with θ = π/4·b/a ∈ [-π/4, π/4],
/// so a = sign(x)·|p| and θ = atan(y/x); in the other wedge p = b·(cos θ, sin θ) with
/// π/2 − θ = π/4·a/b, so b = sign(y)·|p| and a = b·atan(x/y)·4/π. No atan2, no seam.
pub fn invert_uniform_disk_concentric(p: Vec2) -> Option<[f32; 2]> {
    let r2 = p.length_squared();
    if !(r2 <= 1.0 + DOMAIN_TOLERANCE) {
        return None;
    }
    let r = r2.sqrt().min(1.0);
    let (a, b) = if p.x == 0.0 && p.y == 0.0 {
        (0.0, 0.0)
    } else if p.x.abs() >= p.y.abs() {
        let a = r.copysign(p.x);
        (a, a * (p.y / p.x).atan() * (4.0 * FRAC_1_PI))
    } else {
        let b = r.copysign(p.y);
        (b * (p.x / p.y).atan() * (4.0 * FRAC_1_PI), b)
    };
    Some([clamp_unit(0.5 * (a + 1.0)), clamp_unit(0.5 * (b + 1.0))])
}

// ---------------------------------------------------------------------------------------------
// Cosine-weighted hemisphere (Malley's method over the concentric disk)
// ---------------------------------------------------------------------------------------------

/// Cosine-weighted direction on the +z hemisphere: a concentric-disk point lifted to the
/// hemisphere (Malley's method). Chosen over the polar √u mapping because its inverse has no
/// azimuthal seam.
#[inline]
pub fn sample_cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let d = sample_uniform_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Solid-angle density of `sample_cosine_hemisphere`: cos θ / π above the horizon, 0 below.
#[inline]
pub fn pdf_cosine_hemisphere(w: Vec3) -> f32 {
    if w.z > 0.0 {
        w.z * FRAC_1_PI
    } else {
        0.0
    }
}

/// Inverse of `sample_cosine_hemisphere` (projects `w` onto the disk); `None` below the horizon.
/// `w` must be unit length.
#[inline]
pub fn invert_cosine_hemisphere(w: Vec3) -> Option<[f32; 2]> {
    if !(w.z >= 0.0) {
        return None;
    }
    invert_uniform_disk_concentric(Vec2::new(w.x, w.y))
}

// ---------------------------------------------------------------------------------------------
// Uniform sphere and hemisphere (Archimedes: z uniform, φ uniform)
// ---------------------------------------------------------------------------------------------

/// Uniform direction on the unit sphere: z = 1 − 2u0, φ = 2πu1.
#[inline]
pub fn sample_uniform_sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Solid-angle density of `sample_uniform_sphere`: 1/(4π).
#[inline]
pub fn pdf_uniform_sphere() -> f32 {
    0.25 * FRAC_1_PI
}

/// Inverse of `sample_uniform_sphere` for a unit `w`. Exact except on the seam φ = 0 (u1 = 0 and
/// u1 → 1 are the same direction) and at the poles (u1 undefined; 0 is returned).
#[inline]
pub fn invert_uniform_sphere(w: Vec3) -> Option<[f32; 2]> {
    if !w.is_finite() {
        return None;
    }
    let u0 = 0.5 * (1.0 - w.z.clamp(-1.0, 1.0));
    Some([clamp_unit(u0), azimuth_to_unit(w.x, w.y)])
}

/// Uniform direction on the +z hemisphere: z = u0, φ = 2πu1.
#[inline]
pub fn sample_uniform_hemisphere(u: [f32; 2]) -> Vec3 {
    let z = u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Solid-angle density of `sample_uniform_hemisphere`: 1/(2π) above the horizon, 0 below.
#[inline]
pub fn pdf_uniform_hemisphere(w: Vec3) -> f32 {
    if w.z >= 0.0 {
        0.5 * FRAC_1_PI
    } else {
        0.0
    }
}

/// Inverse of `sample_uniform_hemisphere` for a unit `w`; `None` below the horizon. Exact except on
/// the seam φ = 0 and at the pole, as for the sphere.
#[inline]
pub fn invert_uniform_hemisphere(w: Vec3) -> Option<[f32; 2]> {
    if !(w.z >= 0.0) || !w.is_finite() {
        return None;
    }
    Some([clamp_unit(w.z.min(1.0)), azimuth_to_unit(w.x, w.y)])
}

// ---------------------------------------------------------------------------------------------
// Uniform cone around +z
// ---------------------------------------------------------------------------------------------

/// Uniform direction in the cone of half-angle θmax around +z, given `cos_theta_max` in [-1, 1):
/// 1 − cos θ = u0·(1 − cos θmax), φ = 2πu1.
///
/// sin θ is computed from 1 − cos θ (not from cos θ), so narrow cones (the sun: 1 − cos θmax ≈ 1e-5)
/// keep full relative precision in the direction and in its inverse.
#[inline]
pub fn sample_uniform_cone(u: [f32; 2], cos_theta_max: f32) -> Vec3 {
    let one_minus_cos = u[0] * (1.0 - cos_theta_max);
    let cos_theta = 1.0 - one_minus_cos;
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    Vec3::new(sin_theta * c, sin_theta * s, cos_theta)
}

/// Solid-angle density of `sample_uniform_cone`: 1/(2π(1 − cos θmax)) inside the cone, 0 outside.
#[inline]
pub fn pdf_uniform_cone(w: Vec3, cos_theta_max: f32) -> f32 {
    if one_minus_cos_theta(w) <= (1.0 - cos_theta_max) * (1.0 + DOMAIN_TOLERANCE) {
        1.0 / (2.0 * PI * (1.0 - cos_theta_max))
    } else {
        0.0
    }
}

/// 1 − cos θ of a unit direction, accurate near the pole: sin²θ/(1 + cos θ) there.
#[inline]
fn one_minus_cos_theta(w: Vec3) -> f32 {
    if w.z > 0.5 {
        (w.x * w.x + w.y * w.y) / (1.0 + w.z)
    } else {
        1.0 - w.z
    }
}

/// Inverse of `sample_uniform_cone` for a unit `w`; `None` outside the cone. Exact except on the
/// seam φ = 0 and at the apex, as for the sphere.
#[inline]
pub fn invert_uniform_cone(w: Vec3, cos_theta_max: f32) -> Option<[f32; 2]> {
    if !w.is_finite() {
        return None;
    }
    let width = 1.0 - cos_theta_max;
    let omc = one_minus_cos_theta(w);
    if !(omc <= width * (1.0 + DOMAIN_TOLERANCE)) {
        return None;
    }
    Some([clamp_unit(omc / width), azimuth_to_unit(w.x, w.y)])
}

// ---------------------------------------------------------------------------------------------
// Uniform triangle (square-root parameterisation)
// ---------------------------------------------------------------------------------------------

/// Uniform barycentrics `(b1, b2)` on a triangle (the point is (1−b1−b2)·v0 + b1·v1 + b2·v2, the
/// convention of `Hit`): with s = √u0, b1 = s·(1 − u1), b2 = s·u1. The map is a bijection from
/// the open square onto the open triangle (b0 = 1 − s is the distance from the edge v1v2 in
/// barycentric units, u1 the position along the segment parallel to it), with constant Jacobian
/// 1/2, so its inverse is exact except at the vertex v0 (s = 0), where u1 is undefined.
#[inline]
pub fn sample_uniform_triangle(u: [f32; 2]) -> Vec2 {
    let s = u[0].sqrt();
    Vec2::new(s * (1.0 - u[1]), s * u[1])
}

/// Density of `sample_uniform_triangle` per unit barycentric area: 2 on the reference triangle
/// (whose area is 1/2), 0 outside. On a triangle of area A the area density is 1/A.
#[inline]
pub fn pdf_uniform_triangle(b: Vec2) -> f32 {
    let tol = DOMAIN_TOLERANCE;
    if b.x >= -tol && b.y >= -tol && b.x + b.y <= 1.0 + tol {
        2.0
    } else {
        0.0
    }
}

/// Inverse of `sample_uniform_triangle`: u0 = (b1 + b2)², u1 = b2/(b1 + b2); `None` when the
/// barycentrics lie off the triangle (beyond a few ulps). At the vertex v0 u1 = 0.5 is returned.
#[inline]
pub fn invert_uniform_triangle(b: Vec2) -> Option<[f32; 2]> {
    if pdf_uniform_triangle(b) == 0.0 || !b.is_finite() {
        return None;
    }
    let b1 = b.x.max(0.0);
    let b2 = b.y.max(0.0);
    let s = b1 + b2;
    let u1 = if s > 0.0 { b2 / s } else { 0.5 };
    Some([clamp_unit(s * s), clamp_unit(u1)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::chi2::{self, Chi2Config};
    use crate::sampling::Rng;

    /// Number of chi-square tests in the sampling/light/camera suite: the Šidák correction divides
    /// the family-wise significance 1e-3 among them (see `chi2::CHI2_TESTS_SAMPLING`).
    const TESTS: usize = chi2::CHI2_TESTS_SAMPLING;

    fn cfg() -> Chi2Config {
        Chi2Config { test_count: TESTS, ..Chi2Config::default() }
    }

    fn unit_grid(n: usize) -> impl Iterator<Item = [f32; 2]> {
        (0..n).flat_map(move |i| (0..n).map(move |j| [(i as f32 + 0.37) / n as f32, (j as f32 + 0.61) / n as f32]))
    }

    fn torus_dist(a: f32, b: f32) -> f32 {
        let d = (a - b).abs();
        d.min(1.0 - d)
    }

    #[test]
    fn chi2_cosine_hemisphere() {
        let r = chi2::chi2_sphere(
            &cfg(),
            1,
            |rng: &mut Rng| Some(sample_cosine_hemisphere([rng.uniform(), rng.uniform()])),
            |w| pdf_cosine_hemisphere(w) as f64,
        );
        assert!(r.passed, "{}", r.message);
    }

    #[test]
    fn chi2_uniform_sphere_hemisphere_cone() {
        let r = chi2::chi2_sphere(
            &cfg(),
            2,
            |rng: &mut Rng| Some(sample_uniform_sphere([rng.uniform(), rng.uniform()])),
            |_| pdf_uniform_sphere() as f64,
        );
        assert!(r.passed, "sphere: {}", r.message);
        let r = chi2::chi2_sphere(
            &cfg(),
            3,
            |rng: &mut Rng| Some(sample_uniform_hemisphere([rng.uniform(), rng.uniform()])),
            |w| pdf_uniform_hemisphere(w) as f64,
        );
        assert!(r.passed, "hemisphere: {}", r.message);
        for (k, cmax) in [0.3f32, -0.5].into_iter().enumerate() {
            let r = chi2::chi2_sphere(
                &cfg(),
                4 + k as u64,
                |rng: &mut Rng| Some(sample_uniform_cone([rng.uniform(), rng.uniform()], cmax)),
                |w| pdf_uniform_cone(w, cmax) as f64,
            );
            assert!(r.passed, "cone {cmax}: {}", r.message);
        }
    }

    #[test]
    fn chi2_disk_and_triangle() {
        let r = chi2::chi2_square(
            &cfg(),
            [-1.0, 1.0],
            [-1.0, 1.0],
            6,
            |rng: &mut Rng| {
                let p = sample_uniform_disk_concentric([rng.uniform(), rng.uniform()]);
                Some([p.x as f64, p.y as f64])
            },
            |p| pdf_uniform_disk_concentric(Vec2::new(p[0] as f32, p[1] as f32)) as f64,
        );
        assert!(r.passed, "disk: {}", r.message);
        let r = chi2::chi2_square(
            &cfg(),
            [0.0, 1.0],
            [0.0, 1.0],
            7,
            |rng: &mut Rng| {
                let b = sample_uniform_triangle([rng.uniform(), rng.uniform()]);
                Some([b.x as f64, b.y as f64])
            },
            |p| if p[0] + p[1] <= 1.0 { 2.0 } else { 0.0 },
        );
        assert!(r.passed, "triangle: {}", r.message);
    }

    /// The harness must reject wrong pdfs: cosine samples against the uniform hemisphere pdf, and
    /// uniform hemisphere samples against the cosine pdf (a missing/extra cosine factor).
    #[test]
    fn chi2_has_teeth() {
        let r = chi2::chi2_sphere(
            &cfg(),
            8,
            |rng: &mut Rng| Some(sample_cosine_hemisphere([rng.uniform(), rng.uniform()])),
            |w| pdf_uniform_hemisphere(w) as f64,
        );
        assert!(!r.passed, "wrong pdf accepted: {}", r.message);
        let r = chi2::chi2_sphere(
            &cfg(),
            9,
            |rng: &mut Rng| Some(sample_uniform_hemisphere([rng.uniform(), rng.uniform()])),
            |w| pdf_cosine_hemisphere(w) as f64,
        );
        assert!(!r.passed, "wrong pdf accepted: {}", r.message);
        // A subtler error: a cone pdf normalised for a 5% wider cone.
        let r = chi2::chi2_sphere(
            &cfg(),
            10,
            |rng: &mut Rng| Some(sample_uniform_cone([rng.uniform(), rng.uniform()], 0.3)),
            |w| if w.z >= 0.3 { 1.0 / (2.0 * std::f64::consts::PI * 0.7 * 1.05) } else { 0.0 },
        );
        assert!(!r.passed, "wrong cone normalisation accepted: {}", r.message);
    }

    #[test]
    fn round_trips() {
        for u in unit_grid(64) {
            let check = |name: &str, v: Option<[f32; 2]>, periodic_u1: bool| {
                let v = v.unwrap_or_else(|| panic!("{name}: inverse failed at {u:?}"));
                let d1 = if periodic_u1 { torus_dist(u[1], v[1]) } else { (u[1] - v[1]).abs() };
                assert!((u[0] - v[0]).abs() < 1e-4 && d1 < 1e-4, "{name}: {u:?} -> {v:?}");
            };
            check("disk", invert_uniform_disk_concentric(sample_uniform_disk_concentric(u)), false);
            check("cosine", invert_cosine_hemisphere(sample_cosine_hemisphere(u)), false);
            check("sphere", invert_uniform_sphere(sample_uniform_sphere(u)), true);
            check("hemisphere", invert_uniform_hemisphere(sample_uniform_hemisphere(u)), true);
            for cmax in [0.3f32, -0.9, 0.999_99] {
                check("cone", invert_uniform_cone(sample_uniform_cone(u, cmax), cmax), true);
            }
            check("triangle", invert_uniform_triangle(sample_uniform_triangle(u)), false);
        }
        // The extremes of the square, including the exact corners and the disk centre.
        for u in [[0.0, 0.0], [0.5, 0.5], [ONE_MINUS_EPSILON, ONE_MINUS_EPSILON], [0.0, ONE_MINUS_EPSILON]] {
            let v = invert_uniform_disk_concentric(sample_uniform_disk_concentric(u)).unwrap();
            assert!((u[0] - v[0]).abs() < 1e-4 && (u[1] - v[1]).abs() < 1e-4, "{u:?} -> {v:?}");
        }
    }

    #[test]
    fn inverses_refuse_points_off_the_domain() {
        assert!(invert_cosine_hemisphere(Vec3::new(0.0, 0.6, -0.8)).is_none());
        assert!(invert_uniform_hemisphere(Vec3::new(0.0, 0.6, -0.8)).is_none());
        assert!(invert_uniform_cone(Vec3::new(0.8, 0.0, 0.6), 0.9).is_none());
        assert!(invert_uniform_disk_concentric(Vec2::new(0.9, 0.9)).is_none());
        assert!(invert_uniform_triangle(Vec2::new(0.7, 0.7)).is_none());
        assert!(invert_uniform_triangle(Vec2::new(-0.1, 0.2)).is_none());
        assert!(invert_uniform_sphere(Vec3::NAN).is_none());
        for u in unit_grid(16) {
            for v in [
                invert_uniform_sphere(sample_uniform_sphere(u)).unwrap(),
                invert_cosine_hemisphere(sample_cosine_hemisphere(u)).unwrap(),
            ] {
                assert!(v.iter().all(|x| (0.0..1.0).contains(x)));
            }
        }
    }

    /// |det J| of each map (finite differences) equals 1/pdf, away from the singular points (disk
    /// centre, poles, the horizon of the cosine map where the pdf vanishes).
    #[test]
    fn jacobians_match_pdfs() {
        let f3 = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
        for u in unit_grid(12) {
            let u64_ = [u[0] as f64, u[1] as f64];
            // Stay 2h away from the square's edges and its centre lines (the concentric map's kinks
            // lie on its diagonals and are smooth across them, but the centre is singular).
            if u64_.iter().any(|x| !(0.02..0.98).contains(x))
                || ((u64_[0] - 0.5).abs() < 0.03 && (u64_[1] - 0.5).abs() < 0.03)
            {
                continue;
            }
            let checks: Vec<(&str, f64, f64)> = vec![
                (
                    "disk",
                    chi2::jacobian_det_2d(
                        |x| {
                            let p = sample_uniform_disk_concentric([x[0] as f32, x[1] as f32]);
                            [p.x as f64, p.y as f64]
                        },
                        u64_,
                        1e-3,
                    ),
                    pdf_uniform_disk_concentric(sample_uniform_disk_concentric(u)) as f64,
                ),
                (
                    "cosine",
                    chi2::jacobian_det_surface(
                        |x| f3(sample_cosine_hemisphere([x[0] as f32, x[1] as f32])),
                        u64_,
                        1e-3,
                    ),
                    pdf_cosine_hemisphere(sample_cosine_hemisphere(u)) as f64,
                ),
                (
                    "sphere",
                    chi2::jacobian_det_surface(|x| f3(sample_uniform_sphere([x[0] as f32, x[1] as f32])), u64_, 1e-3),
                    pdf_uniform_sphere() as f64,
                ),
                (
                    "hemisphere",
                    chi2::jacobian_det_surface(
                        |x| f3(sample_uniform_hemisphere([x[0] as f32, x[1] as f32])),
                        u64_,
                        1e-3,
                    ),
                    pdf_uniform_hemisphere(Vec3::Z) as f64,
                ),
                (
                    "cone",
                    chi2::jacobian_det_surface(
                        |x| f3(sample_uniform_cone([x[0] as f32, x[1] as f32], 0.2)),
                        u64_,
                        1e-3,
                    ),
                    pdf_uniform_cone(Vec3::Z, 0.2) as f64,
                ),
                (
                    "triangle",
                    chi2::jacobian_det_2d(
                        |x| {
                            let b = sample_uniform_triangle([x[0] as f32, x[1] as f32]);
                            [b.x as f64, b.y as f64]
                        },
                        u64_,
                        1e-3,
                    ),
                    2.0,
                ),
            ];
            for (name, det, pdf) in checks {
                // The cosine map's pdf vanishes at the horizon (the square's edge); skip cells where
                // the finite difference cannot resolve it.
                if pdf < 0.05 {
                    continue;
                }
                let rel = (det * pdf - 1.0).abs();
                assert!(rel < 1e-2, "{name} at {u:?}: |J| = {det}, 1/pdf = {}", 1.0 / pdf);
            }
        }
    }

    type SpherePdf = Box<dyn Fn(Vec3) -> f64>;

    #[test]
    fn pdfs_integrate_to_one() {
        let tests: [(&str, SpherePdf); 4] = [
            ("cosine", Box::new(|w| pdf_cosine_hemisphere(w) as f64)),
            ("sphere", Box::new(|_| pdf_uniform_sphere() as f64)),
            ("hemisphere", Box::new(|w| pdf_uniform_hemisphere(w) as f64)),
            ("cone", Box::new(|w| pdf_uniform_cone(w, 0.3) as f64)),
        ];
        for (name, pdf) in tests {
            let total = chi2::integrate_sphere(&pdf, 16, 32);
            assert!((total - 1.0).abs() < 1e-4, "{name}: integral {total}");
        }
        let disk = chi2::integrate_2d(
            |p| pdf_uniform_disk_concentric(Vec2::new(p[0] as f32, p[1] as f32)) as f64,
            [-1.0, 1.0],
            [-1.0, 1.0],
            200,
            200,
        );
        assert!((disk - 1.0).abs() < 1e-4, "disk: {disk}");
        let tri = chi2::integrate_2d(
            |p| pdf_uniform_triangle(Vec2::new(p[0] as f32, p[1] as f32)) as f64,
            [0.0, 1.0],
            [0.0, 1.0],
            200,
            200,
        );
        assert!((tri - 1.0).abs() < 1e-4, "triangle: {tri}");
    }
}
