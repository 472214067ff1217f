//! The shipped scenes and committed references the agreement tests render and compare against.

use std::path::Path;

use plexus::camera::Camera;
use plexus::film::exr_io::read_exr;
use plexus::film::Image;
use plexus::scene::{load_scene, Scene};

/// `scenes/<name>.toml` with its camera at `size`×`size` pixels (the same field of view: the
/// regions cover the same parts of the film at any size, so a reference's region means hold at
/// every size); `size` 0 keeps the scene's own resolution.
pub fn scene(name: &str, size: u32) -> Scene {
    scene_at(name, size, size)
}

/// [`scene`] at `width`×`height` pixels (the same vertical field of view; a reference must have
/// the same aspect ratio); 0×0 keeps the scene's own resolution.
pub fn scene_at(name: &str, width: u32, height: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(format!("{name}.toml"));
    let mut scene = load_scene(&path, None).unwrap_or_else(|e| panic!("{}: {e}", path.display())).scene;
    let c = &scene.camera;
    if width > 0 && height > 0 {
        scene.camera = Camera::new(c.position, c.position + c.forward, c.up, c.fov_y_degrees, width, height);
    }
    scene
}

/// The committed reference image `references/<name>.exr` (how each was made: the JSON beside it and
/// `scripts/make-references.sh`).
pub fn reference(name: &str) -> Image {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("references").join(format!("{name}.exr"));
    read_exr(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}
