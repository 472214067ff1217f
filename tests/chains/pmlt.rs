//! Path-space MLT (`integrator = "pmlt"`, the bidirectional mutation and the perturbations)
//! against the path tracer, and its determinism and black-scene behaviour. The transition density and the path-length shares are
//! tested inside the library (`integrator::path_space::tests`), where the wrong variants can be
//! switched on.
//!
//! # Agreement
//! As for the primary-sample-space methods (tests/chains/mlt.rs explains it; tests/common/agreement.rs
//! states the bounds): with expected-value splatting the image mean is b, so the **region shares**
//! (4×4 regions, region mean ÷ the render's image mean) of 16 renders test the chain, by Welch's z
//! with |z| < 5 and a power check (a 10% error of any region's share holding at least a quarter of
//! the average share must reach |z| = 5); the **brightness** (image mean, with a 5% power check)
//! tests b, which pmlt takes from its BDPT bootstrap alone (on the box, against 16 path-traced
//! renders). The shares are compared with the committed path-traced references
//! (`references/<scene>.exr`, 4096 spp at 128×128, max_depth 8 as here), whose own noise is
//! estimated from their pixels: the test's standard error is then essentially pmlt's (the
//! reference's noise is 0.1–0.4 of it outside the lamp's regions, whose estimate the lamp's edges
//! inflate), where 16 path-traced or BDPT renders had been most of it in the glass sphere's regions.
//!
//! Strategies per scene (each perturbation with the bidirectional mutation where it is suitable):
//! the box and the glossy box have no specular surface, so the caustic and multi-chain
//! perturbations are never suitable there (asserted: selected 0 times with their weights on) and
//! "all" is bidirectional + lens; on the glass box "all", bidirectional + caustic and
//! bidirectional + multi-chain run by default (bidirectional + lens alone is all but the "all" run
//! again, ignored). Each run asserts that its perturbations were exercised (≥ 1000 accepted
//! proposals in its first render). 32×32, renders of 768–2048 mutations per pixel, so that the
//! chains' stationary distribution, not the resampled bootstrap they start from, makes the image.
//!
//! Measured (2026-12-03, CPU seconds on the shared 2-core machine at load ~15; see each test):
//! - cornell-box (64 chains × 768, bootstrap 40,000): worst |z| = 1.78, weakest power 6.1 (the
//!   lamp's region 1; a 10% share error's z), brightness z = −0.62 (relative standard error
//!   0.0067); acceptance bidirectional 19.1%, lens 64.7%; 35 CPU s with the wrong variant below.
//! - cornell-glossy (64 × 1024): worst |z| = 1.65, weakest power 6.0; ~20 CPU s.
//! - cornell-glass, all (1024 chains × 2048, bidirectional weight 2, `ALL_GLASS`): worst |z| = 3.49
//!   (region 13), weakest power 5.5 (region 14); caustic / multi-chain proposals accepted 13,252 /
//!   5,359 in the first render; 58 CPU s.
//! - cornell-glass, bidirectional + caustic and + multi-chain (1024 × 1536): worst |z| = 1.39 and
//!   1.95, weakest power 6.2 and 5.2 (region 14); accepted 27,648 (83%) and 9,124 (31%); 104 CPU s.
//!
//! **Wrong chains**: the box's test asserts that the bidirectional T without the addition-length
//! probability fails (|z| = 42.6 at 256 mutations per pixel); the ignored `pmlt_wrong_perturbations_fail_on_cornell_glossy_and_glass`
//! showed the lens perturbation's T with the connection's G failing at |z| = 54.3 (glossy) and
//! 67.3 (glass). The multi-chain perturbation's wrong variant is its χ² test's (perturb_tests.rs).

use crate::common::agreement::{
    assert_brightness_agrees, assert_shares_agree_with_image, image_share_agreement, region_means, render_regions,
    GRID, RENDERS, Z_CRITICAL,
};
use crate::common::binary::{plexus, stderr, temp_dir, tiny_scene};
use crate::common::scenes::{reference, scene};

use plexus::film::Image;
use plexus::integrator::path_space::bidirectional::Bidirectional;
use plexus::integrator::path_space::caustic::Caustic;
use plexus::integrator::path_space::lens::Lens;
use plexus::integrator::path_space::Pmlt;
use plexus::integrator::{create, Budget, Integrator, NoProgress, RenderJob};
use plexus::scene::Scene;

fn render(scene: &Scene, params: &str, mpp: u64, seed: u64, threads: usize) -> (Image, serde_json::Value) {
    let params: toml::Table = toml::from_str(params).expect("test parameters");
    let integrator = create("pmlt", &params).expect("integrator");
    let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed, threads };
    let out = integrator.render(scene, &job, &NoProgress).expect("render");
    (out.image, out.extra_stats)
}

/// One pmlt configuration of an agreement test: its label, its `[integrator]` table, the
/// perturbations that must have been exercised (selected and accepted, `EXERCISED_FLOOR`) and those
/// that must never have been suitable on the scene (selected 0 times although their weight is on).
struct Config {
    label: &'static str,
    params: &'static str,
    exercised: &'static [&'static str],
    never_suitable: &'static [&'static str],
}

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

/// A strategy's figures in a render's statistics, by name: (selected, accepted).
fn strategy_counts(stats: &serde_json::Value, name: &str) -> (u64, u64) {
    let s = stats["strategies"].as_array().into_iter().flatten().find(|s| s["name"] == name);
    s.map(|s| (s["selected"].as_u64().unwrap_or(0), s["accepted"].as_u64().unwrap_or(0))).unwrap_or((0, 0))
}

/// An exercised perturbation must have had at least this many proposals accepted in the first
/// render (of about a million iterations: the caustic and multi-chain perturbations are suitable
/// only on the few paths through the glass sphere, ~1% of the iterations).
const EXERCISED_FLOOR: u64 = 1000;

/// Each configuration's region shares against the committed reference of `name` at `SIZE`×`SIZE`,
/// with the power check (`assert_shares_agree_with_image`); prints each strategy's acceptance
/// and asserts the configuration's exercised and never-suitable perturbations. Returns the scene,
/// the reference and the last configuration's renders (for the brightness check).
fn pmlt_agrees_with(name: &str, configs: &[Config], mpp: u64) -> (Scene, Image, Vec<Vec<f64>>) {
    let scene = scene(name, SIZE);
    let reference = reference(name);
    let mut last = Vec::new();
    for config in configs {
        let (renders, stats) = pmlt_regions(&scene, &pmlt_with(config.params), mpp);
        let what = format!("pmlt ({}) vs the pt reference on {name}", config.label);
        for s in stats["strategies"].as_array().into_iter().flatten() {
            println!(
                "{what}: {} selected {} accepted {} (acceptance {:.3})",
                s["name"], s["selected"], s["accepted"], s["acceptance"]
            );
        }
        for &p in config.exercised {
            let (selected, accepted) = strategy_counts(&stats, p);
            assert!(
                accepted >= EXERCISED_FLOOR,
                "{what}: {p} hardly exercised: selected {selected}, accepted {accepted}"
            );
        }
        for &p in config.never_suitable {
            assert_eq!(strategy_counts(&stats, p).0, 0, "{what}: {p} was suitable on {name}");
        }
        assert_shares_agree_with_image(&what, &renders, &reference, GRID);
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
const LENS: Config = Config {
    label: "bidirectional + lens",
    params: "max_depth = 8\nbootstrap = 20000\nchains = 1024\ncaustic = 0\nmulti_chain = 0",
    exercised: &["lens"],
    never_suitable: &[],
};
const CAUSTIC: Config = Config {
    label: "bidirectional + caustic",
    params: "max_depth = 8\nbootstrap = 20000\nchains = 1024\nlens = 0\nmulti_chain = 0",
    exercised: &["caustic"],
    never_suitable: &[],
};
const MULTI_CHAIN: Config = Config {
    label: "bidirectional + multi-chain",
    params: "max_depth = 8\nbootstrap = 20000\nchains = 1024\nlens = 0\ncaustic = 0",
    exercised: &["multi_chain"],
    never_suitable: &[],
};
const ALL: Config = Config {
    label: "all strategies",
    params: "max_depth = 8\nbootstrap = 20000\nchains = 1024",
    exercised: &["lens", "caustic", "multi_chain"],
    never_suitable: &[],
};
/// All strategies on the glass box, the bidirectional mutation's weight doubled (1/2 of the
/// selections where any perturbation is suitable, the perturbations sharing the other half): at the
/// default 1/3 the sphere's regions 10 and 14 stayed below the power check at 1024 chains × 2048
/// mutations per pixel (a 10% share error at |z| = 4.1 and 4.9), the lens perturbation's small
/// steps mixing the chains between the sphere's small bright features (the lamp's image in it,
/// the caustic) more slowly than the bidirectional mutation's jumps.
const ALL_GLASS: Config =
    Config { params: "max_depth = 8\nbootstrap = 20000\nchains = 1024\nbidirectional = 2", ..ALL };
/// All strategies on a scene without specular surfaces: the caustic and multi-chain perturbations
/// are never suitable there (both need a specular vertex), so "all" is the bidirectional mutation
/// with the lens perturbation, and "bidirectional + caustic" or "+ multi-chain" would be the
/// bidirectional mutation alone; asserted instead of rendered.
const ALL_WITHOUT_SPECULAR: Config = Config {
    label: "all strategies",
    params: "max_depth = 8\nbootstrap = 20000\nchains = 64",
    exercised: &["lens"],
    never_suitable: &["caustic", "multi_chain"],
};

/// The box's configuration: `ALL_WITHOUT_SPECULAR` with a bootstrap twice as large, for the
/// brightness test's power (b's relative standard error over 16 renders was 0.99% with 20,000
/// bootstrap samples, at the 1% that the 5% power check allows).
const BOX: Config = Config { params: "max_depth = 8\nbootstrap = 40000\nchains = 64", ..ALL_WITHOUT_SPECULAR };

/// Samples per pixel of the path-traced renders the brightness is compared with (their image mean's
/// relative standard error is ~0.2%, the bootstrap's b's ~1%).
const BRIGHTNESS_PT_SPP: u64 = 64;

/// The Cornell box: no specular vertex (`ALL_WITHOUT_SPECULAR`); the brightness (b) is tested
/// too. Wrong chain: with the addition-length probability left out of the bidirectional
/// mutation's T (the furnace test's wrong variant) the shares must fail.
#[test]
fn pmlt_agrees_with_pt_on_cornell_box() {
    let (scene, reference, right) = pmlt_agrees_with("cornell-box", &[BOX], 768);
    // The brightness against 16 path-traced renders (the reference image's own noise estimate is
    // inflated by the lamp's edges, `relative_noise_of_region_means`, which only weakens the share
    // test in the lamp's regions but would swamp the image mean's).
    let pt = render_regions(&scene, "pt", "max_depth = 8", BRIGHTNESS_PT_SPP, 3, RENDERS);
    assert_brightness_agrees("pmlt vs pt on cornell-box", &right, &pt);
    let mut wrong = pmlt_with(BOX.params);
    wrong.settings.lens = 0.0;
    wrong.bidirectional = Bidirectional { omit_addition_pmf: true, ..Bidirectional::default() };
    let (renders, _) = pmlt_regions(&scene, &wrong, 256);
    let a = image_share_agreement(&renders, &reference, GRID);
    println!("pmlt vs pt on cornell-box, T without p_a: worst |z| = {:.2}\n{}", a.worst_z, a.report());
    assert!(a.worst_z >= Z_CRITICAL, "a wrong T passed the share test: |z| = {:.2}", a.worst_z);
}

/// The glossy Cornell box (a rough gold conductor and a rough plastic block, no specular surface):
/// the lens perturbation reconnects at glossy vertices too.
#[test]
fn pmlt_agrees_with_pt_on_cornell_glossy() {
    pmlt_agrees_with("cornell-glossy", &[ALL_WITHOUT_SPECULAR], 1024);
}

/// The glass Cornell box with all strategies: the glass sphere seen directly (E S S D L, the lens
/// perturbation's retrace), the caustic on the floor (E D S S L, the caustic perturbation) and
/// caustics seen through the sphere (E S S D S S L, the multi-chain perturbation).
#[test]
fn pmlt_agrees_with_pt_on_cornell_glass() {
    pmlt_agrees_with("cornell-glass", &[ALL_GLASS], 2048);
}

/// Each perturbation alone with the bidirectional mutation on the glass box (as above).
#[test]
fn pmlt_each_perturbation_agrees_with_pt_on_cornell_glass() {
    pmlt_agrees_with("cornell-glass", &[CAUSTIC, MULTI_CHAIN], 1536);
}

/// The lens perturbation alone with the bidirectional mutation on the glass box. Not run by
/// default: in `pmlt_agrees_with_pt_on_cornell_glass` the lens perturbation makes 98% of the
/// perturbations' selections (the caustic and multi-chain perturbations are suitable on ~1.6% of
/// the iterations), so this run differs from that one in those iterations only, at its cost again.
/// Note that this configuration keeps the default bidirectional weight (1/3 of the iterations),
/// where the "all" run uses 2 (1/2) for power: measured (2026-12-03, idle, 59 CPU s) the shares
/// agree (worst |z| = 2.28) but the power check fails in region 10 (the sphere), as the "all"
/// run's did at the default weight, so as it stands this test fails its power check.
#[test]
#[ignore = "all but the same run as pmlt_agrees_with_pt_on_cornell_glass (see doc comment)"]
fn pmlt_lens_alone_agrees_with_pt_on_cornell_glass() {
    pmlt_agrees_with("cornell-glass", &[LENS], 2048);
}

/// The share test's **wrong variants** on the glossy and glass scenes (the box's runs in its
/// test): renders at the glossy and glass tests' settings with the lens perturbation's T as if
/// the connection edge had been traced (`Lens::connection_g_in_t`, the χ² test's wrong variant),
/// and, on the glass box with the caustic perturbation, T per projected solid angle at the pivot
/// (`Caustic::omit_pivot_cos`). Prints each run's worst |z|; asserts the lens variant fails on both
/// scenes. Not run by default (the cost of the two agreement tests again: 137 CPU s). Measured
/// (2026-12-03): the lens variant |z| = 54.3 (glossy) and 67.3 (glass); the caustic variant only
/// |z| = 2.46, not seen: at Veach's kernel width (~0.01 rad at the caustic's pivot here) a move
/// changes the pivot's cosine too little to shift the image measurably, which is why its χ² test
/// (perturb_tests.rs) widens the kernel; there it is rejected (χ² = 191.9, p = 1e-12).
#[test]
#[ignore = "the glossy and glass agreement tests' cost again (see doc comment)"]
fn pmlt_wrong_perturbations_fail_on_cornell_glossy_and_glass() {
    for (name, config, mpp) in [("cornell-glossy", ALL_WITHOUT_SPECULAR, 1024), ("cornell-glass", ALL, 2048)] {
        let scene = scene(name, SIZE);
        let mut wrong = pmlt_with(config.params);
        wrong.lens = Lens { connection_g_in_t: true };
        let a = image_share_agreement(&pmlt_regions(&scene, &wrong, mpp).0, &reference(name), GRID);
        println!("{name}, lens T with the connection's G: worst |z| = {:.2}\n{}", a.worst_z, a.report());
        assert!(a.worst_z >= Z_CRITICAL, "{name}: a wrong lens T passed: |z| = {:.2}", a.worst_z);
    }
    let scene = scene("cornell-glass", SIZE);
    let mut wrong = pmlt_with(CAUSTIC.params);
    wrong.caustic = Caustic { omit_pivot_cos: true, ..Caustic::default() };
    let a = image_share_agreement(&pmlt_regions(&scene, &wrong, 1536).0, &reference("cornell-glass"), GRID);
    println!("cornell-glass, caustic T without the pivot's |cos|: worst |z| = {:.2}\n{}", a.worst_z, a.report());
}

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
