//! A path-space vertex: BDPT's vertex with its role in the path and how light interacts there.

use serde::{Deserialize, Serialize};

use crate::integrator::bdpt::{Vertex, VertexKind};
use crate::light::Light;
use crate::material::Material;
use crate::scene::Scene;

/// How light interacts at a vertex: what the mutations (and part 16's tree over path signatures)
/// read. Glossy means a non-delta BSDF that is not Lambertian (GGX conductor, rough plastic).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interaction {
    Camera,
    Diffuse,
    Glossy,
    Specular,
    /// The path's last vertex, on an emitter (an area light point or, at infinity, the environment).
    Emitter,
}

/// One vertex of a path: BDPT's vertex (position, error bound, geometric normal, shading frame,
/// material, emitter, and for a vertex at infinity its direction), with its role fixed by its place
/// in the path: `kind` is `Camera` for the first vertex, `Light` for the last and `Surface`
/// otherwise, so that BDPT's density functions (`Vertex::pdf_light`, `pdf_light_origin`) apply.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct PathVertex {
    pub vertex: Vertex,
    pub interaction: Interaction,
}

impl PathVertex {
    /// Whether a connection (an edge that no sampling traced) can end here: anything but a
    /// specular surface (the pinhole and emitter points can be connected to, as in BDPT).
    pub fn connectible(&self) -> bool {
        self.interaction != Interaction::Specular
    }
}

/// The interaction kind of a surface material.
pub fn material_interaction(material: &Material) -> Interaction {
    match material {
        Material::Diffuse { .. } => Interaction::Diffuse,
        Material::Mirror { .. } | Material::Dielectric { .. } => Interaction::Specular,
        Material::RoughConductor { .. } | Material::RoughPlastic { .. } | Material::RoughDielectric { .. } => {
            Interaction::Glossy
        }
    }
}

/// Gives `v` the role of vertex `index` of a path of `n` vertices (see [`PathVertex`]).
pub fn with_role(scene: &Scene, mut v: Vertex, index: usize, n: usize) -> PathVertex {
    // A point sampled on an area light (BDPT's light subpaths, a new emitter vertex) carries no
    // material; the mutations may scatter there, so it gets its shape's.
    if let (Some(li), false) = (v.light, v.infinite) {
        if let Some(Light::Area(area)) = scene.lights.get(li as usize) {
            if let Some(shape) = scene.shapes.get(area.geom_id as usize) {
                v.material = shape.material;
            }
        }
    }
    let interaction = if index == 0 {
        v.kind = VertexKind::Camera;
        Interaction::Camera
    } else if index + 1 == n {
        v.kind = VertexKind::Light;
        Interaction::Emitter
    } else {
        v.kind = VertexKind::Surface;
        if v.infinite {
            // Only an endpoint can be at infinity; `evaluate` gives such a path f = 0.
            Interaction::Emitter
        } else {
            material_interaction(&scene.materials[v.material as usize].template)
        }
    };
    PathVertex { vertex: v, interaction }
}
