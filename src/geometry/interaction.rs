use glam::{Vec2, Vec3};

use super::{gamma, spawn_ray, triangle_normal, Frame, Hit, Ray, TriangleMesh};

/// Everything shading needs about a ray's hit on a surface.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    /// Hit point, computed from barycentrics (not `o + t d`) so it is the same on every accelerator.
    pub p: Vec3,
    /// Conservative absolute error bound of `p`, per axis.
    pub p_error: Vec3,
    /// Unit geometric normal, as the triangle's winding gives it (not flipped towards the ray).
    pub ng: Vec3,
    /// Shading frame; `shading.n` is the interpolated normal, flipped into ng's hemisphere.
    pub shading: Frame,
    pub uv: Vec2,
    pub geom_id: u32,
    pub prim_id: u32,
    /// Distance along the ray that found this hit.
    pub t: f32,
}

impl SurfaceInteraction {
    /// Builds the interaction for `hit` on `mesh`. The error bound is pbrt-v4's for barycentric
    /// interpolation: γ(7)·Σ|b_i v_i| (pbrt-v4 Sec. 6.8.5).
    #[inline(always)]
    pub fn from_hit(mesh: &TriangleMesh, hit: &Hit) -> SurfaceInteraction {
        SurfaceInteraction::from_corners(mesh, mesh.triangle(hit.prim_id), hit)
    }

    /// [`Self::from_hit`] given the triangle's three positions (`mesh.triangle(hit.prim_id)`, or
    /// the same values from `Scene`'s corner copies); reads the mesh's indices only for its normals
    /// or uvs.
    #[inline(always)]
    pub fn from_corners(mesh: &TriangleMesh, [v0, v1, v2]: [Vec3; 3], hit: &Hit) -> SurfaceInteraction {
        let b1 = hit.b1;
        let b2 = hit.b2;
        let b0 = 1.0 - b1 - b2;
        let p = v0 * b0 + v1 * b1 + v2 * b2;
        let p_error = gamma(7) * ((v0 * b0).abs() + (v1 * b1).abs() + (v2 * b2).abs());
        let ng = triangle_normal(v0, v1, v2);
        let ns = match mesh.normals() {
            Some(ns) => {
                let idx = mesh.indices()[hit.prim_id as usize];
                let n = ns[idx[0] as usize] * b0 + ns[idx[1] as usize] * b1 + ns[idx[2] as usize] * b2;
                let n = n.normalize_or(ng);
                if n.dot(ng) < 0.0 {
                    -n
                } else {
                    n
                }
            }
            None => ng,
        };
        let uv = match mesh.uvs() {
            Some(uv) => {
                let idx = mesh.indices()[hit.prim_id as usize];
                uv[idx[0] as usize] * b0 + uv[idx[1] as usize] * b1 + uv[idx[2] as usize] * b2
            }
            None => Vec2::new(b1, b2),
        };
        SurfaceInteraction {
            p,
            p_error,
            ng,
            shading: Frame::from_normal(ns),
            uv,
            geom_id: hit.geom_id,
            prim_id: hit.prim_id,
            t: hit.t,
        }
    }

    /// A ray leaving this surface in direction `d`.
    #[inline]
    pub fn spawn(&self, d: Vec3) -> Ray {
        spawn_ray(self.p, self.p_error, self.ng, d)
    }
}
