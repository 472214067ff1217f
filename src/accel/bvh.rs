//! PLACEHOLDER until the FFI work lands.
use super::{Accel, AccelKind};
use crate::geometry::{Hit, Ray, TriangleMesh};
use std::sync::Arc;
pub struct Bvh;
impl Bvh {
    pub fn build(meshes: &[Arc<TriangleMesh>]) -> Self {
        let _ = meshes;
        todo!()
    }
}
impl Accel for Bvh {
    fn intersect(&self, _ray: &Ray) -> Option<Hit> {
        todo!()
    }
    fn occluded(&self, _ray: &Ray) -> bool {
        todo!()
    }
    fn kind(&self) -> AccelKind {
        AccelKind::Bvh
    }
    fn memory_bytes(&self) -> usize {
        0
    }
}
