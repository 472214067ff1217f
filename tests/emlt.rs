//! Ensemble MLT (`integrator = "emlt"`) against the path tracer by region shares, its determinism,
//! and its settings. The kernels, the tree, the similarity and the toy ensemble are tested inside
//! the library (`integrator::ensemble`), where their wrong variants can be switched on.
//!
//! # Agreement
//! As pmlt's (tests/pmlt.rs; tests/common/agreement.rs states the bound): the region shares of 16
//! renders against 16 path-traced ones, Welch's |z| < 5 with the power check (a 10% error of any
//! region holding at least a quarter of the average share must reach |z| = 5). Small ensembles
//! (|X| = |Y| = 32) and long chains, so that each chain's stationary distribution, not the resampled
//! bootstrap, makes the image; and at least half of the guided strategies' proposals must be guided
//! (|Υ| ≥ 2), not the plain fallbacks, or the test would not be testing the guided kernels.

use std::path::Path;

mod common;
use common::agreement::{assert_shares_agree, region_means, render_regions, share_agreement, RENDERS, Z_CRITICAL};

use plexus::camera::Camera;
use plexus::film::Image;
use plexus::integrator::ensemble::render::Emlt;
use plexus::integrator::{create, Budget, Integrator, NoProgress, RenderJob};
use plexus::scene::{load_scene, Scene};

fn scene(name: &str, size: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(format!("{name}.toml"));
    let mut scene = load_scene(&path, None).unwrap_or_else(|e| panic!("{}: {e}", path.display())).scene;
    let c = &scene.camera;
    scene.camera = Camera::new(c.position, c.position + c.forward, c.up, c.fov_y_degrees, size, size);
    scene
}

fn render(scene: &Scene, params: &str, mpp: u64, seed: u64, threads: usize) -> (Image, serde_json::Value) {
    let params: toml::Table = toml::from_str(params).expect("test parameters");
    let integrator = create("emlt", &params).expect("integrator");
    let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed, threads };
    let out = integrator.render(scene, &job, &NoProgress).expect("render");
    (out.image, out.extra_stats)
}

/// The region means of 16 renders by `emlt` with `emlt` replaced by a deliberately wrong one.
fn wrong_regions(scene: &Scene, mpp: u64, wrong: &Emlt) -> Vec<Vec<f64>> {
    (1..=RENDERS)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed: k * 7919 + 3, threads: 2 };
            region_means(&wrong.render(scene, &job, &NoProgress).expect("render").image)
        })
        .collect()
}

/// emlt's region shares against the path tracer's at `size`², and the guided share of its
/// proposals (≥ 1/2, asserted). Returns the guided share.
fn emlt_agrees_with_pt(name: &str, params: &str, size: u32, mpp: u64, pt_spp: u64) -> f64 {
    let scene = scene(name, size);
    let reference = render_regions(&scene, "pt", "max_depth = 8", pt_spp, 3, RENDERS);
    let renders = render_regions(&scene, "emlt", params, mpp, 3, RENDERS);
    let what = format!("emlt vs pt on {name}");
    let (_, stats) = render(&scene, params, mpp, 1, 2);
    let ensemble = &stats["ensemble"];
    println!("{what}: strategies {}\nensemble {ensemble}", stats["strategies"]);
    let share = ensemble["guided_share"].as_f64().expect("guided share");
    assert!(share >= 0.5, "{what}: only {share:.3} of the guided strategies' proposals were guided");
    assert_shares_agree(&what, &renders, &reference);
    share
}

/// |X| = |Y| = 128 (256 chains), 16×16 films, 3072 mutations per pixel: 3072 steps per chain.
const CORNELL: &str = "max_depth = 8\nbootstrap = 20000\nensemble_size = 128";
const MPP: u64 = 3072;

/// The Cornell box's shares agree, and a linear lens without λ in its ratio fails the same test.
/// Not run by default: 486 s on the loaded machine (16 pt + 16 emlt + 16 wrong renders), far above
/// this issue's ~2 minutes of suite time. Measured (2026-12-02): worst |z| = 1.28 with the power
/// check passing (weakest region: a 10% error gives z = 5.2), 97.9% of the linear lens's proposals
/// guided (513,860 guided, 10,871 fallbacks), linear lens acceptance 87.1%, bidirectional 19.3%,
/// tree rebuilds 0.31 s over 6,144 swaps, similarity weights 2.2 s. **Wrong variant**: without λ
/// at 1024 mutations per pixel the worst |z| was only 4.67 (< 5, so that run did not reject it);
/// the test now renders the wrong variant at the full 3072, where the same bias against a √3
/// smaller standard error should give |z| ≈ 8 — not yet measured.
#[test]
#[ignore = "486 s on the loaded machine, above the issue's test budget (see doc comment)"]
fn emlt_agrees_with_pt_on_cornell_box_and_a_linear_lens_without_lambda_does_not() {
    let scene_name = "cornell-box";
    emlt_agrees_with_pt(scene_name, CORNELL, 16, MPP, 1024);
    let scene = scene(scene_name, 16);
    let reference = render_regions(&scene, "pt", "max_depth = 8", 1024, 3, RENDERS);
    let table: toml::Table = toml::from_str(CORNELL).expect("toml");
    let mut wrong = Emlt::from_params(&table).expect("settings");
    wrong.linear_lens.omit_lambda = true;
    let a = share_agreement(&wrong_regions(&scene, MPP, &wrong), &reference);
    println!("emlt without λ on {scene_name}: worst |z| = {:.2}\n{}", a.worst_z, a.report());
    assert!(a.worst_z >= Z_CRITICAL, "the linear lens without λ passed: |z| = {:.2}", a.worst_z);
}

/// Not run by default: too slow for the suite (about 4 minutes per scene on the loaded machine at
/// the Cornell box's parameters, which its power check needs); not yet run at them. Measured (2026-12-02) at
/// |X| = |Y| = 32, 16×16, 256 mutations per pixel: the shares agree (worst |z| = 1.78) but the
/// power check fails in 12 regions (a 10% error reaches only |z| = 1.3 … 3.8).
#[test]
#[ignore = "the power check needs ~3000 mutations per pixel, beyond the suite's budget (see doc comment)"]
fn emlt_agrees_with_pt_on_cornell_glossy() {
    emlt_agrees_with_pt("cornell-glossy", CORNELL, 16, MPP, 1024);
}

/// Not run by default, as the glossy scene's test (not measured at these parameters).
#[test]
#[ignore = "the power check needs ~3000 mutations per pixel, beyond the suite's budget"]
fn emlt_agrees_with_pt_on_cornell_glass() {
    emlt_agrees_with_pt("cornell-glass", CORNELL, 16, MPP, 1024);
}

/// Same seed and threads: the same bits; another thread count too (chains are the driver's units
/// and read only Y); another seed: another image.
#[test]
fn emlt_is_deterministic() {
    let scene = scene("cornell-glass", 16);
    let params = "bootstrap = 2000\nensemble_size = 16";
    let bits = |img: &Image| img.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    let a = render(&scene, params, 8, 5, 2).0;
    let b = render(&scene, params, 8, 5, 2).0;
    let c = render(&scene, params, 8, 5, 1).0;
    let d = render(&scene, params, 8, 6, 2).0;
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(bits(&a), bits(&c));
    assert_ne!(bits(&a), bits(&d));
}

/// Bad settings are refused with the setting's name, before any work.
#[test]
fn emlt_settings_are_validated() {
    for (params, needle) in
        [("ensemble_size = 0", "ensemble_size"), ("subset_size = 1", "subset_size"), ("chains = 4", "chains")]
    {
        let table: toml::Table = toml::from_str(params).expect("toml");
        let err = create("emlt", &table).err().unwrap_or_else(|| panic!("accepted {params}")).to_string();
        assert!(err.contains(needle), "{params}: {err}");
    }
}
