//! What `plexus bench` traces: the benchmark scene (a room, a terrain and a grid of displaced
//! spheres from `scene::procedural`), its camera rays and recorded diffuse random-walk rays, and
//! the same meshes as a renderable scene for the path-tracer measurement.

use std::path::Path;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::accel::{Accel, AccelKind};
use crate::camera::Camera;
use crate::geometry::{Frame, Ray, SurfaceInteraction, TriangleMesh};
use crate::sampling::{sample_cosine_hemisphere, Rng};
use crate::scene::procedural::{displaced_sphere, room, terrain};
use crate::scene::{load_scene_str_with_meshes, MeshShape, Scene, SceneError};

/// The benchmark scene: a closed room holding a finely tessellated terrain and a 5×5 grid of
/// displaced spheres, about `triangles` triangles in all (60% terrain, 40% spheres), and a camera
/// inside the room looking down at them. Deterministic for a given `seed`.
pub struct BenchScene {
    pub meshes: Vec<Arc<TriangleMesh>>,
    pub camera: Camera,
}

impl BenchScene {
    pub fn new(triangles: usize, width: u32, height: u32, seed: u64) -> BenchScene {
        let t = triangles.max(1000) as f32;
        let n_terrain = (0.6 * t / 2.0).sqrt().round() as u32;
        // A sphere has 2 n_phi (n_theta − 1) ≈ 4 n_theta² triangles with n_phi = 2 n_theta.
        let n_theta = ((0.4 * t / 25.0) / 4.0).sqrt().round().max(3.0) as u32;
        let mut meshes = vec![
            Arc::new(room(Vec3::new(-10.0, -1.0, -10.0), Vec3::new(10.0, 10.0, 10.0))),
            Arc::new(terrain(Vec2::splat(-10.0), Vec2::splat(10.0), 0.0, 0.8, n_terrain, seed)),
        ];
        for i in 0..5 {
            for j in 0..5 {
                let center = Vec3::new(-6.0 + 3.0 * j as f32, 2.5 + 0.3 * ((i + j) % 3) as f32, -6.0 + 3.0 * i as f32);
                let s = seed.wrapping_mul(31).wrapping_add((i * 5 + j) as u64 + 1);
                meshes.push(Arc::new(displaced_sphere(center, 1.1, n_theta, 2 * n_theta, 0.15, s)));
            }
        }
        let camera = Camera::new(
            Vec3::new(0.0, 7.0, 9.5),
            Vec3::new(0.0, 1.0, -1.0),
            Vec3::Y,
            60.0,
            width.max(1),
            height.max(1),
        );
        BenchScene { meshes, camera }
    }

    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.triangle_count()).sum()
    }

    /// One ray through the centre of every pixel, in scanline order.
    pub fn camera_rays(&self) -> Vec<Ray> {
        let (w, h) = (self.camera.width, self.camera.height);
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| self.camera.ray_through(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)))
            .collect()
    }

    /// The rays of a cosine-weighted diffuse random walk of up to `bounces` bounces from each
    /// camera ray's hit, traced with `accel`; stream `k` of `seed` drives pixel `k`'s walk.
    pub fn bounce_rays(&self, accel: &dyn Accel, camera_rays: &[Ray], bounces: u32, seed: u64) -> Vec<Ray> {
        camera_rays
            .par_iter()
            .enumerate()
            .flat_map_iter(|(k, ray)| {
                let mut rng = Rng::new(seed, k as u64);
                let mut rays = Vec::with_capacity(bounces as usize);
                let mut hit = accel.intersect(ray);
                let mut d = ray.d;
                for _ in 0..bounces {
                    let Some(h) = hit else { break };
                    let si = SurfaceInteraction::from_hit(&self.meshes[h.geom_id as usize], &h);
                    // Scatter on the side the ray came from (every surface here is two-sided).
                    let n = if si.ng.dot(d) > 0.0 { -si.ng } else { si.ng };
                    let local = sample_cosine_hemisphere([rng.uniform(), rng.uniform()]);
                    d = Frame::from_normal(n).to_world(local).normalize();
                    let next = si.spawn(d);
                    rays.push(next);
                    hit = accel.intersect(&next);
                }
                rays
            })
            .collect()
    }

    /// The benchmark scene as a renderable [`Scene`] on Embree, built by the scene loader like a
    /// scene file: the camera, a diffuse white material (reflectance 0.7) and a 6 × 6 quad light
    /// under the room's ceiling come from TOML, and the generated meshes join as in-memory shapes
    /// after the light.
    pub fn renderable(&self) -> Result<Scene, SceneError> {
        let c = &self.camera;
        let look_at = c.position + c.forward;
        let toml = format!(
            r#"
[camera]
position = [{}, {}, {}]
look_at = [{}, {}, {}]
up = [0.0, 1.0, 0.0]
fov = {}
resolution = [{}, {}]

[materials.white]
type = "diffuse"
reflectance = 0.7

[[shapes]]
type = "quad"
material = "white"
emission = {{ radiance = [20.0, 20.0, 20.0] }}
transform = {{ scale = [3.0, 3.0, 1.0], rotate = {{ axis = [1, 0, 0], angle = 90 }}, translate = [0.0, 9.9, 0.0] }}
"#,
            c.position.x,
            c.position.y,
            c.position.z,
            look_at.x,
            look_at.y,
            look_at.z,
            c.fov_y_degrees,
            c.width,
            c.height
        );
        let meshes = self
            .meshes
            .iter()
            .enumerate()
            .map(|(k, mesh)| MeshShape {
                name: format!("bench mesh {k}"),
                mesh: Arc::clone(mesh),
                material: "white".to_string(),
            })
            .collect();
        let loaded =
            load_scene_str_with_meshes(&toml, Path::new(""), "<bench scene>", Some(AccelKind::Embree), meshes)?;
        Ok(loaded.scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_scene_is_sized_as_asked() {
        let scene = BenchScene::new(100_000, 8, 6, 1);
        let n = scene.triangle_count();
        assert!((90_000..110_000).contains(&n), "{n}");
        assert_eq!(scene.camera_rays().len(), 48);
    }

    #[test]
    fn renderable_scene_has_the_light_then_every_generated_mesh() {
        let bench = BenchScene::new(2_000, 8, 6, 1);
        let scene = bench.renderable().expect("the benchmark scene builds");
        assert_eq!(scene.meshes.len(), 1 + bench.meshes.len());
        assert_eq!(scene.lights.len(), 1);
        assert_eq!(scene.shapes[0].light, Some(0));
        for (k, mesh) in bench.meshes.iter().enumerate() {
            assert!(Arc::ptr_eq(&scene.meshes[k + 1], mesh));
            assert_eq!((scene.shapes[k + 1].material, scene.shapes[k + 1].light), (0, None));
        }
        assert_eq!(scene.triangle_count(), 2 + bench.triangle_count());
    }
}
