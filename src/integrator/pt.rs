//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (Veach & Guibas 1995; the structure follows pbrt-v4's `PathIntegrator`).
//!
//! At every non-specular vertex the estimator combines two techniques for direct light: a light
//! sample (light chosen by the scene's light-selection pmf, then a point or direction on it) and the
//! BSDF sample that continues the path. Each is weighted with the power (β = 2) or balance heuristic
//! over the two densities, both expressed per unit solid angle at the shading point, the light's
//! including its selection probability. After a specular (delta) bounce no light sample is possible,
//! so emission found by the continuation ray counts fully. Environment lights are handled both ways
//! like area lights. Russian roulette starts after `rr_depth` bounces.
//!
//! All randomness comes from the work item's stream in a fixed order that depends only on the hits,
//! and hit points come from barycentrics, so Embree and the in-house BVH give the same image.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::driver::{ImageRender, ImageRun};
use super::{settings_from_table, Integrator, Progress, RenderError, RenderJob, RenderOutput};
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::sampling::Rng;
use crate::scene::Scene;
use crate::spectrum::{is_finite, Rgb};
use crate::stats::Counters;

/// How the two direct-lighting techniques are combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mis {
    /// Veach's power heuristic with exponent 2 (Veach 1997, Eq. 9.13): the usual choice.
    Power,
    /// The balance heuristic (Veach 1997, Eq. 9.10).
    Balance,
    /// BSDF sampling only: no light samples; emission found by any ray counts fully. Unbiased but
    /// noisy; useful to cross-check the other modes.
    BsdfOnly,
    /// Light sampling only at non-specular vertices; emission found by a BSDF-sampled ray counts only
    /// after a specular bounce (or seen directly). Unbiased for every light that can be sampled.
    LightOnly,
}

/// Settings of the path tracer (`[integrator]` table of a scene or `--set key=value`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PtSettings {
    /// Maximum number of bounces (scattering events) of a path; 1 gives direct lighting only.
    pub max_depth: u32,
    /// Russian roulette starts after this many bounces.
    pub rr_depth: u32,
    /// How light samples and BSDF samples are weighted: "power", "balance", "bsdf_only",
    /// "light_only".
    pub mis: Mis,
}

impl Default for PtSettings {
    fn default() -> Self {
        PtSettings { max_depth: 16, rr_depth: 5, mis: Mis::Power }
    }
}

/// The path tracer.
#[derive(Clone, Debug)]
pub struct PathTracer {
    pub settings: PtSettings,
}

impl PathTracer {
    pub fn new(settings: PtSettings) -> PathTracer {
        PathTracer { settings }
    }

    /// Builds from an `[integrator]` parameter table.
    pub fn from_params(params: &toml::Table) -> Result<PathTracer, RenderError> {
        let settings: PtSettings = settings_from_table("pt", params)?;
        if settings.max_depth == 0 {
            return Err(RenderError::Settings("pt: max_depth must be at least 1".into()));
        }
        Ok(PathTracer::new(settings))
    }

    /// The weight of the technique with density `pdf_a` against the one with `pdf_b`.
    #[inline]
    fn mis_weight(&self, pdf_a: f32, pdf_b: f32) -> f32 {
        match self.settings.mis {
            Mis::Power => {
                let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
                // Large densities would overflow their squares; the ratio form stays finite.
                if a.is_infinite() {
                    1.0
                } else if a + b > 0.0 {
                    a / (a + b)
                } else {
                    0.0
                }
            }
            Mis::Balance => {
                if pdf_a + pdf_b > 0.0 {
                    pdf_a / (pdf_a + pdf_b)
                } else {
                    0.0
                }
            }
            Mis::BsdfOnly | Mis::LightOnly => unreachable!("single-technique modes do not weight"),
        }
    }

    /// Weight of emission found by a BSDF-sampled ray (density `pdf_bsdf`) that a light sample
    /// would have found with density `pdf_light`.
    #[inline]
    fn weight_bsdf_hit(&self, pdf_bsdf: f32, pdf_light: f32) -> f32 {
        match self.settings.mis {
            Mis::BsdfOnly => 1.0,
            Mis::LightOnly => 0.0,
            _ => self.mis_weight(pdf_bsdf, pdf_light),
        }
    }

    /// Weight of a light sample (density `pdf_light`) that BSDF sampling produces with `pdf_bsdf`.
    #[inline]
    fn weight_light_sample(&self, pdf_light: f32, pdf_bsdf: f32) -> f32 {
        match self.settings.mis {
            Mis::BsdfOnly => 0.0,
            Mis::LightOnly => 1.0,
            _ => self.mis_weight(pdf_light, pdf_bsdf),
        }
    }

    /// Radiance arriving along `ray` (one camera path). Non-finite contributions are dropped and
    /// counted; rays and shadow rays are counted.
    pub fn li(&self, scene: &Scene, mut ray: Ray, rng: &mut Rng, counters: &mut Counters) -> Rgb {
        let mut l = Rgb::ZERO;
        let mut beta = Rgb::ONE;
        // State of the previous vertex, for weighting emission found by the BSDF-sampled ray.
        let mut specular_bounce = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.o;
        let use_nee = self.settings.mis != Mis::BsdfOnly && !scene.lights.is_empty();
        let mut depth = 0u32;

        let add = |l: &mut Rgb, c: Rgb, counters: &mut Counters| {
            if is_finite(c) {
                *l += c;
            } else {
                counters.nonfinite_dropped += 1;
            }
        };

        loop {
            counters.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
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
                        add(&mut l, beta * le * w, counters);
                    }
                }
                break;
            };

            if let Some((index, light)) = scene.area_light(&si) {
                let le = light.emitted(si.ng, -ray.d);
                if le != Rgb::ZERO {
                    let w = if specular_bounce {
                        1.0
                    } else {
                        let pdf_light = self.light_pmf(scene, index) * light.pdf_li(prev_p, ray.d, si.p, si.ng);
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

            let material = scene.material(&si);
            let frame = si.shading;
            let wo = frame.to_local(-ray.d);

            // Next-event estimation (its uniforms are drawn even when unused, so that the stream
            // position depends only on the path's vertices).
            let u_light = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
            if use_nee && !material.is_specular() {
                let (index, pmf, _) = scene.light_sampler.distribution.sample_discrete(u_light[0]);
                let light = &scene.lights[index];
                if let Some(ls) = light.sample_li(si.p, [u_light[1], u_light[2], u_light[3]]) {
                    if ls.pdf > 0.0 && ls.radiance != Rgb::ZERO {
                        let wi = frame.to_local(ls.wi);
                        let f = material.eval(wo, wi, TransportMode::Radiance) * wi.z.abs();
                        if f != Rgb::ZERO {
                            let shadow =
                                if ls.infinite { si.spawn(ls.wi) } else { si.spawn_to(ls.p, Vec3::ZERO, ls.n) };
                            counters.shadow_rays += 1;
                            if !scene.occluded(&shadow) {
                                let pdf_light = pmf * ls.pdf;
                                let pdf_bsdf = material.pdf(wo, wi, TransportMode::Radiance);
                                let w = self.weight_light_sample(pdf_light, pdf_bsdf);
                                add(&mut l, beta * f * ls.radiance * (w / pdf_light), counters);
                            }
                        }
                    }
                }
            }

            // Continue the path by sampling the BSDF.
            let u_bsdf = [rng.uniform(), rng.uniform(), rng.uniform()];
            let Some(bs) = material.sample(wo, u_bsdf, TransportMode::Radiance) else { break };
            // Also rejects a NaN pdf.
            if bs.pdf.is_nan() || bs.pdf <= 0.0 || bs.f == Rgb::ZERO {
                break;
            }
            beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
            if !is_finite(beta) {
                counters.nonfinite_dropped += 1;
                break;
            }
            specular_bounce = bs.delta;
            prev_pdf = bs.pdf;
            prev_p = si.p;
            ray = si.spawn(frame.to_world(bs.wi));

            let u_rr = rng.uniform();
            if depth >= self.settings.rr_depth {
                // Survival probability follows the throughput (pbrt-v4 Sec. 13.1.5, without its
                // η scaling), with a floor so long paths are not cut off too eagerly.
                let q = (1.0 - beta.max_element()).max(0.05);
                if u_rr < q {
                    break;
                }
                beta /= 1.0 - q;
            }
        }
        l
    }

    #[inline]
    fn light_pmf(&self, scene: &Scene, index: u32) -> f32 {
        scene.light_sampler.distribution.pdf_discrete(index as usize)
    }
}

impl Integrator for PathTracer {
    fn name(&self) -> &'static str {
        "pt"
    }

    fn settings_json(&self) -> serde_json::Value {
        serde_json::to_value(&self.settings).unwrap_or(serde_json::Value::Null)
    }

    fn render(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<RenderOutput, RenderError> {
        self.render_run(scene, job, progress).map(|run| run.output)
    }
}

impl PathTracer {
    /// The render with its unnormalised film (`Integrator::render` keeps only the output).
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<ImageRun, RenderError> {
        let render = ImageRender::new(job, scene.camera.width, scene.camera.height, progress)?;
        let (run, _) = render.run(
            |_| (),
            |x, y, rng, slot| {
                let raster = Vec2::new(x as f32 + rng.uniform(), y as f32 + rng.uniform());
                let ray = scene.camera.ray_through(raster);
                let l = self.li(scene, ray, rng, &mut slot.counters);
                slot.film.add(x as usize, y as usize, l);
            },
        );
        Ok(run)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_defaults_and_unknown_keys() {
        let pt = PathTracer::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(pt.settings, PtSettings { max_depth: 16, rr_depth: 5, mis: Mis::Power });
        let t: toml::Table = toml::from_str("max_depth = 3\nmis = \"balance\"").expect("toml");
        let pt = PathTracer::from_params(&t).expect("valid");
        assert_eq!((pt.settings.max_depth, pt.settings.mis), (3, Mis::Balance));
        let bad: toml::Table = toml::from_str("max_dept = 3").expect("toml");
        let err = PathTracer::from_params(&bad).expect_err("unknown key").to_string();
        assert!(err.contains("max_dept"), "{err}");
        let zero: toml::Table = toml::from_str("max_depth = 0").expect("toml");
        assert!(PathTracer::from_params(&zero).is_err());
    }

    #[test]
    fn mis_weights_sum_to_one() {
        for mis in [Mis::Power, Mis::Balance] {
            let pt = PathTracer::new(PtSettings { mis, ..Default::default() });
            for (a, b) in [(1.0f32, 2.0f32), (0.3, 0.0), (1e30, 1e-3), (5.0, 5.0)] {
                let s = pt.weight_light_sample(a, b) + pt.weight_bsdf_hit(b, a);
                assert!((s - 1.0).abs() < 1e-6, "{mis:?} {a} {b}: {s}");
            }
        }
    }
}
