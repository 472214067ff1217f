//! The pinhole camera: primary rays, and the importance function light tracing and BDPT need to
//! connect a vertex to the lens.

use glam::{Vec2, Vec3};

use crate::geometry::Ray;
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
    /// conversion factor distance² / |cos| at the reference, as pbrt's `SampleWi`).
    pub pdf: f32,
    /// Continuous raster position (x right, y down, in pixels).
    pub raster: Vec2,
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
        let _ = d;
        todo!("Camera::raster_of")
    }
    /// Importance W_e(d) of the ray leaving the pinhole in direction `d` (pbrt-v4 Sec. 16.1.1):
    /// 1 / (A_film · cos⁴θ) on the film, zero outside.
    pub fn importance(&self, d: Vec3) -> Rgb {
        let _ = d;
        todo!("Camera::importance")
    }
    /// Densities `(pdf_pos, pdf_dir)` of the camera generating a ray in direction `d`.
    pub fn pdf_we(&self, d: Vec3) -> (f32, f32) {
        let _ = d;
        todo!("Camera::pdf_we")
    }
    /// Connects the scene point `reference` to the pinhole (for light tracing, t = 1).
    pub fn sample_wi(&self, reference: Vec3) -> Option<CameraWiSample> {
        let _ = reference;
        todo!("Camera::sample_wi")
    }
}
