use glam::{Vec2, Vec3};
use rayon::prelude::*;
use thiserror::Error;

use super::Aabb;
use crate::prefetch::prefetch;
use crate::process::huge_pages::{on_huge_pages, vec_for_random_reads};

/// Why a mesh was refused.
#[derive(Debug, Error, PartialEq)]
pub enum MeshError {
    #[error("vertex {index} has a non-finite coordinate ({value:?})")]
    NonFiniteVertex { index: usize, value: [f32; 3] },
    #[error("triangle {triangle} refers to vertex {vertex}, but the mesh has only {count} vertices")]
    IndexOutOfRange { triangle: usize, vertex: u32, count: usize },
    #[error("the mesh has {normals} normals for {vertices} vertices")]
    NormalCount { normals: usize, vertices: usize },
    #[error("the mesh has {uvs} texture coordinates for {vertices} vertices")]
    UvCount { uvs: usize, vertices: usize },
    #[error("the mesh has no triangles")]
    Empty,
    #[error("the mesh has {0} vertices; at most 2^32-1 are supported")]
    TooManyVertices(usize),
}

/// The cross product of a triangle's edges, in f64. Its components scale as the square of the
/// triangle's size and its squared length as the fourth power: in f32 the squared length
/// overflows for edges beyond about 4e9 and is flushed to zero (Embree's threads run with
/// flush-to-zero) below about 1e-10, which turns every normal of a scene modelled in
/// kilometres-as-millimetres into `Vec3::Z` and renders it at a sixth of its brightness. In f64
/// both powers stay in range for every f32 coordinate.
#[inline]
fn edge_cross(a: Vec3, b: Vec3, c: Vec3) -> glam::DVec3 {
    (b - a).as_dvec3().cross((c - a).as_dvec3())
}

/// Unit normal of the triangle `a b c` by its winding, at any scale; `Vec3::Z` for a degenerate
/// (or non-finite) one.
#[inline]
pub fn triangle_normal(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    edge_cross(a, b, c).try_normalize().map_or(Vec3::Z, |n| n.as_vec3())
}

/// Area of the triangle `a b c`, at any scale (infinite only when the area itself exceeds f32).
#[inline]
pub fn triangle_area(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    (0.5 * edge_cross(a, b, c).length()) as f32
}

/// Whether the triangle `a b c` has a non-zero area (at any scale: an f32 cross product of a
/// triangle 1e-20 across is flushed to zero).
#[inline]
pub fn triangle_is_degenerate(a: Vec3, b: Vec3, c: Vec3) -> bool {
    edge_cross(a, b, c) == glam::DVec3::ZERO
}

/// An indexed triangle mesh in world space, owned by Rust and shared (not copied) with Embree and
/// the in-house BVH. Positions and indices of 1–64 MiB live on huge pages (`on_huge_pages`): every
/// closest hit's shading reads its triangle's indices and then its vertices at random places, and
/// with 4 KiB pages these dependent misses also miss the TLB (`plexus bench`'s pt: 5% less time).
///
/// Embree reads vertex buffers with 16-byte loads, so the last vertex must be followed by at least
/// 4 readable bytes: the position array always carries one extra padding vertex after the real
/// ones. `positions()` hides it.
#[derive(Debug, Clone)]
pub struct TriangleMesh {
    padded_positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
}

impl TriangleMesh {
    /// Validates and takes ownership: every vertex finite, every index in range, attribute
    /// arrays (if any) one per vertex. Degenerate (zero-area) triangles are kept; they are never hit.
    pub fn new(
        positions: Vec<Vec3>,
        indices: Vec<[u32; 3]>,
        normals: Option<Vec<Vec3>>,
        uvs: Option<Vec<Vec2>>,
    ) -> Result<Self, MeshError> {
        if indices.is_empty() {
            return Err(MeshError::Empty);
        }
        if positions.len() >= u32::MAX as usize {
            return Err(MeshError::TooManyVertices(positions.len()));
        }
        for (i, p) in positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFiniteVertex { index: i, value: p.to_array() });
            }
        }
        for (t, tri) in indices.iter().enumerate() {
            for &v in tri {
                if v as usize >= positions.len() {
                    return Err(MeshError::IndexOutOfRange { triangle: t, vertex: v, count: positions.len() });
                }
            }
        }
        if let Some(n) = &normals {
            if n.len() != positions.len() {
                return Err(MeshError::NormalCount { normals: n.len(), vertices: positions.len() });
            }
        }
        if let Some(uv) = &uvs {
            if uv.len() != positions.len() {
                return Err(MeshError::UvCount { uvs: uv.len(), vertices: positions.len() });
            }
        }
        // Normals that are zero or non-finite would poison shading frames: drop them all rather
        // than shade some triangles smoothly and others not.
        let normals = normals.filter(|ns| ns.iter().all(|n| n.is_finite() && n.length_squared() > 0.0));
        let mut padded_positions = on_huge_pages(positions, 1);
        padded_positions.push(Vec3::ZERO);
        Ok(TriangleMesh { padded_positions, indices: on_huge_pages(indices, 0), normals, uvs })
    }

    /// Vertex positions, without the padding vertex.
    #[inline]
    pub fn positions(&self) -> &[Vec3] {
        &self.padded_positions[..self.padded_positions.len() - 1]
    }
    /// Positions including the trailing padding vertex (for Embree's shared buffers).
    pub fn padded_positions(&self) -> &[Vec3] {
        &self.padded_positions
    }
    #[inline]
    pub fn indices(&self) -> &[[u32; 3]] {
        &self.indices
    }
    pub fn normals(&self) -> Option<&[Vec3]> {
        self.normals.as_deref()
    }
    pub fn uvs(&self) -> Option<&[Vec2]> {
        self.uvs.as_deref()
    }
    pub fn vertex_count(&self) -> usize {
        self.padded_positions.len() - 1
    }
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
    /// Asks the CPU to start loading triangle `prim`'s index triple into the cache (a hint; no
    /// effect on results). A closest hit's shading reads the indices, then the vertices they
    /// name: two dependent cache misses on large meshes, which the caller can overlap with work
    /// that does not need the hit (`Scene::hit`).
    #[inline]
    pub fn prefetch_indices(&self, prim: u32) {
        if let Some(idx) = self.indices.get(prim as usize) {
            prefetch(idx);
        }
    }
    /// The same for the vertex data (positions, and normals and uvs where present) of triangle
    /// `prim`; reads its index triple, so call it once that has had time to arrive.
    #[inline]
    pub fn prefetch_vertices(&self, prim: u32) {
        let Some(idx) = self.indices.get(prim as usize) else { return };
        for &i in idx {
            if let Some(p) = self.padded_positions.get(i as usize) {
                prefetch(p);
            }
            if let Some(n) = self.normals.as_ref().and_then(|ns| ns.get(i as usize)) {
                prefetch(n);
            }
            if let Some(uv) = self.uvs.as_ref().and_then(|uvs| uvs.get(i as usize)) {
                prefetch(uv);
            }
        }
    }
    /// Whether the mesh has per-vertex normals or uvs (which a hit reads through its indices).
    #[inline]
    pub fn has_vertex_attributes(&self) -> bool {
        self.normals.is_some() || self.uvs.is_some()
    }
    /// Each triangle's three positions side by side, in its winding (36 bytes a triangle): what
    /// `Scene` keeps for shading (`Scene::keep_corners_if_room`). The same f32 values as
    /// [`Self::triangle`].
    pub fn corner_copies(&self) -> Vec<[Vec3; 3]> {
        let mut corners = vec_for_random_reads(self.indices.len());
        let p = &self.padded_positions;
        corners.par_extend(self.indices.par_iter().map(|&[a, b, c]| [p[a as usize], p[b as usize], p[c as usize]]));
        corners
    }
    #[inline]
    pub fn triangle(&self, prim: u32) -> [Vec3; 3] {
        let [a, b, c] = self.indices[prim as usize];
        let p = &self.padded_positions;
        [p[a as usize], p[b as usize], p[c as usize]]
    }
    pub fn triangle_area(&self, prim: u32) -> f32 {
        let [a, b, c] = self.triangle(prim);
        triangle_area(a, b, c)
    }
    /// Unit geometric normal of triangle `prim` (its winding); `Vec3::Z` for a degenerate one.
    #[inline]
    pub fn triangle_normal(&self, prim: u32) -> Vec3 {
        let [a, b, c] = self.triangle(prim);
        triangle_normal(a, b, c)
    }
    pub fn surface_area(&self) -> f64 {
        (0..self.indices.len() as u32).map(|i| self.triangle_area(i) as f64).sum()
    }
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in self.positions() {
            b.grow(*p);
        }
        b
    }
    /// Bytes held by this mesh's arrays.
    pub fn memory_bytes(&self) -> usize {
        self.padded_positions.capacity() * 12
            + self.indices.capacity() * 12
            + self.normals.as_ref().map_or(0, |n| n.capacity() * 12)
            + self.uvs.as_ref().map_or(0, |n| n.capacity() * 8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_meshes() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(TriangleMesh::new(p.clone(), vec![[0, 1, 2]], None, None).is_ok());
        assert_eq!(
            TriangleMesh::new(p.clone(), vec![[0, 1, 3]], None, None).unwrap_err(),
            MeshError::IndexOutOfRange { triangle: 0, vertex: 3, count: 3 }
        );
        let mut bad = p.clone();
        bad[1].x = f32::NAN;
        assert!(matches!(
            TriangleMesh::new(bad, vec![[0, 1, 2]], None, None),
            Err(MeshError::NonFiniteVertex { index: 1, .. })
        ));
        assert_eq!(TriangleMesh::new(p, vec![], None, None).unwrap_err(), MeshError::Empty);
    }

    #[test]
    fn padding_vertex_is_hidden() {
        let m = TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]], None, None).unwrap();
        assert_eq!(m.positions().len(), 3);
        assert_eq!(m.padded_positions().len(), 4);
        assert!((m.triangle_area(0) - 0.5).abs() < 1e-6);
    }

    /// A mesh whose index and position arrays hold between 1 and 64 MiB keeps them in memory
    /// advised for huge pages (shading reads them at every closest hit, at random places); the
    /// contents are unchanged. A small mesh's are not advised.
    #[cfg(target_os = "linux")]
    #[test]
    fn large_arrays_ask_for_huge_pages() {
        use crate::process::huge_pages::{advised_for_huge_pages, HUGE_PAGE};
        let n = 400_000u32; // 4.8 MB of positions and of indices: whole huge pages inside each
        let positions: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, (i % 7) as f32, 1.0)).collect();
        let indices: Vec<[u32; 3]> = (0..n).map(|i| [i, (i + 1) % n, (i + 2) % n]).collect();
        let m = TriangleMesh::new(positions.clone(), indices.clone(), None, None).unwrap();
        assert_eq!(m.positions(), &positions[..]);
        assert_eq!(m.indices(), &indices[..]);
        for (name, start) in
            [("positions", m.padded_positions().as_ptr() as usize), ("indices", m.indices().as_ptr() as usize)]
        {
            // The allocation's first whole huge page: the part Linux can back with one.
            let aligned = start.next_multiple_of(HUGE_PAGE);
            assert!(advised_for_huge_pages(aligned as *const u8), "{name} not advised for huge pages");
        }
        let small = TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]], None, None).unwrap();
        assert!(!advised_for_huge_pages(small.indices().as_ptr()), "a one-triangle mesh's indices advised");
    }
}
