//! Similarity of paths (the paper's Sec. 3.1.2, Eq. 8–9): how close a guide path's vertices are to
//! the current path's, vertex by vertex of the same index.
//!
//!   d(x, v) = max(|x − v|², ε)⁻¹,   S(x, v) = 2/(1 + e^{−d}) − 1 = tanh(d/2)      (Eq. 8)
//!   S(x̄, v̄, j, k) = Π_{l=j}^{k} S(x_l, v_l)                                          (Eq. 9)
//!
//! with ε = 1e-4 in squared world distance. S is 1 for coincident vertices and ≈ 1/(2|x − v|²) for
//! vertices more than a unit apart. It is **not scale invariant**: the same scene modelled in
//! millimetres instead of metres has every S in that 1/(2|x − v|²) tail (so the weights of a
//! weighted guide choice follow inverse squared distance), and in kilometres every S is 1 (the choice
//! is uniform). The paper states no unit; we keep its ε and formula as printed.
//!
//! A vertex at infinity (an environment emitter) is compared by its direction, as a point on the
//! unit sphere.

use glam::DVec3;

use crate::integrator::path_space::PathVertex;

/// ε of Eq. 8, in squared world units.
pub const EPSILON: f64 = 1e-4;

/// S(x, v) of Eq. 8 for two points.
pub fn point_similarity(x: DVec3, v: DVec3) -> f64 {
    let r2 = (x - v).length_squared();
    if r2 <= EPSILON {
        // d = 1/ε and tanh(1/(2ε)) = tanh(5000), which is 1 in f64 (tanh(t) rounds to 1 above
        // t ≈ 19.1): the same value without the tanh (coincident vertices, e.g. a pinhole camera's,
        // are the common case of Eq. 9's first factor).
        return 1.0;
    }
    let d = 1.0 / r2;
    // 2/(1 + e^{−d}) − 1 written as tanh(d/2): the same function, without the cancellation of the
    // subtraction for small d.
    (0.5 * d).tanh()
}

/// Where a vertex is, for similarity: its position, or its direction for a vertex at infinity.
pub fn place(v: &PathVertex) -> DVec3 {
    if v.vertex.infinite {
        v.vertex.dir.as_dvec3()
    } else {
        v.vertex.p.as_dvec3()
    }
}

/// S(x_l, v_l) of Eq. 8 for two path vertices.
pub fn vertex_similarity(x: &PathVertex, v: &PathVertex) -> f64 {
    point_similarity(place(x), place(v))
}

/// S(x̄, v̄, j, k) of Eq. 9: the product over vertices j ..= k (0 when either path is shorter).
pub fn path_similarity(x: &[PathVertex], v: &[PathVertex], j: usize, k: usize) -> f64 {
    if k >= x.len() || k >= v.len() {
        return 0.0;
    }
    (j..=k).map(|l| vertex_similarity(&x[l], &v[l])).product()
}

/// Eq. 9's product for vertices already reduced to their places: S(x_l, v_l) over the pairs of
/// `x` and `v` in order (the same product as `path_similarity` over the same vertices, to the bit:
/// the same factors folded from 1 in the same order).
pub fn places_similarity(x: &[DVec3], v: &[DVec3]) -> f64 {
    x.iter().zip(v).fold(1.0, |s, (&a, &b)| s * point_similarity(a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 8's values at its landmarks: 1 at coincidence (d = 1/ε), tanh(1/2) at unit distance,
    /// the 1/(2r²) tail far away; and the printed sigmoid form agrees with the tanh form.
    #[test]
    fn eq8_landmarks() {
        let o = DVec3::ZERO;
        assert_eq!(point_similarity(o, o), 1.0);
        assert_eq!((0.5 / EPSILON).tanh(), 1.0, "the coincident shortcut must be exact");
        let near = DVec3::X * EPSILON.sqrt() * (1.0 + 1e-9);
        assert_eq!(point_similarity(o, near), 1.0);
        assert!((point_similarity(o, DVec3::X) - 0.5f64.tanh()).abs() < 1e-15);
        let far = point_similarity(o, DVec3::X * 100.0);
        assert!((far - 0.5e-4).abs() < 1e-10, "{far}");
        for r in [0.001f64, 0.05, 0.7, 3.0, 40.0] {
            let d = 1.0 / (r * r).max(EPSILON);
            let printed = 2.0 / (1.0 + (-d).exp()) - 1.0;
            assert!((point_similarity(o, DVec3::Y * r) - printed).abs() < 1e-12);
        }
    }
}
