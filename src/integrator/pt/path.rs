//! The path loop of [`PathTracer`], tuned: the estimator of `oracle`, with the same numbers drawn
//! in the same order and the same sums in the same order, but with its uniforms drawn and its
//! shadow rays traced where they overlap the cache misses of the next hit (the comments say which
//! and by how much).

use glam::Vec3;

use super::{bsdf_uniforms, choose_light, light_point_uniforms, russian_roulette, Mis, PathTracer};
use crate::geometry::{Hit, Ray, SurfaceInteraction};
use crate::material::{Bsdf, BsdfSample, TransportMode};
use crate::sampling::UniformSource;
use crate::scene::Scene;
use crate::spectrum::{is_finite, Rgb};
use crate::stats::Counters;

impl PathTracer {
    /// Radiance arriving along `ray` (one camera path). Non-finite contributions are dropped and
    /// counted; rays and shadow rays are counted. Every bounce reads two blocks of four numbers
    /// from `rng`: the light sample's, then the BSDF sample's three and Russian roulette's one
    /// (their lanes: `choose_light`, `light_point_uniforms`, `bsdf_uniforms`).
    pub fn li(&self, scene: &Scene, ray: Ray, rng: &mut impl UniformSource, counters: &mut Counters) -> Rgb {
        self.li_camera_path(scene, ray, None, rng, counters)
    }

    /// [`Self::li`] for a camera ray whose closest hit `hit` (`Scene::hits_coherent`) was traced
    /// already, with other camera rays in a packet: given the same hit, the same path and the same
    /// numbers.
    pub fn li_from_hit(
        &self,
        scene: &Scene,
        ray: Ray,
        hit: Option<Hit>,
        rng: &mut impl UniformSource,
        counters: &mut Counters,
    ) -> Rgb {
        self.li_camera_path(scene, ray, Some(hit), rng, counters)
    }

    #[inline(always)]
    fn li_camera_path(
        &self,
        scene: &Scene,
        ray: Ray,
        first_hit: Option<Option<Hit>>,
        rng: &mut impl UniformSource,
        counters: &mut Counters,
    ) -> Rgb {
        let start =
            PathState { beta: Rgb::ONE, eta_scale: 1.0, specular_bounce: true, prev_pdf: 0.0, prev_p: ray.o, depth: 0 };
        if self.settings.first_bounce_paths > 1 {
            self.trace::<true>(scene, ray, first_hit, start, rng, counters)
        } else {
            self.trace::<false>(scene, ray, first_hit, start, rng, counters)
        }
    }

    /// The path from `ray` on, its state at the vertex `ray` leaves being `start`; with `SPLITS`,
    /// split into `first_bounce_paths` paths at its first vertex (depth 1). Unsplit paths get
    /// their own copy of the loop without the split's bookkeeping. `first_hit`, when given, is
    /// `ray`'s closest hit, traced already.
    #[allow(clippy::too_many_arguments)]
    fn trace<const SPLITS: bool>(
        &self,
        scene: &Scene,
        mut ray: Ray,
        mut first_hit: Option<Option<Hit>>,
        start: PathState,
        rng: &mut impl UniformSource,
        counters: &mut Counters,
    ) -> Rgb {
        let mut l = Rgb::ZERO;
        let PathState { mut beta, mut eta_scale, mut specular_bounce, mut prev_pdf, mut prev_p, mut depth } = start;
        let use_nee = self.settings.mis != Mis::BsdfOnly && !scene.lights.is_empty();
        // The first vertex, kept for the split's other branches (traced after this one ends).
        let mut split_vertex: Option<SplitVertex> = None;

        let add = |l: &mut Rgb, c: Rgb, counters: &mut Counters| {
            if is_finite(c) {
                *l += c;
            } else {
                counters.nonfinite_dropped += 1;
            }
        };

        // The previous vertex's shadow ray and what it adds if unoccluded, traced only after the next
        // closest hit: `Scene::hit` has by then asked for the new triangle's indices, and the
        // shadow query (which needs nothing of the new hit) runs while they arrive instead of the
        // path stalling on them (the dependent index-then-vertex misses were ~13% of the bench
        // scene's pt time). Traced before anything else is added to `l`, so the sums are the same
        // numbers in the same order as tracing it at its own vertex: the image is bit for bit the
        // same.
        let mut pending_shadow: Option<(Ray, Rgb)> = None;
        let resolve = |pending: &mut Option<(Ray, Rgb)>, l: &mut Rgb, counters: &mut Counters| {
            if let Some((shadow, c)) = pending.take() {
                if !scene.occluded(&shadow) {
                    add(l, c, counters);
                }
            }
        };

        loop {
            counters.rays += 1;
            let hit = match first_hit.take() {
                Some(hit) => {
                    if let Some(hit) = &hit {
                        scene.prefetch_hit(hit);
                    }
                    hit
                }
                None => scene.hit(&ray),
            };
            // On a surface whose BSDF reads bitmap texels, the pending shadow ray waits until the
            // interaction gives the uv and the texels are asked for: it then covers their misses
            // (about 13% of the door's time) instead of the indices'. Either way it is resolved
            // before this vertex adds anything, so the sums are unchanged.
            let shadow_after_texels = matches!(&hit, Some(h) if !scene.masked && scene.reads_texels(h.geom_id));
            if !shadow_after_texels {
                resolve(&mut pending_shadow, &mut l, counters);
            }
            // The vertex's two blocks of uniforms (light sample; BSDF sample and roulette) are
            // drawn here, between the hit and the read of its triangle, so that the Sobol
            // arithmetic overlaps the two dependent cache misses of `interaction` (the indices,
            // then the vertices they name): the same numbers in the same order as drawing them
            // where they are used. Only where a vertex is sure to draw them: not at the last depth,
            // and not in masked scenes, where the hit may turn out to be no surface.
            // The light's choice and its point on the emitter do not depend on the shading point
            // either, so they are drawn here too (when NEE is on; at a specular vertex they go
            // unused).
            let early = match &hit {
                Some(hit) if !scene.masked && depth < self.settings.max_depth => {
                    let u_light: [f32; 4] = rng.next_n();
                    scene.prefetch_vertices(hit);
                    let u_bsdf: [f32; 4] = rng.next_n();
                    let light_point = use_nee.then(|| choose_light(scene, u_light));
                    Some((u_light, u_bsdf, light_point))
                }
                _ => None,
            };
            // The path leaves the scene: the environment's emission, weighted against its light
            // sample at the previous vertex.
            let escape = |l: &mut Rgb, counters: &mut Counters| {
                if let Some((index, env)) = scene.environment_light() {
                    let le = env.environment_radiance(ray.d);
                    let w = if specular_bounce {
                        1.0
                    } else {
                        let pdf_light =
                            self.light_pmf(scene, index) * env.pdf_li(prev_p, ray.d, Vec3::ZERO, Vec3::ZERO);
                        self.weight_bsdf_hit(prev_pdf, pdf_light)
                    };
                    if w > 0.0 {
                        add(l, beta * le * w, counters);
                    }
                }
            };
            // Without masks the hit is the surface (`Scene::interaction`'s first case), built here
            // straight into the loop's registers: through `interaction`'s `Option`, the
            // interaction was stored field by field and copied with wider loads that could not
            // be forwarded from those stores (perf annotate: ~10% of the loop's samples).
            let si = match hit {
                Some(hit) if !scene.masked => scene.surface(&hit),
                Some(hit) => match scene.interaction(&ray, &hit) {
                    Some(si) => si,
                    None => {
                        escape(&mut l, counters);
                        break;
                    }
                },
                None => {
                    escape(&mut l, counters);
                    break;
                }
            };
            if shadow_after_texels {
                scene.prefetch_texels(&si);
                resolve(&mut pending_shadow, &mut l, counters);
            }

            if let Some((index, light)) = scene.area_light(&si) {
                let le = light.emitted(si.ng, -ray.d);
                if le != Rgb::ZERO {
                    let w = if specular_bounce {
                        1.0
                    } else {
                        let pdf_light = self.light_pmf(scene, index) * light.pdf_li_nee(prev_p, ray.d, si.p, si.ng);
                        self.weight_bsdf_hit(prev_pdf, pdf_light)
                    };
                    if w > 0.0 {
                        add(&mut l, beta * le * w, counters);
                    }
                }
            }

            if depth == self.settings.max_depth {
                break;
            }
            depth += 1;

            // Next-event estimation (its uniforms are drawn even when unused, so that the stream
            // position depends only on the path's vertices). Nothing is drawn between the two
            // blocks, so drawing both here is drawing them where they are used.
            let (u_light, u_bsdf, light_point) = early.unwrap_or_else(|| (rng.next_n(), rng.next_n(), None));
            let [u0, u1, u2, u_rr] = bsdf_uniforms(read_lanes(&u_bsdf));
            // The light sample needs no texel, so it is taken before the BSDF is looked up: its
            // arithmetic (the spherical rectangle's, the emitter's) then runs while the texels that
            // `prefetch_texels` asked for arrive, instead of after the lookup has waited for them
            // (door CPU time 0.98× of the other order). Same numbers, same image.
            let surface_material = scene.surface_material(&si);
            let light_sample = (use_nee && !surface_material.is_specular()).then(|| {
                let (index, pmf, point) = light_point.unwrap_or_else(|| choose_light(scene, u_light));
                (pmf, scene.lights[index].li_from_point(si.p, &point, light_point_uniforms(u_light)))
            });
            let material = surface_material.bsdf_at(si.uv);
            debug_assert_eq!(material.is_specular(), surface_material.is_specular());
            let frame = si.shading;
            let wo = frame.to_local(-ray.d);
            if let Some((pmf, Some(ls))) = light_sample {
                if ls.pdf > 0.0 && ls.radiance != Rgb::ZERO {
                    let wi = frame.to_local(ls.wi);
                    // f and the BSDF's density together (they share the half vector, D, Λ).
                    let (f, pdf_bsdf) = material.eval_pdf(wo, wi, TransportMode::Radiance);
                    let f = f * wi.z.abs();
                    if f != Rgb::ZERO {
                        let shadow = ls.shadow_ray_from(si.p, si.p_error, si.ng);
                        counters.shadow_rays += 1;
                        let pdf_light = pmf * ls.pdf;
                        let w = self.weight_light_sample(pdf_light, pdf_bsdf);
                        pending_shadow = Some((shadow, beta * f * ls.radiance * (w / pdf_light)));
                    }
                }
            }
            // Splitting (`first_bounce_paths`): this path goes on as branch 0 with 1/n of the
            // throughput; the vertex is kept for the other branches, traced after it. The light
            // sample above is taken once for all of them. Roulette must look at the throughput
            // without the 1/n, so it goes into `eta_scale` too: rolled on the split throughput,
            // each branch would survive its first roll with 1/n of the probability and be
            // reweighted by n, undoing the split (measured on the door: 8 branches then reduced
            // the variance by 9% instead of about 8×).
            if SPLITS && depth == 1 {
                let n = self.settings.first_bounce_paths as f32;
                (beta, eta_scale) = (beta * (1.0 / n), eta_scale * n);
                split_vertex = Some(SplitVertex { material, si, wo, beta, eta_scale });
            }

            // Continue the path by sampling the BSDF.
            let Some((next, bs)) =
                self.scatter(&material, &si, wo, [u0, u1, u2, u_rr], depth, &mut beta, &mut eta_scale, counters)
            else {
                break;
            };
            specular_bounce = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = si.p;
            ray = next;
        }
        resolve(&mut pending_shadow, &mut l, counters);
        if let Some(v) = split_vertex {
            for k in 1..self.settings.first_bounce_paths {
                let c = rng.with_branch(k, |rng| self.trace_branch(scene, &v, rng, counters));
                add(&mut l, c, counters);
            }
        }
        l
    }

    /// Branch k ≥ 1 of a path split at its first vertex `v`: its own BSDF sample there (the first
    /// block of `rng`, the branch's stream; the vertex's light sample was branch 0's, for all), then
    /// the path on from there, unsplit.
    fn trace_branch(
        &self,
        scene: &Scene,
        v: &SplitVertex,
        rng: &mut impl UniformSource,
        counters: &mut Counters,
    ) -> Rgb {
        let u_bsdf = bsdf_uniforms(rng.next_n());
        let (mut beta, mut eta_scale) = (v.beta, v.eta_scale);
        let Some((ray, bs)) = self.scatter(&v.material, &v.si, v.wo, u_bsdf, 1, &mut beta, &mut eta_scale, counters)
        else {
            return Rgb::ZERO;
        };
        let state =
            PathState { beta, eta_scale, specular_bounce: bs.delta, prev_pdf: bs.pdf, prev_p: v.si.p, depth: 1 };
        self.trace::<false>(scene, ray, None, state, rng, counters)
    }

    /// The continuation from a vertex at `depth`: samples the BSDF with `u` (three numbers, then
    /// roulette's), multiplies the throughput `beta` by f·|cos|/pdf and `eta_scale` by η², and
    /// rolls Russian roulette from `rr_depth` on. The ray leaving the vertex and the BSDF sample,
    /// or `None` where the path ends (no sample, a zero or non-finite throughput, roulette).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn scatter(
        &self,
        material: &Bsdf,
        si: &SurfaceInteraction,
        wo: Vec3,
        u: [f32; 4],
        depth: u32,
        beta: &mut Rgb,
        eta_scale: &mut f32,
        counters: &mut Counters,
    ) -> Option<(Ray, BsdfSample)> {
        let [u0, u1, u2, u_rr] = u;
        let bs = material.sample(wo, [u0, u1, u2], TransportMode::Radiance)?;
        // Also rejects a NaN pdf.
        if bs.pdf.is_nan() || bs.pdf <= 0.0 || bs.f == Rgb::ZERO {
            return None;
        }
        *beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
        *eta_scale *= bs.eta * bs.eta;
        if !is_finite(*beta) {
            counters.nonfinite_dropped += 1;
            return None;
        }
        let ray = si.spawn(si.shading.to_world(bs.wi));
        if depth >= self.settings.rr_depth {
            *beta = russian_roulette(*beta, *eta_scale, self.settings.rr_scale, u_rr)?;
        }
        Some((ray, bs))
    }
}

/// What a path carries from the vertex a ray leaves: its throughput, η² product (for roulette),
/// whether the bounce was specular and its density and position (for weighting emission the ray
/// finds), and the vertex's depth.
#[derive(Clone, Copy, Debug)]
struct PathState {
    beta: Rgb,
    /// Product of η² over the refractions so far: beta · eta_scale is the throughput without the
    /// 1/η² radiance compression, what Russian roulette looks at (pbrt-v4 `etaScale`).
    eta_scale: f32,
    specular_bounce: bool,
    prev_pdf: f32,
    prev_p: Vec3,
    depth: u32,
}

/// The first vertex of a split path: what its other branches sample the BSDF from, and the
/// state every branch starts from there: 1/n of the path's throughput, and `eta_scale` times n so
/// that roulette judges a branch by the unsplit throughput.
#[derive(Clone, Copy, Debug)]
struct SplitVertex {
    material: Bsdf,
    si: SurfaceInteraction,
    wo: Vec3,
    beta: Rgb,
    eta_scale: f32,
}

/// The four numbers of `block` read one by one. The block has just been copied with one 16-byte
/// store; LLVM read (u1, u2) back as one 8-byte load at offset 4, which crosses an 8-byte boundary
/// inside that store, so the load could not be forwarded from it and waited for the store to
/// reach the cache (perf annotate puts 4–5% of the door's pt samples on the load's neighbour;
/// the render's CPU time is 2% lower with the reads below). Volatile reads are never merged, and
/// 4-byte reads at 4-byte offsets are forwarded.
#[inline(always)]
fn read_lanes(block: &[f32; 4]) -> [f32; 4] {
    // SAFETY: plain reads of the elements of a live array.
    block.each_ref().map(|x| unsafe { std::ptr::read_volatile(x) })
}
