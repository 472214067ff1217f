//! The path-space state: a path as its vertex list (camera first, emitter last), each vertex with
//! its interaction kind, and the path's raster position and contribution f(x̄), which
//! [`PathState::new`] evaluates from the vertices alone (`contribution::evaluate`).

use glam::{DVec3, Vec2};
use serde::{Deserialize, Serialize};

use super::contribution::evaluate;
use super::PathContext;
use crate::integrator::bdpt::{Vertex, VertexKind};
use crate::light::Light;
use crate::material::Material;
use crate::scene::Scene;
use crate::stats::Counters;

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

/// A path of the chain: vertices camera first, emitter last; where it lands on the film; its
/// contribution f(x̄) in the module's measure and the chain's scalar target f*(x̄) = luminance(f),
/// both in f64 (`contribution::evaluate` says why).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PathState {
    pub vertices: Vec<PathVertex>,
    pub raster: Vec2,
    pub f: DVec3,
    pub f_star: f64,
}

/// Luminance of an f64 colour (the weights of `spectrum::luminance`).
pub fn luminance64(c: DVec3) -> f64 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

impl PathState {
    /// The path through `vertices` (camera first), with roles assigned and f evaluated (one shadow
    /// ray per edge, counted in `counters`). A non-finite f is a zero path (counted as dropped).
    pub fn new(ctx: &PathContext, vertices: &[Vertex], counters: &mut Counters) -> PathState {
        let n = vertices.len();
        let vertices: Vec<PathVertex> =
            vertices.iter().enumerate().map(|(i, v)| with_role(ctx.scene, *v, i, n)).collect();
        PathState::from_path_vertices(ctx, vertices, counters)
    }

    /// As `new`, for vertices whose roles are already assigned.
    pub fn from_path_vertices(ctx: &PathContext, vertices: Vec<PathVertex>, counters: &mut Counters) -> PathState {
        let (f, raster) = evaluate(ctx, &vertices, counters);
        let f_star = luminance64(f);
        let finite = f_star.is_finite() && f.is_finite();
        if !finite {
            counters.nonfinite_dropped += 1;
        }
        if finite && f_star > 0.0 {
            PathState { vertices, raster, f, f_star }
        } else {
            PathState { vertices, raster, f: DVec3::ZERO, f_star: 0.0 }
        }
    }

    /// Scattering events (vertices − 2), the depth `max_depth` bounds.
    pub fn depth(&self) -> usize {
        self.vertices.len().saturating_sub(2)
    }

    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }
}
