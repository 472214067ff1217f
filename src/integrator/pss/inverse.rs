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

use glam::Vec3;

use crate::integrator::bdpt::{Vertex, BOUNCE_DIMS, CONNECTION_DIMS, LIGHT_START_DIMS};
use crate::light::{triangle_barycentrics, Light, EMISSION_SAMPLE_DIMS, LI_SAMPLE_DIMS};
use crate::material::{TransportMode, BSDF_INVERT_DIMS, BSDF_SAMPLE_DIMS};
use crate::sampling::Rng;
use crate::scene::Scene;

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

/// The primary samples of the three streams a technique reads, in reading order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InvertedSamples {
    pub camera: Vec<f32>,
    pub light: Vec<f32>,
    pub connection: Vec<f32>,
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
        let d = path[0].dir_to(&path[1]);
        let raster = scene.camera.raster_of(d).ok_or(InversionFailure::Film)?;
        out.camera.extend(scene.camera.invert_film(raster).ok_or(InversionFailure::Film)?);
        for i in 1..t - 1 {
            invert_bounce(scene, &path[i], &path[i - 1], &path[i + 1], TransportMode::Radiance, rng, &mut out.camera)?;
        }
    } else {
        out.camera.extend([rng.uniform(), rng.uniform()]);
    }

    // Light stream: selection and emission, then one block per light vertex that was extended.
    let emitter = &path[n - 1];
    if s >= 2 {
        let (light_index, light) = emitter_light(scene, emitter)?;
        out.light.push(select_light(scene, light_index, rng)?);
        let next = &path[n - 2];
        let dir = emitter.dir_to(next);
        // For an environment the inverse projects any point of the ray onto its emission disk.
        let (prim, p) = if emitter.infinite { (0, next.p) } else { (emitter_triangle(light, emitter.p)?, emitter.p) };
        let u: [f32; EMISSION_SAMPLE_DIMS] =
            light.invert_emission(prim, p, dir, rng.uniform()).ok_or(InversionFailure::Emitter)?;
        out.light.extend(u);
        for j in 1..s - 1 {
            let v = &path[n - 1 - j];
            invert_bounce(scene, v, &path[n - j], &path[n - 2 - j], TransportMode::Importance, rng, &mut out.light)?;
        }
    } else if s == 1 {
        // The light subpath's start is read but next-event estimation replaces it (Eq. 40, unit).
        out.light.extend((0..LIGHT_START_DIMS).map(|_| rng.uniform()));
    }

    // Connection stream: next-event estimation's light selection and emitter point (s = 1).
    if s == 1 && t >= 2 {
        let (light_index, light) = emitter_light(scene, emitter)?;
        out.connection.push(select_light(scene, light_index, rng)?);
        let reference = &path[n - 2];
        let wi = reference.dir_to(emitter);
        let prim = if emitter.infinite { 0 } else { emitter_triangle(light, emitter.p)? };
        let u: [f32; LI_SAMPLE_DIMS] =
            light.invert_li(wi, prim, emitter.p, rng.uniform()).ok_or(InversionFailure::Emitter)?;
        out.connection.extend(u);
        debug_assert_eq!(out.connection.len(), CONNECTION_DIMS);
    }
    Ok(out)
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
) -> Result<(), InversionFailure> {
    if v.infinite {
        return Err(InversionFailure::Shape);
    }
    let material = &scene.materials[v.material as usize];
    let wo = v.frame.to_local(v.dir_to(previous));
    let wi = v.frame.to_local(v.dir_to(next));
    let gamma: [f32; BSDF_INVERT_DIMS] = std::array::from_fn(|_| rng.uniform());
    let inverse = material.invert(wo, wi, mode, gamma).ok_or(InversionFailure::Bsdf)?;
    out.extend(inverse.u);
    // MLT runs without Russian roulette, so the block's last number is unused (Eq. 40, unit).
    out.extend((BSDF_SAMPLE_DIMS..BOUNCE_DIMS).map(|_| rng.uniform()));
    Ok(())
}

/// The light at an emitter vertex (a sampled emitter point, an emissive surface reached by the
/// camera subpath, or the environment).
fn emitter_light<'a>(scene: &'a Scene, v: &Vertex) -> Result<(usize, &'a Light), InversionFailure> {
    let index = v.light.ok_or(InversionFailure::LightSelection)? as usize;
    let light = scene.lights.get(index).ok_or(InversionFailure::LightSelection)?;
    Ok((index, light))
}

/// Light selection's probabilistic inverse (Eq. 40).
fn select_light(scene: &Scene, index: usize, rng: &mut Rng) -> Result<f32, InversionFailure> {
    scene.light_sampler.invert(index, rng.uniform()).ok_or(InversionFailure::LightSelection)
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
