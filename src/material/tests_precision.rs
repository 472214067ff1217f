//! The f32 fast paths against exact references: the combined `eval_pdf` against `eval` and
//! `pdf`; the f32 visible-normal sampler against an f64 one; the three-lane f32 conductor
//! Fresnel against the exact complex equations in f64.
//! Each states its bound, and the naive variant each one avoids is shown to exceed it.

use glam::{DVec3, Vec3};

use super::microfacet::{sin_cos_turns, Ggx};
use super::tests::{dir, rng_u3};
use super::*;
use crate::sampling::Rng;

const MODE: TransportMode = TransportMode::Radiance;

fn materials() -> Vec<Material> {
    let mut out = vec![Material::Diffuse { reflectance: Rgb::new(0.9, 0.5, 0.1) }];
    for &alpha in &[1e-4f32, 1e-3, 0.05, 0.3, 1.0] {
        out.push(Material::RoughConductor { alpha, eta: Rgb::new(0.18, 0.42, 1.37), k: Rgb::new(3.42, 2.35, 1.77) });
        let p = Plastic::new(Rgb::new(0.8, 0.5, 0.2), Rgb::ONE, 1.5, false);
        out.push(Material::RoughPlastic { alpha, plastic: p });
        out.push(Material::RoughPlastic { alpha, plastic: p.with_roughness(alpha) });
        out.push(Material::RoughDielectric { alpha, ior: 1.5 });
    }
    out
}

/// `eval_pdf` is exactly `(eval, pdf)`, and a smooth sample's `f` and `pdf` are exactly `eval` and
/// `pdf` at its direction (MIS weighs a BSDF-sampled hit with the sample's pdf and a light sample
/// with `eval_pdf`'s: they must be one function). Bit-equal, since both run the same arithmetic.
#[test]
fn eval_pdf_is_eval_and_pdf() {
    let mut rng = Rng::new(101, 0);
    for m in materials() {
        for &theta in &[0.0f32, 30.0, 75.0, 89.9] {
            let wo = dir(theta, 0.7);
            for _ in 0..2_000 {
                let other = crate::sampling::sample_uniform_sphere([rng.uniform(), rng.uniform()]);
                let (f, pdf) = m.eval_pdf(wo, other, MODE);
                assert_eq!(f, m.eval(wo, other, MODE), "{m:?} {wo:?} {other:?}");
                assert_eq!(pdf, m.pdf(wo, other, MODE), "{m:?} {wo:?} {other:?}");
                let Some(s) = m.sample(wo, rng_u3(&mut rng), MODE) else { continue };
                assert_eq!(s.f, m.eval(wo, s.wi, MODE), "{m:?} {wo:?} {s:?}");
                assert_eq!(s.pdf, m.pdf(wo, s.wi, MODE), "{m:?} {wo:?} {s:?}");
            }
        }
    }
}

/// The visible-normal sampler as it was, in f64 throughout (Heitz 2018's listing; r = √u0 and
/// the lift's 1 − p1² − q2² formed in f64): the reference for the f32 one.
fn sample_visible_f64(alpha: f32, wo: Vec3, u: [f32; 2]) -> DVec3 {
    let a = f64::from(alpha);
    let w = wo.as_dvec3();
    let vh = DVec3::new(a * w.x, a * w.y, w.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 { DVec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { DVec3::X };
    let t2 = vh.cross(t1);
    let r = f64::from(u[0]).sqrt();
    let phi = 2.0 * std::f64::consts::PI * f64::from(u[1]);
    let (p1, p2) = (r * phi.cos(), r * phi.sin());
    let s = 0.5 * (1.0 + vh.z);
    let q2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
    let nh = p1 * t1 + q2 * t2 + (1.0 - p1 * p1 - q2 * q2).max(0.0).sqrt() * vh;
    DVec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
}

/// The f32 sampler with the lift formed directly, z = √(1 − p1² − q2²) in f32 (and φ = 2πu1
/// rounded at 2π's scale): the wrong variant `sample_visible` avoids.
fn sample_visible_naive_f32(alpha: f32, wo: Vec3, u: [f32; 2]) -> Vec3 {
    let a = alpha;
    let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { Vec3::X };
    let t2 = vh.cross(t1);
    let r = u[0].sqrt();
    let (sin, cos) = (2.0 * std::f32::consts::PI * u[1]).sin_cos();
    let (p1, p2) = (r * cos, r * sin);
    let s = 0.5 * (1.0 + vh.z);
    let q2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
    let nh = p1 * t1 + q2 * t2 + (1.0 - p1 * p1 - q2 * q2).max(0.0).sqrt() * vh;
    Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
}

/// Uniforms: uniform, or (`tail`) with u0 within 1e-6 of 1, the polar map's rim, where a
/// near-mirror lobe's far tails are.
fn uniforms(rng: &mut Rng, tail: bool) -> [f32; 2] {
    let u0 = if tail { 1.0 - 1e-6 * rng.uniform() } else { rng.uniform() };
    [u0.min(crate::sampling::ONE_MINUS_EPSILON), rng.uniform()]
}

/// Worst distance between `sampler`'s microfacet normal and the f64 reference's, over widths
/// 1e-4…1 and incidence up to 89.99°.
fn worst_vndf_error(sampler: impl Fn(f32, Vec3, [f32; 2]) -> Vec3, tail: bool) -> f64 {
    let mut rng = Rng::new(107, 0);
    let mut worst = 0.0f64;
    for &alpha in &[1e-4f32, 1e-3, 0.05, 0.3, 1.0] {
        for &theta in &[0.0f32, 1e-3, 45.0, 80.0, 89.9, 89.99] {
            let wo = dir(theta, 0.7);
            for _ in 0..20_000 {
                let u = uniforms(&mut rng, tail);
                let h = sampler(alpha, wo, u).as_dvec3();
                worst = worst.max((h - sample_visible_f64(alpha, wo, u)).length());
            }
        }
    }
    worst
}

/// The f32 sampler draws the f64 reference's microfacet normal to within 2e-6 for uniform u
/// (measured worst 1e-6, at α = 0.05 and 89.99°; an f32 unit vector itself carries 6e-8), and to
/// within 1e-4 in the rim's tails (measured 6e-5 at α = 1e-3, 89.99°: there the f32 disk point's
/// rounding is amplified ~1/α, in a region sampled with probability ~1e-6). The naive f32 lift
/// is off by tenths in the tails.
#[test]
fn f32_visible_normals_match_the_f64_warp() {
    let careful = |alpha: f32, wo: Vec3, u: [f32; 2]| Ggx::new(alpha).sample_visible(wo, u);
    let (worst, worst_tail) = (worst_vndf_error(careful, false), worst_vndf_error(careful, true));
    let (naive, naive_tail) =
        (worst_vndf_error(sample_visible_naive_f32, false), worst_vndf_error(sample_visible_naive_f32, true));
    eprintln!("visible normals, worst |h − h_f64| (uniform u, rim tails): careful f32 {worst:e}, {worst_tail:e}; naive f32 {naive:e}, {naive_tail:e}");
    assert!(worst < 2e-6, "careful f32 sampler off by {worst:e}");
    assert!(worst_tail < 1e-4, "careful f32 sampler off by {worst_tail:e} in the tails");
    assert!(naive_tail > 1e-2, "the naive variant should fail the bound, {naive_tail:e}");
}

/// The quadrant-reduced azimuth against f64, over the whole of [0, 1).
#[test]
fn sin_cos_turns_is_accurate() {
    let mut worst = 0.0f64;
    for i in 0..100_000u32 {
        let t = i as f32 / 100_000.0;
        let (s, c) = sin_cos_turns(t);
        let phi = 2.0 * std::f64::consts::PI * f64::from(t);
        worst = worst.max((f64::from(s) - phi.sin()).abs().max((f64::from(c) - phi.cos()).abs()));
    }
    assert!(worst < 1.2e-7, "worst {worst:e}");
}

/// The exact conductor equations with complex arithmetic in f64 (the implementation the f32 one
/// replaced): the reference.
fn fresnel_conductor_f64(cos_i: f64, eta: f64, k: f64) -> f64 {
    type C = (f64, f64);
    let mul = |a: C, b: C| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let div = |a: C, b: C| {
        let d = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
    };
    let sqrt = |a: C| {
        let m = (a.0 * a.0 + a.1 * a.1).sqrt();
        ((0.5 * (m + a.0)).max(0.0).sqrt(), (0.5 * (m - a.0)).max(0.0).sqrt().copysign(a.1))
    };
    let n = (eta, k);
    let c = cos_i;
    let sin2_t = div(((1.0 - c * c).max(0.0), 0.0), mul(n, n));
    let cos_t = sqrt((1.0 - sin2_t.0, -sin2_t.1));
    let n_cos_t = mul(n, cos_t);
    let rs = div((c - n_cos_t.0, -n_cos_t.1), (c + n_cos_t.0, n_cos_t.1));
    let rp = div((n.0 * c - cos_t.0, n.1 * c - cos_t.1), (n.0 * c + cos_t.0, n.1 * c + cos_t.1));
    0.5 * (rs.0 * rs.0 + rs.1 * rs.1 + rp.0 * rp.0 + rp.1 * rp.1)
}

/// The real-form equations with a² = (|a+ib|² + t0)/2 formed directly (t0 formed as in
/// `fresnel_conductor`): the wrong variant.
fn fresnel_conductor_naive_f32(cos_i: f32, eta: f32, k: f32) -> f32 {
    let (c2, s2) = (cos_i * cos_i, 1.0 - cos_i * cos_i);
    let t0 = (eta * eta - k * k - 1.0) + c2;
    let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).sqrt();
    let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
    let (t1, t2) = (a2b2 + c2, 2.0 * cos_i * a);
    let rs = (t1 - t2) / (t1 + t2);
    let (t3, t4) = (c2 * a2b2 + s2 * s2, t2 * s2);
    0.5 * (rs + rs * (t3 - t4) / (t3 + t4))
}

/// Worst relative error of 1 − R (the absorbed fraction, where a metal's reflectance lives)
/// against the f64 reference, over metals from silver-like (η 0.05, k 4) to dielectric-like
/// (k = 0) and incidence from normal to grazing.
fn worst_fresnel_error(f: impl Fn(f32, f32, f32) -> f32) -> f64 {
    let mut worst = 0.0f64;
    for &eta in &[0.05f32, 0.18, 0.42, 1.0, 1.5, 3.0] {
        for &k in &[0.0f32, 0.5, 1.77, 3.42, 4.0, 8.0] {
            for i in 0..=200 {
                let c = (i as f32 / 200.0).powi(3);
                let reference = fresnel_conductor_f64(f64::from(c), f64::from(eta), f64::from(k));
                if !reference.is_finite() {
                    continue;
                }
                let got = f64::from(f(c, eta, k));
                let err = (got - reference).abs() / (1.0 - reference).max(1e-3);
                worst = worst.max(err);
            }
        }
    }
    worst
}

/// The three-lane f32 conductor Fresnel keeps 1 − R to 4e-4 relative, floored at 1e-3 absolute
/// (there: 4e-7, a few ulps of R ≈ 1), of the f64 complex equations: measured 1.9e-4. The naive
/// real form (a² formed by cancellation for metals, k > η) measured 6.3e-4.
#[test]
fn conductor_fresnel_f32_matches_f64() {
    let lanes = worst_fresnel_error(|c, eta, k| fresnel_conductor(c, Rgb::splat(eta), Rgb::splat(k)).x);
    let naive = worst_fresnel_error(fresnel_conductor_naive_f32);
    eprintln!("conductor Fresnel, worst relative error of 1 − R: lanes {lanes:e}, naive {naive:e}");
    assert!(lanes < 4e-4, "three-lane f32 Fresnel off by {lanes:e}");
    assert!(naive > 4e-4, "the naive variant should fail the bound, {naive:e}");
}
