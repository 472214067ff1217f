//! Bidirectional path tracing and light tracing against the path tracer, the MIS weights of every
//! technique for the same path, and the per-technique images.
//!
//! # The agreement test and its bound
//!
//! Each integrator renders K = 16 independent images (seeds 1..=16) of a downscaled scene. For every
//! one of the 16 regions of a 4×4 grid and for the whole image, the luminance mean of each render is
//! one sample of that region's estimator, so the K values give the estimator's mean and its variance
//! measured from the renders themselves — correlations between pixels from light-tracing splats
//! included. The two integrators are compared with Welch's statistic
//! z = (m_a − m_b) / sqrt(v_a/K + v_b/K). Under agreement z follows a Student t with 15 to 30
//! degrees of freedom (Welch–Satterthwaite); |z| > 5 has two-sided probability below 5.5e-5 at 22
//! degrees of freedom, so with the Bonferroni correction over the 17 comparisons the family-wise
//! false-failure probability is below 1e-3 (below 3e-3 in the worst case of 15 degrees of freedom).
//! The seeds are fixed, so the outcome is one fixed draw. The tests also check their own power: the
//! relative standard error of the image mean must be small enough that a 5% brightness error would
//! be flagged.

use std::path::Path;

use crate::common::agreement::{assert_agree, estimate};

use plexus::camera::Camera;
use plexus::film::Image;
use plexus::integrator::bdpt::path::{full_path, split_path, technique_can_sample, technique_weight};
use plexus::integrator::bdpt::{
    evaluate_technique, generate_camera_subpath, generate_light_subpath, BdptContext, ConnectScratch, FilmRegion,
    MisHeuristic, Vertex,
};
use plexus::integrator::{create, Budget, NoProgress, RenderJob};
use plexus::sampling::Rng;
use plexus::scene::load_scene;
use plexus::scene::Scene;
use plexus::spectrum::is_black;
use plexus::stats::Counters;

fn scene(name: &str, width: u32, height: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(format!("{name}.toml"));
    let mut scene = load_scene(&path, None).unwrap_or_else(|e| panic!("{}: {e}", path.display())).scene;
    let c = &scene.camera;
    scene.camera = Camera::new(c.position, c.position + c.forward, c.up, c.fov_y_degrees, width, height);
    scene
}

fn bdpt_agrees_with_pt(name: &str, size: u32, spp_pt: u64, spp_bdpt: u64) {
    let scene = scene(name, size, size);
    let pt = estimate(&scene, "pt", "max_depth = 8", spp_pt, 1);
    let bdpt = estimate(&scene, "bdpt", "max_depth = 8", spp_bdpt, 1);
    assert_agree(&format!("bdpt vs pt on {name}"), bdpt, pt);
}

// Runtime bounds (release, 2 threads): each test renders 2 × 16 images of at most 32×32 pixels.

#[test]
fn bdpt_agrees_with_pt_on_cornell_box() {
    bdpt_agrees_with_pt("cornell-box", 32, 32, 8);
}

#[test]
fn bdpt_agrees_with_pt_on_cornell_glossy() {
    // 16 BDPT spp: at 8, BDPT's own standard error of the image mean (1.25e-3) nearly used up the
    // 1.3e-3 the power check allows, so PT's share decided the check by its seeds' luck.
    bdpt_agrees_with_pt("cornell-glossy", 32, 32, 16);
}

#[test]
fn bdpt_agrees_with_pt_on_cornell_glass() {
    bdpt_agrees_with_pt("cornell-glass", 32, 32, 8);
}

#[test]
fn bdpt_agrees_with_pt_on_environment() {
    bdpt_agrees_with_pt("environment", 32, 32, 8);
}

#[test]
fn bdpt_power_heuristic_agrees_with_pt_on_cornell_box() {
    let scene = scene("cornell-box", 32, 32);
    let pt = estimate(&scene, "pt", "max_depth = 8", 32, 1);
    let bdpt = estimate(&scene, "bdpt", "max_depth = 8\nmis = \"power\"", 8, 1);
    assert_agree("bdpt (power) vs pt on cornell-box", bdpt, pt);
}

#[test]
fn light_tracing_agrees_with_pt_on_cornell_box() {
    let scene = scene("cornell-box", 32, 32);
    let pt = estimate(&scene, "pt", "max_depth = 8", 32, 1);
    let light = estimate(&scene, "light", "max_depth = 8", 32, 1);
    assert_agree("light vs pt on cornell-box", light, pt);
}

/// For complete paths produced by every technique of random subpath pairs, the MIS weights of all
/// techniques that can produce the path — each computed from that technique's own subpaths, rebuilt
/// by `split_path` — sum to 1 within 1e-4, and match the weight vector the producing evaluation
/// returned. Any disagreement between the generators' pdf bookkeeping and the recurrence shows up.
#[test]
fn mis_weights_of_all_techniques_sum_to_one() {
    for name in ["cornell-box", "cornell-glossy", "cornell-glass", "environment"] {
        let scene = scene(name, 16, 16);
        for heuristic in [MisHeuristic::Balance, MisHeuristic::Power] {
            let ctx = BdptContext::new(&scene, usize::MAX, heuristic);
            let mut rng = Rng::new(2024, 0);
            let mut counters = Counters::default();
            let (mut camera, mut light) = (Vec::<Vertex>::new(), Vec::<Vertex>::new());
            let mut scratch = ConnectScratch::default();
            let mut alternatives = Vec::new();
            let mut checked = 0usize;
            let mut multi = 0usize;
            for _ in 0..400 {
                let raster =
                    generate_camera_subpath(&ctx, FilmRegion::WholeFilm, &mut rng, 7, &mut camera, &mut counters);
                generate_light_subpath(&ctx, &mut rng, 6, &mut light, &mut counters);
                for t in 1..=camera.len() {
                    for s in 0..=light.len() {
                        if (s == 1 && t == 1) || s + t < 2 {
                            continue;
                        }
                        let Some(c) = evaluate_technique(
                            &ctx,
                            &light,
                            &camera,
                            s,
                            t,
                            raster,
                            &mut rng,
                            &mut scratch,
                            &mut counters,
                            Some(&mut alternatives),
                        ) else {
                            continue;
                        };
                        if is_black(c.contribution) {
                            continue;
                        }
                        let path = full_path(&light, &camera, &c);
                        let n = path.len();
                        assert_eq!(alternatives.len(), n + 1);
                        assert!((alternatives[s] - c.mis_weight).abs() < 1e-6);
                        let mut sum = 0.0f64;
                        let mut samplers = 0;
                        for tp in 1..=n {
                            let sp = n - tp;
                            if !technique_can_sample(&scene, &path, tp) {
                                assert!(
                                    alternatives[sp] == 0.0,
                                    "{name}: ({s},{t}) gives weight {} to impossible ({sp},{tp})",
                                    alternatives[sp]
                                );
                                continue;
                            }
                            let (l, cam) = split_path(&scene, &path, tp);
                            let w = technique_weight(&scene, heuristic, &l, &cam);
                            assert!(
                                (w - alternatives[sp]).abs() < 1e-4,
                                "{name} {heuristic:?}: path from ({s},{t}): technique ({sp},{tp}) has weight {w} on its own \
                                 subpaths but {} from ({s},{t})",
                                alternatives[sp]
                            );
                            sum += w as f64;
                            samplers += 1;
                        }
                        assert!(
                            (sum - 1.0).abs() < 1e-4,
                            "{name} {heuristic:?}: weights of a path from ({s},{t}) sum to {sum}"
                        );
                        checked += 1;
                        multi += (samplers > 1) as usize;
                    }
                }
            }
            assert!(
                checked > 200 && multi > 100,
                "{name}: too few paths checked ({checked}, {multi} with several techniques)"
            );
        }
    }
}

/// With `technique_images`, the weighted per-technique layers add up to the BDPT image (up to f32
/// rounding of each layer), and every (s, t) has a weighted and an unweighted layer.
#[test]
fn technique_images_sum_to_the_bdpt_image() {
    let scene = scene("cornell-box", 24, 24);
    let params: toml::Table =
        toml::from_str("max_depth = 6\ntechnique_images = true\ntechnique_max_depth = 3").expect("params");
    let integrator = create("bdpt", &params).expect("bdpt");
    let job = RenderJob { budget: Budget::SamplesPerPixel(4), seed: 5, threads: 2 };
    let out = integrator.render(&scene, &job, &NoProgress).expect("render");
    let weighted: Vec<&Image> = out.layers.iter().filter(|(n, _)| n.ends_with(".weighted")).map(|(_, i)| i).collect();
    let unweighted = out.layers.iter().filter(|(n, _)| n.ends_with(".unweighted")).count();
    // Depths 0..=3: 2 + 3 + 4 + 5 techniques without (1,1), plus the deeper remainder.
    assert_eq!(weighted.len(), 14);
    assert_eq!(unweighted, 14);
    assert!(
        out.layers.iter().any(|(n, _)| n == "s0t2.weighted") && out.layers.iter().any(|(n, _)| n == "s2t1.unweighted")
    );
    let mut nonzero_layers = 0;
    for l in &weighted {
        nonzero_layers += l.pixels.iter().any(|p| !is_black(*p)) as usize;
    }
    assert!(nonzero_layers >= 10, "only {nonzero_layers} techniques contributed");
    for i in 0..out.image.pixels.len() {
        let sum: glam::DVec3 = weighted.iter().map(|l| l.pixels[i].as_dvec3()).sum();
        let want = out.image.pixels[i].as_dvec3();
        let err = (sum - want).abs().max_element();
        assert!(err <= 1e-5 * want.abs().max_element() + 1e-7, "pixel {i}: layers sum to {sum:?}, image {want:?}");
    }
}
