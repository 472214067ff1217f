//! The portal perturbation (issue 15; Otsu, Hanika & Dachsbacher, Sec. 4) against committed
//! references: `pmlt` with portals on the paper's Fig. 4 scene (portal-planes) and on a window
//! interior lit by an environment (breakfast-window), by region shares with the power check of
//! tests/common/agreement.rs, and the deliberately wrong variant (the acceptance ratio without its
//! G terms) rejected by the same test. The portal move's own density, reverse consistency and
//! early rejections are tested inside the library (`integrator::path_space::portal`).
//!
//! # The share test against a committed reference
//! A reference render is one image, not 16 independent renders, so the reference side's variance
//! of a region's share is estimated from the image's own pixels
//! ([`relative_noise_of_region_means`]); Welch's z is (m − m_ref)/√(v + v_ref) with v the
//! variance of the mean share over the 16 pmlt renders, bounded by |z| < 5 (Bonferroni over 16
//! regions, tests/common/agreement.rs), and the power check asks that a 10% error of any region's
//! share holding at least a quarter of the average share reach |z| = 5.

use std::path::Path;

mod common;
use common::agreement::{
    mean_and_variance_of_mean, region_means, shares, GRID, POWER_SHARE_FLOOR, REGIONS, RENDERS, SHARE_ERROR, Z_CRITICAL,
};

use plexus::camera::Camera;
use plexus::film::exr_io::read_exr;
use plexus::film::Image;
use plexus::integrator::path_space::portal::PortalPerturbation;
use plexus::integrator::path_space::Pmlt;
use plexus::integrator::{Budget, Integrator, NoProgress, RenderJob};
use plexus::scene::{load_scene, Scene};
use plexus::spectrum::luminance;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `scenes/<name>.toml` with its camera at `size`×`size` pixels (the same field of view: the
/// regions cover the same parts of the film at any size, so a reference's region means hold at
/// every size).
fn scene(name: &str, size: u32) -> Scene {
    let path = root().join("scenes").join(format!("{name}.toml"));
    let mut scene = load_scene(&path, None).unwrap_or_else(|e| panic!("{}: {e}", path.display())).scene;
    let c = &scene.camera;
    scene.camera = Camera::new(c.position, c.position + c.forward, c.up, c.fov_y_degrees, size, size);
    scene
}

fn reference(name: &str) -> Image {
    read_exr(&root().join("references").join(format!("{name}.exr"))).expect("reference")
}

/// The region means of 16 pmlt renders of `scene` with `params` (seeds k·7919 + 3, as
/// `render_regions`), each finite and dropping nothing; `omit_geometry` renders with the portal
/// perturbation's wrong variant. Also the first render's statistics.
fn portal_regions(scene: &Scene, params: &str, mpp: u64, omit_geometry: bool) -> (Vec<Vec<f64>>, serde_json::Value) {
    let table: toml::Table = toml::from_str(params).expect("test parameters");
    let mut pmlt = Pmlt::from_params(&table).expect("settings");
    pmlt.portal = PortalPerturbation { omit_geometry };
    let mut stats = serde_json::Value::Null;
    let regions = (1..=RENDERS)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed: k * 7919 + 3, threads: 2 };
            let out = pmlt.render(scene, &job, &NoProgress).expect("render");
            assert!(out.image.all_finite(), "non-finite pixels");
            assert_eq!(out.counters.nonfinite_dropped, 0, "non-finite contributions");
            if k == 1 {
                stats = out.extra_stats;
            }
            region_means(&out.image)
        })
        .collect();
    (regions, stats)
}

/// The luminance noise of each region's mean in `image` (regions as `region_means`), relative to
/// the image mean, from second differences of horizontally adjacent pixels: for independent pixel
/// noise σ², E[(v_{x+1} − 2v_x + v_{x−1})²] = 6σ², and a smooth image gradient drops out to first
/// order (what is left of the image's curvature and edges only inflates the estimate, which makes
/// the share test more conservative and its power check harder to pass).
fn relative_noise_of_region_means(image: &Image) -> Vec<f64> {
    let lum = |x: usize, y: usize| luminance(image.get(x, y)) as f64;
    let mean = region_means(image)[REGIONS];
    let region = |x: usize, y: usize| (y * GRID / image.height) * GRID + x * GRID / image.width;
    let (mut sq, mut diffs, mut pixels) = (vec![0.0; REGIONS], vec![0usize; REGIONS], vec![0usize; REGIONS]);
    for y in 0..image.height {
        for x in 0..image.width {
            let r = region(x, y);
            pixels[r] += 1;
            if x >= 1 && x + 1 < image.width && region(x - 1, y) == r && region(x + 1, y) == r {
                sq[r] += (lum(x + 1, y) - 2.0 * lum(x, y) + lum(x - 1, y)).powi(2);
                diffs[r] += 1;
            }
        }
    }
    (0..REGIONS).map(|r| (sq[r] / (6.0 * diffs[r] as f64) / pixels[r] as f64).sqrt() / mean).collect()
}

/// The share test against a committed reference (module docs): per region Welch's z and the z a
/// 10% share error would reach. Returns (z, power z) per region and prints them.
fn shares_against_reference(what: &str, renders: &[Vec<f64>], reference_image: &Image) -> (Vec<f64>, Vec<f64>) {
    let reference = shares(&[region_means(reference_image)]).remove(0);
    let (mean, variance) = mean_and_variance_of_mean(&shares(renders));
    let noise = relative_noise_of_region_means(reference_image);
    let (mut z, mut power) = (Vec::new(), Vec::new());
    for r in 0..REGIONS {
        let sd = (variance[r] + noise[r] * noise[r]).sqrt();
        z.push((mean[r] - reference[r]) / sd);
        power.push(SHARE_ERROR * reference[r] / sd);
        println!(
            "  {what}, region {r:2}: share {:.4} vs {:.4}  z = {:+.2}  (a 10% error: z = {:.1}; reference noise {:.2} of \
             the chain's)",
            mean[r],
            reference[r],
            z[r],
            power[r],
            noise[r] / variance[r].sqrt()
        );
    }
    (z, power)
}

/// Asserts the power check and then agreement (module docs); returns the worst |z|.
fn assert_agrees_with_reference(what: &str, renders: &[Vec<f64>], reference_image: &Image) -> f64 {
    let (z, power) = shares_against_reference(what, renders, reference_image);
    let reference = shares(&[region_means(reference_image)]).remove(0);
    for r in 0..REGIONS {
        assert!(
            reference[r] < POWER_SHARE_FLOOR || power[r] > Z_CRITICAL,
            "{what}: too weak in region {r} (a 10% error: z = {:.2})",
            power[r]
        );
    }
    let worst = z.iter().fold(0.0f64, |w, z| w.max(z.abs()));
    println!("{what}: worst |z| = {worst:.2}");
    assert!(worst < Z_CRITICAL, "{what}: region shares disagree (|z| = {worst:.2})");
    worst
}

/// Prints each strategy's acceptance from a render's statistics.
fn print_acceptance(what: &str, stats: &serde_json::Value) {
    for s in stats["strategies"].as_array().into_iter().flatten() {
        println!(
            "{what}: {} selected {} accepted {} (acceptance {:.3})",
            s["name"], s["selected"], s["accepted"], s["acceptance"]
        );
    }
}

/// pmlt's settings and mutations per pixel of the portal-planes tests: the bidirectional mutation
/// and the portal perturbation only (issue 15's "a chain with only portal and bidirectional
/// mutations"), 64 chains.
const PORTAL_PLANES_PARAMS: &str =
    "max_depth = 8\nbootstrap = 20000\nchains = 64\nbidirectional = 1.0\nportal = 1.0\nlens = 0.0\ncaustic = 0.0\nmulti_chain = 0.0";
const PORTAL_PLANES_MPP: u64 = 1536;

/// The portal perturbation on the portal paper's Fig. 4 scene with the bidirectional mutation
/// beside it: the region shares of 16 pmlt renders (32×32, 64 chains, 1536 mutations per pixel)
/// against the committed reference `references/portal-planes.exr` (BDPT, 8192 spp at 32×32,
/// `scripts/make-references.sh`), by the module's share test.
///
/// The chains are few and long (24,576 mutations each, ~35 image-plane autocorrelation times of
/// ~700 mutations, `scripts/bench-portals.sh`) so that the chain's own stationary distribution,
/// not the resampled bootstrap it starts from, makes the image: that is what lets the wrong
/// variant below fail at the same settings. The shares' noise depends on the mutations per render
/// (measured: the same power with 1024 chains × 1024 mutations as with 64 × 16,384 at equal
/// totals), and 1536 per pixel is what the power check needs (measured 4.92 at 1024, 5 needed).
///
/// Measured (2026-12-03, load ~15 on 2 cores; this test and the wrong variant together 71.8 CPU
/// s): worst |z| = 2.57 (region 5), the power check's weakest region 2 at z = 6.2 for a 10% error,
/// the reference's noise 0.29–0.69 of the chains' standard error per region; acceptance
/// bidirectional 2.3%, portal 97.9%.
#[test]
fn pmlt_portal_agrees_with_the_reference_on_portal_planes() {
    let scene = scene("portal-planes", 32);
    let what = "pmlt (bidirectional + portal) vs the reference on portal-planes";
    let (renders, stats) = portal_regions(&scene, PORTAL_PLANES_PARAMS, PORTAL_PLANES_MPP, false);
    print_acceptance(what, &stats);
    assert_eq!(stats["strategies"][1]["name"], "portal");
    assert_agrees_with_reference(what, &renders, &reference("portal-planes"));
}

/// **Wrong variant**, rejected by the same test at the same settings: the portal perturbation
/// without the G terms of its acceptance ratio (T = k/|n·ω*|, `PortalPerturbation::omit_geometry`),
/// whose portal moves alone would sample f·G(x_i, x_{i+1}) and so over-weight the reflector's
/// centre (G through the hole up to 4.5× larger there than at the film's corners). Measured
/// (2026-12-03): worst |z| = 18.56, the four centre regions' shares +14% to +17% (z = +13.9 to
/// +18.0) and the four corners' −19% to −21% (z = −14.9 to −18.6): rejected. (With the old
/// settings, 1024 chains of 128 mutations, a fifth of the image-plane autocorrelation time, it
/// reached only |z| = 3.79: the chains hardly left their correct bootstrap starts.)
#[test]
fn pmlt_portal_without_g_terms_fails_on_portal_planes() {
    let scene = scene("portal-planes", 32);
    let what = "pmlt (bidirectional + portal without the G terms) vs the reference on portal-planes";
    let (renders, _) = portal_regions(&scene, PORTAL_PLANES_PARAMS, PORTAL_PLANES_MPP, true);
    let (z, _) = shares_against_reference(what, &renders, &reference("portal-planes"));
    let worst = z.iter().fold(0.0f64, |w, z| w.max(z.abs()));
    println!("{what}: worst |z| = {worst:.2}");
    assert!(worst >= Z_CRITICAL, "{what}: the ratio without G passed the share test (|z| = {worst:.2})");
}

/// The window interior (scenes/breakfast-window.toml: the breakfast room lit by the procedural sky,
/// its sun shining in, through one window with a portal on it) with the paper's configuration
/// (bidirectional 1/2, the local half shared by the lens and the portal perturbation: weights
/// 2, 2, 2), against the committed reference `references/breakfast-window.exr` (pt, 32,768 spp at
/// 32×32, `scripts/make-references.sh`), by the module's share test. 1024 chains (at 64 chains the
/// shares' noise was ~2.6× higher at equal mutations: the chains stay long on the sun patch).
///
/// Not run by default, and its power check fails: measured (2026-12-03, load ~16, 195 CPU s at
/// 4096 mutations per pixel) the shares agree (worst |z| = 2.34, region 0) but a 10% share error
/// would reach |z| = 5 in only 2 of the 12 regions above the floor (weakest: region 15 at 0.8,
/// regions 12 and 13 at 1.4 and 1.3). The reference side dominates: its noise estimated from
/// second differences (`relative_noise_of_region_means`) is 2–8× the chains' standard error,
/// because at 32×32 this room's edges (table, chairs, the window frame's stripes in the sun patch)
/// are counted as noise; with the chains' noise alone all but regions 12 and 13 (~3.1) would pass, so
/// about 3× the mutations (~600 CPU s) and a reference whose noise is measured from independent
/// renders rather than estimated from its pixels would be needed: beyond issue 15's budget.
/// (At 256 mutations per pixel, 64 chains had ~2.6× the shares' noise of 1024 chains.)
#[test]
#[ignore = "power check fails: reference noise estimated from pixels; ~600 CPU s needed (see doc comment)"]
fn pmlt_portal_agrees_with_the_reference_on_breakfast_window() {
    let scene = scene("breakfast-window", 32);
    let params = "max_depth = 8\nbootstrap = 20000\nchains = 1024\nbidirectional = 2.0\nlens = 2.0\nportal = 2.0\ncaustic = 0.0\nmulti_chain = 0.0";
    let what = "pmlt (bidirectional + lens + portal) vs the reference on breakfast-window";
    let (renders, stats) = portal_regions(&scene, params, 4096, false);
    print_acceptance(what, &stats);
    assert_agrees_with_reference(what, &renders, &reference("breakfast-window"));
}
