//! Ray queries. Two accelerators answer them behind one trait: Embree (through the safe wrapper
//! in `embree`) and the in-house BVH (`bvh`). Nothing outside this module knows which one runs.

pub mod bvh;
pub mod embree;

use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::geometry::{Hit, Ray, TriangleMesh};

/// A built, read-only acceleration structure over a list of meshes. `Hit::geom_id` is the index
/// of the mesh in the list the structure was built from.
pub trait Accel: Send + Sync {
    /// Closest hit with `t` in `[ray.t_min, ray.t_max]`, if any.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;
    /// Closest hits of rays that start close together and point about the same way (a camera's
    /// rays through neighbouring pixels): `hits[i]` for `rays[i]`. An accelerator with packet
    /// queries traces them together; its packet kernel may round differently from its single-ray
    /// one, so on rare rays (a shared edge, a tie) the hit can be another triangle's or differ in
    /// the last bits (Embree: 6 of 9.1 million rays on the living room). `hits` must be as long as
    /// `rays`.
    fn intersect_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            *hit = self.intersect(ray);
        }
    }
    /// Whether anything is hit with `t` in `[ray.t_min, ray.t_max]`.
    fn occluded(&self, ray: &Ray) -> bool;
    /// Which implementation this is.
    fn kind(&self) -> AccelKind;
    /// Bytes held by the acceleration structure itself (not the shared meshes), if known.
    fn memory_bytes(&self) -> usize;
    /// The most bytes the structure held at once, its build's temporary arrays included (at least
    /// `memory_bytes`). Building is the peak of loading a large scene: Embree's build holds its
    /// primitive references beside the growing tree.
    fn peak_memory_bytes(&self) -> usize {
        self.memory_bytes()
    }
}

/// The accelerators a user can choose between.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AccelKind {
    #[default]
    Embree,
    Bvh,
}

impl fmt::Display for AccelKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            AccelKind::Embree => "embree",
            AccelKind::Bvh => "bvh",
        })
    }
}

impl FromStr for AccelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "embree" => Ok(AccelKind::Embree),
            "bvh" => Ok(AccelKind::Bvh),
            other => Err(format!("unknown accelerator '{other}': expected 'embree' or 'bvh'")),
        }
    }
}

/// Why an accelerator could not be built.
#[derive(Debug, Error)]
pub enum AccelError {
    #[error("Embree: {0}")]
    Embree(String),
    #[error("the scene has {0} meshes; at most 2^32-1 are supported")]
    TooManyMeshes(usize),
}

/// Builds the accelerator of the given kind over `meshes` (shared, not copied).
pub fn build(kind: AccelKind, meshes: &[Arc<TriangleMesh>]) -> Result<Box<dyn Accel>, AccelError> {
    if meshes.len() >= u32::MAX as usize {
        return Err(AccelError::TooManyMeshes(meshes.len()));
    }
    Ok(match kind {
        AccelKind::Embree => Box::new(embree::EmbreeAccel::build(meshes)?),
        AccelKind::Bvh => Box::new(bvh::Bvh::build(meshes)),
    })
}
