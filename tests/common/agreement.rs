//! Cross-estimator agreement by region (tests/bdpt.rs explains the bound): an integrator renders
//! `RENDERS` independent images; for each of the GRID×GRID regions and the whole image, the
//! luminance means over the renders give the estimator's mean and its variance measured from the
//! renders themselves. Two integrators agree when Welch's |z| < `Z_CRITICAL` everywhere, and a test
//! is only valid if a 5% error of the image mean would exceed that bound (the power check).

use plexus::film::Image;
use plexus::integrator::{create, Budget, NoProgress, RenderJob};
use plexus::scene::Scene;
use plexus::spectrum::luminance;

pub const RENDERS: u64 = 16;
pub const GRID: usize = 4;
/// |z| above this fails (Bonferroni over 17 comparisons, t with ≥ 15 degrees of freedom: the
/// family-wise false-failure probability is below ~1e-3).
pub const Z_CRITICAL: f64 = 5.0;

/// Luminance means of the GRID×GRID regions, then of the whole image.
pub fn region_means(image: &Image) -> Vec<f64> {
    let mut sums = [0.0f64; GRID * GRID + 1];
    let mut counts = [0usize; GRID * GRID + 1];
    for y in 0..image.height {
        for x in 0..image.width {
            let v = luminance(image.get(x, y)) as f64;
            let r = (y * GRID / image.height) * GRID + x * GRID / image.width;
            sums[r] += v;
            counts[r] += 1;
            sums[GRID * GRID] += v;
            counts[GRID * GRID] += 1;
        }
    }
    sums.iter().zip(&counts).map(|(s, &c)| s / c.max(1) as f64).collect()
}

/// Per-region mean and variance of the mean over `RENDERS` renders with seeds
/// `k · 7919 + seed_offset`, k = 1..=RENDERS. Every render must be finite and drop nothing.
pub fn estimate(scene: &Scene, integrator: &str, params: &str, spp: u64, seed_offset: u64) -> (Vec<f64>, Vec<f64>) {
    let table: toml::Table = toml::from_str(params).expect("test parameters");
    let samples: Vec<Vec<f64>> = (1..=RENDERS)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(spp), seed: k * 7919 + seed_offset, threads: 2 };
            let out = create(integrator, &table).expect("integrator").render(scene, &job, &NoProgress).expect("render");
            assert!(out.image.all_finite(), "{integrator}: non-finite pixels");
            assert_eq!(out.counters.nonfinite_dropped, 0, "{integrator}: non-finite contributions");
            region_means(&out.image)
        })
        .collect();
    let k = RENDERS as f64;
    let n = samples[0].len();
    let mut means = vec![0.0; n];
    let mut var_of_mean = vec![0.0; n];
    for r in 0..n {
        let m = samples.iter().map(|s| s[r]).sum::<f64>() / k;
        means[r] = m;
        var_of_mean[r] = samples.iter().map(|s| (s[r] - m).powi(2)).sum::<f64>() / (k - 1.0) / k;
    }
    (means, var_of_mean)
}

/// Asserts the power check, then |z| < Z_CRITICAL for every region and the whole image.
pub fn assert_agree(what: &str, (ma, va): (Vec<f64>, Vec<f64>), (mb, vb): (Vec<f64>, Vec<f64>)) {
    let image = GRID * GRID;
    let se = (va[image] + vb[image]).sqrt();
    assert!(
        0.05 * mb[image] > Z_CRITICAL * se,
        "{what}: the test is too weak (image mean {:.5}, standard error {se:.5})",
        mb[image]
    );
    let mut report = String::new();
    let mut worst = 0.0f64;
    for r in 0..=image {
        let se = (va[r] + vb[r]).sqrt();
        let z = if se > 0.0 {
            (ma[r] - mb[r]) / se
        } else if ma[r] == mb[r] {
            0.0
        } else {
            f64::INFINITY
        };
        worst = worst.max(z.abs());
        report += &format!("  region {r:2}: {:.5} vs {:.5}  z = {z:+.2}\n", ma[r], mb[r]);
    }
    println!("{what}: worst |z| = {worst:.2}\n{report}");
    assert!(worst < Z_CRITICAL, "{what}: disagreement (|z| = {worst:.2} ≥ {Z_CRITICAL})\n{report}");
}
