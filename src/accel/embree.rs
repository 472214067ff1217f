//! PLACEHOLDER until the FFI work lands.
use super::{Accel, AccelError, AccelKind};
use crate::geometry::{Hit, Ray, TriangleMesh};
use std::sync::Arc;
pub struct EmbreeAccel;
impl EmbreeAccel {
    pub fn build(meshes: &[Arc<TriangleMesh>]) -> Result<Self, AccelError> {
        let _ = meshes;
        todo!()
    }
}
impl Accel for EmbreeAccel {
    fn intersect(&self, _ray: &Ray) -> Option<Hit> {
        todo!()
    }
    fn occluded(&self, _ray: &Ray) -> bool {
        todo!()
    }
    fn kind(&self) -> AccelKind {
        AccelKind::Embree
    }
    fn memory_bytes(&self) -> usize {
        0
    }
}
