//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (Veach & Guibas 1995; the structure follows pbrt-v4's `PathIntegrator`).
//!
//! At every non-specular vertex the estimator combines two techniques for direct light: a light
//! sample (light chosen by the scene's light-selection pmf, then a point or direction on it; a
//! rectangle light seen from nearby by solid angle, `AreaLight::sample_li_nee`) and the
//! BSDF sample that continues the path. Each is weighted with the power (β = 2) or balance heuristic
//! over the two densities, both expressed per unit solid angle at the shading point, the light's
//! including its selection probability. After a specular (delta) bounce no light sample is possible,
//! so emission found by the continuation ray counts fully. Environment lights are handled both ways
//! like area lights. Russian roulette starts after `rr_depth` bounces and keeps a path with
//! probability `rr_scale` times its throughput, refraction's 1/η² undone (`roulette_survival`).
//!
//! All randomness comes from the work item's stream in a fixed order that depends only on the hits,
//! and hit points come from barycentrics, so Embree and the in-house BVH give the same image (up to
//! the last bits of their triangle tests). The camera rays of eight consecutive samples of a tile
//! are traced together (`Scene::hits_coherent`, Embree's packets) before their paths go on one by
//! one, in the film's order.
//!
//! The module's parts: this file holds the settings, the MIS weights and which uniform feeds which
//! choice; `oracle` the estimator written plainly, vertex by vertex, as the reference the others
//! must reproduce bit for bit; `path` the same estimator tuned for speed (its numbers drawn and
//! its shadow rays traced where they hide cache misses); `camera_packets` the render, whose
//! camera rays are traced in packets before each path goes on; `roulette` Russian roulette.

use serde::{Deserialize, Serialize};

use super::driver::ImageEngine;
use super::{settings_from_table, Plugin, RenderError};
use crate::light::LiPoint;
use crate::sampling::SamplerKind;
use crate::scene::Scene;

mod camera_packets;
mod oracle;
mod path;
mod roulette;

pub use roulette::{roulette_survival, russian_roulette};

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
    /// Russian roulette starts after this many bounces (2: as pbrt-v4, whose roulette first rolls
    /// after its second bounce; docs/lab/benchmarks-history.md, "Russian roulette's start depth").
    pub rr_depth: u32,
    /// Russian roulette keeps a path with probability min(1, `rr_scale` × its throughput)
    /// (`roulette_survival`); 1 is pbrt's and Mitsuba's rule. Must be positive and finite.
    pub rr_scale: f32,
    /// How light samples and BSDF samples are weighted: "power", "balance", "bsdf_only",
    /// "light_only".
    pub mis: Mis,
    /// The numbers samples read: "sobol" (Owen-scrambled Sobol per pixel) or "independent"
    /// (`sampling::SamplerKind`).
    pub sampler: SamplerKind,
    /// Paths continued from the first vertex of each camera path (splitting): each carries
    /// 1/n of the throughput there and reads its own stream. The camera ray, the first hit and its
    /// light sample are paid once for n continuations.
    pub first_bounce_paths: u32,
}

impl Default for PtSettings {
    fn default() -> Self {
        PtSettings {
            max_depth: 16,
            rr_depth: 2,
            rr_scale: 2.0,
            mis: Mis::Power,
            sampler: SamplerKind::default(),
            first_bounce_paths: 1,
        }
    }
}

/// The most continuations a camera path may split into. One pass (a sample per pixel) costs about
/// this many paths per pixel, and an interrupt waits for the pass: the bound keeps a pass to what
/// an unsplit render of that many samples per pixel would take.
pub const MAX_FIRST_BOUNCE_PATHS: u32 = 64;

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
        if !(1..=MAX_FIRST_BOUNCE_PATHS).contains(&settings.first_bounce_paths) {
            return Err(RenderError::Settings(format!(
                "pt: first_bounce_paths must be in 1 ..= {MAX_FIRST_BOUNCE_PATHS}, not {}",
                settings.first_bounce_paths
            )));
        }
        if !(settings.rr_scale > 0.0 && settings.rr_scale.is_finite()) {
            return Err(RenderError::Settings(format!(
                "pt: rr_scale must be a positive finite number (1 is the throughput rule), not {}",
                settings.rr_scale
            )));
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

    #[inline]
    fn light_pmf(&self, scene: &Scene, index: u32) -> f32 {
        scene.light_sampler.distribution.pdf_discrete(index as usize)
    }
}

impl Plugin for PathTracer {
    type Engine = ImageEngine;
    type Settings = PtSettings;

    fn plugin_name(&self) -> &'static str {
        "pt"
    }

    fn settings(&self) -> &PtSettings {
        &self.settings
    }
}

/// Light selection and the emitter half of its sample (`Light::sample_li_point`) from the light
/// sample's four uniforms; only called when there are lights. Inlined: called out of line, its
/// result went through memory in narrower stores than the caller's reloads (stalled store
/// forwards, ~4% of the door's time).
#[inline(always)]
fn choose_light(scene: &Scene, u: [f32; 4]) -> (usize, f32, LiPoint) {
    let (index, pmf) = scene.light_sampler.distribution.sample_index(u[2]);
    (index, pmf, scene.lights[index].sample_li_point(light_point_uniforms(u)))
}

// Which lane of a vertex's block of four uniforms feeds which choice. With the Sobol sampler a
// block is one padded set, Sobol dimensions 0–3 of a scrambled sequence (`sampling::sobol`), and
// its pairs are not equally stratified: dimensions (0, 1) form a (0, 2)-sequence (every 2^m
// consecutive points put one point in each elementary interval of area 2^-m), while with Joe and
// Kuo's numbers the pairs (1, 2) and (2, 3) have t = 1 and up to t = 2 (a quarter as fine).
// So each block's two-dimensional warp (the point on the light or the direction from the
// environment; the BSDF's direction) reads lanes 0 and 1, and the discrete choices (which light,
// which triangle, which lobe) and roulette the other two. `tests::warps_read_the_stratified_pair`
// checks the nets. Measured against lanes 2–3 for the light's point and 1–2 for the direction,
// 16 renders of 64 spp each: variance 0.996×, 0.987×, 0.994× and 0.989× on the Cornell box, its
// glossy and glass variants and the door (standard errors 1.1–1.6%, so about 1% gained, not
// resolved scene by scene; docs/lab/performance.md).

/// The light sample's uniforms after the light's choice (lane 2): the triangle's (lane 3), then
/// the point's or the environment's direction (lanes 0 and 1), as `Light::sample_li_point` reads
/// them.
#[inline(always)]
fn light_point_uniforms(u: [f32; 4]) -> [f32; 3] {
    [u[3], u[0], u[1]]
}

/// The BSDF sample's three uniforms (the lobe's choice, lane 2; the direction, lanes 0 and 1, as
/// `Bsdf::sample` reads them) and Russian roulette's (lane 3), from a block read lane by lane.
#[inline(always)]
fn bsdf_uniforms(block: [f32; 4]) -> [f32; 4] {
    [block[2], block[0], block[1], block[3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether the points hit every elementary interval of area 1/n exactly once (n = 2^m points):
    /// a (0, m, 2)-net, the finest stratification a pair of Sobol dimensions can have.
    fn is_zero_net(points: &[[f32; 2]]) -> bool {
        let m = points.len().trailing_zeros();
        assert_eq!(points.len(), 1 << m);
        (0..=m).all(|a| {
            let (cols, rows) = (1u32 << a, 1u32 << (m - a));
            let mut seen = vec![false; points.len()];
            points.iter().all(|[u, v]| {
                let cell = (u * cols as f32) as usize * rows as usize + (v * rows as f32) as usize;
                !std::mem::replace(&mut seen[cell], true)
            })
        })
    }

    /// The light sample's point and the BSDF's direction read the lanes of a Sobol block whose pair
    /// is a (0, 2)-sequence: 2^m consecutive samples of a pixel's stream are a (0, m, 2)-net there,
    /// for several scrambles and m up to 8. The earlier lanes (the point on lanes 2 and 3, the
    /// direction on lanes 1 and 2) are not nets at m = 8 (t = 1 there), which this test tells apart.
    #[test]
    fn warps_read_the_stratified_pair() {
        use crate::sampling::{SobolStream, UniformSource};
        for key in [1u64, 0x9e37_79b9_7f4a_7c15, 12345] {
            let blocks: Vec<[f32; 4]> = (0..256).map(|i| SobolStream::new(key, i).next_n()).collect();
            for m in 1..=8 {
                let first = &blocks[..1 << m];
                let light: Vec<[f32; 2]> =
                    first.iter().map(|b| light_point_uniforms(*b)).map(|u| [u[1], u[2]]).collect();
                let direction: Vec<[f32; 2]> = first.iter().map(|b| bsdf_uniforms(*b)).map(|u| [u[1], u[2]]).collect();
                assert!(is_zero_net(&light), "light point, key {key}, 2^{m} samples");
                assert!(is_zero_net(&direction), "BSDF direction, key {key}, 2^{m} samples");
            }
            let old_light: Vec<[f32; 2]> = blocks.iter().map(|b| [b[2], b[3]]).collect();
            let old_direction: Vec<[f32; 2]> = blocks.iter().map(|b| [b[1], b[2]]).collect();
            assert!(!is_zero_net(&old_light) && !is_zero_net(&old_direction));
        }
    }

    #[test]
    fn settings_defaults_and_unknown_keys() {
        let pt = PathTracer::from_params(&toml::Table::new()).expect("defaults");
        assert_eq!(
            pt.settings,
            PtSettings {
                max_depth: 16,
                rr_depth: 2,
                rr_scale: 2.0,
                mis: Mis::Power,
                sampler: SamplerKind::Sobol,
                first_bounce_paths: 1
            }
        );
        let t: toml::Table = toml::from_str("max_depth = 3\nmis = \"balance\"").expect("toml");
        let pt = PathTracer::from_params(&t).expect("valid");
        assert_eq!((pt.settings.max_depth, pt.settings.mis), (3, Mis::Balance));
        let bad: toml::Table = toml::from_str("max_dept = 3").expect("toml");
        let err = PathTracer::from_params(&bad).expect_err("unknown key").to_string();
        assert!(err.contains("max_dept"), "{err}");
        let zero: toml::Table = toml::from_str("max_depth = 0").expect("toml");
        assert!(PathTracer::from_params(&zero).is_err());
        for bad_scale in ["0.0", "-1.0", "nan", "inf"] {
            let t: toml::Table = toml::from_str(&format!("rr_scale = {bad_scale}")).expect("toml");
            let err = PathTracer::from_params(&t).expect_err(bad_scale).to_string();
            assert!(err.contains("rr_scale"), "{bad_scale}: {err}");
        }
        let zero_paths: toml::Table = toml::from_str("first_bounce_paths = 0").expect("toml");
        let err = PathTracer::from_params(&zero_paths).expect_err("no paths").to_string();
        assert!(err.contains("first_bounce_paths"), "{err}");
        let many: toml::Table = toml::from_str("first_bounce_paths = 65").expect("toml");
        let err = PathTracer::from_params(&many).expect_err("too many paths").to_string();
        assert!(err.contains("1 ..= 64"), "{err}");
        let t: toml::Table = toml::from_str("rr_scale = 1").expect("toml");
        assert_eq!(PathTracer::from_params(&t).expect("integer scale").settings.rr_scale, 1.0);
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
