//! TEMPORARY: the light constructors (`AreaLight::new`, `ConstantEnvironment::new`,
//! `ImageEnvironment::new`, `LightSampler::new`, in src/light/) and `film::exr_io::read_exr` are
//! being written by their owners. Until they land, the scene builds those values from their
//! public fields here; each function becomes a one-line call to the owner's constructor and this
//! file goes away.

use std::path::Path;
use std::sync::Arc;

use glam::Mat3;

use crate::film::Image;
use crate::geometry::{Aabb, TriangleMesh};
use crate::light::{AreaLight, ConstantEnvironment, ImageEnvironment, Light, LightSampler};
use crate::sampling::{Distribution1D, Distribution2D};
use crate::spectrum::{luminance, Rgb};

pub fn area_light(mesh: Arc<TriangleMesh>, geom_id: u32, radiance: Rgb, two_sided: bool) -> AreaLight {
    let areas: Vec<f32> = (0..mesh.triangle_count() as u32).map(|i| mesh.triangle_area(i)).collect();
    let area = areas.iter().map(|&a| a as f64).sum::<f64>() as f32;
    AreaLight { triangles: Distribution1D::new(&areas), area, mesh, geom_id, radiance, two_sided }
}

pub fn constant_environment(radiance: Rgb, bounds: Aabb) -> ConstantEnvironment {
    let (scene_center, scene_radius) = bounds.bounding_sphere();
    ConstantEnvironment { radiance, scene_center, scene_radius }
}

pub fn image_environment(
    width: usize,
    height: usize,
    texels: Vec<Rgb>,
    scale: f32,
    to_local: Mat3,
    bounds: Aabb,
) -> ImageEnvironment {
    // Luminance times sin θ of each row's centre: the lat-long map's solid-angle Jacobian.
    let weights: Vec<f32> = texels
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let theta = std::f32::consts::PI * ((i / width) as f32 + 0.5) / height as f32;
            luminance(*t) * theta.sin()
        })
        .collect();
    let distribution = Distribution2D::new(&weights, width, height);
    let (scene_center, scene_radius) = bounds.bounding_sphere();
    ImageEnvironment { width, height, texels, scale, to_local, distribution, scene_center, scene_radius }
}

pub fn light_sampler(lights: &[Light]) -> LightSampler {
    let powers: Vec<f32> = lights.iter().map(Light::power).collect();
    LightSampler { distribution: Distribution1D::new(&powers) }
}

pub fn read_exr(path: &Path) -> Result<Image, String> {
    use exr::prelude::read_first_rgba_layer_from_file;
    let img = read_first_rgba_layer_from_file(
        path,
        |size, _| Image::new(size.width(), size.height()),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width;
            img.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
        },
    )
    .map_err(|e| e.to_string())?;
    Ok(img.layer_data.channel_data.pixels)
}
