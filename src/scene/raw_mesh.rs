//! The plain arrays every mesh reader fills (OBJ, PLY, Mitsuba's serialized format, the inline
//! shapes), before the transform and validation. Its own module so that the readers, which the
//! format dispatch (`mesh_io`) calls, need not name the dispatch back.

use glam::{Vec2, Vec3};

/// A mesh as read or generated, before the transform and validation.
#[derive(Clone, Debug, Default)]
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
}
