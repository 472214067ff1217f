//! Area emission from a triangle mesh: uniform points on a triangle and on a mesh (triangle chosen
//! by area), cosine-weighted emission directions, each with its pdf and its inverse.
//!
//! Dimension layout (shared by the forward samplers and the inverses, so they cannot drift):
//! - a point on the mesh takes 3 uniforms: `u[0]` chooses the triangle (discrete, by area; its
//!   inverse is the ambiguous interval of RJMLT Eq. 40, resampled with a fresh uniform γ), `u[1..3]`
//!   the barycentrics (`warp::sample_uniform_triangle`, exact inverse);
//! - an emission direction takes 2 uniforms: the cosine-weighted hemisphere around the triangle's
//!   geometric normal. A two-sided emitter splits `u[0]` into halves, [0, ½) for the front and
//!   [½, 1) for the back, each stretched back to [0, 1): the side is a function of the direction,
//!   so this stays a bijection and its inverse is exact.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::spherical_rectangle::{Rectangle, SphericalRectangle};
use super::{AreaLight, EmissionInverse, EmissionSample, LiInverse, LightLiSample};
use crate::geometry::{gamma, Frame, TriangleMesh};
use crate::sampling::{
    clamp_unit, invert_cosine_hemisphere, invert_uniform_triangle, pdf_cosine_hemisphere, sample_cosine_hemisphere,
    sample_uniform_triangle, Distribution1D,
};
use crate::spectrum::{luminance, Rgb};

/// How near a rectangle light, in diagonals of the rectangle from its centre, the path tracer
/// samples it by solid angle (`AreaLight::solid_angle_sampling`). Measured
/// (docs/lab/benchmarks-history.md, "Sampling rectangle lights by solid angle"): within 1 diagonal
/// solid-angle sampling takes 10% of the door's variance and 33% of the Cornell box's; 0.75 loses a
/// third of the box's gain, and 1.25 to 4 add cost (+12% CPU time on the door at 4) for at most
/// 1.6% less variance.
pub const SOLID_ANGLE_SAMPLING_RANGE: f32 = 1.0;

/// A point sampled on a mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshPoint {
    pub prim: u32,
    /// Barycentrics (b1, b2) in the convention of `Hit`.
    pub b: Vec2,
    pub p: Vec3,
    /// Conservative absolute error bound of `p`, per axis: the hit point's bound γ(7)·Σ|b_i v_i|
    /// (`SurfaceInteraction::from_hit`; pbrt-v4 Sec. 6.8.5), for rays that end at the point.
    pub p_error: Vec3,
    /// Unit geometric normal of the triangle (its winding), the same as `SurfaceInteraction::ng`.
    pub n: Vec3,
}

/// Unit geometric normal of triangle `prim`, computed exactly as `SurfaceInteraction::from_hit` does.
pub fn triangle_normal(mesh: &TriangleMesh, prim: u32) -> Vec3 {
    mesh.triangle_normal(prim)
}

/// Uniform point on triangle `prim` of `mesh` from 2 uniforms; its area density is 1/area.
pub fn sample_triangle_point(mesh: &TriangleMesh, prim: u32, u: [f32; 2]) -> MeshPoint {
    point_on_triangle(mesh, prim, u, triangle_normal(mesh, prim))
}

/// `sample_triangle_point` given the triangle's unit normal `n` (`triangle_normal`), which an
/// [`AreaLight`] keeps per triangle rather than recompute per sample.
fn point_on_triangle(mesh: &TriangleMesh, prim: u32, u: [f32; 2], n: Vec3) -> MeshPoint {
    let [v0, v1, v2] = mesh.triangle(prim);
    let b = sample_uniform_triangle(u);
    let b0 = 1.0 - b.x - b.y;
    let p = v0 * b0 + v1 * b.x + v2 * b.y;
    let p_error = gamma(7) * ((v0 * b0).abs() + (v1 * b.x).abs() + (v2 * b.y).abs());
    MeshPoint { prim, b, p, p_error, n }
}

/// Barycentrics (b1, b2) of `p` on triangle `prim`, or `None` when `p` is off the triangle: farther
/// from its plane, or outside its edges, than the rounding error of a point computed on it (a
/// relative 1e-4 of the triangle's size plus the hit-point error bound γ(7)·|p|, pbrt-v4 Sec. 6.8.5).
pub fn triangle_barycentrics(mesh: &TriangleMesh, prim: u32, p: Vec3) -> Option<Vec2> {
    if prim as usize >= mesh.triangle_count() || !p.is_finite() {
        return None;
    }
    let [v0, v1, v2] = mesh.triangle(prim);
    // In f64: the Gram system loses about log10(condition) digits on slivers.
    let (e1, e2, d) = ((v1 - v0).as_dvec3(), (v2 - v0).as_dvec3(), (p - v0).as_dvec3());
    let (a11, a12, a22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = a11 * a22 - a12 * a12;
    if !(det > 0.0) {
        return None;
    }
    let (r1, r2) = (d.dot(e1), d.dot(e2));
    let b1 = (a22 * r1 - a12 * r2) / det;
    let b2 = (a11 * r2 - a12 * r1) / det;
    let size = a11.sqrt() + a22.sqrt();
    let magnitude = v0.abs().max(v1.abs()).max(v2.abs()).max(p.abs()).max_element() as f64;
    let tol_dist = 1e-4 * size + 4.0 * gamma(7) as f64 * magnitude;
    let off_plane = (d - e1 * b1 - e2 * b2).length();
    // The same tolerance in barycentric units (distance / the triangle's smallest height).
    let tol_b = tol_dist * size / det.sqrt();
    if off_plane > tol_dist || b1 < -tol_b || b2 < -tol_b || b1 + b2 > 1.0 + tol_b {
        return None;
    }
    // Clamp the admitted rounding back onto the triangle.
    let (b1, b2) = (b1.max(0.0), b2.max(0.0));
    let s = b1 + b2;
    let (b1, b2) = if s > 1.0 { (b1 / s, b2 / s) } else { (b1, b2) };
    Some(Vec2::new(b1 as f32, b2 as f32))
}

/// Inverse of `sample_triangle_point`: `None` when `p` is off the triangle. Exact except at the
/// vertex v0 (see `warp::invert_uniform_triangle`).
pub fn invert_triangle_point(mesh: &TriangleMesh, prim: u32, p: Vec3) -> Option<[f32; 2]> {
    invert_uniform_triangle(triangle_barycentrics(mesh, prim, p)?)
}

/// Uniform point on a mesh: triangle by area with `u[0]` (`triangles` built from the triangle
/// areas), then a uniform point in it with `u[1..3]`. Its area density is 1/(total area).
pub fn sample_mesh_point(mesh: &TriangleMesh, triangles: &Distribution1D, u: [f32; 3]) -> Option<MeshPoint> {
    if triangles.is_empty() {
        return None;
    }
    let (prim, pmf) = triangles.sample_index(u[0]);
    if !(pmf > 0.0) {
        return None;
    }
    Some(sample_triangle_point(mesh, prim as u32, [u[1], u[2]]))
}

/// Area density of `sample_mesh_point` on a mesh of total area `area`.
pub fn pdf_mesh_point(area: f32) -> f32 {
    if area > 0.0 {
        1.0 / area
    } else {
        0.0
    }
}

/// Inverse of `sample_mesh_point` for the point `p` on triangle `prim`: the triangle's interval of
/// `u[0]` is ambiguous, so `gamma` (a fresh uniform) places `u[0]` uniformly inside it (RJMLT Eq.
/// 40; Jacobian pmf(prim)); `u[1..3]` are the exact barycentric inverse. `None` for a triangle of
/// zero area or a point off it.
pub fn invert_mesh_point(
    mesh: &TriangleMesh,
    triangles: &Distribution1D,
    prim: u32,
    p: Vec3,
    gamma: f32,
) -> Option<[f32; 3]> {
    let u0 = triangles.invert_discrete(prim as usize, gamma)?;
    let [u1, u2] = invert_triangle_point(mesh, prim, p)?;
    Some([u0, u1, u2])
}

/// Cosine-weighted emission direction around the geometric normal `n` (both hemispheres, chosen by
/// halves of `u[0]`, when `two_sided`).
pub fn sample_emission_direction(n: Vec3, two_sided: bool, u: [f32; 2]) -> Vec3 {
    let frame = Frame::from_normal(n);
    if two_sided {
        if u[0] < 0.5 {
            frame.to_world(sample_cosine_hemisphere([2.0 * u[0], u[1]]))
        } else {
            let w = sample_cosine_hemisphere([(2.0 * u[0] - 1.0).min(crate::sampling::ONE_MINUS_EPSILON), u[1]]);
            frame.to_world(Vec3::new(w.x, w.y, -w.z))
        }
    } else {
        frame.to_world(sample_cosine_hemisphere(u))
    }
}

/// Solid-angle density of `sample_emission_direction`: |cos θ|/π (halved when two-sided) on the
/// emitting side(s), 0 elsewhere.
pub fn pdf_emission_direction(n: Vec3, two_sided: bool, w: Vec3) -> f32 {
    let c = n.dot(w);
    if two_sided {
        0.5 * pdf_cosine_hemisphere(Vec3::new(0.0, 0.0, c.abs()))
    } else {
        pdf_cosine_hemisphere(Vec3::new(0.0, 0.0, c))
    }
}

/// Inverse of `sample_emission_direction` for a unit `w`; `None` behind a one-sided emitter.
pub fn invert_emission_direction(n: Vec3, two_sided: bool, w: Vec3) -> Option<[f32; 2]> {
    let frame = Frame::from_normal(n);
    let local = frame.to_local(w);
    if two_sided {
        if local.z >= 0.0 {
            let [a, b] = invert_cosine_hemisphere(local)?;
            Some([clamp_unit(0.5 * a), b])
        } else {
            let [a, b] = invert_cosine_hemisphere(Vec3::new(local.x, local.y, -local.z))?;
            Some([clamp_unit(0.5 * a + 0.5), b])
        }
    } else {
        invert_cosine_hemisphere(local)
    }
}

impl AreaLight {
    /// An area light over every triangle of `mesh` (the scene's mesh `geom_id`), triangles chosen
    /// by area.
    pub fn new(mesh: Arc<TriangleMesh>, geom_id: u32, radiance: Rgb, two_sided: bool) -> AreaLight {
        let areas: Vec<f32> = (0..mesh.triangle_count() as u32).map(|i| mesh.triangle_area(i)).collect();
        let area = areas.iter().map(|&a| a as f64).sum::<f64>() as f32;
        let normals: Vec<Vec3> = (0..mesh.triangle_count() as u32).map(|i| triangle_normal(&mesh, i)).collect();
        let rectangle = normals.first().and_then(|&n| Rectangle::from_mesh(&mesh, n));
        AreaLight {
            triangles: Distribution1D::new(&areas),
            normals,
            mesh,
            geom_id,
            radiance,
            two_sided,
            area,
            rectangle,
        }
    }

    /// `sample_mesh_point` on this light's mesh, with the triangle's normal from `normals` (the
    /// same value `triangle_normal` computes: a normal per light sample in f64 showed as 1.4–3% of
    /// pt's profile).
    #[inline(always)]
    pub(super) fn sample_point(&self, u: [f32; 3]) -> Option<MeshPoint> {
        if self.triangles.is_empty() {
            return None;
        }
        let (prim, pmf) = self.triangles.sample_index(u[0]);
        let n = *self.normals.get(prim)?;
        (pmf > 0.0).then(|| point_on_triangle(&self.mesh, prim as u32, [u[1], u[2]], n))
    }

    /// Radiance leaving a point with geometric normal `n` in direction `w`.
    pub fn emitted(&self, n: Vec3, w: Vec3) -> Rgb {
        if self.two_sided || n.dot(w) > 0.0 {
            self.radiance
        } else {
            Rgb::ZERO
        }
    }

    /// Luminance flux: L·A·π, twice that when two-sided.
    pub fn power(&self) -> f32 {
        let sides = if self.two_sided { 2.0 } else { 1.0 };
        luminance(self.radiance).max(0.0) * self.area * std::f32::consts::PI * sides
    }

    /// A point on the light by uniform area sampling, seen from `reference`. `None` when the point
    /// sends nothing towards `reference` (back of a one-sided emitter, grazing, coincident).
    pub fn sample_li(&self, reference: Vec3, u: [f32; 3]) -> Option<LightLiSample> {
        self.li_from_point(reference, &self.sample_point(u)?)
    }

    /// `sample_li` seen from `reference` for the point `q` that `sample_point` drew.
    #[inline(always)]
    pub(super) fn li_from_point(&self, reference: Vec3, q: &MeshPoint) -> Option<LightLiSample> {
        self.li_towards(reference, q.p, q.p_error, q.n, |wi| self.pdf_li(reference, wi, q.p, q.n))
    }

    /// The light sample at the emitter point `p` (error bound `p_error`, normal `n`) seen from
    /// `reference`, with the solid-angle density `pdf_of(wi)` of whichever sampler drew it. `None`
    /// when the point sends nothing towards `reference` (back of a one-sided emitter, coincident)
    /// or the density is zero or not finite.
    #[inline(always)]
    fn li_towards(
        &self,
        reference: Vec3,
        p: Vec3,
        p_error: Vec3,
        n: Vec3,
        pdf_of: impl FnOnce(Vec3) -> f32,
    ) -> Option<LightLiSample> {
        let to_light = p - reference;
        let dist2 = to_light.length_squared();
        if !(dist2 > 0.0) {
            return None;
        }
        let wi = to_light / dist2.sqrt();
        let radiance = self.emitted(n, -wi);
        if radiance == Rgb::ZERO {
            return None;
        }
        let pdf = pdf_of(wi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(LightLiSample { wi, p, p_error, n, radiance, pdf, infinite: false })
    }

    /// Solid-angle density at `reference` of choosing `p_light` (normal `n_light`): the area density
    /// 1/A converted by distance²/|cos θ_light|.
    pub fn pdf_li(&self, reference: Vec3, wi: Vec3, p_light: Vec3, n_light: Vec3) -> f32 {
        let cos_l = n_light.dot(wi).abs();
        let dist2 = (p_light - reference).length_squared();
        if !(cos_l > 0.0) || self.area <= 0.0 {
            return 0.0;
        }
        pdf_mesh_point(self.area) * dist2 / cos_l
    }

    /// The spherical rectangle that sampling by solid angle uses from `reference`: where the light
    /// is a rectangle and `reference` is within [`SOLID_ANGLE_SAMPLING_RANGE`] diagonals of its
    /// centre, on a side it emits to. Elsewhere the path tracer samples the light by area, as
    /// everything else does: far away d²/|cos θ_light| hardly varies over the emitter, and a
    /// sample by solid angle (four normals, four arccosines, a sine and cosine, a chain of square
    /// roots and divisions) costs about 75 ns against 5 ns for a point by area.
    #[inline]
    fn solid_angle_sampling(&self, reference: Vec3) -> Option<SphericalRectangle<'_>> {
        let rect = self.rectangle.as_ref()?;
        let to_center = reference - rect.center();
        let range = SOLID_ANGLE_SAMPLING_RANGE * rect.diagonal();
        let in_front = self.two_sided || to_center.dot(rect.normal()) > 0.0;
        if !(in_front && to_center.length_squared() < range * range) {
            return None;
        }
        SphericalRectangle::new(rect, reference)
    }

    /// The path tracer's light sample from `reference`: by solid angle near a rectangle light
    /// (`u[1..3]`; `u[0]` unused), else `sample_li`.
    pub fn sample_li_nee(&self, reference: Vec3, u: [f32; 3]) -> Option<LightLiSample> {
        self.li_from_rectangle_point(reference, self.sample_point(u).as_ref(), u)
    }

    /// `sample_li_nee` given the point `sample_point` drew from `u` (drawn before the reference
    /// point is known, as for any area light; used where `reference` is far from the light).
    #[inline(always)]
    pub(super) fn li_from_rectangle_point(
        &self,
        reference: Vec3,
        by_area: Option<&MeshPoint>,
        u: [f32; 3],
    ) -> Option<LightLiSample> {
        let Some(sr) = self.solid_angle_sampling(reference) else {
            return self.li_from_point(reference, by_area?);
        };
        let (p, p_error) = sr.sample([u[1], u[2]]);
        // Both triangles have this normal (`Rectangle::from_mesh`).
        self.li_towards(reference, p, p_error, self.normals[0], |_| sr.pdf())
    }

    /// Density of `sample_li_nee` per unit solid angle at `reference` for the point `p_light`.
    pub fn pdf_li_nee(&self, reference: Vec3, wi: Vec3, p_light: Vec3, n_light: Vec3) -> f32 {
        match self.solid_angle_sampling(reference) {
            Some(sr) => sr.pdf(),
            None => self.pdf_li(reference, wi, p_light, n_light),
        }
    }

    /// Inverse of `sample_li`: the uniforms that choose the point `p_light` on triangle `prim`
    /// (`gamma` resamples the triangle's interval, Eq. 40), per unit area of the point.
    pub fn invert_li(&self, prim: u32, p_light: Vec3, gamma: f32) -> Option<LiInverse> {
        let u = invert_mesh_point(&self.mesh, &self.triangles, prim, p_light, gamma)?;
        Some(LiInverse { u, jacobian: self.mesh_point_inverse_jacobian(prim)? })
    }

    /// |J| of `invert_mesh_point` on triangle `prim`: the length of its interval of `u[0]`
    /// (Eq. 40) times the uniform-triangle warp's 1/area. `None` for a zero-area triangle.
    fn mesh_point_inverse_jacobian(&self, prim: u32) -> Option<f32> {
        let area = self.mesh.triangle_area(prim);
        let jacobian = self.triangles.pdf_discrete(prim as usize) / area;
        (area > 0.0 && jacobian.is_finite() && jacobian > 0.0).then_some(jacobian)
    }

    /// An emitted ray: point by area with `u[0..3]`, cosine-weighted direction with `u[3..5]`.
    pub fn sample_emission(&self, u: [f32; 5]) -> Option<EmissionSample> {
        let q = self.sample_point([u[0], u[1], u[2]])?;
        let dir = sample_emission_direction(q.n, self.two_sided, [u[3], u[4]]);
        let pdf_dir = pdf_emission_direction(q.n, self.two_sided, dir);
        if !(pdf_dir > 0.0) || self.area <= 0.0 {
            return None;
        }
        Some(EmissionSample {
            p: q.p,
            n: q.n,
            dir,
            radiance: self.emitted(q.n, dir),
            pdf_pos: pdf_mesh_point(self.area),
            pdf_dir,
            infinite: false,
        })
    }

    /// `(pdf_pos, pdf_dir)` of `sample_emission` producing the ray from `p` (normal `n`) along `dir`.
    pub fn pdf_emission(&self, n: Vec3, dir: Vec3) -> (f32, f32) {
        (pdf_mesh_point(self.area), pdf_emission_direction(n, self.two_sided, dir))
    }

    /// Inverse of `sample_emission` for the ray leaving `p` on triangle `prim` along `dir`.
    pub fn invert_emission(&self, prim: u32, p: Vec3, dir: Vec3, gamma: f32) -> Option<EmissionInverse> {
        let [u0, u1, u2] = invert_mesh_point(&self.mesh, &self.triangles, prim, p, gamma)?;
        let n = triangle_normal(&self.mesh, prim);
        let [u3, u4] = invert_emission_direction(n, self.two_sided, dir)?;
        // The cosine warp's inverse has Jacobian |cos θ|/π per unit solid angle, halved by the
        // two-sided split of u[3]: `pdf_emission_direction`.
        let jacobian_dir = pdf_emission_direction(n, self.two_sided, dir);
        Some(EmissionInverse {
            u: [u0, u1, u2, u3, u4],
            jacobian_pos: self.mesh_point_inverse_jacobian(prim)?,
            jacobian_dir,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::chi2::{self, Chi2Config, CHI2_TESTS_SAMPLING};
    use crate::sampling::Rng;

    /// The unit square in z = 0 split into four triangles of unequal area (apex at (0.3, 0.6)),
    /// plus a degenerate (zero-area) triangle that must never be chosen.
    fn square_mesh() -> Arc<TriangleMesh> {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.3, 0.6, 0.0),
        ];
        let idx = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 0, 1]];
        Arc::new(TriangleMesh::new(p, idx, None, None).unwrap())
    }

    fn cfg() -> Chi2Config {
        Chi2Config { res: [20, 20], samples: 80_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() }
    }

    /// The path tracer's light sample (`sample_li_nee`) is by solid angle near a rectangle light
    /// and by area far from it and on other meshes, and `pdf_li_nee` is the density each sample
    /// reports: the MIS weight of a BSDF-sampled ray that hits the light must use the density the
    /// light sample would have had (returning the area density there instead passes
    /// tests/images/pt.rs's comparison of MIS modes, so it is checked here). E[1/pdf] over the samples is
    /// the solid angle the light subtends, in both regimes: by solid angle exactly (1/pdf is S),
    /// by area within 5 standard errors of the sample mean (1/pdf = A·|cos θ|/d² has a relative
    /// spread of 7.5% over the light at that distance, so the bound is about 0.27% of S; a false
    /// alarm has probability 6e-7).
    #[test]
    fn nee_samples_rectangles_by_solid_angle_nearby_and_pdf_li_nee_is_their_density() {
        let corners = vec![Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let mesh = Arc::new(TriangleMesh::new(corners, vec![[0, 1, 2], [0, 2, 3]], None, None).unwrap());
        let light = AreaLight::new(mesh, 0, Rgb::ONE, false);
        let rect = light.rectangle.expect("two triangles forming a rectangle");
        assert!(AreaLight::new(square_mesh(), 0, Rgb::ONE, false).rectangle.is_none());
        // The same rectangle with its second triangle wound the other way faces both ways.
        let corners = vec![Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let flipped = Arc::new(TriangleMesh::new(corners, vec![[0, 1, 2], [0, 3, 2]], None, None).unwrap());
        assert!(AreaLight::new(flipped, 0, Rgb::ONE, false).rectangle.is_none());
        let mut rng = Rng::new(11, 0);
        // Near (solid angle) and beyond one diagonal, √5 ≈ 2.24, of the centre (area).
        for (reference, by_solid_angle) in [(Vec3::new(0.5, 0.3, 0.4), true), (Vec3::new(6.0, 5.0, 9.0), false)] {
            let s = SphericalRectangle::new(&rect, reference).unwrap().solid_angle() as f64;
            let (mut inverse_pdf_sum, mut inverse_pdf_sq) = (0.0f64, 0.0f64);
            let n = 20_000;
            for _ in 0..n {
                let ls = light.sample_li_nee(reference, [rng.uniform(), rng.uniform(), rng.uniform()]).unwrap();
                let pdf = light.pdf_li_nee(reference, ls.wi, ls.p, ls.n);
                assert!((pdf / ls.pdf - 1.0).abs() < 1e-5, "{reference}: pdf_li_nee {pdf} vs the sample's {}", ls.pdf);
                let expected =
                    if by_solid_angle { (1.0 / s) as f32 } else { light.pdf_li(reference, ls.wi, ls.p, ls.n) };
                assert!((ls.pdf / expected - 1.0).abs() < 1e-5, "{reference}: pdf {} vs {expected}", ls.pdf);
                inverse_pdf_sum += 1.0 / ls.pdf as f64;
                inverse_pdf_sq += (1.0 / ls.pdf as f64).powi(2);
            }
            let mean = inverse_pdf_sum / n as f64;
            let standard_error = ((inverse_pdf_sq / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            let bound = 5.0 * standard_error + 1e-6 * s;
            assert!((mean - s).abs() <= bound, "{reference}: E[1/pdf] {mean} vs solid angle {s} (bound {bound})");
        }
        // Behind the one-sided emitter there is no sample either way.
        assert!(light.sample_li_nee(Vec3::new(0.5, 0.3, -0.4), [0.5; 3]).is_none());
    }

    #[test]
    fn mesh_point_chi2_and_round_trip() {
        let light = AreaLight::new(square_mesh(), 0, Rgb::ONE, false);
        assert!((light.area - 1.0).abs() < 1e-6);
        let r = chi2::chi2_square(
            &cfg(),
            [0.0, 1.0],
            [0.0, 1.0],
            31,
            |rng: &mut Rng| {
                let q =
                    sample_mesh_point(&light.mesh, &light.triangles, [rng.uniform(), rng.uniform(), rng.uniform()])?;
                Some([q.p.x as f64, q.p.y as f64])
            },
            |_| pdf_mesh_point(light.area) as f64,
        );
        assert!(r.passed, "{}", r.message);
        let mut rng = Rng::new(2, 7);
        for _ in 0..20_000 {
            let u = [rng.uniform(), rng.uniform(), rng.uniform()];
            let q = sample_mesh_point(&light.mesh, &light.triangles, u).unwrap();
            assert_ne!(q.prim, 4, "the degenerate triangle was chosen");
            let g = rng.uniform();
            let v = invert_mesh_point(&light.mesh, &light.triangles, q.prim, q.p, g).unwrap();
            // u[1..3] are exact; u[0] is resampled in the triangle's interval (Eq. 40) ...
            assert!((u[1] - v[1]).abs() < 1e-4 && (u[2] - v[2]).abs() < 1e-4, "{u:?} -> {v:?}");
            // ... so sampling it again gives the same point.
            let q2 = sample_mesh_point(&light.mesh, &light.triangles, v).unwrap();
            assert_eq!(q2.prim, q.prim);
            assert!((q2.p - q.p).length() < 1e-5);
        }
    }

    /// Eq. 40: for a fixed point, the inverted u[0] is uniform over its triangle's interval.
    #[test]
    fn mesh_point_inverse_is_uniform_in_the_triangle_interval() {
        let light = AreaLight::new(square_mesh(), 0, Rgb::ONE, false);
        let prim = 2u32;
        let p = Vec3::new(0.5, 0.9, 0.0);
        let (lo, hi) = (light.triangles.cdf[2], light.triangles.cdf[3]);
        let c = Chi2Config { res: [16, 1], samples: 32_000, ..cfg() };
        let r = chi2::chi2_1d(
            &c,
            [lo, hi],
            32,
            |rng| invert_mesh_point(&light.mesh, &light.triangles, prim, p, rng.uniform()).map(|u| u[0] as f64),
            |_| 1.0 / (hi - lo),
        );
        assert!(r.passed, "{}", r.message);
    }

    #[test]
    fn points_off_the_emitter_are_refused() {
        let mesh = square_mesh();
        let tris = AreaLight::new(mesh.clone(), 0, Rgb::ONE, false).triangles;
        // Off the plane, outside the triangle's edges, on another triangle, degenerate triangle,
        // out-of-range index.
        assert!(invert_mesh_point(&mesh, &tris, 0, Vec3::new(0.5, 0.1, 0.01), 0.5).is_none());
        assert!(invert_mesh_point(&mesh, &tris, 0, Vec3::new(0.5, -0.1, 0.0), 0.5).is_none());
        assert!(invert_mesh_point(&mesh, &tris, 0, Vec3::new(0.5, 0.9, 0.0), 0.5).is_none());
        assert!(invert_mesh_point(&mesh, &tris, 4, Vec3::new(0.5, 0.0, 0.0), 0.5).is_none());
        assert!(invert_mesh_point(&mesh, &tris, 9, Vec3::new(0.5, 0.1, 0.0), 0.5).is_none());
        // A point on the edge shared by triangles 0 and 1 belongs to both.
        let edge = Vec3::new(0.65, 0.3, 0.0);
        assert!(invert_mesh_point(&mesh, &tris, 0, edge, 0.5).is_some());
        assert!(invert_mesh_point(&mesh, &tris, 1, edge, 0.5).is_some());
    }

    /// Far from the origin, a point computed from barycentrics is off by its rounding error; the
    /// inverse must still accept it and round-trip the barycentric uniforms.
    #[test]
    fn triangle_inverse_far_from_the_origin() {
        let o = Vec3::new(1e5, -2e5, 3e4);
        let mesh = TriangleMesh::new(
            vec![o, o + Vec3::new(2.0, 0.0, 0.5), o + Vec3::new(0.3, 1.5, 0.0)],
            vec![[0, 1, 2]],
            None,
            None,
        )
        .unwrap();
        let mut rng = Rng::new(4, 4);
        for _ in 0..1000 {
            let u = [rng.uniform() * 0.98 + 0.01, rng.uniform() * 0.98 + 0.01];
            let q = sample_triangle_point(&mesh, 0, u);
            let v = invert_triangle_point(&mesh, 0, q.p).expect("point on the triangle refused");
            // f32 positions near 1e5 are quantised to ~8e-3, a sizeable fraction of this triangle,
            // so u itself cannot round-trip to 1e-4; the point it maps back to must, within that
            // quantisation.
            let q2 = sample_triangle_point(&mesh, 0, v);
            assert!((q2.p - q.p).length() < 2e-2, "{u:?} -> {} -> {v:?} -> {}", q.p, q2.p);
        }
    }

    #[test]
    fn emission_direction_chi2_round_trip_jacobian() {
        let n = Vec3::new(0.3, -0.4, 0.866).normalize();
        for (k, two_sided) in [false, true].into_iter().enumerate() {
            let r = chi2::chi2_sphere(
                &Chi2Config { test_count: CHI2_TESTS_SAMPLING, ..Default::default() },
                40 + k as u64,
                |rng: &mut Rng| Some(sample_emission_direction(n, two_sided, [rng.uniform(), rng.uniform()])),
                |w| pdf_emission_direction(n, two_sided, w) as f64,
            );
            assert!(r.passed, "two_sided {two_sided}: {}", r.message);
            let total = chi2::integrate_sphere(|w| pdf_emission_direction(n, two_sided, w) as f64, 16, 32);
            assert!((total - 1.0).abs() < 1e-3, "{total}");
            let mut rng = Rng::new(5, k as u64);
            for _ in 0..10_000 {
                let u = [rng.uniform(), rng.uniform()];
                let w = sample_emission_direction(n, two_sided, u);
                let v = invert_emission_direction(n, two_sided, w).unwrap();
                assert!((u[0] - v[0]).abs() < 1e-4 && (u[1] - v[1]).abs() < 1e-4, "{u:?} -> {w} -> {v:?}");
                let pdf = pdf_emission_direction(n, two_sided, w) as f64;
                let ud = [u[0] as f64, u[1] as f64];
                let safe = ud.iter().all(|x| (0.01..0.99).contains(x)) && (ud[0] - 0.5).abs() > 0.01 && pdf > 0.05;
                // The concentric map is only C0 on its diagonals |a| = |b| and singular at its centre:
                // keep the finite-difference stencil away from both (in the square of the cosine map,
                // whose first coordinate is stretched ×2 when two-sided).
                let u0 = if !two_sided {
                    ud[0]
                } else if ud[0] < 0.5 {
                    2.0 * ud[0]
                } else {
                    2.0 * ud[0] - 1.0
                };
                let (a, b) = (2.0 * u0 - 1.0, 2.0 * ud[1] - 1.0);
                let smooth = (a.abs() - b.abs()).abs() > 0.02 && a.abs().max(b.abs()) > 0.05;
                if safe && smooth {
                    let det = chi2::jacobian_det_surface(
                        |x| {
                            let d = sample_emission_direction(n, two_sided, [x[0] as f32, x[1] as f32]);
                            [d.x as f64, d.y as f64, d.z as f64]
                        },
                        ud,
                        1e-3,
                    );
                    assert!((det * pdf - 1.0).abs() < 1e-2, "|J| {det}, 1/pdf {}", 1.0 / pdf);
                }
            }
        }
        assert!(invert_emission_direction(n, false, -n).is_none());
    }

    #[test]
    fn mesh_point_jacobian_is_triangle_area() {
        let mesh = square_mesh();
        let tris = AreaLight::new(mesh.clone(), 0, Rgb::ONE, false).triangles;
        for prim in 0..4u32 {
            for u in [[0.3, 0.4], [0.7, 0.2], [0.5, 0.9]] {
                let det = chi2::jacobian_det_surface(
                    |x| {
                        let p = sample_triangle_point(&mesh, prim, [x[0] as f32, x[1] as f32]).p;
                        [p.x as f64, p.y as f64, p.z as f64]
                    },
                    u,
                    1e-3,
                );
                // Area density = pmf(prim) / A_prim = 1 / A_total.
                let density = tris.pmf(prim as usize) as f64 / det;
                assert!((density - 1.0).abs() < 1e-2, "prim {prim}: {density}");
                assert!((det - mesh.triangle_area(prim) as f64).abs() < 1e-2 * det);
            }
        }
    }

    #[test]
    fn sample_li_pdf_matches_pdf_li_and_respects_sides() {
        let mesh = Arc::new(
            TriangleMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]], None, None).unwrap(), // normal +z
        );
        let one = AreaLight::new(mesh.clone(), 0, Rgb::splat(2.0), false);
        let two = AreaLight::new(mesh, 0, Rgb::splat(2.0), true);
        let above = Vec3::new(0.2, 0.2, 1.0);
        let below = Vec3::new(0.2, 0.2, -1.0);
        let s = one.sample_li(above, [0.3, 0.4, 0.5]).unwrap();
        assert!((s.pdf - one.pdf_li(above, s.wi, s.p, s.n)).abs() < 1e-6 * s.pdf);
        let dist2 = (s.p - above).length_squared();
        assert!((s.pdf - dist2 / (s.n.dot(s.wi).abs() * 0.5)).abs() < 1e-4 * s.pdf);
        assert!(one.sample_li(below, [0.3, 0.4, 0.5]).is_none());
        assert!(two.sample_li(below, [0.3, 0.4, 0.5]).is_some());
        assert_eq!(one.emitted(Vec3::Z, -Vec3::Z), Rgb::ZERO);
        assert_eq!(two.emitted(Vec3::Z, -Vec3::Z), Rgb::splat(2.0));
        let inv = one.invert_li(0, s.p, 0.5).unwrap();
        let again = one.sample_li(above, inv.u).unwrap();
        assert!((inv.jacobian - pdf_mesh_point(one.area)).abs() < 1e-6 * inv.jacobian);
        assert!((again.p - s.p).length() < 1e-5);
        let e = one.sample_emission([0.1, 0.2, 0.3, 0.4, 0.5]).unwrap();
        let (pp, pd) = one.pdf_emission(e.n, e.dir);
        assert!((pp - e.pdf_pos).abs() < 1e-6 && (pd - e.pdf_dir).abs() < 1e-6);
        let inverse = one.invert_emission(0, e.p, e.dir, 0.7).unwrap();
        assert!((inverse.jacobian_pos - e.pdf_pos).abs() < 1e-6 * e.pdf_pos);
        assert!((inverse.jacobian_dir - e.pdf_dir).abs() < 1e-6 * e.pdf_dir);
        for (a, b) in inverse.u.iter().zip([0.1, 0.2, 0.3, 0.4, 0.5]).skip(1) {
            assert!((a - b).abs() < 1e-4);
        }
    }
}
