//! Cross-estimator agreement by region (tests/bdpt.rs explains the bound): an integrator renders
//! K independent images; for each of the GRID×GRID regions and the whole image, the luminance
//! means over the renders give the estimator's mean and its variance measured from the renders
//! themselves. Two integrators agree when Welch's |z| < `Z_CRITICAL` everywhere.
//!
//! Two comparisons are offered:
//! - [`assert_agree`]: region means and the image mean, valid only if a 5% error of the image mean
//!   would exceed the bound (the power check). For unbiased estimators (pt, bdpt, light).
//! - [`assert_shares_agree`]: region **shares** (region mean ÷ image mean of the same render),
//!   valid only if a stated relative error of a region's share would exceed the bound. For Markov
//!   chain estimators, whose image mean is fixed by the normalisation b (expected-value splatting
//!   deposits one unit of luminance weight per iteration) while the chain decides only how that
//!   light is shared between the regions: a share test tests the chain, and dividing by the
//!   render's own image mean removes b's error from it. [`assert_brightness_agrees`] tests b.

use plexus::film::Image;
use plexus::integrator::{create, Budget, NoProgress, RenderJob};
use plexus::scene::Scene;
use plexus::spectrum::luminance;

pub const RENDERS: u64 = 16;
pub const GRID: usize = 4;
/// Number of regions (the whole image comes after them in a render's region means).
pub const REGIONS: usize = GRID * GRID;
/// |z| above this fails (Bonferroni over 17 comparisons, t with ≥ 15 degrees of freedom: the
/// family-wise false-failure probability is below ~1e-3).
pub const Z_CRITICAL: f64 = 5.0;

/// Luminance means of the GRID×GRID regions, then of the whole image.
pub fn region_means(image: &Image) -> Vec<f64> {
    region_means_on(image, GRID)
}

/// Luminance means of the `grid`×`grid` regions (row by row), then of the whole image.
pub fn region_means_on(image: &Image, grid: usize) -> Vec<f64> {
    let regions = grid * grid;
    let mut sums = vec![0.0f64; regions + 1];
    let mut counts = vec![0usize; regions + 1];
    for y in 0..image.height {
        for x in 0..image.width {
            let v = luminance(image.get(x, y)) as f64;
            let r = (y * grid / image.height) * grid + x * grid / image.width;
            sums[r] += v;
            counts[r] += 1;
            sums[regions] += v;
            counts[regions] += 1;
        }
    }
    sums.iter().zip(&counts).map(|(s, &c)| s / c.max(1) as f64).collect()
}

/// The region means ([`region_means`]) of `renders` independent renders with seeds
/// `k · 7919 + seed_offset`, k = 1..=renders. Every render must be finite and drop nothing.
pub fn render_regions(
    scene: &Scene,
    integrator: &str,
    params: &str,
    spp: u64,
    seed_offset: u64,
    renders: u64,
) -> Vec<Vec<f64>> {
    let table: toml::Table = toml::from_str(params).expect("test parameters");
    (1..=renders)
        .map(|k| {
            let job = RenderJob { budget: Budget::SamplesPerPixel(spp), seed: k * 7919 + seed_offset, threads: 2 };
            let out = create(integrator, &table).expect("integrator").render(scene, &job, &NoProgress).expect("render");
            assert!(out.image.all_finite(), "{integrator}: non-finite pixels");
            assert_eq!(out.counters.nonfinite_dropped, 0, "{integrator}: non-finite contributions");
            region_means(&out.image)
        })
        .collect()
}

/// Per entry, the mean over the samples (one per render) and the variance of that mean.
pub fn mean_and_variance_of_mean(samples: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let k = samples.len() as f64;
    assert!(samples.len() >= 2, "a variance needs at least two renders");
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

/// Per-region mean and variance of the mean over `RENDERS` renders (see [`render_regions`]).
pub fn estimate(scene: &Scene, integrator: &str, params: &str, spp: u64, seed_offset: u64) -> (Vec<f64>, Vec<f64>) {
    mean_and_variance_of_mean(&render_regions(scene, integrator, params, spp, seed_offset, RENDERS))
}

/// Welch's z of a − b with the variances of the means `va`, `vb` (±∞ for a difference without
/// variance, 0 for none).
fn welch_z(ma: f64, va: f64, mb: f64, vb: f64) -> f64 {
    let se = (va + vb).sqrt();
    if se > 0.0 {
        (ma - mb) / se
    } else if ma == mb {
        0.0
    } else {
        f64::INFINITY
    }
}

/// Asserts the power check, then |z| < Z_CRITICAL for every region and the whole image.
pub fn assert_agree(what: &str, (ma, va): (Vec<f64>, Vec<f64>), (mb, vb): (Vec<f64>, Vec<f64>)) {
    let image = REGIONS;
    let se = (va[image] + vb[image]).sqrt();
    assert!(
        0.05 * mb[image] > Z_CRITICAL * se,
        "{what}: the test is too weak (image mean {:.5}, standard error {se:.5})",
        mb[image]
    );
    let mut report = String::new();
    let mut worst = 0.0f64;
    for r in 0..=image {
        let z = welch_z(ma[r], va[r], mb[r], vb[r]);
        worst = worst.max(z.abs());
        report += &format!("  region {r:2}: {:.5} vs {:.5}  z = {z:+.2}\n", ma[r], mb[r]);
    }
    println!("{what}: worst |z| = {worst:.2}\n{report}");
    assert!(worst < Z_CRITICAL, "{what}: disagreement (|z| = {worst:.2} ≥ {Z_CRITICAL})\n{report}");
}

/// Each render's region shares (its region means, then its image mean, as [`region_means_on`]
/// gives them): region mean ÷ the same render's image mean (the regions have
/// equal pixel counts up to rounding, so the shares average about 1). A black render has no shares.
pub fn shares(renders: &[Vec<f64>]) -> Vec<Vec<f64>> {
    renders
        .iter()
        .map(|r| {
            let (regions, image) = r.split_at(r.len() - 1);
            assert!(image[0] > 0.0, "a black render has no region shares");
            regions.iter().map(|m| m / image[0]).collect()
        })
        .collect()
}

/// The outcome of [`share_agreement`]: per region the two mean shares, Welch's z and the power
/// ratio (the z that a relative error `share_error` of that region's reference share would give;
/// > Z_CRITICAL means the test would see it).
pub struct ShareAgreement {
    pub method: Vec<f64>,
    pub reference: Vec<f64>,
    pub z: Vec<f64>,
    pub power_z: Vec<f64>,
    pub worst_z: f64,
}

impl ShareAgreement {
    pub fn report(&self) -> String {
        let mut report = String::new();
        for r in 0..self.z.len() {
            report += &format!(
                "  region {r:2}: share {:.4} vs {:.4}  z = {:+.2}  (a {:.0}% error: z = {:.1})\n",
                self.method[r],
                self.reference[r],
                self.z[r],
                100.0 * SHARE_ERROR,
                self.power_z[r]
            );
        }
        report
    }
}

/// The relative error of a region's share that the share test must be able to see.
pub const SHARE_ERROR: f64 = 0.10;

/// Region shares of a method's renders against a reference's (both from [`render_regions`]).
///
/// Bound: under agreement each region's Welch z follows a Student t with ≥ 15 degrees of freedom
/// for 16 renders a side (Welch–Satterthwaite); the 16 share comparisons are Bonferroni-corrected
/// with the same |z| < `Z_CRITICAL` = 5 as [`assert_agree`] (two-sided t₁₅ tail 1.6e-4, so the
/// family-wise false-failure probability is below 16 × 1.6e-4 = 2.6e-3, and below 1e-3 at the
/// 22 degrees of freedom typical of unequal variances). The shares of one render are dependent
/// (they average to 1), which Bonferroni does not need to know. A share is a ratio of two means of
/// the same render, so it is biased by O(CV²) of the image mean (Taylor expansion of m/M); CV is at
/// most a few per cent per render here, which makes the bias ≤ 1e-3 relative, far below the 5%
/// the test resolves.
pub fn share_agreement(method: &[Vec<f64>], reference: &[Vec<f64>]) -> ShareAgreement {
    let (ma, va) = mean_and_variance_of_mean(&shares(method));
    let (mb, vb) = mean_and_variance_of_mean(&shares(reference));
    let z: Vec<f64> = (0..ma.len()).map(|r| welch_z(ma[r], va[r], mb[r], vb[r])).collect();
    let power_z = (0..ma.len()).map(|r| welch_z(mb[r] * (1.0 + SHARE_ERROR), va[r], mb[r], vb[r])).collect();
    let worst_z = z.iter().fold(0.0f64, |w, z| w.max(z.abs()));
    ShareAgreement { method: ma, reference: mb, z, power_z, worst_z }
}

/// Regions whose reference share is below this need no power: a 5% error of a region holding less
/// than a quarter of the average region's light moves less than 1.25% of the average region's
/// light, and such regions (corners in shadow) are noisy relative to their share.
pub const POWER_SHARE_FLOOR: f64 = 0.25;

/// Asserts the share test's power (every region holding at least `POWER_SHARE_FLOOR` of the
/// average share would show a `SHARE_ERROR` relative error of its share with |z| > Z_CRITICAL),
/// then |z| < Z_CRITICAL for every region's share. Returns the statistics.
pub fn assert_shares_agree(what: &str, method: &[Vec<f64>], reference: &[Vec<f64>]) -> ShareAgreement {
    check_shares(what, share_agreement(method, reference))
}

/// The image means (the normalisation b of a Markov chain method) of a method's renders against a
/// reference's: the power check (a 5% brightness error would exceed the bound), then |z| <
/// Z_CRITICAL. Returns z.
pub fn assert_brightness_agrees(what: &str, method: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    let image =
        |renders: &[Vec<f64>]| mean_and_variance_of_mean(&renders.iter().map(|r| vec![r[REGIONS]]).collect::<Vec<_>>());
    let ((ma, va), (mb, vb)) = (image(method), image(reference));
    let se = (va[0] + vb[0]).sqrt();
    assert!(
        0.05 * mb[0] > Z_CRITICAL * se,
        "{what}: the brightness test is too weak (image mean {:.5}, standard error {se:.5})",
        mb[0]
    );
    let z = welch_z(ma[0], va[0], mb[0], vb[0]);
    println!(
        "{what}: image mean {:.5} vs {:.5}, z = {z:+.2} (relative standard error {:.4})",
        ma[0],
        mb[0],
        se / mb[0]
    );
    assert!(z.abs() < Z_CRITICAL, "{what}: brightness disagrees (|z| = {:.2} ≥ {Z_CRITICAL})", z.abs());
    z
}

/// The luminance noise of each region's mean in `image` (regions as [`region_means`]), relative to
/// the image mean, from second differences of horizontally adjacent pixels: for independent pixel
/// noise σ², E[(v_{x+1} − 2v_x + v_{x−1})²] = 6σ², and a smooth image gradient drops out to first
/// order (the light's falloff across a region is nearly linear; what is left of its curvature and
/// of the edges inside a region only inflates the estimate, which makes a test that adds it to its
/// variance more conservative).
pub fn relative_noise_of_region_means(image: &Image) -> Vec<f64> {
    relative_noise_of_region_means_on(image, GRID)
}

/// [`relative_noise_of_region_means`] for `grid`×`grid` regions.
pub fn relative_noise_of_region_means_on(image: &Image, grid: usize) -> Vec<f64> {
    let regions = grid * grid;
    let lum = |x: usize, y: usize| luminance(image.get(x, y)) as f64;
    let mean = region_means_on(image, grid)[regions];
    let region = |x: usize, y: usize| (y * grid / image.height) * grid + x * grid / image.width;
    let (mut sq, mut diffs, mut pixels) = (vec![0.0; regions], vec![0usize; regions], vec![0usize; regions]);
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
    (0..regions).map(|r| (sq[r] / (6.0 * diffs[r] as f64) / pixels[r] as f64).sqrt() / mean).collect()
}

/// Region shares of a method's renders against one committed reference image (any resolution of
/// the same camera: the film's box filter makes a region's mean independent of the pixel count),
/// the reference's own noise estimated from its pixels ([`relative_noise_of_region_means`]) as the
/// reference side's variance: z = (m − m_ref)/√(v + v_ref) per region, with the same bound
/// (`Z_CRITICAL`) and power figure (`SHARE_ERROR`) as [`share_agreement`]. The image mean's own
/// noise is left out of v_ref: a share divides it out, and at the references' 67 million samples
/// it is far below a region's.
pub fn image_share_agreement(method: &[Vec<f64>], reference: &Image, grid: usize) -> ShareAgreement {
    let regions = grid * grid;
    assert_eq!(method[0].len(), regions + 1, "the method's regions are not {grid}×{grid}");
    let means = region_means_on(reference, grid);
    let reference_shares: Vec<f64> = means[..regions].iter().map(|m| m / means[regions]).collect();
    let noise = relative_noise_of_region_means_on(reference, grid);
    let (ma, va) = mean_and_variance_of_mean(&shares(method));
    let sd: Vec<f64> = (0..regions).map(|r| (va[r] + noise[r] * noise[r]).sqrt()).collect();
    let z: Vec<f64> = (0..regions).map(|r| (ma[r] - reference_shares[r]) / sd[r]).collect();
    let power_z = (0..regions).map(|r| SHARE_ERROR * reference_shares[r] / sd[r]).collect();
    let worst_z = z.iter().fold(0.0f64, |w, z| w.max(z.abs()));
    let ratios: Vec<String> = (0..regions).map(|r| format!("{:.2}", noise[r] / va[r].sqrt())).collect();
    println!("the reference's noise over the method's standard error by region: {}", ratios.join(" "));
    ShareAgreement { method: ma, reference: reference_shares, z, power_z, worst_z }
}

/// [`image_share_agreement`] asserted as [`assert_shares_agree`] asserts [`share_agreement`]: the
/// power check for every region holding at least `POWER_SHARE_FLOOR` of the average share, then
/// |z| < Z_CRITICAL everywhere.
pub fn assert_shares_agree_with_image(
    what: &str,
    method: &[Vec<f64>],
    reference: &Image,
    grid: usize,
) -> ShareAgreement {
    let a = image_share_agreement(method, reference, grid);
    check_shares(what, a)
}

/// The assertions of [`assert_shares_agree`] on an agreement already computed.
fn check_shares(what: &str, a: ShareAgreement) -> ShareAgreement {
    let report = a.report();
    println!("{what}: region shares, worst |z| = {:.2}\n{report}", a.worst_z);
    let weak: Vec<usize> =
        (0..a.z.len()).filter(|&r| a.reference[r] >= POWER_SHARE_FLOOR && !(a.power_z[r] > Z_CRITICAL)).collect();
    assert!(
        weak.is_empty(),
        "{what}: the share test is too weak: a {:.0}% share error in regions {weak:?} would not reach |z| = \
         {Z_CRITICAL}\n{report}",
        100.0 * SHARE_ERROR
    );
    assert!(a.worst_z < Z_CRITICAL, "{what}: region shares disagree (|z| = {:.2} ≥ {Z_CRITICAL})\n{report}", a.worst_z);
    a
}
