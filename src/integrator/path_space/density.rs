//! Generating one vertex from its neighbour, and the density of having done so, side by side: the
//! building blocks of every mutation's `propose` and `transition`. Densities are per unit area at
//! the new vertex (per unit solid angle for a vertex at infinity), in the delta-stripped convention
//! (module docs, "Measure"): at a specular vertex the lobe's selection probability takes the place
//! of the directional density. The samplers are BDPT's (the pinhole over the whole film, emission,
//! BSDF sampling), so these densities are BDPT's `Vertex::pdf` family, except at delta lobes, which
//! BDPT counts as density 0 (it never connects there) and a mutation must count as their mass.
//!
//! # Light-direction steps through a refraction
//! f strips each specular vertex x_j's δ with respect to the solid angle of the direction towards
//! the light, ω_b = dir(x_j → x_{j+1}) (`contribution`: F/|n_s·ω_b|), and a camera-side walk,
//! which draws ω_b from ω_a = dir(x_j → x_{j−1}), carries the same δ, so its lobe probability is
//! its density in f's measure. A light-side walk draws ω_a from ω_b: its δ is δ_σ(ω_a − R⁻¹(ω_b)),
//! with respect to the solid angle of ω_a. The two are the same distribution on the pair
//! (ω_a, ω_b) written in different variables: δ_σ(ω_a − R⁻¹(ω_b)) = δ_σ(ω_b − R(ω_a)) ·
//! |dσ(ω_b)/dσ(ω_a)|. Reflection keeps solid angle (the factor is 1). Refraction about the
//! shading normal conserves étendue, η_a² |cos θ_a| dσ(ω_a) = η_b² |cos θ_b| dσ(ω_b) (Veach 1997,
//! "Robust Monte Carlo Methods for Light Transport Simulation", Sec. 5.2, Eq. 5.3–5.4: the
//! projected solid angles of the two sides scale by η²), so
//!
//!   h = |dσ(ω_b)/dσ(ω_a)| = η_a² |cos θ_a| / (η_b² |cos θ_b|),
//!
//! η_a and η_b the indices of the media the segments towards the camera and towards the light lie
//! in, θ from the shading normal the material refracts about ([`refraction_measure_factor`]). A
//! light-direction step's density in f's measure is its lobe probability times h
//! ([`density_next`] with `Side::Light`; `retrace::retrace_jacobian` towards the camera). Along a
//! chord of a sphere or through a parallel slab the factors of entry and exit cancel; a lamp
//! inside glass of index 1.5 seen at normal incidence has h = 1/2.25.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN densities along with zero and negative ones.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::Vec3;

use crate::geometry::{spawn_ray, Ray};
use crate::integrator::bdpt::{Vertex, VertexKind};
use crate::light::{sample_emission_direction, Light};
use crate::material::{Material, TransportMode};
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::spectrum::Rgb;
use crate::stats::Counters;

/// Which end of the path a walk grows from: the camera (radiance transport, towards the light) or
/// the emitter (importance transport, towards the camera).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Camera,
    Light,
}

impl Side {
    fn mode(self) -> TransportMode {
        match self {
            Side::Camera => TransportMode::Radiance,
            Side::Light => TransportMode::Importance,
        }
    }
}

/// The first surface along `ray`, as a vertex reached from the walk's previous vertex; for a camera
/// walk that leaves the scene, the environment as a vertex at infinity (if the scene has one).
pub(super) fn trace(scene: &Scene, ray: &Ray, side: Side, counters: &mut Counters) -> Option<Vertex> {
    counters.rays += 1;
    match scene.intersect(ray) {
        Some(si) => Some(Vertex::surface(scene, &si, -ray.d, Rgb::ONE, side.mode())),
        None if side == Side::Camera && scene.environment.is_some() => {
            Some(Vertex::escaped(scene.environment, ray.d, Rgb::ONE, 0.0))
        }
        None => None,
    }
}

/// Samples the vertex that follows `from` on `side`, `prev` being the vertex before `from` on the
/// same side (None at the pinhole and at an emitter point). Returns None when the sample fails or
/// the ray leaves the scene without an environment to meet. The densities are [`density_next`].
///
/// - the pinhole: a raster position uniform over the whole film (BDPT's `FilmRegion::WholeFilm`);
/// - an emitter point (the light vertex kept by a mutation): a cosine-weighted emission direction;
///   a kept environment vertex cannot be continued (its ray's origin on the scene's disk is not
///   part of the vertex), which [`density_next`] reports as density 0;
/// - a surface: its BSDF (a delta lobe by its selection probability).
pub fn sample_next(
    scene: &Scene,
    from: &Vertex,
    prev: Option<&Vertex>,
    side: Side,
    rng: &mut Rng,
    counters: &mut Counters,
) -> Option<Vertex> {
    let ray = match from.kind {
        VertexKind::Camera => {
            let u = [rng.uniform(), rng.uniform()];
            scene.camera.sample_ray(u)
        }
        VertexKind::Light => {
            let Some(Light::Area(area)) = from.light.map(|l| &scene.lights[l as usize]) else { return None };
            if from.infinite {
                return None;
            }
            let dir = sample_emission_direction(from.ng, area.two_sided, [rng.uniform(), rng.uniform()]);
            spawn_ray(from.p, from.p_error, from.ng, dir)
        }
        VertexKind::Surface => {
            let prev = prev?;
            if from.infinite {
                return None;
            }
            let material = from.bsdf(scene);
            let wo = from.frame.to_local(from.dir_to(prev));
            let u = [rng.uniform(), rng.uniform(), rng.uniform()];
            let bs = material.sample(wo, u, side.mode())?;
            if !(bs.pdf > 0.0) {
                return None;
            }
            let wi = from.frame.to_world(bs.wi).normalize();
            spawn_ray(from.p, from.p_error, from.ng, wi)
        }
    };
    trace(scene, &ray, side, counters)
}

/// Area density (solid angle for a vertex at infinity) at `next` of [`sample_next`] producing it
/// from `from` with predecessor `prev` on `side`, in f's measure: a light-side step through a
/// refraction carries the factor h of the module docs.
pub fn density_next(scene: &Scene, from: &Vertex, prev: Option<&Vertex>, next: &Vertex, side: Side) -> f64 {
    let mut measure = 1.0;
    let pdf = match from.kind {
        VertexKind::Camera => scene.camera.pdf_we(from.dir_to(next)).1,
        VertexKind::Light => {
            if from.infinite {
                return 0.0;
            }
            // The emission direction's density, already converted to area at `next`.
            return from.pdf_light(scene, next) as f64;
        }
        VertexKind::Surface => {
            let Some(prev) = prev else { return 0.0 };
            if from.infinite {
                return 0.0;
            }
            let material = from.bsdf(scene);
            let wo = from.frame.to_local(from.dir_to(prev));
            let wi = from.frame.to_local(from.dir_to(next));
            if material.is_specular() {
                if side == Side::Light {
                    // `prev` is the light-side neighbour, `next` the camera-side one.
                    measure = refraction_measure_factor(&material.material, wi, wo);
                }
                material.pdf_delta(wo, wi)
            } else {
                // BSDF densities do not depend on the transport mode.
                material.pdf(wo, wi, side.mode())
            }
        }
    };
    if !(pdf > 0.0) {
        return 0.0;
    }
    from.convert_density(pdf, next) as f64 * measure
}

/// The factor h = η_a² |cos θ_a| / (η_b² |cos θ_b|) that turns a light-side walk's density at a
/// specular vertex into f's measure (module docs), for the local directions `towards_camera` (ω_a)
/// and `towards_light` (ω_b) in the shading frame the material refracts about: 1 for reflection
/// (both directions on one side) and for every material but the smooth dielectric, whose outside
/// (+z, the side the geometric normal points to) has index 1 and inside index `ior`.
pub fn refraction_measure_factor(material: &Material, towards_camera: Vec3, towards_light: Vec3) -> f64 {
    let Material::Dielectric { ior } = *material else { return 1.0 };
    let (cos_a, cos_b) = (towards_camera.z as f64, towards_light.z as f64);
    if !(cos_a * cos_b < 0.0) {
        return 1.0;
    }
    let eta = |cos: f64| if cos > 0.0 { 1.0 } else { ior as f64 };
    eta(cos_a).powi(2) * cos_a.abs() / (eta(cos_b).powi(2) * cos_b.abs())
}

/// [`refraction_measure_factor`] at the specular path vertex `v` between its camera-side
/// neighbour `camera_side` and its light-side neighbour `light_side` (1 at a non-specular `v`).
pub fn light_step_measure_factor(scene: &Scene, v: &Vertex, camera_side: &Vertex, light_side: &Vertex) -> f64 {
    let material = v.bsdf(scene);
    if !material.is_specular() {
        return 1.0;
    }
    let towards_camera = v.frame.to_local(v.dir_to(camera_side));
    let towards_light = v.frame.to_local(v.dir_to(light_side));
    refraction_measure_factor(&material.material, towards_camera, towards_light)
}

/// A new emitter vertex for a light walk that starts from scratch (the mutation deleted the light
/// vertex): a light chosen by power and an emitted ray from it, as BDPT's light subpaths start.
/// Returns the vertex and the emitted ray (which the walk's next step follows: for an environment
/// its origin lies on the scene's disk, which the vertex at infinity does not keep).
pub fn sample_emitter(scene: &Scene, rng: &mut Rng) -> Option<(Vertex, Ray)> {
    let distribution = &scene.light_sampler.distribution;
    if distribution.is_empty() || scene.lights.is_empty() {
        return None;
    }
    let (li, pmf, _) = distribution.sample_discrete(rng.uniform());
    if !(pmf > 0.0) || li >= scene.lights.len() {
        return None;
    }
    let u = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
    let es = scene.lights[li].sample_emission(u)?;
    if !(es.pdf_pos > 0.0) || !(es.pdf_dir > 0.0) {
        return None;
    }
    let v = if es.infinite {
        Vertex::environment_light(li as u32, es.dir, Rgb::ONE, 0.0)
    } else {
        Vertex::area_light(li as u32, es.p, es.n, Rgb::ONE, 0.0)
    };
    let ray = if es.infinite { Ray::new(es.p, es.dir) } else { spawn_ray(es.p, v.p_error, es.n, es.dir) };
    Some((v, ray))
}

/// Follows the emitted ray of [`sample_emitter`] to the walk's next vertex.
pub fn trace_emitted(scene: &Scene, ray: &Ray, counters: &mut Counters) -> Option<Vertex> {
    trace(scene, ray, Side::Light, counters)
}

/// Density of [`sample_emitter`] choosing the emitter vertex `v` (area measure on an area light,
/// solid angle for an environment direction): BDPT's `pdf_light_origin`, light selection included.
pub fn density_emitter(scene: &Scene, v: &Vertex) -> f64 {
    // `pdf_light_origin` reads its second argument only for an environment's reference point,
    // which its direction density ignores.
    let reference = Vertex::camera(Vec3::ZERO, Rgb::ONE);
    v.pdf_light_origin(scene, &reference) as f64
}

/// Density at `next` of the emitted ray of [`sample_emitter`] from the new emitter vertex `v`:
/// the direction's density converted to area (area lights) or the ray origin's density on the disk
/// times the cosine at `next` (environments): BDPT's `pdf_light`.
pub fn density_emitted(scene: &Scene, v: &Vertex, next: &Vertex) -> f64 {
    v.pdf_light(scene, next) as f64
}

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};

    use super::refraction_measure_factor;
    use crate::geometry::Frame;
    use crate::material::{Material, TransportMode};

    const GLASS: Material = Material::Dielectric { ior: 1.5 };

    /// The production refraction (`Material::sample`'s refraction lobe) of the unit world direction
    /// `w` (pointing away from the surface, on either side) about the unit normal `n`: the other
    /// side's direction, or None under total internal reflection.
    fn refract(material: &Material, n: Vec3, w: Vec3) -> Option<Vec3> {
        let frame = Frame::from_normal(n);
        let wo = frame.to_local(w);
        let probs = material.lobe_probabilities(wo);
        let s = material.sample(wo, [probs[0] + 0.5 * probs[1], 0.5, 0.5], TransportMode::Radiance)?;
        (s.delta && s.wi.z * wo.z < 0.0).then(|| frame.to_world(s.wi).normalize())
    }

    /// h at a refracting vertex with unit normal `n`, between the world directions towards the
    /// camera and towards the light.
    fn h(n: Vec3, towards_camera: Vec3, towards_light: Vec3) -> f64 {
        let frame = Frame::from_normal(n);
        refraction_measure_factor(&GLASS, frame.to_local(towards_camera), frame.to_local(towards_light))
    }

    /// |dσ(ω_b)/dσ(ω_a)| of the refraction map ω_a ↦ ω_b about the +z normal, by central finite
    /// differences of `refract` (the solid angle of the image of a small patch over the patch's):
    /// an estimate of h that does not use its closed form.
    fn numerical_jacobian(wa: Vec3) -> f64 {
        let frame = Frame::from_normal(wa);
        let map = |x: f64, y: f64| -> DVec3 {
            let w = (wa.as_dvec3() + x * frame.s.as_dvec3() + y * frame.t.as_dvec3()).normalize();
            refract(&GLASS, Vec3::Z, w.as_vec3()).expect("no total internal reflection").as_dvec3()
        };
        let e = 1e-3;
        let (dx, dy) = ((map(e, 0.0) - map(-e, 0.0)) / (2.0 * e), (map(0.0, e) - map(0.0, -e)) / (2.0 * e));
        // The patch dx·dy at wa has solid angle dx·dy (the tangent offsets are orthonormal, to first
        // order in e); its image spans |∂ω_b/∂x × ∂ω_b/∂y| (projected on ω_b, which it is normal to).
        dx.cross(dy).dot(map(0.0, 0.0)).abs()
    }

    /// One interface, both ways: a lamp inside η = 1.5 glass seen from the air at normal incidence
    /// has h = 1/2.25 and the reverse step 2.25; at oblique exit h falls below 1/2.25; h of the
    /// reverse pair is 1/h; reflection and every other material give 1; and h is the solid-angle
    /// Jacobian of the production refraction (finite differences, relative error < 1e-3 from the
    /// f32 directions and the O(e²) difference quotient).
    #[test]
    fn refraction_measure_factor_at_one_interface() {
        let up = Vec3::Z;
        let down = -Vec3::Z;
        let normal = refraction_measure_factor(&GLASS, up, down);
        assert!((normal - 1.0 / 2.25).abs() < 1e-7, "{normal}");
        let inward = refraction_measure_factor(&GLASS, down, up);
        assert!((inward - 2.25).abs() < 1e-6, "{inward}");
        for degrees in [10.0f32, 30.0, 40.0] {
            let t = degrees.to_radians();
            let inside = Vec3::new(t.sin(), 0.0, -t.cos());
            let outside = refract(&GLASS, up, inside).expect("inside the critical angle");
            let exit = refraction_measure_factor(&GLASS, outside, inside);
            let expected = (outside.z as f64) / (2.25 * (t.cos() as f64));
            assert!((exit - expected).abs() < 1e-6 * expected, "{degrees}°: {exit} vs {expected}");
            assert!(exit < normal, "{degrees}°: h = {exit} does not fall at oblique exit");
            let entry = refraction_measure_factor(&GLASS, inside, outside);
            assert!((exit * entry - 1.0).abs() < 1e-6, "{degrees}°: h · h_reverse = {}", exit * entry);
            let jacobian = numerical_jacobian(outside);
            assert!((jacobian / exit - 1.0).abs() < 1e-3, "{degrees}°: Jacobian {jacobian} vs h {exit}");
        }
        let oblique = Vec3::new(0.6, 0.0, 0.8);
        assert_eq!(refraction_measure_factor(&GLASS, oblique, Vec3::new(-0.6, 0.0, 0.8)), 1.0);
        let rough = Material::RoughDielectric { alpha: 0.2, ior: 1.5 };
        assert_eq!(refraction_measure_factor(&rough, oblique, -oblique), 1.0);
        let mirror = Material::Mirror { reflectance: crate::spectrum::Rgb::ONE };
        assert_eq!(refraction_measure_factor(&mirror, oblique, Vec3::new(-0.6, 0.0, 0.8)), 1.0);
    }

    /// A ray through a body of glass, entering at `p1` (outward normal `n1`) along the unit `d`
    /// and leaving at the point and outward normal `exit` gives for the refracted ray: Π h over the
    /// two refractions of the path camera → entry → exit → light (light arriving along the ray's
    /// reverse), and the same for the path traversed the other way (camera behind the exit).
    fn chord_product(n1: Vec3, d: Vec3, exit: impl Fn(Vec3) -> (Vec3, Vec3)) -> (f64, f64) {
        let inside = refract(&GLASS, n1, -d).expect("enters");
        let (_, n2) = exit(inside);
        let out = refract(&GLASS, n2, -inside).expect("leaves");
        let forward = h(n1, -d, inside) * h(n2, -inside, out);
        let backward = h(n2, out, -inside) * h(n1, inside, -d);
        (forward, backward)
    }

    /// Π h = 1 along every chord of a sphere and through a parallel slab (the entry's and exit's
    /// angles inside are equal), in both directions; through a prism's two non-parallel faces it
    /// is not 1 (the scenes that can see a missing h need such a pair).
    #[test]
    fn refraction_measure_factors_cancel_along_a_sphere_chord_and_through_a_slab() {
        for (i, d) in
            [Vec3::new(0.3, 0.1, -1.0), Vec3::new(-0.2, 0.5, -1.0), Vec3::new(0.05, -0.7, -1.0)].into_iter().enumerate()
        {
            let d = d.normalize();
            // Unit sphere at the origin, hit by a ray aimed at a point off its centre.
            let o = Vec3::new(0.3 * i as f32 - 0.3, 0.4, 0.0) - 3.0 * d;
            let b = o.dot(d);
            let t = -b - (b * b - o.length_squared() + 1.0).sqrt();
            let p1 = o + t * d;
            let sphere_exit = |w: Vec3| {
                let p2 = p1 + (-2.0 * p1.dot(w)) * w;
                (p2, p2.normalize())
            };
            let (forward, backward) = chord_product(p1.normalize(), d, sphere_exit);
            assert!((forward - 1.0).abs() < 1e-5 && (backward - 1.0).abs() < 1e-5, "sphere: {forward}, {backward}");
            // A slab between z = 0 (outward normal +z) and z = −1 (outward normal −z).
            let slab_exit = |_: Vec3| (Vec3::ZERO, -Vec3::Z);
            let (forward, backward) = chord_product(Vec3::Z, d, slab_exit);
            assert!((forward - 1.0).abs() < 1e-5 && (backward - 1.0).abs() < 1e-5, "slab: {forward}, {backward}");
            // A prism: entry through +z, exit through a face tilted by 30°.
            let tilted = Vec3::new(0.5, 0.0, -(0.75f32).sqrt());
            let (forward, backward) = chord_product(Vec3::Z, d, |_| (Vec3::ZERO, tilted));
            assert!((forward - 1.0).abs() > 0.01 && (forward * backward - 1.0).abs() < 1e-5, "prism: {forward}");
        }
    }
}
