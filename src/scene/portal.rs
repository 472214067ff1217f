//! The one query a portal answers: where a segment or ray crosses it (the portal paper's Sec. 4.2,
//! "a ray-quad intersection algorithm similar to the Möller–Trumbore algorithm"). Portals are never
//! part of the acceleration structure: only the path-space portal perturbation
//! (`integrator::path_space::portal_perturbation`) asks this, so a scene without portals pays nothing.
//!
//! In f64: the perturbation pivots a path edge about the crossing point and must find the same
//! crossing again on the new edge (its reverse-consistency check), which f32's ~1e-7 relative error
//! on the plane distance would blur at the quad's border more often than needed.

use glam::DVec3;

use super::Portal;

/// A crossing of a portal: the ray parameter and the point on the quad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PortalHit {
    pub t: f64,
    pub point: DVec3,
}

impl Portal {
    /// The unit normal of the quad's plane (edge_u × edge_v, normalised; the side does not matter:
    /// a portal is crossed both ways).
    pub fn normal(&self) -> DVec3 {
        self.edge_u.as_dvec3().cross(self.edge_v.as_dvec3()).normalize()
    }

    /// Where the ray `origin + t·dir` crosses the quad for t in (0, t_max) (t_max = ∞ for a ray to
    /// infinity), or None. `dir` need not be unit; t is in its units.
    ///
    /// Möller–Trumbore's determinant form for the parallelogram corner + s·edge_u + v·edge_v: with
    /// q = dir × edge_v and det = edge_u·q, s = (origin − corner)·q / det, v = dir·((origin −
    /// corner) × edge_u) / det and t = edge_v·((origin − corner) × edge_u) / det; the hit is inside
    /// for s, v ∈ [0, 1] (the triangle test's s + v ≤ 1 becomes v ≤ 1).
    pub fn intersect(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<PortalHit> {
        let (corner, eu, ev) = (self.corner.as_dvec3(), self.edge_u.as_dvec3(), self.edge_v.as_dvec3());
        let q = dir.cross(ev);
        let det = eu.dot(q);
        // Parallel to the plane (or degenerate): no crossing. The scale is |dir|·|eu|·|ev|.
        if det.abs() <= 1e-12 * dir.length() * eu.length() * ev.length() {
            return None;
        }
        let inv = 1.0 / det;
        let o = origin - corner;
        let s = o.dot(q) * inv;
        if !(0.0..=1.0).contains(&s) {
            return None;
        }
        let r = o.cross(eu);
        let v = dir.dot(r) * inv;
        if !(0.0..=1.0).contains(&v) {
            return None;
        }
        let t = ev.dot(r) * inv;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        Some(PortalHit { t, point: origin + dir * t })
    }
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};

    use super::Portal;

    fn square() -> Portal {
        // The square [−1, 1]² in the plane y = 2.
        Portal {
            corner: Vec3::new(-1.0, 2.0, -1.0),
            edge_u: Vec3::new(2.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 2.0),
        }
    }

    #[test]
    fn crossings_inside_outside_and_beyond_the_segment() {
        let p = square();
        let up = DVec3::Y;
        let hit = p.intersect(DVec3::new(0.5, 0.0, -0.25), up, 10.0).expect("crosses");
        assert!((hit.t - 2.0).abs() < 1e-12 && (hit.point - DVec3::new(0.5, 2.0, -0.25)).length() < 1e-12);
        // From the other side, and with an unnormalised direction (t in its units).
        let hit = p.intersect(DVec3::new(0.0, 4.0, 0.0), DVec3::new(0.0, -4.0, 0.0), 1.0).expect("crosses down");
        assert!((hit.t - 0.5).abs() < 1e-12);
        assert!(p.intersect(DVec3::new(1.5, 0.0, 0.0), up, 10.0).is_none(), "outside in s");
        assert!(p.intersect(DVec3::new(0.0, 0.0, -1.01), up, 10.0).is_none(), "outside in v");
        assert!(p.intersect(DVec3::new(0.0, 0.0, 0.0), up, 1.99).is_none(), "segment ends before the plane");
        assert!(p.intersect(DVec3::new(0.0, 3.0, 0.0), up, f64::INFINITY).is_none(), "plane behind the origin");
        assert!(p.intersect(DVec3::new(0.0, 1.0, 0.0), DVec3::X, 10.0).is_none(), "parallel");
        assert!((p.normal().abs() - DVec3::Y).length() < 1e-12);
    }

    /// A parallelogram (edges not perpendicular): a point just inside its slanted edge is hit, one
    /// just outside is not (the test is the parallelogram's, not its bounding rectangle's).
    #[test]
    fn a_slanted_parallelogram() {
        let p = Portal { corner: Vec3::ZERO, edge_u: Vec3::new(1.0, 0.0, 0.0), edge_v: Vec3::new(1.0, 1.0, 0.0) };
        let down = DVec3::new(0.0, 0.0, -1.0);
        assert!(p.intersect(DVec3::new(0.55, 0.5, 1.0), down, 2.0).is_some());
        assert!(p.intersect(DVec3::new(0.45, 0.5, 1.0), down, 2.0).is_none());
        assert!(p.intersect(DVec3::new(1.85, 0.9, 1.0), down, 2.0).is_some());
        assert!(p.intersect(DVec3::new(1.95, 0.9, 1.0), down, 2.0).is_none(), "beyond the far slanted edge");
    }
}
