//! Inline shapes, generated in object space and placed by the shape's transform:
//! - `quad`: the square [-1, 1]² in the plane z = 0, front (+z) facing (Mitsuba's `rectangle`);
//! - `box`: the cube [-1, 1]³, faces pointing outwards;
//! - `disk`: the unit disk in z = 0, front (+z) facing, a fan of `segments` triangles;
//! - `sphere`: the unit sphere, `rings` latitude bands and `2·rings` longitude segments, smooth
//!   normals, outward facing.
//!
//! Counter-clockwise winding seen from the front, so the geometric normal (b − a) × (c − a) points
//! to the front side.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::raw_mesh::RawMesh;

/// Default number of segments of a disk.
pub const DISK_DEFAULT_SEGMENTS: u32 = 64;
/// Default number of latitude bands of a sphere.
pub const SPHERE_DEFAULT_RINGS: u32 = 32;

pub fn quad() -> RawMesh {
    RawMesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        normals: None,
        uvs: Some(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]),
    }
}

pub fn cube() -> RawMesh {
    let mut out = RawMesh { uvs: Some(Vec::new()), ..Default::default() };
    let faces = [
        (Vec3::X, Vec3::Y),
        (-Vec3::X, Vec3::Z),
        (Vec3::Y, Vec3::Z),
        (-Vec3::Y, Vec3::X),
        (Vec3::Z, Vec3::X),
        (-Vec3::Z, Vec3::Y),
    ];
    for (n, u) in faces {
        // v = n × u makes u × v = n, so the corners below run counter-clockwise seen from outside.
        let v = n.cross(u);
        let base = out.positions.len() as u32;
        out.positions.extend([n - u - v, n + u - v, n + u + v, n - u + v]);
        out.uvs.as_mut().unwrap().extend([
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ]);
        out.indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    }
    out
}

pub fn disk(segments: u32) -> RawMesh {
    let mut positions = vec![Vec3::ZERO];
    let mut uvs = vec![Vec2::new(0.5, 0.5)];
    for i in 0..segments {
        let phi = 2.0 * PI * i as f32 / segments as f32;
        let (s, c) = phi.sin_cos();
        positions.push(Vec3::new(c, s, 0.0));
        uvs.push(Vec2::new(0.5 + 0.5 * c, 0.5 + 0.5 * s));
    }
    let indices = (0..segments).map(|i| [0, 1 + i, 1 + (i + 1) % segments]).collect();
    RawMesh { positions, indices, normals: None, uvs: Some(uvs) }
}

/// A UV sphere with poles on ±z. Vertices lie on the unit sphere; the seam column is duplicated
/// (same positions, u = 1 instead of 0) so texture coordinates stay continuous.
pub fn sphere(rings: u32) -> RawMesh {
    let segments = 2 * rings;
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for r in 0..=rings {
        let theta = PI * r as f32 / rings as f32;
        let (st, ct) = theta.sin_cos();
        for s in 0..=segments {
            // The seam column repeats column 0's positions bit for bit (sin 2π is not exactly 0 in
            // f32), so the mesh stays watertight for watertight ray tests.
            let phi = 2.0 * PI * (s % segments) as f32 / segments as f32;
            let (sp, cp) = phi.sin_cos();
            // Exact poles, so the top and bottom caps close without slivers.
            let p = if r == 0 {
                Vec3::Z
            } else if r == rings {
                -Vec3::Z
            } else {
                Vec3::new(st * cp, st * sp, ct)
            };
            positions.push(p);
            uvs.push(Vec2::new(s as f32 / segments as f32, r as f32 / rings as f32));
        }
    }
    let row = segments + 1;
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let b = a + 1;
            let c = a + row;
            let d = c + 1;
            // Rows go from +z down and φ increases counter-clockwise about +z, so seen from outside
            // b is right of a and c below it: (a, c, b) and (b, c, d) wind counter-clockwise.
            // Skip the triangles that collapse at the poles.
            if r != 0 {
                indices.push([a, c, b]);
            }
            if r != rings - 1 {
                indices.push([b, c, d]);
            }
        }
    }
    let normals = positions.clone();
    RawMesh { positions, indices, normals: Some(normals), uvs: Some(uvs) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sum over triangles of (centroid · area-weighted normal) / 3 = the enclosed volume, by the
    /// divergence theorem; positive exactly when every face winds outwards.
    fn signed_volume(m: &RawMesh) -> f32 {
        m.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn cube_is_closed_and_outward() {
        let v = signed_volume(&cube());
        assert!((v - 8.0).abs() < 1e-5, "{v}");
    }

    #[test]
    fn sphere_is_closed_and_outward() {
        let m = sphere(32);
        let v = signed_volume(&m);
        // The inscribed polyhedron has slightly less than 4π/3 volume.
        let exact = 4.0 * PI / 3.0;
        assert!(v > 0.98 * exact && v < exact, "{v}");
        // Every triangle's winding agrees with the outward normals at its corners.
        let ns = m.normals.as_ref().unwrap();
        for t in &m.indices {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let g = (b - a).cross(c - a);
            assert!(g.length() > 0.0, "degenerate triangle {t:?}");
            assert!(g.dot(ns[t[0] as usize] + ns[t[1] as usize] + ns[t[2] as usize]) > 0.0);
        }
    }

    /// Every edge, keyed by its endpoint positions, is used once in each direction: the surface
    /// is closed and consistently wound, with no cracks at the seam or the poles.
    fn assert_watertight(m: &RawMesh) {
        use std::collections::HashMap;
        let key = |p: Vec3| p.to_array().map(f32::to_bits);
        let mut edges: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
        for t in &m.indices {
            for k in 0..3 {
                let (a, b) = (key(m.positions[t[k] as usize]), key(m.positions[t[(k + 1) % 3] as usize]));
                *edges.entry((a, b)).or_default() += 1;
                *edges.entry((b, a)).or_default() -= 1;
            }
        }
        assert!(edges.values().all(|&c| c == 0), "open or inconsistently wound edges");
    }

    #[test]
    fn closed_shapes_are_watertight() {
        assert_watertight(&cube());
        assert_watertight(&sphere(2));
        assert_watertight(&sphere(17));
    }

    #[test]
    fn quad_and_disk_face_plus_z() {
        for m in [quad(), disk(16)] {
            for t in &m.indices {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                assert!((b - a).cross(c - a).z > 0.0);
            }
        }
        let m = disk(256);
        let area: f32 = m
            .indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        // The inscribed 256-gon: area = (n/2)·sin(2π/n) = π(1 − O(1/n²)).
        let exact = 128.0 * (2.0 * PI / 256.0).sin();
        assert!((area - exact).abs() < 1e-4, "{area}");
    }
}
