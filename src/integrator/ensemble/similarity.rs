//! Similarity of paths (the paper's Sec. 3.1.2, Eq. 8–9): how close a guide path's vertices are to
//! the current path's, vertex by vertex of the same index.
//!
//!   d(x, v) = max(|x − v|²/L², ε)⁻¹,   S(x, v) = 2/(1 + e^{−d}) − 1 = tanh(d/2)   (Eq. 8)
//!   S(x̄, v̄, j, k) = Π_{l=j}^{k} S(x_l, v_l)                                        (Eq. 9)
//!
//! with ε = 1e-4, now a dimensionless squared distance.
//!
//! # The length L
//! Eq. 8 as printed compares a squared world distance with 1 and with ε = 1e-4, so it depends on
//! the scene's unit: the same scene in millimetres has every S in the tail ≈ 1/(2|x − v|²) (a
//! weighted guide choice becomes inverse-square distance weighting, almost nearest-of-M), and in
//! kilometres every S is 1 (the choice is uniform). The paper states no unit; its scenes are
//! modelled at about a metre per unit. We divide |x − v|² by L², where L is a length **of the
//! current path x̄**: the mean length of its edges between two finite vertices (Chaitanya et al.'s
//! total path length, which the paper's Sec. 3.1.2 cites, per edge). Why the path and not the
//! scene: a scene's extent is set by its largest object (a ground plane, a distant wall) and says
//! nothing about the distances at which paths in one corner differ, while the path's own edges
//! are the distances its vertices' neighbourhoods are seen from (a room's paths get a room's
//! scale, a small object's paths a small one's, in one scene). For a room of about a metre, L is
//! about a metre and Eq. 8 acts as printed at the paper's scale. S(x, v) is then unchanged when
//! the scene, x̄ and v̄ are scaled together, and S is no longer symmetric (L is x̄'s).
//!
//! Because L belongs to x̄, a guide's selection weight w(v | x̄) = S(x̄, v̄)/Σ S uses x̄'s L and the
//! reverse weight w(v | ȳ) uses ȳ's own L: each is the weight the proposal made from that path
//! would use, so the acceptance ratio stays exact (`GuideView::weights` computes L from the path
//! it is given, never from the move).
//!
//! # Vertices at infinity
//! A vertex at infinity (an environment emitter) is compared by its direction, as a point on the
//! unit sphere, with no L (directions have no unit). A finite vertex and a vertex at infinity of
//! the same index (an area light and the environment, both emitters) are not similar: S = 0. A path
//! with no edge between finite vertices (the camera seeing the environment) has no L; its finite
//! vertices (the camera alone) then contribute a factor 1.

use glam::DVec3;

use crate::integrator::path_space::PathVertex;

/// ε of Eq. 8, a squared distance in units of L² (module docs).
pub const EPSILON: f64 = 1e-4;

/// S of Eq. 8 for a squared distance `r2` already in units of L² (or on the unit sphere).
pub fn similarity_r2(r2: f64) -> f64 {
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

/// S(x, v) of Eq. 8 for two points of a domain whose unit is L (the toy tests' unit square).
pub fn point_similarity(x: DVec3, v: DVec3) -> f64 {
    similarity_r2((x - v).length_squared())
}

/// Where a vertex is, for similarity: its position, or its direction for a vertex at infinity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    pub p: DVec3,
    pub infinite: bool,
}

/// The place of a path vertex (`Place`).
pub fn place(v: &PathVertex) -> Place {
    if v.vertex.infinite {
        Place { p: v.vertex.dir.as_dvec3(), infinite: true }
    } else {
        Place { p: v.vertex.p.as_dvec3(), infinite: false }
    }
}

/// L of a path (module docs): the mean length of its edges between two finite vertices, or None
/// when it has none.
pub fn path_length(x: &[PathVertex]) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0u32);
    for e in x.windows(2) {
        if !e[0].vertex.infinite && !e[1].vertex.infinite {
            sum += (e[1].vertex.p.as_dvec3() - e[0].vertex.p.as_dvec3()).length();
            n += 1;
        }
    }
    let l = sum / n.max(1) as f64;
    (n > 0 && l > 0.0 && l.is_finite()).then_some(l)
}

/// The factor 1/L² that turns a squared world distance into Eq. 8's (module docs), None without L.
pub fn inverse_length2(x: &[PathVertex]) -> Option<f64> {
    path_length(x).map(|l| 1.0 / (l * l)).filter(|s| s.is_finite() && *s > 0.0)
}

/// S(x_l, v_l) of Eq. 8 for two places, with `inv_l2` = 1/L² of the current path x̄.
pub fn place_similarity(x: Place, v: Place, inv_l2: Option<f64>) -> f64 {
    match (x.infinite, v.infinite) {
        (true, true) => similarity_r2((x.p - v.p).length_squared()),
        (false, false) => match inv_l2 {
            Some(s) => similarity_r2((x.p - v.p).length_squared() * s),
            None => 1.0,
        },
        _ => 0.0,
    }
}

/// S(x̄, v̄, j, k) of Eq. 9: the product over vertices j ..= k (0 when either path is shorter),
/// with x̄'s own L.
pub fn path_similarity(x: &[PathVertex], v: &[PathVertex], j: usize, k: usize) -> f64 {
    if k >= x.len() || k >= v.len() {
        return 0.0;
    }
    let inv_l2 = inverse_length2(x);
    (j..=k).map(|l| place_similarity(place(&x[l]), place(&v[l]), inv_l2)).product()
}

/// Eq. 9's product for vertices already reduced to their places: S(x_l, v_l) over the pairs of
/// `x` and `v` in order, with x̄'s `inv_l2` (the same product as `path_similarity` over the same
/// vertices, to the bit: the same factors folded from 1 in the same order).
pub fn places_similarity(x: &[Place], v: &[Place], inv_l2: Option<f64>) -> f64 {
    x.iter().zip(v).fold(1.0, |s, (&a, &b)| s * place_similarity(a, b, inv_l2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 8's values at its landmarks (squared distances in units of L²): 1 at coincidence
    /// (d = 1/ε), tanh(1/2) at unit distance, the 1/(2r²) tail far away; and the printed sigmoid
    /// form agrees with the tanh form.
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

    /// A finite and an infinite vertex are not similar; two directions compare on the unit sphere
    /// whatever L is; without L the finite vertices contribute 1.
    #[test]
    fn places_at_infinity() {
        let dir = |d: DVec3| Place { p: d.normalize(), infinite: true };
        let at = |p: DVec3| Place { p, infinite: false };
        assert_eq!(place_similarity(at(DVec3::ZERO), dir(DVec3::Y), Some(1.0)), 0.0);
        let (a, b) = (dir(DVec3::Y), dir(DVec3::new(1.0, 1.0, 0.0)));
        let s = place_similarity(a, b, Some(1.0));
        assert_eq!(s, place_similarity(a, b, Some(1e6)));
        assert!(s > 0.0 && s < 1.0);
        assert_eq!(place_similarity(at(DVec3::ZERO), at(DVec3::X), None), 1.0);
    }
}
