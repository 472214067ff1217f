//! emlt's agreement renders and share test, shared by tests/chains/emlt.rs (part 1) and
//! tests/chains/emlt_part2.rs (part 2): tests/chains/emlt.rs's module docs say why the renders are small
//! (8×8) with many chains, and why the power is checked on the 2×2 quadrants.

use super::agreement::{
    assert_shares_agree_with_image, image_share_agreement, image_shares_chi2, region_means_on, SharesChi2, GRID,
    RENDERS, Z_CRITICAL,
};
use super::scenes::{reference, scene_at};

use plexus::film::Image;
use plexus::integrator::ensemble::emlt_render::Emlt;
use plexus::integrator::{Budget, Integrator, NoProgress, RenderJob};
use plexus::scene::Scene;

/// Image side of the agreement renders: 4×4 regions of 2×2 pixels (a region's share depends on
/// the mutations and chains per render, not its pixels; the references' regions are the same at
/// any resolution of the camera).
pub const SIZE: u32 = 8;
/// The power-checked grid.
pub const COARSE: usize = 2;

/// emlt with the settings of a TOML table.
pub fn emlt_with(params: &str) -> Emlt {
    let table: toml::Table = toml::from_str(params).expect("test parameters");
    Emlt::from_params(&table).expect("settings")
}

/// `RENDERS` renders by `emlt` (seeds as `render_regions`), each finite and dropping nothing, and
/// the first render's statistics.
pub fn emlt_renders(scene: &Scene, emlt: &Emlt, mpp: u64) -> (Vec<Image>, serde_json::Value) {
    emlt_renders_seeded(scene, emlt, mpp, 3)
}

/// [`emlt_renders`] with the seeds `k · 7919 + seed_offset`, k = 1..=`RENDERS` (another seed
/// offset: another, independent set of renders).
pub fn emlt_renders_seeded(scene: &Scene, emlt: &Emlt, mpp: u64, seed_offset: u64) -> (Vec<Image>, serde_json::Value) {
    chain_renders(emlt, scene, mpp, seed_offset)
}

/// `RENDERS` renders of `scene` by `integrator` at `mpp` mutations (samples) per pixel, seeds
/// k·7919 + `seed_offset`, 2 threads, each finite and dropping nothing; and the first render's
/// statistics.
pub fn chain_renders(
    integrator: &dyn Integrator,
    scene: &Scene,
    mpp: u64,
    seed_offset: u64,
) -> (Vec<Image>, serde_json::Value) {
    let mut stats = serde_json::Value::Null;
    let images = (1..=RENDERS)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed: k * 7919 + seed_offset, threads: 2 };
            let out = integrator.render(scene, &job, &NoProgress).expect("render");
            let name = integrator.name();
            assert!(out.image.all_finite(), "{name}: non-finite pixels");
            assert_eq!(out.counters.nonfinite_dropped, 0, "{name}: non-finite contributions");
            if k == 1 {
                stats = out.extra_stats;
            }
            out.image
        })
        .collect();
    (images, stats)
}

/// The outcome of [`share_test`]: the worst share |z| on the power-checked 2×2 quadrants and on
/// the 4×4 regions, the χ² test of the 4×4 regions' shares, and the renders' 4×4 region means
/// (`region_means_on`; for [`shares_chi2_false_failure_rate`]'s null model).
#[derive(Clone, Debug)]
pub struct ShareTest {
    pub coarse_z: f64,
    pub fine_z: f64,
    pub chi2: SharesChi2,
    pub regions: Vec<Vec<f64>>,
}

impl ShareTest {
    /// Some part of the test rejects: a |z| ≥ `Z_CRITICAL` on either grid, or the χ².
    pub fn fails(&self) -> bool {
        self.coarse_z.max(self.fine_z) >= Z_CRITICAL || !self.chi2.passes()
    }

    /// One line: both grids' worst |z| and the χ².
    pub fn summary(&self) -> String {
        format!("worst |z| {:.2} (2×2) / {:.2} (4×4), {}", self.coarse_z, self.fine_z, self.chi2.summary())
    }
}

/// The share test: the power-checked 2×2 quadrants, the 4×4 regions checked for |z| < 5 without a
/// power claim, and the χ² of the 4×4 regions' shares (`image_shares_chi2`: p ≥
/// `SHARES_CHI2_ALPHA`), all asserted only if `assert_agreement`. The χ² sees what the worst |z|
/// can miss: a wrong chain moving a few per cent of the light between many regions at once
/// (docs/lab/mlt.md, "negative controls' power").
pub fn share_test(what: &str, images: &[Image], reference: &Image, assert_agreement: bool) -> ShareTest {
    let grids: Vec<(usize, Vec<Vec<f64>>)> =
        [COARSE, GRID].iter().map(|&g| (g, images.iter().map(|i| region_means_on(i, g)).collect())).collect();
    let mut worst = Vec::new();
    for (g, regions) in &grids {
        let label = format!("{what}, {g}×{g} regions");
        let a = if assert_agreement && *g == COARSE {
            assert_shares_agree_with_image(&label, regions, reference, *g)
        } else {
            let a = image_share_agreement(regions, reference, *g);
            println!("{label}: worst |z| = {:.2}\n{}", a.worst_z, a.report());
            a
        };
        worst.push(a.worst_z);
    }
    let chi2 = image_shares_chi2(&grids[1].1, reference, GRID);
    let regions = grids.into_iter().nth(1).expect("the 4×4 grid").1;
    let test = ShareTest { coarse_z: worst[0], fine_z: worst[1], chi2, regions };
    println!("{what}: {}", test.summary());
    if assert_agreement {
        assert!(test.fine_z < Z_CRITICAL, "{what}: the 4×4 region shares disagree (|z| = {:.2})", test.fine_z);
        assert!(test.chi2.passes(), "{what}: the 4×4 region shares disagree by χ²: {}", test.chi2.summary());
    }
    test
}

/// Prints each strategy's selected and accepted counts from a render's statistics.
pub fn print_strategies(what: &str, stats: &serde_json::Value) {
    for s in stats["strategies"].as_array().into_iter().flatten() {
        let acceptance = s["acceptance"].as_f64().unwrap_or(0.0);
        println!(
            "{what}: {} selected {} accepted {} acceptance {acceptance:.3}",
            s["name"], s["selected"], s["accepted"]
        );
    }
    println!("{what}: ensemble {}", stats["ensemble"]);
}

/// emlt's region shares on `name` at `SIZE`² against the committed reference (`share_test`,
/// asserted), and the guided share of its guided strategies' proposals (≥ 1/2, asserted; each
/// strategy named in `guided` must have made guided proposals). Returns the share test and the
/// first render's statistics.
pub fn emlt_agrees_with_reference(
    name: &str,
    emlt: &Emlt,
    mpp: u64,
    guided: &[&str],
) -> (ShareTest, serde_json::Value) {
    emlt_agrees_with_reference_at(name, (SIZE, SIZE), emlt, mpp, guided)
}

/// [`emlt_agrees_with_reference`] at `width`×`height` pixels (the reference's aspect ratio).
pub fn emlt_agrees_with_reference_at(
    name: &str,
    (width, height): (u32, u32),
    emlt: &Emlt,
    mpp: u64,
    guided: &[&str],
) -> (ShareTest, serde_json::Value) {
    let scene = scene_at(name, width, height);
    let (images, stats) = emlt_renders(&scene, emlt, mpp);
    let what = format!("emlt vs the reference on {name}");
    let ensemble = &stats["ensemble"];
    print_strategies(&what, &stats);
    let test = share_test(&what, &images, &reference(name), true);
    let share = ensemble["guided_share"].as_f64().expect("guided share");
    assert!(share >= 0.5, "{what}: only {share:.3} of the guided strategies' proposals were guided");
    for g in ensemble["guided"].as_array().into_iter().flatten() {
        if guided.contains(&g["name"].as_str().unwrap_or("")) {
            assert!(g["guided"].as_u64().unwrap_or(0) > 0, "{what}: {} was never guided", g["name"]);
        }
    }
    (test, stats)
}
