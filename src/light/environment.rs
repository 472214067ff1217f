//! Environments at infinity: constant and image (equirectangular), with direction sampling,
//! emission sampling (a direction, then a point on a disk perpendicular to it that covers the
//! scene), their pdfs and their inverses.
//!
//! # The equirectangular convention (its one home)
//! A world direction `w` (pointing from the scene towards the environment) is first rotated into
//! the map's frame, `d = to_local · w`. Then, with +y up:
//! - θ = angle between d and +y ∈ [0, π], φ = atan2(d.z, d.x) wrapped into [0, 2π);
//! - the image coordinates are (x, y) = (φ/2π, θ/π) ∈ [0, 1)², so column ⌊x·width⌋, row
//!   ⌊y·height⌋, row 0 at the top (+y, θ = 0);
//! - conversely d = (sin θ cos φ, cos θ, sin θ sin φ).
//!
//! Radiance is piecewise constant per texel (no filtering), exactly the function the 2D
//! distribution importance-samples, so the pdf ∝ luminance is exact inside each texel.
//!
//! # Dimension layout
//! `sample_li`: `u[0]` unused (an inverse resamples it uniformly: unit Jacobian, RJMLT Sec. 6.1),
//! `u[1..3]` the direction. `sample_emission`: `u[0]` unused, `u[1..3]` the direction towards the
//! environment, `u[3..5]` the point on the disk (concentric mapping).

// `!(x > 0.0)` is deliberate throughout: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::f32::consts::PI;

use glam::{Mat3, Vec2, Vec3};

use super::{ConstantEnvironment, EmissionInverse, EmissionSample, ImageEnvironment, LiInverse, LightLiSample};
use crate::geometry::{Aabb, Frame};
use crate::sampling::{
    clamp_unit, invert_uniform_disk_concentric, invert_uniform_sphere, pdf_uniform_sphere,
    sample_uniform_disk_concentric, sample_uniform_sphere, Distribution2D,
};
use crate::spectrum::{luminance, Rgb};

/// Map coordinates (x, y) ∈ [0, 1]² of the map-local unit direction `d` (see the module doc).
pub fn direction_to_equirect(d: Vec3) -> Vec2 {
    // atan2 of (sin θ, cos θ) keeps full precision at the poles, unlike acos.
    let theta = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y);
    let mut phi = d.z.atan2(d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    Vec2::new((phi / (2.0 * PI)).clamp(0.0, 1.0), (theta / PI).clamp(0.0, 1.0))
}

/// The map-local unit direction at map coordinates `p` (see the module doc).
pub fn equirect_to_direction(p: Vec2) -> Vec3 {
    let (sin_t, cos_t) = (PI * p.y).sin_cos();
    let (sin_p, cos_p) = (2.0 * PI * p.x).sin_cos();
    Vec3::new(sin_t * cos_p, cos_t, sin_t * sin_p)
}

/// The far point used as a light "position" for a shadow ray towards an environment: beyond the
/// scene's bounding sphere along `wi` from `reference`.
fn far_point(reference: Vec3, wi: Vec3, center: Vec3, radius: f32) -> Vec3 {
    reference + wi * (2.0 * (radius + (reference - center).length()))
}

/// A ray entering the scene from the environment direction `w_env` (pointing away from the scene):
/// its origin is a uniform point on the disk of radius `radius` centred at `center + radius·w_env`
/// and perpendicular to it; its direction is −w_env. Area density of the origin: 1/(π·radius²).
fn disk_point(w_env: Vec3, center: Vec3, radius: f32, u: [f32; 2]) -> Vec3 {
    let frame = Frame::from_normal(w_env);
    let d = sample_uniform_disk_concentric(u);
    center + radius * (w_env + frame.s * d.x + frame.t * d.y)
}

/// Inverse of `disk_point` for any point `p` on the ray (it is projected along w_env onto the
/// disk), e.g. the first surface point the emitted ray reaches. `None` outside the disk.
fn invert_disk_point(w_env: Vec3, center: Vec3, radius: f32, p: Vec3) -> Option<[f32; 2]> {
    let frame = Frame::from_normal(w_env);
    let q = p - center;
    invert_uniform_disk_concentric(Vec2::new(q.dot(frame.s), q.dot(frame.t)) / radius)
}

fn disk_pdf(radius: f32) -> f32 {
    1.0 / (PI * radius * radius)
}

/// What an environment at infinity is to the light transport, written once for the constant and
/// the image environment: each gives its direction sampler (towards the environment) with its
/// solid-angle density and inverse, its radiance and the scene's bounding sphere; next-event
/// sampling (`sample_li`, a far point along the direction), emission (a direction, then a point
/// on the disk that covers the scene) and their pdfs and inverses follow from those.
pub trait Environment {
    /// A direction towards the environment from `u`, with its solid-angle density.
    fn sample_direction(&self, u: [f32; 2]) -> Option<(Vec3, f32)>;
    /// Solid-angle density of `sample_direction` at world direction `w`.
    fn pdf_direction(&self, w: Vec3) -> f32;
    /// Inverse of `sample_direction`.
    fn invert_direction(&self, w: Vec3) -> Option<[f32; 2]>;
    /// Radiance seen looking along the world direction `w`.
    fn radiance_along(&self, w: Vec3) -> Rgb;
    /// The scene's bounding sphere (centre, radius): where far points and emission disks go.
    fn scene_sphere(&self) -> (Vec3, f32);

    fn sample_li(&self, reference: Vec3, u: [f32; 3]) -> Option<LightLiSample> {
        let (wi, pdf) = self.sample_direction([u[1], u[2]])?;
        let (center, radius) = self.scene_sphere();
        Some(LightLiSample {
            wi,
            p: far_point(reference, wi, center, radius),
            p_error: Vec3::ZERO,
            n: Vec3::ZERO,
            radiance: self.radiance_along(wi),
            pdf,
            infinite: true,
        })
    }
    /// Inverse of `sample_li` for the direction `wi`; `gamma` fills the unused `u[0]`. The
    /// direction warp's Jacobian is its density `pdf_direction`.
    fn invert_li(&self, wi: Vec3, gamma: f32) -> Option<LiInverse> {
        let [a, b] = self.invert_direction(wi)?;
        Some(LiInverse { u: [clamp_unit(gamma), a, b], jacobian: self.pdf_direction(wi) })
    }
    fn sample_emission(&self, u: [f32; 5]) -> Option<EmissionSample> {
        let (w_env, pdf_dir) = self.sample_direction([u[1], u[2]])?;
        let (center, radius) = self.scene_sphere();
        Some(EmissionSample {
            p: disk_point(w_env, center, radius, [u[3], u[4]]),
            n: -w_env,
            dir: -w_env,
            radiance: self.radiance_along(w_env),
            pdf_pos: disk_pdf(radius),
            pdf_dir,
            infinite: true,
        })
    }
    /// `(pdf_pos, pdf_dir)` for the emitted ray along `dir` (any origin on the disk).
    fn pdf_emission(&self, dir: Vec3) -> (f32, f32) {
        (disk_pdf(self.scene_sphere().1), self.pdf_direction(-dir))
    }
    /// Inverse of `sample_emission` for the ray along `dir` through `p` (any point on it).
    fn invert_emission(&self, p: Vec3, dir: Vec3, gamma: f32) -> Option<EmissionInverse> {
        let (center, radius) = self.scene_sphere();
        let [a, b] = self.invert_direction(-dir)?;
        let [c, d] = invert_disk_point(-dir, center, radius, p)?;
        Some(EmissionInverse {
            u: [clamp_unit(gamma), a, b, c, d],
            jacobian_pos: disk_pdf(radius),
            jacobian_dir: self.pdf_direction(-dir),
        })
    }
}

impl ConstantEnvironment {
    /// A constant environment around a scene bounded by `scene_bounds`.
    pub fn new(radiance: Rgb, scene_bounds: Aabb) -> ConstantEnvironment {
        let (scene_center, scene_radius) = scene_bounds.bounding_sphere();
        ConstantEnvironment { radiance, scene_center, scene_radius: scene_radius.max(1e-3) }
    }

    /// Luminance flux into the scene: L·4π·πR² (pbrt-v4's `UniformInfiniteLight::Phi`).
    pub fn power(&self) -> f32 {
        luminance(self.radiance).max(0.0) * 4.0 * PI * PI * self.scene_radius * self.scene_radius
    }
}

impl Environment for ConstantEnvironment {
    /// Uniform direction on the sphere from `u[0..2]` with its solid-angle density.
    fn sample_direction(&self, u: [f32; 2]) -> Option<(Vec3, f32)> {
        Some((sample_uniform_sphere(u), pdf_uniform_sphere()))
    }
    fn pdf_direction(&self, _w: Vec3) -> f32 {
        pdf_uniform_sphere()
    }
    fn invert_direction(&self, w: Vec3) -> Option<[f32; 2]> {
        invert_uniform_sphere(w)
    }
    fn radiance_along(&self, _w: Vec3) -> Rgb {
        self.radiance
    }
    fn scene_sphere(&self) -> (Vec3, f32) {
        (self.scene_center, self.scene_radius)
    }
}

impl ImageEnvironment {
    /// An equirectangular environment of `width`×`height` row-major texels (row 0 at +y), scaled by
    /// `scale`, with `to_local` the world-to-map rotation. Texels are importance-sampled in
    /// proportion to luminance × sin θ (the map's area distortion, evaluated at the row centre).
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        scale: f32,
        to_local: Mat3,
        scene_bounds: Aabb,
    ) -> ImageEnvironment {
        let mut weights = vec![0.0f32; width * height];
        for v in 0..height {
            let sin_theta = (PI * (v as f32 + 0.5) / height as f32).sin();
            for u in 0..width {
                let t = texels.get(v * width + u).copied().unwrap_or(Rgb::ZERO);
                weights[v * width + u] = luminance(t).max(0.0) * sin_theta;
            }
        }
        let distribution = Distribution2D::new(&weights, width, height);
        let (scene_center, scene_radius) = scene_bounds.bounding_sphere();
        ImageEnvironment {
            width,
            height,
            texels,
            scale,
            to_local,
            distribution,
            scene_center,
            scene_radius: scene_radius.max(1e-3),
        }
    }

    /// Radiance seen looking along the world direction `w`: the texel's value × scale.
    pub fn radiance(&self, w: Vec3) -> Rgb {
        if self.width == 0 || self.height == 0 || !w.is_finite() {
            return Rgb::ZERO;
        }
        let p = direction_to_equirect(self.to_local * w);
        let col = ((p.x * self.width as f32) as usize).min(self.width - 1);
        let row = ((p.y * self.height as f32) as usize).min(self.height - 1);
        self.texels.get(row * self.width + col).copied().unwrap_or(Rgb::ZERO) * self.scale
    }

    /// Luminance flux into the scene: πR² · ∫ L dω (the sum over texels of L·sin θ·Δθ·Δφ).
    pub fn power(&self) -> f32 {
        if self.width == 0 || self.height == 0 {
            return 0.0;
        }
        let d_area = (PI / self.height as f32) * (2.0 * PI / self.width as f32);
        let mut total = 0.0f64;
        for v in 0..self.height {
            let sin_theta = (PI * (v as f32 + 0.5) / self.height as f32).sin();
            for u in 0..self.width {
                let t = self.texels.get(v * self.width + u).copied().unwrap_or(Rgb::ZERO);
                total += (luminance(t).max(0.0) * sin_theta * d_area) as f64;
            }
        }
        total as f32 * self.scale * PI * self.scene_radius * self.scene_radius
    }
}

impl Environment for ImageEnvironment {
    /// Importance-sampled direction (world, towards the environment) from `u`, with its solid-angle
    /// density p(x, y)/(2π² sin θ). `None` at a pole (sin θ = 0) or for an all-black map.
    fn sample_direction(&self, u: [f32; 2]) -> Option<(Vec3, f32)> {
        let (p, pdf_xy) = self.distribution.sample_continuous(u);
        if !(pdf_xy > 0.0) {
            return None;
        }
        let sin_theta = (PI * p.y).sin();
        if !(sin_theta > 0.0) {
            return None;
        }
        let w = self.to_local.transpose() * equirect_to_direction(p);
        Some((w, pdf_xy / (2.0 * PI * PI * sin_theta)))
    }
    /// Solid-angle density of `sample_direction` at world direction `w`.
    fn pdf_direction(&self, w: Vec3) -> f32 {
        let d = self.to_local * w;
        let sin_theta = (d.x * d.x + d.z * d.z).sqrt();
        if !(sin_theta > 0.0) {
            return 0.0;
        }
        self.distribution.pdf_continuous(direction_to_equirect(d)) / (2.0 * PI * PI * sin_theta)
    }
    /// Inverse of `sample_direction`: the marginal and conditional CDFs at the map coordinates of
    /// `w` (exact, uniform inside the texel). `None` for a texel of zero density.
    fn invert_direction(&self, w: Vec3) -> Option<[f32; 2]> {
        if !w.is_finite() {
            return None;
        }
        self.distribution.invert_continuous(direction_to_equirect(self.to_local * w))
    }

    fn radiance_along(&self, w: Vec3) -> Rgb {
        self.radiance(w)
    }
    fn scene_sphere(&self) -> (Vec3, f32) {
        (self.scene_center, self.scene_radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::chi2::{self, Chi2Config, CHI2_TESTS_SAMPLING};
    use crate::sampling::Rng;

    fn bounds() -> Aabb {
        Aabb { min: Vec3::new(-1.0, 0.0, -2.0), max: Vec3::new(3.0, 2.0, 1.0) }
    }

    /// A 16×8 map with a bright spot, a black column (zero-density texels) and coloured texels.
    fn env(rotation: Mat3) -> ImageEnvironment {
        let (w, h) = (16, 8);
        let mut t = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let base = 0.2 + 0.1 * ((u * 3 + v * 5) % 7) as f32;
                let c = if u == 5 {
                    Rgb::ZERO
                } else if (u, v) == (11, 2) {
                    Rgb::new(40.0, 30.0, 10.0)
                } else {
                    Rgb::new(base, 0.5 * base, 2.0 * base)
                };
                t.push(c);
            }
        }
        ImageEnvironment::new(w, h, t, 1.5, rotation, bounds())
    }

    /// `pdf_direction` as a density over map coordinates (x, y): × dω/dxdy = 2π² sin θ, with sin θ
    /// taken from the same rotated f32 direction `pdf_direction` sees (near the poles an
    /// independently computed sin θ would differ by rounding in relative terms, which only makes
    /// the adaptive quadrature chase noise).
    fn map_density(e: &ImageEnvironment, p: [f64; 2]) -> f64 {
        let w = e.to_local.transpose() * equirect_to_direction(Vec2::new(p[0] as f32, p[1] as f32));
        let d = e.to_local * w;
        let sin_theta = ((d.x * d.x + d.z * d.z) as f64).sqrt();
        e.pdf_direction(w) as f64 * 2.0 * std::f64::consts::PI.powi(2) * sin_theta
    }

    fn rotation() -> Mat3 {
        Mat3::from_rotation_y(0.7) * Mat3::from_rotation_x(-0.4)
    }

    #[test]
    fn equirect_convention() {
        // +y is the top row, θ = 0; φ = 0 along +x, φ = π/2 along +z.
        assert!(direction_to_equirect(Vec3::Y).y.abs() < 1e-6);
        assert!((direction_to_equirect(-Vec3::Y).y - 1.0).abs() < 1e-6);
        let px = direction_to_equirect(Vec3::X);
        assert!(px.x.abs() < 1e-6 && (px.y - 0.5).abs() < 1e-6);
        let pz = direction_to_equirect(Vec3::Z);
        assert!((pz.x - 0.25).abs() < 1e-6);
        for p in [Vec2::new(0.1, 0.2), Vec2::new(0.6, 0.9), Vec2::new(0.99, 0.01)] {
            let q = direction_to_equirect(equirect_to_direction(p));
            assert!((p - q).length() < 1e-5);
        }
        // A texel's radiance is found where the convention says: column 11, row 2.
        let e = env(Mat3::IDENTITY);
        let w = equirect_to_direction(Vec2::new(11.5 / 16.0, 2.5 / 8.0));
        assert_eq!(e.radiance(w), Rgb::new(40.0, 30.0, 10.0) * 1.5);
    }

    #[test]
    fn image_direction_chi2_integral_round_trip() {
        let e = env(rotation());
        // Binned in the map's own coordinates (x, y) (the convention of the module doc), two bins per
        // texel, so the texels' edges fall on bin edges and the expected counts are exact; the
        // density there is pdf_direction · 2π² sin θ. The rotation is exercised too: samples are
        // world directions, mapped back through `to_local`. (Oblique texel edges in (cos θ, φ) bins
        // would make the quadrature of the expectations far more expensive than the test.)
        // Within ~1e-6 of the map's poles the azimuth of a rotated f32 direction is rounding noise, so
        // the pdf there is noisy and the adaptive quadrature would chase it: 6 bisections (1/64 of a
        // bin) bound the cost, and the mass of that band is ~1e-12, far below one count.
        let cfg = Chi2Config {
            res: [32, 16],
            samples: 100_000,
            test_count: CHI2_TESTS_SAMPLING,
            max_depth: 6,
            ..Default::default()
        };
        let r = chi2::chi2_square(
            &cfg,
            [0.0, 1.0],
            [0.0, 1.0],
            50,
            |rng: &mut Rng| {
                let (w, _) = e.sample_direction([rng.uniform(), rng.uniform()])?;
                let p = direction_to_equirect(e.to_local * w);
                Some([p.x as f64, p.y as f64])
            },
            |p| map_density(&e, p),
        );
        assert!(r.passed, "{}", r.message);
        // ∫ pdf dω over the sphere, integrated over the map's own coordinates (dω = 2π² sin θ dx dy)
        // with cells aligned to the texels, so the quadrature is exact up to rounding.
        let total = chi2::integrate_2d(|p| map_density(&e, p), [0.0, 1.0], [0.0, 1.0], 16, 8);
        assert!((total - 1.0).abs() < 1e-4, "{total}");
        let mut rng = Rng::new(6, 6);
        for _ in 0..20_000 {
            let u = [rng.uniform(), rng.uniform()];
            let (w, pdf) = e.sample_direction(u).unwrap();
            assert!((pdf - e.pdf_direction(w)).abs() <= 1e-3 * pdf, "{pdf} vs {}", e.pdf_direction(w));
            let v = e.invert_direction(w).unwrap();
            let d0 = (u[0] - v[0]).abs().min(1.0 - (u[0] - v[0]).abs());
            assert!(d0 < 1e-4 && (u[1] - v[1]).abs() < 1e-4, "{u:?} -> {w} -> {v:?}");
        }
        // The black column has no preimage.
        let black = rotation().transpose() * equirect_to_direction(Vec2::new(5.5 / 16.0, 0.5));
        assert_eq!(e.invert_direction(black), None);
        assert_eq!(e.pdf_direction(black), 0.0);
    }

    #[test]
    fn image_direction_jacobian() {
        let e = env(rotation());
        let mut rng = Rng::new(8, 1);
        let mut checked = 0;
        for _ in 0..2000 {
            let u = [rng.uniform() as f64, rng.uniform() as f64];
            let h = 1e-3;
            let Some((w, pdf)) = e.sample_direction([u[0] as f32, u[1] as f32]) else { continue };
            // Only where the four neighbours stay in the same texel (the map jumps between texels).
            let texel = |w: Vec3| {
                let p = direction_to_equirect(e.to_local * w);
                ((p.x * 16.0) as i32, (p.y * 8.0) as i32)
            };
            let same = [[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]].iter().all(|o| {
                e.sample_direction([(u[0] + o[0]) as f32, (u[1] + o[1]) as f32])
                    .is_some_and(|(q, _)| texel(q) == texel(w))
            });
            let inside = u.iter().all(|x| (2.0 * h..1.0 - 2.0 * h).contains(x));
            if !same || !inside || pdf < 1e-3 {
                continue;
            }
            let det = chi2::jacobian_det_surface(
                |x| {
                    let d = e.sample_direction([x[0] as f32, x[1] as f32]).unwrap().0;
                    [d.x as f64, d.y as f64, d.z as f64]
                },
                u,
                h,
            );
            let pm = direction_to_equirect(e.to_local * w);
            assert!((det * pdf as f64 - 1.0).abs() < 1e-2, "|J| {det}, 1/pdf {} at u {u:?} map {pm}", 1.0 / pdf);
            checked += 1;
        }
        assert!(checked > 500, "{checked}");
    }

    #[test]
    fn constant_environment_li_and_emission() {
        let c = ConstantEnvironment::new(Rgb::splat(0.5), bounds());
        let cfg = Chi2Config { test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let r = chi2::chi2_sphere(
            &cfg,
            51,
            |rng: &mut Rng| c.sample_li(Vec3::ZERO, [rng.uniform(), rng.uniform(), rng.uniform()]).map(|s| s.wi),
            |w| c.pdf_direction(w) as f64,
        );
        assert!(r.passed, "{}", r.message);
        let reference = Vec3::new(0.5, 0.5, 0.5);
        let s = c.sample_li(reference, [0.3, 0.2, 0.7]).unwrap();
        assert!(s.infinite && (s.p - reference).normalize().dot(s.wi) > 0.9999);
        assert!((s.p - c.scene_center).length() > c.scene_radius);
        let v = c.invert_li(s.wi, 0.9).unwrap().u;
        assert!((v[1] - 0.2).abs() < 1e-4 && (v[2] - 0.7).abs() < 1e-4 && (v[0] - 0.9).abs() < 1e-6);
    }

    /// Emission from an environment: origins uniform on the disk (chi-square in the disk's frame),
    /// densities consistent, and the inverse exact from the origin or from any point on the ray.
    #[test]
    fn environment_emission_disk_and_inverse() {
        let e = env(rotation());
        let c = ConstantEnvironment::new(Rgb::ONE, bounds());
        let r = c.scene_radius;
        // Fix the direction (u[1..3]) and test the origin distribution on the disk.
        let u12 = [0.37f32, 0.81f32];
        let w_env = c.sample_direction(u12).unwrap().0;
        let frame = Frame::from_normal(w_env);
        let cfg = Chi2Config { res: [24, 24], samples: 60_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let t = chi2::chi2_square(
            &cfg,
            [-1.0, 1.0],
            [-1.0, 1.0],
            52,
            |rng: &mut Rng| {
                let s = c.sample_emission([rng.uniform(), u12[0], u12[1], rng.uniform(), rng.uniform()])?;
                let q = (s.p - c.scene_center - w_env * r) / r;
                assert!(q.dot(w_env).abs() < 1e-4, "origin off the disk plane");
                Some([q.dot(frame.s) as f64, q.dot(frame.t) as f64])
            },
            |p| if p[0] * p[0] + p[1] * p[1] <= 1.0 { std::f64::consts::FRAC_1_PI } else { 0.0 },
        );
        assert!(t.passed, "{}", t.message);
        let mut rng = Rng::new(9, 9);
        for _ in 0..5000 {
            let u = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
            for light in [
                super::super::Light::ImageEnvironment(env(rotation())),
                super::super::Light::ConstantEnvironment(ConstantEnvironment::new(Rgb::ONE, bounds())),
            ] {
                let Some(s) = light.sample_emission(u) else { continue };
                let (pp, pd) = light.pdf_emission(s.p, s.n, s.dir);
                assert!((pp - s.pdf_pos).abs() <= 1e-5 * pp && (pd - s.pdf_dir).abs() <= 1e-3 * pd);
                // From a point further along the ray (where it would hit the scene).
                let along = s.p + s.dir * (0.7 * r);
                let v = light.invert_emission(0, along, s.dir, 0.25).unwrap().u;
                assert!((v[0] - 0.25).abs() < 1e-6);
                // The azimuth is periodic: compare on the torus.
                let torus = |a: f32, b: f32| (a - b).abs().min(1.0 - (a - b).abs());
                let (d1, d2) = (torus(u[1], v[1]), torus(u[2], v[2]));
                assert!(d1 < 1e-4 && d2 < 1e-4, "{u:?} -> {v:?}");
                assert!((u[3] - v[3]).abs() < 1e-3 && (u[4] - v[4]).abs() < 1e-3, "{u:?} -> {v:?}");
            }
        }
        let _ = e;
    }
}
