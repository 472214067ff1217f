//! Path-space MLT (`integrator = "pmlt"`, the bidirectional mutation and the perturbations) against the path tracer, and
//! its determinism and black-scene behaviour. The transition density and the path-length shares are
//! tested inside the library (`integrator::path_space::tests`), where the wrong variants can be
//! switched on.
//!
//! # Agreement
//! As for the primary-sample-space methods (tests/mlt.rs explains it; tests/common/agreement.rs
//! states the bounds): with expected-value splatting the image mean is b, so the **region shares**
//! (4×4 regions, region mean ÷ the render's image mean) of 16 renders test the chain against 16
//! path-traced renders, by Welch's z with |z| < 5 and a power check (a 10% error of any region's
//! share holding at least a quarter of the average share must reach |z| = 5); the **brightness**
//! (image mean, with a 5% power check) tests b, which pmlt takes from its BDPT bootstrap alone.
//! 64 chains, 768 mutations per pixel of 32×32 (all strategies: bidirectional + lens here), so that
//! the chains' stationary distribution, not the resampled bootstrap they start from, makes the
//! image; the path tracer at 1024 spp. Measured (2026-12-02, this file 1025 s with 3 test threads on
//! the shared machine at load ~13, over issues 13+14's budget): cornell-box shares worst |z| = 1.41,
//! brightness z = −3.21 (relative standard error 0.0095); cornell-glossy worst |z| = 2.46;
//! acceptance bidirectional 19.1% / lens 64.8% (box), 18.5% / 63.3% (glossy). **Wrong chain**: with
//! the addition-length probability left out of the bidirectional T the box's shares fail at
//! |z| = 111.3 (asserted). The glass scene's test is ignored (its power check fails, see there).

use std::path::Path;

mod common;
use common::agreement::{
    assert_brightness_agrees, assert_shares_agree, mean_and_variance_of_mean, region_means,
    relative_noise_of_region_means, render_regions, share_agreement, shares, POWER_SHARE_FLOOR, RENDERS, SHARE_ERROR,
    Z_CRITICAL,
};
use common::binary::{plexus, stderr, temp_dir, tiny_scene};

use plexus::camera::Camera;
use plexus::film::exr_io::read_exr;
use plexus::film::Image;
use plexus::integrator::path_space::bidirectional::Bidirectional;
use plexus::integrator::path_space::portal::PortalPerturbation;
use plexus::integrator::path_space::Pmlt;
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
    let integrator = create("pmlt", &params).expect("integrator");
    let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed, threads };
    let out = integrator.render(scene, &job, &NoProgress).expect("render");
    (out.image, out.extra_stats)
}

/// One pmlt configuration of an agreement test: its label and its `[integrator]` table.
type Config = (&'static str, &'static str);

/// The region means of `RENDERS` independent pmlt renders (seeds as `render_regions`), each
/// finite and dropping nothing, and the first render's statistics (so the acceptance figures cost no
/// extra render).
fn pmlt_regions(scene: &Scene, pmlt: &Pmlt, mpp: u64) -> (Vec<Vec<f64>>, serde_json::Value) {
    let mut stats = serde_json::Value::Null;
    let regions = (1..=RENDERS)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed: k * 7919 + 3, threads: 2 };
            let out = pmlt.render(scene, &job, &NoProgress).expect("render");
            assert!(out.image.all_finite(), "pmlt: non-finite pixels");
            assert_eq!(out.counters.nonfinite_dropped, 0, "pmlt: non-finite contributions");
            if k == 1 {
                stats = out.extra_stats;
            }
            region_means(&out.image)
        })
        .collect();
    (regions, stats)
}

fn pmlt_with(params: &str) -> Pmlt {
    let table: toml::Table = toml::from_str(params).expect("test parameters");
    Pmlt::from_params(&table).expect("settings")
}

/// Each configuration's region shares against one set of path-traced renders of `name` at
/// `SIZE`×`SIZE`, with the power check (`assert_shares_agree`); prints each strategy's
/// acceptance. Returns the scene, the path tracer's region means and the last configuration's
/// (for the brightness and wrong-variant checks, which reuse them).
fn pmlt_agrees_with(
    name: &str,
    configs: &[Config],
    mpp: u64,
    (reference_integrator, spp): (&str, u64),
) -> (Scene, Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let scene = scene(name, SIZE);
    let reference = render_regions(&scene, reference_integrator, "max_depth = 8", spp, 3, RENDERS);
    let mut last = Vec::new();
    for (label, params) in configs {
        let (renders, stats) = pmlt_regions(&scene, &pmlt_with(params), mpp);
        let what = format!("pmlt ({label}) vs {reference_integrator} on {name}");
        assert_shares_agree(&what, &renders, &reference);
        for s in stats["strategies"].as_array().into_iter().flatten() {
            println!(
                "{what}: {} selected {} accepted {} (acceptance {:.3})",
                s["name"], s["selected"], s["accepted"], s["acceptance"]
            );
        }
        last = renders;
    }
    (scene, reference, last)
}

/// Image side of the agreement renders: 4×4 regions of 8×8 pixels. (At 16×16 with 512 mutations
/// per pixel the power check failed: a 10% share error would reach only |z| = 2.4 in the box's
/// region 9; the share's noise depends on the mutations per render, not on the pixels.)
const SIZE: u32 = 32;
/// The strategies of the agreement tests: the bidirectional mutation with each perturbation alone,
/// and all of them (the defaults).
const LENS: Config =
    ("bidirectional + lens", "max_depth = 8\nbootstrap = 20000\nchains = 64\ncaustic = 0\nmulti_chain = 0");
const CAUSTIC: Config =
    ("bidirectional + caustic", "max_depth = 8\nbootstrap = 20000\nchains = 64\nlens = 0\nmulti_chain = 0");
const MULTI_CHAIN: Config =
    ("bidirectional + multi-chain", "max_depth = 8\nbootstrap = 20000\nchains = 64\nlens = 0\ncaustic = 0");
const ALL: Config = ("all strategies", "max_depth = 8\nbootstrap = 20000\nchains = 64");

/// The Cornell box: no specular vertex, so the caustic and multi-chain perturbations are never
/// suitable and "all" is the bidirectional mutation with the lens perturbation; the brightness (b)
/// is tested too. Wrong chain: with the addition-length probability left out of the bidirectional
/// mutation's T (the furnace test's wrong variant) the shares must fail.
#[test]
fn pmlt_agrees_with_pt_on_cornell_box() {
    let (scene, reference, right) = pmlt_agrees_with("cornell-box", &[ALL], 768, ("pt", 1024));
    assert_brightness_agrees("pmlt vs pt on cornell-box", &right, &reference);
    let mut wrong = pmlt_with(ALL.1);
    wrong.settings.lens = 0.0;
    wrong.bidirectional = Bidirectional { omit_addition_pmf: true, ..Bidirectional::default() };
    let (renders, _) = pmlt_regions(&scene, &wrong, 256);
    let a = share_agreement(&renders, &reference);
    println!("pmlt vs pt on cornell-box, T without p_a: worst |z| = {:.2}\n{}", a.worst_z, a.report());
    assert!(a.worst_z >= Z_CRITICAL, "a wrong T passed the share test: |z| = {:.2}", a.worst_z);
}

/// The glossy Cornell box (a rough gold conductor): the lens perturbation reconnects at glossy
/// vertices too.
#[test]
fn pmlt_agrees_with_pt_on_cornell_glossy() {
    // 1024 mutations and 1536 spp: the rough-coating plastic (a darker blue block) left region 8
    // at power 4.9 with 768 / 1024.
    pmlt_agrees_with("cornell-glossy", &[ALL], 1024, ("pt", 1536));
}

/// The glass Cornell box with all strategies: the glass sphere seen directly (E S S D L, the lens
/// perturbation's retrace), the caustic on the floor (E D S S L, the caustic perturbation) and
/// caustics seen through the sphere (E S S D S S L, the multi-chain perturbation). The reference
/// is BDPT (tested against the path tracer in tests/bdpt.rs), whose light-tracing techniques see
/// the floor caustic with far less variance than the path tracer, which would otherwise dominate
/// the share test's noise in the sphere's regions.
///
/// Not run by default: the shares agree but the power check fails. Measured (2026-12-02, 32×32, 64
/// chains × 1024 mutations per pixel, BDPT 256 spp): worst |z| = 1.84, but a 10% share error would
/// reach only |z| = 3.0 in region 10 and 2.1 in region 14 (the sphere), 5 needed; about 6× the
/// mutations (or a less noisy reference) would be needed, beyond the test budget.
#[test]
#[ignore = "power check fails in the sphere's regions 10 and 14 at this budget (see doc comment)"]
fn pmlt_agrees_with_bdpt_on_cornell_glass() {
    pmlt_agrees_with("cornell-glass", &[ALL], 1024, ("bdpt", 256));
}

/// Each perturbation alone with the bidirectional mutation on the glass box (as above). Not run by
/// default: three more sets of 16 renders, beyond issues 13 and 14's test budget.
#[test]
#[ignore = "three more sets of 16 renders: beyond the test budget (run with --ignored)"]
fn pmlt_each_perturbation_agrees_with_bdpt_on_cornell_glass() {
    pmlt_agrees_with("cornell-glass", &[LENS, CAUSTIC, MULTI_CHAIN], 1024, ("bdpt", 256));
}

/// The region means of 16 renders of portal-planes by pmlt with `params` (seeds as
/// `render_regions`); `omit_geometry` renders with the portal perturbation's wrong variant.
fn portal_regions(scene: &Scene, params: &str, mpp: u64, omit_geometry: bool) -> Vec<Vec<f64>> {
    let table: toml::Table = toml::from_str(params).expect("test parameters");
    let mut pmlt = Pmlt::from_params(&table).expect("settings");
    pmlt.portal = PortalPerturbation { omit_geometry };
    (1..=RENDERS)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed: k * 7919 + 3, threads: 2 };
            let out = pmlt.render(scene, &job, &NoProgress).expect("render");
            assert!(out.image.all_finite(), "non-finite pixels");
            region_means(&out.image)
        })
        .collect()
}

/// pmlt's settings and mutations per pixel of the portal-planes tests (bidirectional + portal).
const PORTAL_PLANES_PARAMS: &str =
    "max_depth = 8\nbootstrap = 20000\nchains = 1024\nbidirectional = 1.0\nportal = 1.0\nlens = 0.0\ncaustic = 0.0\nmulti_chain = 0.0";
const PORTAL_PLANES_MPP: u64 = 1024;

/// The portal perturbation (issue 15) on the portal paper's Fig. 4 scene, with the bidirectional
/// mutation only beside it: the region shares of 16 pmlt renders (32×32, 64 chains) against the
/// committed reference `references/portal-planes.exr` (BDPT, 8192 spp at 32×32,
/// `scripts/make-references.sh`), by tests/common/agreement.rs's share test (Welch's z < 5 with
/// its power check: a 10% error of any region's share must reach |z| = 5), the reference's own
/// variance estimated from its pixels (`relative_noise_of_region_means`). 1024 chains of 1024
/// mutations each, about 1.5 image-plane autocorrelation times (~700 mutations with the portal
/// perturbation, `scripts/bench-portals.sh`), so the chains move well away from their resampled
/// bootstrap starts; fewer mutations leave the power check short (measured: 3.2 at 256 per pixel).
///
/// Measured (2026-12-02, under load ~14 on 2 cores, 136 s with the wrong variant below at 1/8 of
/// the mutations; the agreement part ~100 s): worst |z| = 1.87 (region 14), the power check's
/// weakest region 12 at z = 5.1 for a 10% error, the reference's noise 0.23–0.70 of the chain's
/// standard error per region.
#[test]
fn pmlt_portal_agrees_with_the_reference_on_portal_planes() {
    let scene = scene("portal-planes", 32);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let reference_image = read_exr(&root.join("references/portal-planes.exr")).expect("reference");
    let reference = vec![region_means(&reference_image); RENDERS as usize];
    let (params, mpp) = (PORTAL_PLANES_PARAMS, PORTAL_PLANES_MPP);
    let renders = portal_regions(&scene, params, mpp, false);
    let what = "pmlt (bidirectional + portal) vs the reference on portal-planes";
    // The share test of tests/common/agreement.rs with the reference's own noise (estimated from
    // its pixels) as the reference side's variance: Welch's z = (m − m_ref)/√(v + v_ref).
    let a = share_agreement(&renders, &reference);
    let (_, variance) = mean_and_variance_of_mean(&shares(&renders));
    let noise = relative_noise_of_region_means(&reference_image);
    let mut worst = 0.0f64;
    for (r, (&v, &nz)) in variance.iter().zip(&noise).enumerate() {
        let sd = (v + nz * nz).sqrt();
        let (z, power) = ((a.method[r] - a.reference[r]) / sd, SHARE_ERROR * a.reference[r] / sd);
        println!(
            "  region {r:2}: share {:.4} vs {:.4}  z = {z:+.2}  (a 10% error: z = {power:.1}; reference noise {:.2} of the chain's)",
            a.method[r],
            a.reference[r],
            nz / v.sqrt()
        );
        assert!(a.reference[r] < POWER_SHARE_FLOOR || power > Z_CRITICAL, "{what}: too weak in region {r}");
        worst = worst.max(z.abs());
    }
    println!("{what}: worst |z| = {worst:.2}");
    assert!(worst < Z_CRITICAL, "{what}: region shares disagree (|z| = {worst:.2})");
    let (_, stats) = render(&scene, params, 64, 1, 2);
    println!("{what}: {}\n{}", stats["strategies"][0], stats["strategies"][1]);
    assert_eq!(stats["strategies"][1]["name"], "portal");
}

/// **Wrong variant** of the test above: the portal perturbation without the G terms of its
/// acceptance ratio (T = k/|n·ω*|, `PortalPerturbation::omit_geometry`), whose portal moves alone
/// would sample f·G(x_i, x_{i+1}) and so over-weight the reflector's centre (G through the hole up
/// to 4.5× larger there than at the film's corners). Measured (2026-12-02, 243 s under load, a
/// benchmark running beside it): worst |z| = 14.53, the centre region 5's share +12% (z = +12.6)
/// and the corner region 12's −18% (z = −12.4): rejected. Not run by default: it doubles the
/// portal-planes test's time beyond issue 15's budget, and at 1/8 of the mutations (128 per
/// chain, 1/5 of the image-plane autocorrelation time, so the chains hardly leave their correct
/// bootstrap starts) it reached only |z| = 3.79.
#[test]
#[ignore = "doubles the portal-planes test's time (see doc comment)"]
fn pmlt_portal_without_g_terms_fails_on_portal_planes() {
    let scene = scene("portal-planes", 32);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let reference_image = read_exr(&root.join("references/portal-planes.exr")).expect("reference");
    let reference = vec![region_means(&reference_image); RENDERS as usize];
    let wrong = share_agreement(&portal_regions(&scene, PORTAL_PLANES_PARAMS, PORTAL_PLANES_MPP, true), &reference);
    println!("portal-planes without the G terms: worst |z| = {:.2}\n{}", wrong.worst_z, wrong.report());
    assert!(wrong.worst_z >= Z_CRITICAL, "the ratio without G passed the share test: |z| = {:.2}", wrong.worst_z);
}

/// Same seed and thread count: the same bits; another thread count too (chains are the driver's
/// units, applied in unit order); another seed: another image.
#[test]
fn pmlt_is_deterministic() {
    let scene = scene("cornell-glass", 16);
    let params = "bootstrap = 2000\nchains = 32";
    let bits = |img: &Image| img.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    let a = render(&scene, params, 8, 5, 2).0;
    let b = render(&scene, params, 8, 5, 2).0;
    let c = render(&scene, params, 8, 5, 1).0;
    let d = render(&scene, params, 8, 6, 2).0;
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(bits(&a), bits(&c));
    assert_ne!(bits(&a), bits(&d));
}

/// A scene whose only emitter faces away from everything renders black, with the warning on stderr
/// (and in the JSON), exit 0.
#[test]
fn pmlt_on_a_black_scene_is_black_with_a_warning_on_stderr() {
    let dir = temp_dir("pmlt-black");
    // The lamp turned to face up, into empty space: no path reaches the camera.
    let text = tiny_scene("[8, 8]", "")
        .replace("angle = 90 }, translate = [0.0, 2.0, 0.0]", "angle = -90 }, translate = [0.0, 2.0, 0.0]");
    std::fs::write(dir.path().join("black.toml"), text).expect("write scene");
    let out = plexus(
        &[
            "render",
            "black.toml",
            "--integrator",
            "pmlt",
            "--spp",
            "2",
            "--set",
            "bootstrap=2000",
            "--set",
            "chains=4",
            "-o",
            "black.exr",
        ],
        dir.path(),
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning: no bootstrap path"), "no warning on stderr: {err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("black.json")).expect("json")).expect("parse");
    assert!(!json["integrator_stats"]["warnings"].as_array().expect("warnings").is_empty());
    assert_eq!(json["image_mean"].as_array().map(|m| m.iter().all(|v| v.as_f64() == Some(0.0))), Some(true), "{json}");
}

/// Bad settings are refused with the setting's name (exit 2 at the CLI), before any work.
#[test]
fn pmlt_settings_are_validated() {
    for (params, needle) in [("max_depth = 2000", "max_depth"), ("chains = 0", "chains"), ("sigma = 0.1", "sigma")] {
        let table: toml::Table = toml::from_str(params).expect("toml");
        let err = create("pmlt", &table).err().unwrap_or_else(|| panic!("accepted {params}")).to_string();
        assert!(err.contains(needle), "{params}: {err}");
    }
}
