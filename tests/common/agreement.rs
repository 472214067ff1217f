//! Cross-estimator agreement by region (tests/images/bdpt.rs explains the bound): an integrator renders
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
//! - [`image_shares_chi2`]: all the regions' shares at once against a reference image, T = Σ z²
//!   against Box's a·χ²_ν (bound derived at [`shares_chi2`], p < `SHARES_CHI2_ALPHA` fails), for
//!   a wrong chain that moves a few per cent of the light between many regions, which no single
//!   region's |z| need show (tests/common/ensemble.rs's `share_test` asserts it).

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

/// A committed reference image's region shares on a `grid`×`grid` grid (region mean over image
/// mean) and each share's relative noise estimated from its pixels
/// ([`relative_noise_of_region_means_on`]): the reference side of the share tests.
fn reference_shares_on(reference: &Image, grid: usize) -> (Vec<f64>, Vec<f64>) {
    let regions = grid * grid;
    let means = region_means_on(reference, grid);
    let shares = means[..regions].iter().map(|m| m / means[regions]).collect();
    (shares, relative_noise_of_region_means_on(reference, grid))
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
    let (reference_shares, noise) = reference_shares_on(reference, grid);
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

/// Significance of the region shares' χ² test ([`image_shares_chi2`]): it fails when its p-value
/// is below this. Its actual false-failure rate, simulated on correct emlt runs' covariances
/// ([`shares_chi2_false_failure_rate`], 10⁶ trials each), is 2.5e-4 to 4.9e-4 (the plug-in error
/// of a and ν from 16 renders); accepted, as it stays below the z tests' own family-wise rate
/// (≤ 2.6e-3, [`share_agreement`]) and the tests are seeded (docs/lab/mlt.md, "negative controls' power").
pub const SHARES_CHI2_ALPHA: f64 = 1e-4;

/// The outcome of [`shares_chi2`]: the statistic T = Σ z_r² (the regions' share z of
/// [`image_share_agreement`]), the null distribution it is compared with, a·χ²_ν (Box's
/// approximation: `scale` a, `dof` ν), and T's p-value under it.
#[derive(Clone, Copy, Debug)]
pub struct SharesChi2 {
    pub t: f64,
    pub scale: f64,
    pub dof: f64,
    pub p: f64,
}

impl SharesChi2 {
    /// The T at which p = `SHARES_CHI2_ALPHA`: the (1 − α) quantile of a·χ²_ν.
    pub fn bound(&self) -> f64 {
        self.scale * plexus::sampling::chi2::chi2_upper_quantile(SHARES_CHI2_ALPHA, self.dof)
    }

    /// The test passes: p ≥ `SHARES_CHI2_ALPHA`.
    pub fn passes(&self) -> bool {
        self.p >= SHARES_CHI2_ALPHA
    }

    /// One line: T, the bound, a, ν and p.
    pub fn summary(&self) -> String {
        format!(
            "χ² T = {:.2} (bound {:.2} at p = {SHARES_CHI2_ALPHA:e}; a = {:.3}, ν = {:.2}), p = {:.3e}",
            self.t,
            self.bound(),
            self.scale,
            self.dof,
            self.p
        )
    }
}

/// The χ² test of all the regions' shares at once: T = Σ_r z_r², z_r = (x̄_r − y_r)/√(v̂_r + u_r)
/// as in [`image_share_agreement`] (x̄ the mean of the method's per-render shares, v̂ its
/// estimated variance, y the reference's shares, u their pixel-estimated variance).
///
/// **Bound.** The z test bounds the worst region; a wrong chain that moves a few per cent of the
/// light between many regions at once shows as many moderate z's, which T adds up. Under
/// agreement d = x̄ − y is Gaussian (means of 16 renders; the reference's 67 million samples) with
/// covariance Σ = C_m + C_y: C_m the covariance of the method's mean shares (its renders' sample
/// covariance ÷ K, K = 16 renders; the shares of one render are correlated: they sum to the number
/// of regions R), C_y = J D Jᵀ the reference's (D = diag u; J = I − y 1ᵀ/R carries a region's noise
/// into every share through the image mean, since y_r = m_r/M). Both annihilate 1 (shares sum to
/// R), so d lives in R − 1 dimensions: one degree of freedom is lost. With the weights W =
/// diag(1/w_r), w_r = v_r + u_r known, T = dᵀW d is a sum of χ²₁'s weighted by the eigenvalues of
/// A = W^½ Σ W^½, with mean tr A and variance 2 tr A²; Box (1954) matches a·χ²_ν to these two
/// moments: a = Var/(2 E), ν = 2 E²/Var (ν ≤ rank A ≤ R − 1).
///
/// The weights are estimated (v̂_r from the same 16 renders, u_r from the reference's pixels), so
/// T's tail is heavier than the known-weight sum's: alone, d_r²/v̂_r is an F(1, 15), whose 1e-4
/// tail is at 27.5 against χ²₁'s 15.1. The moments below carry that: by Welch–Satterthwaite ŵ_r ≈
/// w_r χ²_f/f with f_r = (K − 1)(w_r/v_r)² (u_r's own estimate, from thousands of pixel
/// differences, counts as exact), and d is independent of ŵ (a Gaussian sample's mean and
/// covariance are independent), so E[1/ŵ_r] = g₁/w_r, g₁ = f/(f − 2), and E[1/ŵ_r²] = g₂/w_r²,
/// g₂ = f²/((f − 2)(f − 4)); two regions' variance estimates covary by Cov(v̂_r, v̂_s) =
/// 2 C_rs²/(K − 1) (Wishart), so E[1/(ŵ_r ŵ_s)] ≈ g₁_r g₁_s (1 + 2 B_rs²/(K − 1)), B = the method's
/// share of A. Then E[T] = Σ_r A_rr g₁_r and E[T²] = Σ_rs (A_rr A_ss + 2 A_rs²) G_rs (Isserlis),
/// G_rr = g₂_r, G_rs the product above; Box's a and ν are matched to these. Σ is replaced by its
/// estimate (the bound is then a plug-in; tests/chains/emlt_part2.rs's simulation measures the resulting
/// false-failure rate). The share's ratio bias is O(CV²) of a render's image mean, as for the
/// z test.
pub fn shares_chi2(method: &[Vec<f64>], reference: &[f64], reference_variance: &[f64]) -> SharesChi2 {
    let regions = reference.len();
    let k = method.len() as f64;
    let mean: Vec<f64> = (0..regions).map(|r| method.iter().map(|s| s[r]).sum::<f64>() / k).collect();
    // C_m: the sample covariance of the renders' shares ÷ K.
    let mut cm = vec![vec![0.0; regions]; regions];
    for s in method {
        for r in 0..regions {
            for q in 0..regions {
                cm[r][q] += (s[r] - mean[r]) * (s[q] - mean[q]) / ((k - 1.0) * k);
            }
        }
    }
    // C_y = J D Jᵀ, J_rj = δ_rj − y_r/R.
    let j = |r: usize, q: usize| f64::from(u8::from(r == q)) - reference[r] / regions as f64;
    let w: Vec<f64> = (0..regions).map(|r| cm[r][r] + reference_variance[r]).collect();
    let (mut a, mut b) = (vec![vec![0.0; regions]; regions], vec![vec![0.0; regions]; regions]);
    for r in 0..regions {
        for q in 0..regions {
            let cy: f64 = (0..regions).map(|i| j(r, i) * reference_variance[i] * j(q, i)).sum();
            let norm = (w[r] * w[q]).sqrt();
            a[r][q] = (cm[r][q] + cy) / norm;
            b[r][q] = cm[r][q] / norm;
        }
    }
    let t: f64 = (0..regions).map(|r| (mean[r] - reference[r]).powi(2) / w[r]).sum();
    let f: Vec<f64> = (0..regions).map(|r| (k - 1.0) / b[r][r].powi(2)).collect();
    let g1: Vec<f64> = f.iter().map(|f| f / (f - 2.0)).collect();
    let g2: Vec<f64> = f.iter().map(|f| f * f / ((f - 2.0) * (f - 4.0))).collect();
    let expected: f64 = (0..regions).map(|r| a[r][r] * g1[r]).sum();
    let mut second = 0.0;
    for r in 0..regions {
        for q in 0..regions {
            let (g, a2) = if r == q {
                (g2[r], a[r][r].powi(2))
            } else {
                // A_rq² with the method's part B_rq² replaced by its unbiased estimate.
                let (n, c) = (k - 1.0, a[r][q] - b[r][q]);
                let b2 = n * n / ((n + 2.0) * (n - 1.0)) * (b[r][q].powi(2) - b[r][r] * b[q][q] / n);
                (g1[r] * g1[q] * (1.0 + 2.0 * b2.max(0.0) / n), b2 + 2.0 * b[r][q] * c + c * c)
            };
            second += (a[r][r] * a[q][q] + 2.0 * a2) * g;
        }
    }
    let variance = second - expected * expected;
    let (scale, dof) = (variance / (2.0 * expected), 2.0 * expected * expected / variance);
    let p = plexus::sampling::chi2::chi2_survival(t / scale, dof);
    SharesChi2 { t, scale, dof, p }
}

/// [`shares_chi2`] of a method's renders (regions as [`region_means_on`] gives them on a
/// `grid`×`grid` grid) against one committed reference image, its variance estimated from its
/// pixels as in [`image_share_agreement`].
pub fn image_shares_chi2(method: &[Vec<f64>], reference: &Image, grid: usize) -> SharesChi2 {
    let regions = grid * grid;
    assert_eq!(method[0].len(), regions + 1, "the method's regions are not {grid}×{grid}");
    let (reference_shares, noise) = reference_shares_on(reference, grid);
    let variance: Vec<f64> = noise.iter().map(|n| n * n).collect();
    shares_chi2(&shares(method), &reference_shares, &variance)
}

/// The false-failure rate of [`shares_chi2`] under agreement, by simulation: `trials` times, K =
/// `RENDERS` renders' shares x_k = y + F g_k and the reference's y + J (√u ⊙ g′) (g, g′ standard
/// normal, J as in [`shares_chi2`]; `factor` F is R × m with columns summing to 0, so each render's
/// shares sum to R as real ones do, and F Fᵀ is a render's share covariance). Returns the fraction
/// of trials with p < `SHARES_CHI2_ALPHA`, and the fraction a plain χ²_{R−1} bound (T against
/// χ²_{R−1}'s 1 − α quantile: the shares' correlations and estimated variances ignored) fails.
pub fn shares_chi2_false_failure_rate(
    reference: &[f64],
    reference_variance: &[f64],
    factor: &[Vec<f64>],
    trials: u64,
    seed: u64,
) -> (f64, f64) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let regions = reference.len();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut normal = move || -> f64 { StandardNormal.sample(&mut rng) };
    let (mut failures, mut plain) = (0u64, 0u64);
    for _ in 0..trials {
        let method: Vec<Vec<f64>> = (0..RENDERS)
            .map(|_| {
                let g: Vec<f64> = (0..factor[0].len()).map(|_| normal()).collect();
                (0..regions).map(|r| reference[r] + factor[r].iter().zip(&g).map(|(f, g)| f * g).sum::<f64>()).collect()
            })
            .collect();
        let e: Vec<f64> = (0..regions).map(|r| reference_variance[r].sqrt() * normal()).collect();
        let mean_e = e.iter().sum::<f64>() / regions as f64;
        let observed: Vec<f64> = (0..regions).map(|r| reference[r] + e[r] - reference[r] * mean_e).collect();
        let c = shares_chi2(&method, &observed, reference_variance);
        failures += u64::from(!c.passes());
        plain += u64::from(plexus::sampling::chi2::chi2_survival(c.t, (regions - 1) as f64) < SHARES_CHI2_ALPHA);
    }
    (failures as f64 / trials as f64, plain as f64 / trials as f64)
}

/// [`shares_chi2_false_failure_rate`] with the null model of a method's renders (4×4 region means,
/// as [`region_means_on`] gives them) against a reference image: F = the renders' share deviations
/// from their mean ÷ √(K − 1) (F Fᵀ is their sample covariance), y and u the reference's shares and
/// pixel-estimated variances.
pub fn image_shares_chi2_false_failure_rate(
    method: &[Vec<f64>],
    reference: &Image,
    grid: usize,
    trials: u64,
    seed: u64,
) -> (f64, f64) {
    let regions = grid * grid;
    let (y, noise) = reference_shares_on(reference, grid);
    let u: Vec<f64> = noise.iter().map(|n| n * n).collect();
    let s = shares(method);
    let (mean, _) = mean_and_variance_of_mean(&s);
    let k = s.len() as f64;
    let factor: Vec<Vec<f64>> =
        (0..regions).map(|r| s.iter().map(|x| (x[r] - mean[r]) / (k - 1.0).sqrt()).collect()).collect();
    shares_chi2_false_failure_rate(&y, &u, &factor, trials, seed)
}
