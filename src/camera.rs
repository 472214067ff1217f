//! The pinhole camera: primary rays, and the importance function light tracing and BDPT need to
//! connect a vertex to the lens.

// `!(x > 0.0)` is deliberate: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::{Vec2, Vec3};

use crate::geometry::Ray;
use crate::sampling::clamp_unit;
use crate::spectrum::Rgb;

/// Uniforms a camera ray consumes: a 2D position on the film (the pinhole needs none for the lens).
pub const CAMERA_SAMPLE_DIMS: usize = 2;

/// A pinhole camera looking from `position` towards `look_at`, with vertical field of view `fov_y`
/// (degrees) and a `width`×`height` film.
#[derive(Clone, Debug)]
pub struct Camera {
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit vector to the right on the film.
    pub right: Vec3,
    /// Unit vector up on the film.
    pub up: Vec3,
    pub fov_y_degrees: f32,
    pub width: u32,
    pub height: u32,
    /// tan(fov_y/2)
    pub tan_half_fov: f32,
    /// Area of the film plane at distance 1 from the pinhole.
    pub film_area: f32,
}

/// A point of camera importance seen from a scene point: where on the film it lands.
#[derive(Clone, Copy, Debug)]
pub struct CameraWiSample {
    /// Unit direction from the reference point towards the pinhole.
    pub wi: Vec3,
    pub distance: f32,
    /// Importance W_e for that direction.
    pub importance: Rgb,
    /// Solid-angle density at the reference point (the pinhole is a delta position: this is the
    /// conversion factor distance² / cos θ, θ the angle between the ray and the viewing axis at the
    /// pinhole, as pbrt-v4's `SampleWi` with a lens of area 1).
    pub pdf: f32,
    /// Continuous raster position (x right, y down, in pixels).
    pub raster: Vec2,
}

/// What `Camera::invert_ray` found: the film uniforms of a primary ray and |J| of the inverse map
/// (uniforms per unit solid angle at the pinhole; RJMLT Eq. 39's first step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayInverse {
    pub u: [f32; CAMERA_SAMPLE_DIMS],
    pub jacobian: f32,
}

// INTERFACE (construction here; sampling methods owned by the sampling work):
impl Camera {
    /// Builds a camera; `up` need not be orthogonal to the viewing direction.
    pub fn new(position: Vec3, look_at: Vec3, up: Vec3, fov_y_degrees: f32, width: u32, height: u32) -> Camera {
        let forward = (look_at - position).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        let tan_half_fov = (fov_y_degrees.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        let film_area = (2.0 * tan_half_fov * aspect) * (2.0 * tan_half_fov);
        Camera { position, forward, right, up, fov_y_degrees, width, height, tan_half_fov, film_area }
    }
    /// The ray through the continuous raster position `raster` (pixels; (0,0) is the top-left corner).
    pub fn ray_through(&self, raster: Vec2) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let x = (2.0 * raster.x / self.width as f32 - 1.0) * self.tan_half_fov * aspect;
        let y = (1.0 - 2.0 * raster.y / self.height as f32) * self.tan_half_fov;
        let d = (self.forward + self.right * x + self.up * y).normalize();
        Ray::new(self.position, d)
    }
    /// Raster position where direction `d` (from the pinhole outwards) lands, if on the film.
    pub fn raster_of(&self, d: Vec3) -> Option<Vec2> {
        let cos_theta = d.dot(self.forward);
        if !(cos_theta > 0.0) || !d.is_finite() {
            return None;
        }
        // The film plane at distance 1: the inverse of `ray_through`.
        let x = d.dot(self.right) / cos_theta;
        let y = d.dot(self.up) / cos_theta;
        let aspect = self.width as f32 / self.height as f32;
        let raster = Vec2::new(
            (x / (self.tan_half_fov * aspect) + 1.0) * 0.5 * self.width as f32,
            (1.0 - y / self.tan_half_fov) * 0.5 * self.height as f32,
        );
        let inside =
            raster.x >= 0.0 && raster.x < self.width as f32 && raster.y >= 0.0 && raster.y < self.height as f32;
        inside.then_some(raster)
    }
    /// Cosine between the unit direction of `d` and the viewing axis, if `d` lands on the film.
    fn cos_on_film(&self, d: Vec3) -> Option<f32> {
        self.raster_of(d)?;
        let cos_theta = d.normalize_or_zero().dot(self.forward);
        (cos_theta > 0.0).then_some(cos_theta)
    }
    /// Importance W_e(d) of the ray leaving the pinhole in direction `d` (pbrt-v4 Sec. 16.1.1):
    /// 1 / (A_film · cos⁴θ) on the film, zero outside.
    pub fn importance(&self, d: Vec3) -> Rgb {
        match self.cos_on_film(d) {
            Some(c) => Rgb::splat(1.0 / (self.film_area * (c * c) * (c * c))),
            None => Rgb::ZERO,
        }
    }
    /// Densities `(pdf_pos, pdf_dir)` of the camera generating a ray in direction `d`: the pinhole
    /// is a delta position (pdf_pos = 1, as pbrt-v4's `PDF_We` for a lens of area 1), and a point
    /// uniform on the film of area A at distance 1 has the solid-angle density 1/(A·cos³θ)
    /// (dA = dω / cos³θ). (0, 0) off the film.
    pub fn pdf_we(&self, d: Vec3) -> (f32, f32) {
        match self.cos_on_film(d) {
            Some(c) => (1.0, 1.0 / (self.film_area * c * c * c)),
            None => (0.0, 0.0),
        }
    }
    /// Connects the scene point `reference` to the pinhole (for light tracing, t = 1). `pdf` is
    /// pbrt-v4's `SampleWi` density for a pinhole: distance² / cos θ, with θ the angle between the
    /// viewing axis and the ray at the pinhole.
    pub fn sample_wi(&self, reference: Vec3) -> Option<CameraWiSample> {
        let to_camera = self.position - reference;
        let distance = to_camera.length();
        if !(distance > 0.0) || !distance.is_finite() {
            return None;
        }
        let wi = to_camera / distance;
        let raster = self.raster_of(-wi)?;
        let cos_theta = (-wi).dot(self.forward);
        if !(cos_theta > 0.0) {
            return None;
        }
        Some(CameraWiSample {
            wi,
            distance,
            importance: self.importance(-wi),
            pdf: distance * distance / cos_theta,
            raster,
        })
    }

    /// Continuous raster position from 2 uniforms over the whole film: (u0·width, u1·height). The
    /// pixel is ⌊raster⌋: a discrete choice by an interval of u per pixel (RJMLT Eq. 40), but since
    /// the position inside the pixel is the rest of the same uniform, the map is a bijection.
    pub fn sample_film(&self, u: [f32; CAMERA_SAMPLE_DIMS]) -> Vec2 {
        Vec2::new(u[0] * self.width as f32, u[1] * self.height as f32)
    }
    /// Density of `sample_film` per unit raster area (pixels²): 1/(width·height) on the film.
    pub fn pdf_film(&self, raster: Vec2) -> f32 {
        if raster.x >= 0.0 && raster.x <= self.width as f32 && raster.y >= 0.0 && raster.y <= self.height as f32 {
            1.0 / (self.width as f32 * self.height as f32)
        } else {
            0.0
        }
    }
    /// Inverse of `sample_film`: exact; `None` off the film.
    pub fn invert_film(&self, raster: Vec2) -> Option<[f32; CAMERA_SAMPLE_DIMS]> {
        let (w, h) = (self.width as f32, self.height as f32);
        if !(raster.x >= 0.0 && raster.x <= w && raster.y >= 0.0 && raster.y <= h) {
            return None;
        }
        Some([clamp_unit(raster.x / w), clamp_unit(raster.y / h)])
    }
    /// The ray through a uniform film position (`sample_film` then `ray_through`).
    pub fn sample_ray(&self, u: [f32; CAMERA_SAMPLE_DIMS]) -> Ray {
        self.ray_through(self.sample_film(u))
    }
    /// Inverse of `sample_ray` for a primary-ray direction `d` (from the pinhole outwards): the
    /// uniforms whose ray has direction `d`, with the Jacobian of the map from directions to them;
    /// `None` when `d` misses the film.
    pub fn invert_ray(&self, d: Vec3) -> Option<RayInverse> {
        let u = self.invert_film(self.raster_of(d)?)?;
        // |∂u/∂ω| as the chain of the inverse's own steps (it must equal `pdf_we(d).1`, which the
        // RJMLT Jacobian test checks through BDPT's densities): a direction at angle θ to the axis
        // meets the film plane at distance 1 where dA = dω / cos³θ; raster_of scales the plane by
        // (W / (2 tan·aspect)) × (H / (2 tan)) pixels per unit area, invert_film by 1/(W·H).
        let cos_theta = d.normalize_or_zero().dot(self.forward);
        let aspect = self.width as f32 / self.height as f32;
        let plane_to_unit_square = 1.0 / ((2.0 * self.tan_half_fov * aspect) * (2.0 * self.tan_half_fov));
        let jacobian = plane_to_unit_square / (cos_theta * cos_theta * cos_theta);
        (jacobian.is_finite() && jacobian > 0.0).then_some(RayInverse { u, jacobian })
    }
    /// Raster position inside pixel `pixel` from 2 uniforms (per-pixel sampling).
    pub fn sample_pixel(&self, pixel: glam::UVec2, u: [f32; CAMERA_SAMPLE_DIMS]) -> Vec2 {
        Vec2::new(pixel.x as f32 + u[0], pixel.y as f32 + u[1])
    }
    /// Inverse of `sample_pixel`: the pixel containing `raster` and the uniforms inside it. Exact
    /// (up to the rounding of raster − pixel); `None` off the film.
    pub fn invert_pixel(&self, raster: Vec2) -> Option<(glam::UVec2, [f32; CAMERA_SAMPLE_DIMS])> {
        if !(raster.x >= 0.0 && raster.x < self.width as f32 && raster.y >= 0.0 && raster.y < self.height as f32) {
            return None;
        }
        let pixel = glam::UVec2::new(
            (raster.x as u32).min(self.width.saturating_sub(1)),
            (raster.y as u32).min(self.height.saturating_sub(1)),
        );
        Some((pixel, [clamp_unit(raster.x - pixel.x as f32), clamp_unit(raster.y - pixel.y as f32)]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::chi2::{self, Chi2Config, CHI2_TESTS_SAMPLING};
    use crate::sampling::Rng;

    fn camera() -> Camera {
        Camera::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.5, 1.5, -2.0), Vec3::Y, 50.0, 64, 40)
    }

    #[test]
    fn raster_of_inverts_ray_through() {
        let c = camera();
        let mut rng = Rng::new(1, 1);
        for _ in 0..10_000 {
            let r = Vec2::new(rng.uniform() * 64.0, rng.uniform() * 40.0);
            let d = c.ray_through(r).d;
            let back = c.raster_of(d).expect("film point refused");
            assert!((back - r).length() < 1e-3, "{r} -> {back}");
        }
        assert!(c.raster_of(-c.forward).is_none());
        assert!(c.raster_of(c.forward + c.right * 10.0).is_none());
    }

    #[test]
    fn film_round_trips() {
        let c = camera();
        let mut rng = Rng::new(2, 1);
        for _ in 0..10_000 {
            let u = [rng.uniform(), rng.uniform()];
            let v = c.invert_ray(c.sample_ray(u).d).unwrap().u;
            assert!((u[0] - v[0]).abs() < 1e-4 && (u[1] - v[1]).abs() < 1e-4, "{u:?} -> {v:?}");
            let raster = c.sample_film(u);
            let (px, w) = c.invert_pixel(raster).unwrap();
            assert_eq!(c.sample_pixel(px, w), raster);
        }
        assert!(c.invert_film(Vec2::new(-1.0, 3.0)).is_none());
        assert!(c.invert_pixel(Vec2::new(64.0, 3.0)).is_none());
    }

    /// Ray directions from uniform film positions are distributed as pdf_we's solid-angle density
    /// (chi-square in (cos θ, φ) about the viewing axis), whose integral over the film is 1, and the
    /// Jacobian of u → direction is 1/pdf_dir.
    #[test]
    fn direction_density_chi2_integral_jacobian() {
        let c = Camera::new(Vec3::ZERO, Vec3::Z, Vec3::Y, 60.0, 48, 32);
        // cos θ of the film's corners bounds the domain.
        let corner = c.ray_through(Vec2::ZERO).d.z as f64;
        let cfg = Chi2Config { res: [24, 48], samples: 100_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let to_param = |d: Vec3| chi2::direction_to_sphere_param(d.normalize());
        let r = chi2::chi2_test(
            &cfg,
            [corner - 1e-3, 1.0],
            [0.0, 2.0 * std::f64::consts::PI],
            60,
            |rng: &mut Rng| to_param(c.sample_ray([rng.uniform(), rng.uniform()]).d),
            |p| c.pdf_we(chi2::sphere_param_to_direction(p)).1 as f64,
        );
        assert!(r.passed, "{}", r.message);
        // The importance integrates to 1 over the film's solid angle against cos θ... and the
        // density to 1: integrate over the film plane (dω = cos³θ dA) with cells of the film.
        let t = c.tan_half_fov as f64;
        let aspect = 48.0 / 32.0;
        let total = chi2::integrate_2d(
            |p| {
                let d = Vec3::new(p[0] as f32, p[1] as f32, 1.0);
                let cos = 1.0 / (p[0] * p[0] + p[1] * p[1] + 1.0).sqrt();
                c.pdf_we(d).1 as f64 * cos * cos * cos
            },
            [-t * aspect, t * aspect],
            [-t, t],
            8,
            8,
        );
        assert!((total - 1.0).abs() < 1e-4, "{total}");
        let we = chi2::integrate_2d(
            |p| {
                let d = Vec3::new(p[0] as f32, p[1] as f32, 1.0);
                let cos = 1.0 / (p[0] * p[0] + p[1] * p[1] + 1.0).sqrt();
                // ∫ W_e cos θ dω over the film = 1 (pbrt-v4 Eq. 16.3's normalisation).
                c.importance(d).x as f64 * cos * cos.powi(3)
            },
            [-t * aspect, t * aspect],
            [-t, t],
            8,
            8,
        );
        assert!((we - 1.0).abs() < 1e-4, "{we}");
        let mut rng = Rng::new(3, 3);
        for _ in 0..500 {
            let u = [0.01 + 0.98 * rng.uniform() as f64, 0.01 + 0.98 * rng.uniform() as f64];
            let det = chi2::jacobian_det_surface(
                |x| {
                    let d = c.sample_ray([x[0] as f32, x[1] as f32]).d;
                    [d.x as f64, d.y as f64, d.z as f64]
                },
                u,
                1e-3,
            );
            let pdf = c.pdf_we(c.sample_ray([u[0] as f32, u[1] as f32]).d).1 as f64;
            assert!((det * pdf - 1.0).abs() < 1e-2, "|J| {det}, 1/pdf {}", 1.0 / pdf);
        }
    }

    #[test]
    fn sample_wi_matches_importance_and_raster() {
        let c = camera();
        let p = c.position + c.forward * 3.0 + c.right * 0.4 - c.up * 0.2;
        let s = c.sample_wi(p).unwrap();
        assert!((s.distance - (p - c.position).length()).abs() < 1e-5);
        let ray = c.ray_through(s.raster);
        assert!(ray.d.dot((p - c.position).normalize()) > 0.99999);
        let cos = (-s.wi).dot(c.forward);
        assert!((s.pdf - s.distance * s.distance / cos).abs() < 1e-4 * s.pdf);
        assert!((s.importance.x - 1.0 / (c.film_area * cos.powi(4))).abs() < 1e-4 * s.importance.x);
        assert!(c.sample_wi(c.position - c.forward).is_none());
        assert!(c.sample_wi(c.position).is_none());
    }
}
