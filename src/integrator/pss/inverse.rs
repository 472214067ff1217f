//! Inverse sampling techniques S_j⁻¹ (Bitterli et al. 2017, Sec. 4–6): from a complete path, the
//! primary samples that BDPT technique j = (s, t) of MMLT's evaluation (`mlt.rs`) would have read
//! to produce exactly that path.
//!
//! A technique is a random walk of low-dimensional sampling steps (Eq. 39), so its inverse is an
//! "inverse random walk" over the same steps, each inverted by the routine that sits beside its
//! sampler:
//!
//! | step | stream, dimensions | inverse |
//! | --- | --- | --- |
//! | film position of the primary ray | camera `[0, 2)` | `Camera::invert_film` (exact) |
//! | BSDF lobe and direction at camera vertex i | camera block `i − 1` | `Material::invert` (Eq. 41/44) |
//! | Russian roulette | last number of each block | unused (no roulette in MLT): γ, Eq. 40 |
//! | light selection | light `0` / connection `0` | `LightSampler::invert` (interval, Eq. 40) |
//! | emitter point and emission direction | light `[1, 6)` | `Light::invert_emission` |
//! | BSDF at light vertex j | light block `j − 1` | `Material::invert` (importance transport) |
//! | emitter point of next-event estimation (s = 1) | connection `[1, 4)` | `Light::invert_li` |
//!
//! Numbers the technique reads but does not use (the film of a t = 1 technique, the whole light
//! stream start of an s = 1 technique, the direction of a delta lobe, the roulette number) are
//! drawn uniformly: the unit-Jacobian case of Eq. 40. Every ambiguous choice (which light, which
//! lobe, where inside a discrete interval) is resampled with fresh uniforms γ, which makes this a
//! probabilistic inverse (Sec. 5): the jump's acceptance then follows Eq. 38 with the lobe-choice
//! correction of Eq. 43, which the lobe choice T(t) of Eq. 44 (`Material::invert`) cancels.
//!
//! Every step also returns the Jacobian of its inverse, and the walk multiplies them (Eq. 39 turns
//! |J[S⁻¹]| into a product over the steps), with the ray-casting factor |cos θ|/d² wherever a
//! sampled direction meets the next vertex, into `InvertedSamples::jacobian` (uniforms per unit
//! of the technique's path measure: area at every vertex whose position a density chose, solid
//! angle for a vertex at infinity; a vertex reached through a delta lobe is no coordinate of its
//! own and counts by the lobe's discrete mass). Divided by the lobe choices Π T(t), it must be
//! the technique's path density p_j(x̄) as BDPT computes it (Eq. 27–29: |J[h_ij]| = p_j/p_i); the
//! tests check exactly that.

use glam::Vec3;

use crate::integrator::bdpt::{Vertex, VertexKind, BOUNCE_DIMS, CONNECTION_DIMS, LIGHT_START_DIMS};
use crate::light::{triangle_barycentrics, Light};
use crate::material::{TransportMode, BSDF_INVERT_DIMS, BSDF_SAMPLE_DIMS};
use crate::sampling::Rng;
use crate::scene::Scene;

/// Relative distance (to the adjacent segments' lengths) within which a path regenerated from its
/// inverted primary samples counts as the same path. The round trip loses a few f32 ulps per
/// vertex (direction maps, ray offsets), amplified along the walk; a different surface hit or a
/// missed one is off by a whole segment.
const SAME_PATH_TOLERANCE: f32 = 1e-3;

/// Why a path could not be turned back into primary samples. A jump whose inverse fails is
/// rejected and counted under its reason.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InversionFailure {
    /// The primary ray's direction misses the film.
    Film,
    /// No BSDF lobe can produce the path's direction at a vertex (wrong hemisphere, not the delta
    /// direction, a numerically degenerate pair).
    Bsdf,
    /// The emitter vertex carries no light, or a light of zero selection probability.
    LightSelection,
    /// The emitter point or direction cannot be produced by the emitter's sampler (off the mesh,
    /// behind a one-sided emitter).
    Emitter,
    /// The path does not have the shape the technique needs (too short, t = 0).
    Shape,
}

impl InversionFailure {
    pub fn name(self) -> &'static str {
        match self {
            InversionFailure::Film => "film",
            InversionFailure::Bsdf => "bsdf",
            InversionFailure::LightSelection => "light_selection",
            InversionFailure::Emitter => "emitter",
            InversionFailure::Shape => "shape",
        }
    }

    pub const ALL: [InversionFailure; 5] = [
        InversionFailure::Film,
        InversionFailure::Bsdf,
        InversionFailure::LightSelection,
        InversionFailure::Emitter,
        InversionFailure::Shape,
    ];
}

/// The primary samples of the three streams a technique reads, in reading order, and the
/// Jacobian factors of the inverse that produced them.
#[derive(Clone, Debug, PartialEq)]
pub struct InvertedSamples {
    pub camera: Vec<f32>,
    pub light: Vec<f32>,
    pub connection: Vec<f32>,
    /// |J[S_j⁻¹](x̄, γ̄)| of Eq. 38: the product of every step's |J[g_l⁻¹]| (Eq. 39; Eq. 42 for a
    /// lobe mixture, α_t |J[g_t⁻¹]|; Eq. 40 for a discrete choice, its interval's length) and of
    /// the ray-casting Jacobians, in uniforms per unit path measure (see the module docs).
    pub jacobian: f64,
    /// Π T(t) of Eq. 44 over the BSDF steps: the probability of the branches this probabilistic
    /// inverse chose. Eq. 43 divides the Jacobian by it.
    pub branch_choice: f64,
}

impl Default for InvertedSamples {
    fn default() -> InvertedSamples {
        InvertedSamples {
            camera: Vec::new(),
            light: Vec::new(),
            connection: Vec::new(),
            jacobian: 1.0,
            branch_choice: 1.0,
        }
    }
}

impl InvertedSamples {
    /// |J[S_j⁻¹]| / Π T(t): with the lobe choice of Eq. 44 this is the technique's path density
    /// p_j(x̄), which the acceptance of Eq. 38/43 needs.
    pub fn density(&self) -> f64 {
        self.jacobian / self.branch_choice
    }

    fn multiply(&mut self, step: StepFactors) {
        self.jacobian *= step.jacobian;
        self.branch_choice *= step.branch_choice;
    }
}

/// S_j⁻¹ for the technique with `s` light vertices on `path` (camera first, emitter last, as
/// `bdpt::full_path` builds it), with fresh uniforms from `rng` for every ambiguous number. The
/// result has exactly as many numbers per stream as MMLT's evaluation of (s, t) reads:
/// camera 2 + 4·(t − 2) (2 when t = 1), light 6 + 4·(s − 2) (6 when s = 1, none when s = 0),
/// connection 4 when s = 1 and t ≥ 2.
pub fn invert_technique(
    scene: &Scene,
    path: &[Vertex],
    s: usize,
    rng: &mut Rng,
) -> Result<InvertedSamples, InversionFailure> {
    let n = path.len();
    if n < 2 || s >= n {
        return Err(InversionFailure::Shape);
    }
    let t = n - s;
    let mut out = InvertedSamples::default();

    // Camera stream: the film position, then one block per camera vertex that was extended.
    if t >= 2 {
        let film = scene.camera.invert_ray(path[0].dir_to(&path[1])).ok_or(InversionFailure::Film)?;
        out.camera.extend(film.u);
        out.jacobian *= f64::from(film.jacobian) * ray_cast_jacobian(&path[0], &path[1]);
        for i in 1..t - 1 {
            let step = invert_bounce(
                scene,
                &path[i],
                &path[i - 1],
                &path[i + 1],
                TransportMode::Radiance,
                rng,
                &mut out.camera,
            )?;
            out.multiply(step);
        }
    } else {
        out.camera.extend([rng.uniform(), rng.uniform()]);
    }

    // Light stream: selection and emission, then one block per light vertex that was extended.
    let emitter = &path[n - 1];
    if s >= 2 {
        let (light_index, light) = emitter_light(scene, emitter)?;
        select_light(scene, light_index, rng, &mut out.light, &mut out.jacobian)?;
        let next = &path[n - 2];
        let dir = emitter.dir_to(next);
        // For an environment the inverse projects any point of the ray onto its emission disk.
        let (prim, p) = if emitter.infinite { (0, next.p) } else { (emitter_triangle(light, emitter.p)?, emitter.p) };
        let emission = light.invert_emission(prim, p, dir, rng.uniform()).ok_or(InversionFailure::Emitter)?;
        out.light.extend(emission.u);
        out.jacobian *= f64::from(emission.jacobian_pos) * f64::from(emission.jacobian_dir);
        out.jacobian *= if emitter.infinite {
            // The measure of a vertex at infinity is its direction; the origin's density on the
            // disk perpendicular to it becomes an area density at `next` by the cosine alone.
            if next.on_surface() {
                f64::from(next.ng.dot(dir).abs())
            } else {
                1.0
            }
        } else {
            ray_cast_jacobian(emitter, next)
        };
        for j in 1..s - 1 {
            let v = &path[n - 1 - j];
            let step = invert_bounce(
                scene,
                v,
                &path[n - j],
                &path[n - 2 - j],
                TransportMode::Importance,
                rng,
                &mut out.light,
            )?;
            out.multiply(step);
        }
    } else if s == 1 {
        // The light subpath's start is read but next-event estimation replaces it (Eq. 40, unit).
        out.light.extend((0..LIGHT_START_DIMS).map(|_| rng.uniform()));
    }

    // Connection stream: next-event estimation's light selection and emitter point (s = 1).
    if s == 1 && t >= 2 {
        let (light_index, light) = emitter_light(scene, emitter)?;
        select_light(scene, light_index, rng, &mut out.connection, &mut out.jacobian)?;
        let reference = &path[n - 2];
        let wi = reference.dir_to(emitter);
        let prim = if emitter.infinite { 0 } else { emitter_triangle(light, emitter.p)? };
        let point = light.invert_li(wi, prim, emitter.p, rng.uniform()).ok_or(InversionFailure::Emitter)?;
        out.connection.extend(point.u);
        // Per unit area of the emitter point (solid angle for an environment): the measure of the
        // path's last vertex, so no ray-casting factor.
        out.jacobian *= f64::from(point.jacobian);
        debug_assert_eq!(out.connection.len(), CONNECTION_DIMS);
    }
    Ok(out)
}

/// The Jacobian of one scattering step's inverse and the probability T(t) of the lobe it chose.
#[derive(Clone, Copy, Debug)]
struct StepFactors {
    jacobian: f64,
    branch_choice: f64,
}

/// Inverts the scattering at `v` from the direction towards `previous` (its subpath's predecessor)
/// to the direction towards `next`, appending the bounce block (BSDF numbers, then roulette).
fn invert_bounce(
    scene: &Scene,
    v: &Vertex,
    previous: &Vertex,
    next: &Vertex,
    mode: TransportMode,
    rng: &mut Rng,
    out: &mut Vec<f32>,
) -> Result<StepFactors, InversionFailure> {
    if v.infinite {
        return Err(InversionFailure::Shape);
    }
    let material = v.bsdf(scene);
    let wo = v.frame.to_local(v.dir_to(previous));
    let wi = v.frame.to_local(v.dir_to(next));
    let gamma: [f32; BSDF_INVERT_DIMS] = std::array::from_fn(|_| rng.uniform());
    let inverse = material.invert(wo, wi, mode, gamma).ok_or(InversionFailure::Bsdf)?;
    out.extend(inverse.u);
    // Eq. 42: α_t |J[g_t⁻¹]| per unit solid angle, or the discrete mass α_t of a delta lobe, whose
    // direction fixes `next` (no ray-casting factor: `next` is no coordinate of the path then).
    let ray_cast = if inverse.delta { 1.0 } else { ray_cast_jacobian(v, next) };
    let factors = StepFactors {
        jacobian: f64::from(inverse.jacobian) * ray_cast,
        branch_choice: f64::from(inverse.lobe_choice_prob),
    };
    // MLT runs without Russian roulette, so the block's last number is unused (Eq. 40, unit).
    out.extend((BSDF_SAMPLE_DIMS..BOUNCE_DIMS).map(|_| rng.uniform()));
    Ok(factors)
}

/// The light at an emitter vertex (a sampled emitter point, an emissive surface reached by the
/// camera subpath, or the environment).
fn emitter_light<'a>(scene: &'a Scene, v: &Vertex) -> Result<(usize, &'a Light), InversionFailure> {
    let index = v.light.ok_or(InversionFailure::LightSelection)? as usize;
    let light = scene.lights.get(index).ok_or(InversionFailure::LightSelection)?;
    Ok((index, light))
}

/// Light selection's probabilistic inverse (Eq. 40): appends u to `out`, multiplies `jacobian` by
/// the interval's length.
fn select_light(
    scene: &Scene,
    index: usize,
    rng: &mut Rng,
    out: &mut Vec<f32>,
    jacobian: &mut f64,
) -> Result<(), InversionFailure> {
    let (u, interval) = scene.light_sampler.invert(index, rng.uniform()).ok_or(InversionFailure::LightSelection)?;
    out.push(u);
    *jacobian *= f64::from(interval);
    Ok(())
}

/// Jacobian of casting a ray from `from` through the direction towards `to`: solid angle at
/// `from` per unit area at `to`, |cos θ_to| / d² against `to`'s geometric normal (the surface the
/// ray hits); 1 for a vertex at infinity, whose measure is the direction itself.
fn ray_cast_jacobian(from: &Vertex, to: &Vertex) -> f64 {
    if to.infinite {
        return 1.0;
    }
    let w = (to.p - from.p).as_dvec3();
    let d2 = w.length_squared();
    if !(d2 > 0.0) {
        return 0.0;
    }
    let cos = if to.on_surface() { to.ng.as_dvec3().dot(w).abs() / d2.sqrt() } else { 1.0 };
    cos / d2
}

/// The triangle of an area light's mesh that holds `p` (vertices do not record which triangle an
/// emitter point was sampled on). A linear search, in the order the mesh stores its triangles: an
/// emitter is usually a handful of triangles. Points on a shared edge may match either triangle;
/// both give the same point back.
fn emitter_triangle(light: &Light, p: Vec3) -> Result<u32, InversionFailure> {
    let Light::Area(area) = light else { return Ok(0) };
    (0..area.mesh.triangle_count() as u32)
        .find(|&prim| {
            area.triangles.pdf_discrete(prim as usize) > 0.0 && triangle_barycentrics(&area.mesh, prim, p).is_some()
        })
        .ok_or(InversionFailure::Emitter)
}

/// Whether a path regenerated from inverted primary samples is the path it was inverted from:
/// the same number of vertices, each within `SAME_PATH_TOLERANCE` of the shorter adjacent segment
/// (directions for vertices at infinity) and on the same material.
pub fn same_path(a: &[Vertex], b: &[Vertex]) -> bool {
    if a.len() != b.len() || a.is_empty() {
        return false;
    }
    let segment = |path: &[Vertex], k: usize| -> f32 {
        let mut len = f32::INFINITY;
        for m in [k.wrapping_sub(1), k + 1] {
            if let Some(v) = path.get(m) {
                if !v.infinite && !path[k].infinite {
                    len = len.min(v.p.distance(path[k].p));
                }
            }
        }
        len
    };
    a.iter().zip(b).enumerate().all(|(k, (x, y))| {
        if x.infinite != y.infinite || (x.kind != y.kind && k > 0 && k + 1 < a.len()) {
            return false;
        }
        // Two surfaces can meet within the tolerance (a corner): the same point must be on the
        // same material and emitter.
        let on_surface = |v: &Vertex| v.kind == VertexKind::Surface && !v.infinite;
        if on_surface(x) && on_surface(y) && (x.material != y.material || x.light != y.light) {
            return false;
        }
        if x.infinite {
            x.dir.dot(y.dir) >= 1.0 - SAME_PATH_TOLERANCE * SAME_PATH_TOLERANCE
        } else {
            x.p.distance(y.p) <= SAME_PATH_TOLERANCE * segment(b, k)
        }
    })
}

#[cfg(test)]
mod tests;
