//! A generic chi-square goodness-of-fit harness for sampling routines, in the manner of Mitsuba's
//! warp tests, plus the quadrature and finite-difference helpers the warp tests share.
//!
//! A test bins a 2D parameter domain, draws `samples` points from a sampler, integrates the
//! claimed pdf over every bin (nested adaptive Gauss–Kronrod) for the expected counts, pools bins whose
//! expected count is below `min_expected` (the chi-square approximation needs about 5 per cell),
//! and computes the p-value of Pearson's statistic from the chi-square distribution (regularised
//! upper incomplete gamma function, from statrs). A sampler may fail (return `None`) with the
//! probability mass the pdf does not cover (e.g. a BSDF whose pdf integrates to less than 1): those
//! failures and points outside the domain fill one extra cell whose expectation is N·(1 − ∫pdf).
//!
//! The null hypothesis is rejected when p < α, α the Šidák-corrected level
//! 1 − (1 − significance)^(1/test_count), so that across all `test_count` tests of a suite the
//! probability of any false rejection is `significance` (1e-3 by default). Every test is seeded.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::Vec3;

use super::Rng;

/// Number of chi-square tests in the suite of `sampling`, `light` and `camera` (the Šidák family).
/// Raise it when adding a test there.
pub const CHI2_TESTS_SAMPLING: usize = 40;

/// Parameters of one chi-square test.
#[derive(Clone, Debug)]
pub struct Chi2Config {
    /// Bins along the first and second parameter.
    pub res: [usize; 2],
    pub samples: usize,
    /// Family-wise significance level over `test_count` tests.
    pub significance: f64,
    /// Number of tests in the family (Šidák correction).
    pub test_count: usize,
    /// Bins with a smaller expected count are pooled.
    pub min_expected: f64,
    /// Absolute tolerance (in probability) of the per-bin quadrature.
    pub quad_eps: f64,
    /// Minimum and maximum bisection depth of the adaptive Gauss–Kronrod rule in each dimension. The
    /// minimum depth is what lets the quadrature find features narrower than a bin.
    pub min_depth: u32,
    pub max_depth: u32,
}

impl Default for Chi2Config {
    fn default() -> Self {
        Chi2Config {
            res: [24, 48],
            samples: 100_000,
            significance: 1e-3,
            test_count: 1,
            min_expected: 5.0,
            quad_eps: 1e-8,
            min_depth: 1,
            max_depth: 12,
        }
    }
}

/// The result of a chi-square test; `message` explains it (and lists the worst cells).
#[derive(Clone, Debug)]
pub struct Chi2Outcome {
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
    /// The Šidák-corrected per-test level the p-value was compared with.
    pub alpha: f64,
    pub passed: bool,
    pub message: String,
}

/// Chi-square test of `sampler` (points in the rectangle `a_range` × `b_range`, or `None` for a
/// failed sample) against `pdf`, a density with respect to da·db, integrated per bin by nested
/// adaptive Gauss–Kronrod (`cfg.quad_eps`, `cfg.min_depth`, `cfg.max_depth`).
pub fn chi2_test(
    cfg: &Chi2Config,
    a_range: [f64; 2],
    b_range: [f64; 2],
    seed: u64,
    sampler: impl FnMut(&mut Rng) -> Option<[f64; 2]>,
    pdf: impl Fn([f64; 2]) -> f64,
) -> Chi2Outcome {
    let mass = |a: [f64; 2], b: [f64; 2]| adaptive_integrate_2d(&pdf, a, b, cfg.quad_eps, cfg.min_depth, cfg.max_depth);
    chi2_test_bin_masses(cfg, a_range, b_range, seed, sampler, mass)
}

/// Chi-square test of `sampler` against expected probabilities given per bin:
/// `bin_mass([a0, a1], [b0, b1])` is the probability that a sample lands in that bin. For densities
/// whose bin integrals are known or better computed another way than by `chi2_test`'s quadrature
/// (a 1D density, an indicator function of a set only a sampler can decide).
pub fn chi2_test_bin_masses(
    cfg: &Chi2Config,
    a_range: [f64; 2],
    b_range: [f64; 2],
    seed: u64,
    mut sampler: impl FnMut(&mut Rng) -> Option<[f64; 2]>,
    bin_mass: impl Fn([f64; 2], [f64; 2]) -> f64,
) -> Chi2Outcome {
    let [na, nb] = cfg.res;
    let n_cells = na * nb;
    let mut observed = vec![0.0f64; n_cells + 1];
    let mut rng = Rng::new(seed, 0x6368_6932);
    let (wa, wb) = (a_range[1] - a_range[0], b_range[1] - b_range[0]);
    for _ in 0..cfg.samples {
        let cell = sampler(&mut rng)
            .filter(|p| p[0].is_finite() && p[1].is_finite())
            .and_then(|p| {
                let fa = (p[0] - a_range[0]) / wa;
                let fb = (p[1] - b_range[0]) / wb;
                if !(0.0..=1.0).contains(&fa) || !(0.0..=1.0).contains(&fb) {
                    return None;
                }
                let i = ((fa * na as f64) as usize).min(na - 1);
                let j = ((fb * nb as f64) as usize).min(nb - 1);
                Some(j * na + i)
            })
            .unwrap_or(n_cells);
        observed[cell] += 1.0;
    }

    let n = cfg.samples as f64;
    let mut expected = vec![0.0f64; n_cells + 1];
    let mut total = 0.0;
    for j in 0..nb {
        for i in 0..na {
            let a0 = a_range[0] + wa * i as f64 / na as f64;
            let a1 = a_range[0] + wa * (i + 1) as f64 / na as f64;
            let b0 = b_range[0] + wb * j as f64 / nb as f64;
            let b1 = b_range[0] + wb * (j + 1) as f64 / nb as f64;
            let mass = bin_mass([a0, a1], [b0, b1]);
            total += mass;
            expected[j * na + i] = mass * n;
        }
    }
    expected[n_cells] = (1.0 - total).max(0.0) * n;
    let label =
        |c: usize| if c == n_cells { "failed/outside".to_string() } else { format!("bin ({}, {})", c % na, c / na) };
    finish(cfg, &observed, &expected, total, label)
}

/// Chi-square test of a sampler of unit directions against a solid-angle `pdf`, binned in
/// (cos θ, φ) ∈ [-1, 1] × [0, 2π) — equal-area bins, since dω = d(cos θ) dφ.
pub fn chi2_sphere(
    cfg: &Chi2Config,
    seed: u64,
    mut sampler: impl FnMut(&mut Rng) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
) -> Chi2Outcome {
    chi2_test(
        cfg,
        [-1.0, 1.0],
        [0.0, 2.0 * std::f64::consts::PI],
        seed,
        |rng| sampler(rng).and_then(direction_to_sphere_param),
        |p| pdf(sphere_param_to_direction(p)),
    )
}

/// Chi-square test of a sampler of points in a rectangle (same as `chi2_test`; the name says
/// what the domain is).
pub fn chi2_square(
    cfg: &Chi2Config,
    a_range: [f64; 2],
    b_range: [f64; 2],
    seed: u64,
    sampler: impl FnMut(&mut Rng) -> Option<[f64; 2]>,
    pdf: impl Fn([f64; 2]) -> f64,
) -> Chi2Outcome {
    chi2_test(cfg, a_range, b_range, seed, sampler, pdf)
}

/// Chi-square test of a 1D sampler on `range` against `pdf`, with `cfg.res[0]` bins (the second
/// resolution is ignored): e.g. the distribution of the uniforms an ambiguous inverse produces.
pub fn chi2_1d(
    cfg: &Chi2Config,
    range: [f64; 2],
    seed: u64,
    mut sampler: impl FnMut(&mut Rng) -> Option<f64>,
    pdf: impl Fn(f64) -> f64,
) -> Chi2Outcome {
    let cfg1 = Chi2Config { res: [cfg.res[0], 1], ..cfg.clone() };
    // A 1D integral per bin: integrating a constant second dimension adaptively as well would
    // multiply the cost by the inner rule's evaluations at every outer point.
    let mass = |a: [f64; 2], _: [f64; 2]| adaptive_integrate(&pdf, a, cfg.quad_eps, cfg.min_depth, cfg.max_depth);
    chi2_test_bin_masses(&cfg1, range, [0.0, 1.0], seed, |rng| sampler(rng).map(|x| [x, 0.5]), mass)
}

/// (cos θ, φ) of a unit direction, φ ∈ [0, 2π); `None` if `w` is not unit length within 1e-3.
pub fn direction_to_sphere_param(w: Vec3) -> Option<[f64; 2]> {
    let w = w.as_dvec3();
    if !w.is_finite() || (w.length() - 1.0).abs() > 1e-3 {
        return None;
    }
    let w = w.normalize();
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * std::f64::consts::PI;
    }
    Some([w.z.clamp(-1.0, 1.0), phi])
}

/// The unit direction with (cos θ, φ) = `p`.
pub fn sphere_param_to_direction(p: [f64; 2]) -> Vec3 {
    let z = p[0].clamp(-1.0, 1.0);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new((r * p[1].cos()) as f32, (r * p[1].sin()) as f32, z as f32)
}

fn finish(
    cfg: &Chi2Config,
    observed: &[f64],
    expected: &[f64],
    total: f64,
    label: impl Fn(usize) -> String,
) -> Chi2Outcome {
    let alpha = 1.0 - (1.0 - cfg.significance).powf(1.0 / cfg.test_count.max(1) as f64);
    let fail =
        |message: String| Chi2Outcome { statistic: f64::INFINITY, dof: 0, p_value: 0.0, alpha, passed: false, message };

    // Samples where the pdf claims (essentially) nothing can happen are an outright failure: pooling
    // would hide them among many cells.
    for (c, (&o, &e)) in observed.iter().zip(expected).enumerate() {
        if o > 0.0 && e <= 1e-9 {
            return fail(format!(
                "{} samples in {} whose expected count is {e:.3e} (pdf integral over the domain {total:.6})",
                o,
                label(c)
            ));
        }
    }

    let mut order: Vec<usize> = (0..observed.len()).filter(|&c| expected[c] > 0.0 || observed[c] > 0.0).collect();
    order.sort_by(|&x, &y| expected[x].total_cmp(&expected[y]));
    let mut cells: Vec<(f64, f64, usize)> = Vec::new();
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for &c in &order {
        if expected[c] < cfg.min_expected {
            pool_o += observed[c];
            pool_e += expected[c];
        } else {
            cells.push((observed[c], expected[c], c));
        }
    }
    if pool_e > 0.0 {
        if pool_e >= cfg.min_expected || cells.is_empty() {
            cells.push((pool_o, pool_e, usize::MAX));
        } else {
            // Too little to stand alone: merge into the smallest regular cell.
            cells[0].0 += pool_o;
            cells[0].1 += pool_e;
        }
    }
    if cells.len() < 2 {
        return fail(format!("only {} cell(s) after pooling: the binning cannot test this distribution", cells.len()));
    }
    let mut contributions: Vec<(f64, usize, f64, f64)> = cells
        .iter()
        .map(|&(o, e, c)| {
            let d = o - e;
            (d * d / e, c, o, e)
        })
        .collect();
    let statistic: f64 = contributions.iter().map(|x| x.0).sum();
    let dof = cells.len() - 1;
    let p_value = chi2_survival(statistic, dof as f64);
    let passed = p_value >= alpha;
    contributions.sort_by(|x, y| y.0.total_cmp(&x.0));
    let worst: Vec<String> = contributions
        .iter()
        .take(5)
        .map(|&(q, c, o, e)| {
            let name = if c == usize::MAX { "pooled cells".to_string() } else { label(c) };
            format!("{name}: observed {o}, expected {e:.1} (+{q:.1})")
        })
        .collect();
    let message = format!(
        "chi2 = {statistic:.1} with {dof} dof, p = {p_value:.3e} {} alpha = {alpha:.3e}; pdf integral {total:.6}; worst: {}",
        if passed { ">=" } else { "<" },
        worst.join("; ")
    );
    Chi2Outcome { statistic, dof, p_value, alpha, passed, message }
}

// ---------------------------------------------------------------------------------------------
// The chi-square distribution
// ---------------------------------------------------------------------------------------------

/// P(X ≥ x) for X chi-square distributed with `dof` degrees of freedom: Q(dof/2, x/2), the
/// regularised upper incomplete gamma function (statrs). With no degrees of freedom a positive
/// statistic is impossible under the null hypothesis, so its p-value is 0.
pub fn chi2_survival(x: f64, dof: f64) -> f64 {
    if !(x > 0.0) {
        return 1.0;
    }
    statrs::function::gamma::checked_gamma_ur(0.5 * dof, 0.5 * x).unwrap_or(0.0)
}

/// The x with P(X ≥ x) = `alpha` for X chi-square distributed with `dof` (> 0) degrees of freedom:
/// [`chi2_survival`]'s inverse (statrs), the bound a statistic may reach at significance `alpha`.
pub fn chi2_upper_quantile(alpha: f64, dof: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(dof).map_or(f64::NAN, |d| d.inverse_cdf(1.0 - alpha))
}

// ---------------------------------------------------------------------------------------------
// Quadrature
// ---------------------------------------------------------------------------------------------

/// Gauss–Kronrod 15-point nodes (positive half, the last is the centre) and weights, with the
/// embedded 7-point Gauss weights for the odd-indexed nodes (QUADPACK's qk15). Only interior points
/// are evaluated, so a pdf that jumps exactly at a bin edge (the horizon, a texel edge) is
/// integrated exactly instead of being smeared by an endpoint evaluation.
const GK_X: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
const GK_W: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_18,
    0.140_653_259_715_525_92,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_83,
];
const G7_W: [f64; 4] =
    [0.129_484_966_168_869_7, 0.279_705_391_489_276_7, 0.381_830_050_505_118_9, 0.417_959_183_673_469_4];

/// (Kronrod estimate, |Kronrod − Gauss|) of ∫ f over [a, b].
fn gauss_kronrod(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> (f64, f64) {
    let c = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let fc = f(c);
    let mut k = GK_W[7] * fc;
    let mut g = G7_W[3] * fc;
    for i in 0..7 {
        let (f1, f2) = (f(c - h * GK_X[i]), f(c + h * GK_X[i]));
        k += GK_W[i] * (f1 + f2);
        if i % 2 == 1 {
            g += G7_W[i / 2] * (f1 + f2);
        }
    }
    (k * h, ((k - g) * h).abs())
}

/// ∫ f over `range` by adaptive Gauss–Kronrod (15 points) with absolute tolerance `eps`, bisecting
/// at least `min_depth` and at most `max_depth` times.
pub fn adaptive_integrate(f: &impl Fn(f64) -> f64, range: [f64; 2], eps: f64, min_depth: u32, max_depth: u32) -> f64 {
    fn rec(f: &impl Fn(f64) -> f64, a: f64, b: f64, eps: f64, depth: u32, min_depth: u32, max_depth: u32) -> f64 {
        if depth >= min_depth {
            let (v, err) = gauss_kronrod(f, a, b);
            if depth >= max_depth || err <= eps {
                return v;
            }
        }
        let m = 0.5 * (a + b);
        rec(f, a, m, 0.5 * eps, depth + 1, min_depth, max_depth)
            + rec(f, m, b, 0.5 * eps, depth + 1, min_depth, max_depth)
    }
    rec(f, range[0], range[1], eps, 0, min_depth, max_depth)
}

/// ∫∫ f over a rectangle by nested adaptive Gauss–Kronrod (the inner integral over the first
/// parameter).
pub fn adaptive_integrate_2d(
    f: &impl Fn([f64; 2]) -> f64,
    a_range: [f64; 2],
    b_range: [f64; 2],
    eps: f64,
    min_depth: u32,
    max_depth: u32,
) -> f64 {
    let inner_eps = eps / (b_range[1] - b_range[0]).abs().max(1e-300);
    let inner = |b: f64| adaptive_integrate(&|a: f64| f([a, b]), a_range, inner_eps, min_depth, max_depth);
    adaptive_integrate(&inner, b_range, eps, min_depth, max_depth)
}

/// ∫∫ f over a rectangle split into `na`×`nb` cells, each integrated adaptively (tolerance 1e-9
/// per cell, at most 8 bisections per dimension): robust to discontinuities, e.g. a pdf that is zero outside a disk or a triangle.
pub fn integrate_2d(f: impl Fn([f64; 2]) -> f64, a_range: [f64; 2], b_range: [f64; 2], na: usize, nb: usize) -> f64 {
    integrate_2d_to(f, a_range, b_range, [na, nb], 1e-9, 8)
}

/// `integrate_2d` with the per-cell absolute tolerance `eps` and bisection limit `max_depth` given:
/// for integrands evaluated in f32, whose rounding noise (~1e-7 of their value) a tolerance of 1e-9
/// can never meet, so that every cell would be bisected to the limit.
pub fn integrate_2d_to(
    f: impl Fn([f64; 2]) -> f64,
    a_range: [f64; 2],
    b_range: [f64; 2],
    [na, nb]: [usize; 2],
    eps: f64,
    max_depth: u32,
) -> f64 {
    let mut total = 0.0;
    for j in 0..nb {
        for i in 0..na {
            let a0 = a_range[0] + (a_range[1] - a_range[0]) * i as f64 / na as f64;
            let a1 = a_range[0] + (a_range[1] - a_range[0]) * (i + 1) as f64 / na as f64;
            let b0 = b_range[0] + (b_range[1] - b_range[0]) * j as f64 / nb as f64;
            let b1 = b_range[0] + (b_range[1] - b_range[0]) * (j + 1) as f64 / nb as f64;
            total += adaptive_integrate_2d(&f, [a0, a1], [b0, b1], eps, 0, max_depth);
        }
    }
    total
}

/// ∫ f dω over the unit sphere, on an `n_z`×`n_phi` grid of (cos θ, φ) cells.
pub fn integrate_sphere(f: impl Fn(Vec3) -> f64, n_z: usize, n_phi: usize) -> f64 {
    integrate_2d(|p| f(sphere_param_to_direction(p)), [-1.0, 1.0], [0.0, 2.0 * std::f64::consts::PI], n_z, n_phi)
}

// ---------------------------------------------------------------------------------------------
// Numerical Jacobians
// ---------------------------------------------------------------------------------------------

/// |det ∂map/∂u| of a map from the square to the plane, by central differences with step `h`.
/// Compare with 1/pdf (RJMLT Sec. 4: |J[S]| = 1/p for a diffeomorphism).
pub fn jacobian_det_2d(map: impl Fn([f64; 2]) -> [f64; 2], u: [f64; 2], h: f64) -> f64 {
    let d0 = central_difference(&map, u, 0, h);
    let d1 = central_difference(&map, u, 1, h);
    (d0[0] * d1[1] - d0[1] * d1[0]).abs()
}

/// Area-scaling factor |∂map/∂u0 × ∂map/∂u1| of a map from the square onto a surface in 3D (the unit
/// sphere of directions, a triangle, a film): the Jacobian with respect to solid angle or area.
pub fn jacobian_det_surface(map: impl Fn([f64; 2]) -> [f64; 3], u: [f64; 2], h: f64) -> f64 {
    let d0 = central_difference(&map, u, 0, h);
    let d1 = central_difference(&map, u, 1, h);
    let c = [d0[1] * d1[2] - d0[2] * d1[1], d0[2] * d1[0] - d0[0] * d1[2], d0[0] * d1[1] - d0[1] * d1[0]];
    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
}

fn central_difference<const N: usize>(
    map: &impl Fn([f64; 2]) -> [f64; N],
    u: [f64; 2],
    axis: usize,
    h: f64,
) -> [f64; N] {
    let mut up = u;
    let mut down = u;
    up[axis] += h;
    down[axis] -= h;
    let (a, b) = (map(up), map(down));
    let mut d = [0.0; N];
    for k in 0..N {
        d[k] = (a[k] - b[k]) / (2.0 * h);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incomplete_gamma_matches_known_values() {
        // Chi-square quantiles from standard tables: P(X ≥ 3.841) = 0.05 with 1 dof, P(X ≥ 18.307)
        // = 0.05 with 10 dof, P(X ≥ 124.342) = 0.05 with 100 dof, P(X ≥ 149.449) = 0.001 with 100.
        for (x, k, p) in
            [(3.841_459, 1.0, 0.05), (18.307_04, 10.0, 0.05), (124.342_1, 100.0, 0.05), (149.448_8, 100.0, 0.001)]
        {
            let q = chi2_survival(x, k);
            assert!((q - p).abs() < 1e-4 * p.max(1e-3) * 10.0, "Q({x}, {k}) = {q}, expected {p}");
        }
        // Exponential special case: 2 dof, P(X ≥ x) = e^{-x/2}, deep in the tail too.
        for x in [0.1, 1.0, 10.0, 100.0, 1000.0] {
            let q = chi2_survival(x, 2.0);
            let e = (-x / 2.0f64).exp();
            assert!((q - e).abs() <= 1e-10 * e.max(1e-300) + 1e-300, "2 dof at {x}: {q} vs {e}");
        }
        assert_eq!(chi2_survival(0.0, 5.0), 1.0);
        assert_eq!(chi2_survival(3.0, 0.0), 0.0);
    }

    #[test]
    fn upper_quantile_inverts_the_survival_function() {
        // The tables' 1-dof and 10-dof 5% points, then the round trip where the share tests use it
        // (α = 1e-4, non-integer ν from Box's approximation).
        assert!((chi2_upper_quantile(0.05, 1.0) - 3.841_459).abs() < 1e-5);
        assert!((chi2_upper_quantile(0.05, 10.0) - 18.307_04).abs() < 1e-4);
        for dof in [1.0, 4.3, 8.0, 15.0, 40.5] {
            let x = chi2_upper_quantile(1e-4, dof);
            let p = chi2_survival(x, dof);
            assert!((p - 1e-4).abs() < 1e-8, "ν = {dof}: Q({x}) = {p}");
        }
    }

    #[test]
    fn quadrature_handles_steps() {
        // A disk indicator: area π/4 of a radius-1/2 disk inside the unit square.
        let v = integrate_2d(
            |p| if (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) <= 0.25 { 1.0 } else { 0.0 },
            [0.0, 1.0],
            [0.0, 1.0],
            16,
            16,
        );
        assert!((v - std::f64::consts::FRAC_PI_4).abs() < 1e-5, "{v}");
        let s = adaptive_integrate(&|x: f64| x.sin(), [0.0, std::f64::consts::PI], 1e-12, 2, 20);
        assert!((s - 2.0).abs() < 1e-10);
    }

    /// Under the null hypothesis the test passes, and it rejects a uniform sampler tested against
    /// a linear pdf on [0,1]² (a gross error) and a mildly miscalibrated one.
    #[test]
    fn harness_accepts_truth_and_rejects_lies() {
        let cfg = Chi2Config { res: [16, 16], samples: 50_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let uniform = |rng: &mut Rng| Some([rng.uniform_f64(), rng.uniform_f64()]);
        let ok = chi2_square(&cfg, [0.0, 1.0], [0.0, 1.0], 1, uniform, |_| 1.0);
        assert!(ok.passed, "{}", ok.message);
        let bad = chi2_square(&cfg, [0.0, 1.0], [0.0, 1.0], 2, uniform, |p| 2.0 * p[0]);
        assert!(!bad.passed, "{}", bad.message);
        // 3% of the samples fail but the pdf claims full mass: the failure cell exposes it.
        let lossy =
            |rng: &mut Rng| if rng.uniform() < 0.03 { None } else { Some([rng.uniform_f64(), rng.uniform_f64()]) };
        let bad = chi2_square(&cfg, [0.0, 1.0], [0.0, 1.0], 3, lossy, |_| 1.0);
        assert!(!bad.passed, "{}", bad.message);
        // ... and passes when the pdf carries the 97% it really covers.
        let ok = chi2_square(&cfg, [0.0, 1.0], [0.0, 1.0], 4, lossy, |_| 0.97);
        assert!(ok.passed, "{}", ok.message);
        // A 1D test of a triangular density.
        let tri = chi2_1d(&cfg, [0.0, 1.0], 5, |rng| Some(rng.uniform_f64().sqrt()), |x| 2.0 * x);
        assert!(tri.passed, "{}", tri.message);
    }

    #[test]
    fn numerical_jacobians() {
        let polar = |u: [f64; 2]| [u[0] * u[1].cos(), u[0] * u[1].sin()];
        assert!((jacobian_det_2d(polar, [0.7, 1.0], 1e-5) - 0.7).abs() < 1e-8);
        let sphere = |u: [f64; 2]| {
            let z: f64 = 1.0 - 2.0 * u[0];
            let r = (1.0 - z * z).sqrt();
            let phi = 2.0 * std::f64::consts::PI * u[1];
            [r * phi.cos(), r * phi.sin(), z]
        };
        assert!((jacobian_det_surface(sphere, [0.3, 0.4], 1e-5) - 4.0 * std::f64::consts::PI).abs() < 1e-6);
    }
}
