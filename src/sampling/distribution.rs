//! Piecewise-constant distributions in 1D and 2D, read continuously (a point in [0,1)^d) or
//! discretely (an item index), each with its pdf and its inverse.
//!
//! The continuous inverse is the CDF itself (RJMLT Sec. 6, "inversion method": exact, Jacobian =
//! pdf). A discrete choice maps a whole interval [cdf[i], cdf[i+1]) of u to one index, so its
//! inverse is probabilistic (RJMLT Eq. 40): a fresh uniform γ places u = cdf[i] + γ·pmf(i) inside
//! the interval, with Jacobian pmf(i).

// `!(x > 0.0)` is deliberate throughout: it rejects NaN along with the out-of-range values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::Vec2;

use super::warp::ONE_MINUS_EPSILON;

/// A piecewise-constant 1D distribution over `n` equal cells of [0, 1) (or, read discretely, over
/// `n` items), proportional to non-negative weights.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// Weights as given.
    pub func: Vec<f32>,
    /// Normalised CDF, `n + 1` entries from 0 to 1.
    pub cdf: Vec<f64>,
    /// Sum of weights / n (the integral of the step function over [0,1)).
    pub func_integral: f64,
}

/// A piecewise-constant 2D distribution over [0,1)²: a marginal over rows and one conditional per
/// row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    pub conditionals: Vec<Distribution1D>,
    pub marginal: Distribution1D,
}

/// The f32 nearest to `x` inside [lo, hi), or `None` when no f32 lies in the interval (then no f32
/// uniform can select it, so the forward sampler cannot have produced it either). `x` must lie in
/// [lo, hi); rounding moves it by at most half an ulp, so one step back suffices.
fn f32_in_interval(x: f64, lo: f64, hi: f64) -> Option<f32> {
    let mut f = x as f32;
    if (f as f64) < lo {
        f = f.next_up();
    }
    if (f as f64) >= hi {
        f = f.next_down();
    }
    ((f as f64) >= lo && (f as f64) < hi).then_some(f.min(ONE_MINUS_EPSILON))
}

// INTERFACE (implementation owned by the sampling work):
impl Distribution1D {
    /// Builds from non-negative finite weights; all-zero weights give the uniform distribution.
    /// Negative or non-finite weights are treated as zero (never a panic).
    pub fn new(weights: &[f32]) -> Distribution1D {
        let func: Vec<f32> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 }).collect();
        let n = func.len();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0f64);
        let mut acc = 0.0f64;
        for &w in &func {
            acc += w as f64;
            cdf.push(acc);
        }
        let func_integral = if n > 0 { acc / n as f64 } else { 0.0 };
        if acc > 0.0 {
            for c in cdf.iter_mut() {
                *c /= acc;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n.max(1) as f64;
            }
        }
        if n > 0 {
            // Exactly 1 at the end, whatever the rounding of the division.
            cdf[n] = 1.0;
        }
        Distribution1D { func, cdf, func_integral }
    }
    pub fn len(&self) -> usize {
        self.func.len()
    }
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }
    /// Discrete choice: `(index, probability of index, u remapped to [0,1) inside its interval)`.
    /// An empty distribution returns `(0, 0.0, u)`.
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let n = self.len();
        if n == 0 {
            return (0, 0.0, u);
        }
        let uf = u as f64;
        let i = self.interval_of(uf);
        let (lo, hi) = (self.cdf[i], self.cdf[i + 1]);
        let pmf = hi - lo;
        let remapped = if pmf > 0.0 { ((uf - lo) / pmf).clamp(0.0, ONE_MINUS_EPSILON as f64) as f32 } else { 0.0 };
        (i, pmf as f32, remapped.min(ONE_MINUS_EPSILON))
    }
    /// `sample_discrete` without the remapped uniform: `(index, probability of index)`, the same
    /// two values, for callers that do not reuse `u` (light selection per path vertex: the remap's
    /// f64 division was most of the choice's cost). An empty distribution returns `(0, 0.0)`.
    #[inline]
    pub fn sample_index(&self, u: f32) -> (usize, f32) {
        if self.is_empty() {
            return (0, 0.0);
        }
        let i = self.interval_of(u as f64);
        (i, (self.cdf[i + 1] - self.cdf[i]) as f32)
    }
    /// The interval with cdf[i] <= u < cdf[i+1] of a non-empty distribution, clamped to the items;
    /// empty intervals (zero weight) are never chosen. One item needs no search.
    #[inline]
    fn interval_of(&self, u: f64) -> usize {
        let n = self.len();
        if n == 1 {
            return 0;
        }
        (self.cdf.partition_point(|&c| c <= u).max(1) - 1).min(n - 1)
    }
    /// Probability of choosing `index` discretely (0 out of range).
    pub fn pdf_discrete(&self, index: usize) -> f32 {
        self.pmf_f64(index) as f32
    }
    /// Same as `pdf_discrete`: the probability mass of `index`.
    pub fn pmf(&self, index: usize) -> f32 {
        self.pdf_discrete(index)
    }
    fn pmf_f64(&self, index: usize) -> f64 {
        if index < self.len() {
            self.cdf[index + 1] - self.cdf[index]
        } else {
            0.0
        }
    }
    /// Probabilistic inverse of `sample_discrete` (RJMLT Eq. 40): u = cdf[i] + γ·pmf(i) for a fresh
    /// uniform `gamma`, so that u is uniform in the interval that selects `index`; its Jacobian is
    /// pmf(i). `None` for an index that cannot be chosen (zero weight, out of range).
    pub fn invert_discrete(&self, index: usize, gamma: f32) -> Option<f32> {
        let pmf = self.pmf_f64(index);
        if !(pmf > 0.0) {
            return None;
        }
        let (lo, hi) = (self.cdf[index], self.cdf[index + 1]);
        let g = (gamma as f64).clamp(0.0, 1.0);
        f32_in_interval((lo + g * pmf).min(hi), lo, hi).or_else(|| f32_in_interval(lo, lo, hi))
    }

    /// Continuous sample in [0, 1): `(x, pdf(x), cell index)`. Inverse-CDF sampling of the step
    /// function; uniform inside the chosen cell.
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let n = self.len();
        if n == 0 {
            return (u, 0.0, 0);
        }
        let (i, pmf, rem) = self.sample_discrete(u);
        let lo = i as f64 / n as f64;
        let hi = (i + 1) as f64 / n as f64;
        let x = f32_in_interval(lo + rem as f64 / n as f64, lo, hi).unwrap_or((lo as f32).min(ONE_MINUS_EPSILON));
        (x, pmf * n as f32, i)
    }
    /// Density of `sample_continuous` at `x` (0 outside [0, 1)).
    pub fn pdf_continuous(&self, x: f32) -> f32 {
        match self.cell_of(x) {
            Some(i) => (self.pmf_f64(i) * self.len() as f64) as f32,
            None => 0.0,
        }
    }
    /// Inverse of `sample_continuous`: the CDF at `x`, exact (the map is a bijection on cells of
    /// non-zero weight). `None` outside [0, 1] or in a cell of zero weight.
    pub fn invert_continuous(&self, x: f32) -> Option<f32> {
        let i = self.cell_of(x)?;
        let pmf = self.pmf_f64(i);
        if !(pmf > 0.0) {
            return None;
        }
        let n = self.len() as f64;
        let frac = (x as f64 * n - i as f64).clamp(0.0, 1.0);
        let (lo, hi) = (self.cdf[i], self.cdf[i + 1]);
        f32_in_interval((lo + frac * pmf).min(hi), lo, hi).or_else(|| f32_in_interval(lo, lo, hi))
    }
    /// The cell containing `x` ∈ [0, 1] (x = 1 belongs to the last cell).
    fn cell_of(&self, x: f32) -> Option<usize> {
        let n = self.len();
        if n == 0 || !(0.0..=1.0).contains(&x) {
            return None;
        }
        Some(((x as f64 * n as f64) as usize).min(n - 1))
    }
}

impl Distribution2D {
    /// Builds from `width`×`height` row-major non-negative weights (row `v` holds
    /// `weights[v*width..(v+1)*width]`). The point (x, y) ∈ [0,1)² lies in column ⌊x·width⌋ and row
    /// ⌊y·height⌋. Missing weights (a short slice) count as zero.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Distribution2D {
        let conditionals: Vec<Distribution1D> = (0..height)
            .map(|v| {
                let row: Vec<f32> = (0..width).map(|u| weights.get(v * width + u).copied().unwrap_or(0.0)).collect();
                Distribution1D::new(&row)
            })
            .collect();
        let marginal_weights: Vec<f32> = conditionals.iter().map(|c| c.func_integral as f32).collect();
        let marginal = Distribution1D::new(&marginal_weights);
        Distribution2D { conditionals, marginal }
    }
    pub fn width(&self) -> usize {
        self.conditionals.first().map_or(0, |c| c.len())
    }
    pub fn height(&self) -> usize {
        self.conditionals.len()
    }
    /// Continuous sample: the row from the marginal with `u[1]`, the column from that row's
    /// conditional with `u[0]`. Returns the point (x, y) and its density on [0,1)².
    pub fn sample_continuous(&self, u: [f32; 2]) -> (Vec2, f32) {
        if self.height() == 0 || self.width() == 0 {
            return (Vec2::new(u[0], u[1]), 0.0);
        }
        let (y, pdf_y, row) = self.marginal.sample_continuous(u[1]);
        let (x, pdf_x, _) = self.conditionals[row].sample_continuous(u[0]);
        (Vec2::new(x, y), pdf_x * pdf_y)
    }
    /// Density of `sample_continuous` at `p` (0 outside [0,1]²).
    pub fn pdf_continuous(&self, p: Vec2) -> f32 {
        match self.marginal.cell_of(p.y) {
            Some(row) => self.marginal.pdf_continuous(p.y) * self.conditionals[row].pdf_continuous(p.x),
            None => 0.0,
        }
    }
    /// Inverse of `sample_continuous`: the marginal CDF at y and the conditional CDF at x. Exact;
    /// `None` for a point outside [0,1]² or in a cell of zero density.
    pub fn invert_continuous(&self, p: Vec2) -> Option<[f32; 2]> {
        let row = self.marginal.cell_of(p.y)?;
        let u1 = self.marginal.invert_continuous(p.y)?;
        let u0 = self.conditionals[row].invert_continuous(p.x)?;
        Some([u0, u1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::chi2::{self, Chi2Config, CHI2_TESTS_SAMPLING};
    use crate::sampling::Rng;

    fn weights() -> Vec<f32> {
        vec![0.5, 0.0, 3.0, 1.0, 0.0, 0.0, 2.5, 1e-4]
    }

    #[test]
    fn discrete_pmf_and_sampling_agree() {
        let d = Distribution1D::new(&weights());
        let total: f32 = weights().iter().sum();
        for (i, w) in weights().iter().enumerate() {
            assert!((d.pmf(i) - w / total).abs() < 1e-6);
        }
        assert_eq!(d.pmf(99), 0.0);
        let mut counts = [0usize; 8];
        let mut rng = Rng::new(1, 2);
        let n = 200_000;
        for _ in 0..n {
            let u = rng.uniform();
            let (i, p, r) = d.sample_discrete(u);
            assert!(p > 0.0 && (0.0..1.0).contains(&r));
            assert_eq!(d.sample_index(u), (i, p), "u = {u}");
            counts[i] += 1;
        }
        let cfg = Chi2Config { res: [8, 1], samples: n, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        // Bin k of [0,8) holds index k: the pmf as a density on [0, 8).
        let r = chi2::chi2_1d(
            &cfg,
            [0.0, 8.0],
            3,
            |rng| Some(d.sample_discrete(rng.uniform()).0 as f64 + 0.5),
            |x| d.pmf(x as usize) as f64,
        );
        assert!(r.passed, "{}", r.message);
        assert_eq!(counts[1] + counts[4] + counts[5], 0);
    }

    #[test]
    fn all_zero_weights_are_uniform_and_empty_is_safe() {
        let d = Distribution1D::new(&[0.0, 0.0, 0.0, 0.0]);
        for i in 0..4 {
            assert_eq!(d.pmf(i), 0.25);
        }
        assert_eq!(d.sample_discrete(0.6).0, 2);
        assert_eq!(d.pdf_continuous(0.3), 1.0);
        let e = Distribution1D::new(&[]);
        assert!(e.is_empty());
        assert_eq!(e.sample_discrete(0.3).1, 0.0);
        assert_eq!(e.sample_index(0.3), (0, 0.0));
        // One item: no search, whatever the uniform (as the search gave).
        let one = Distribution1D::new(&[0.7]);
        for u in [0.0, 0.5, ONE_MINUS_EPSILON, 1.0, f32::NAN] {
            assert_eq!(one.sample_index(u), (0, 1.0));
            assert_eq!(one.sample_discrete(u).0, 0);
        }
        assert_eq!(e.invert_discrete(0, 0.5), None);
        let bad = Distribution1D::new(&[f32::NAN, -1.0, 2.0]);
        assert_eq!(bad.pmf(2), 1.0);
    }

    /// The discrete inverse (Eq. 40): sample(invert(i, γ)) = i, the remapped u equals γ, and for a
    /// fixed i the inverted u is uniform on the interval (a 1D chi-square test).
    #[test]
    fn discrete_inverse_is_uniform_in_its_interval() {
        let d = Distribution1D::new(&weights());
        let mut rng = Rng::new(5, 0);
        for _ in 0..10_000 {
            let i = [0usize, 2, 3, 6, 7][(rng.uniform() * 5.0) as usize];
            let g = rng.uniform();
            let u = d.invert_discrete(i, g).unwrap();
            let (j, _, r) = d.sample_discrete(u);
            assert_eq!(i, j);
            // Index 7 has pmf ≈ 1.4e-5: f32 resolution in u (6e-8) limits γ's recovery to ~5e-3.
            let tol = if i == 7 { 1e-2 } else { 1e-4 };
            assert!((r - g).abs() < tol, "index {i}: γ {g} -> u {u} -> {r}");
        }
        assert_eq!(d.invert_discrete(1, 0.5), None);
        assert_eq!(d.invert_discrete(8, 0.5), None);
        let (lo, hi) = (d.cdf[2], d.cdf[3]);
        let cfg = Chi2Config { res: [20, 1], samples: 40_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let r = chi2::chi2_1d(
            &cfg,
            [lo, hi],
            11,
            |rng| d.invert_discrete(2, rng.uniform()).map(|u| u as f64),
            |_| 1.0 / (hi - lo),
        );
        assert!(r.passed, "{}", r.message);
    }

    /// An interval narrower than an f32 ulp cannot be selected by any f32 u; the inverse says so
    /// instead of returning a u that selects a neighbour.
    #[test]
    fn discrete_inverse_never_lands_in_a_neighbour() {
        let mut w = vec![1.0f32; 1000];
        w[500] = 1e-12;
        let d = Distribution1D::new(&w);
        for i in 0..1000 {
            for g in [0.0, 0.5, ONE_MINUS_EPSILON] {
                if let Some(u) = d.invert_discrete(i, g) {
                    assert_eq!(d.sample_discrete(u).0, i);
                } else {
                    assert_eq!(i, 500);
                }
            }
        }
    }

    #[test]
    fn continuous_1d_round_trip_and_chi2() {
        let d = Distribution1D::new(&weights());
        let mut rng = Rng::new(9, 1);
        for _ in 0..10_000 {
            let u = rng.uniform();
            let (x, pdf, _) = d.sample_continuous(u);
            assert!((pdf - d.pdf_continuous(x)).abs() <= 1e-5 * pdf);
            let v = d.invert_continuous(x).unwrap();
            assert!((u - v).abs() < 1e-4, "{u} -> {x} -> {v}");
        }
        assert_eq!(d.invert_continuous(1.5 / 8.0), None);
        assert_eq!(d.invert_continuous(-0.1), None);
        let cfg = Chi2Config { res: [64, 1], samples: 100_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let r = chi2::chi2_1d(
            &cfg,
            [0.0, 1.0],
            4,
            |rng| Some(d.sample_continuous(rng.uniform()).0 as f64),
            |x| d.pdf_continuous(x as f32) as f64,
        );
        assert!(r.passed, "{}", r.message);
        // Integrates to 1.
        let total = chi2::integrate_2d(|p| d.pdf_continuous(p[0] as f32) as f64, [0.0, 1.0], [0.0, 1.0], 8, 1);
        assert!((total - 1.0).abs() < 1e-6, "{total}");
    }

    fn image() -> (Vec<f32>, usize, usize) {
        let (w, h) = (13, 7);
        let mut f = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let x = ((u * 7 + v * 3) % 11) as f32;
                f.push(if (u + v) % 5 == 0 { 0.0 } else { x * x + 0.1 });
            }
        }
        // One empty row.
        for u in 0..w {
            f[3 * w + u] = 0.0;
        }
        (f, w, h)
    }

    #[test]
    fn continuous_2d_chi2_round_trip_jacobian() {
        let (f, w, h) = image();
        let d = Distribution2D::new(&f, w, h);
        let cfg = Chi2Config { res: [26, 14], samples: 100_000, test_count: CHI2_TESTS_SAMPLING, ..Default::default() };
        let r = chi2::chi2_square(
            &cfg,
            [0.0, 1.0],
            [0.0, 1.0],
            21,
            |rng| {
                let (p, _) = d.sample_continuous([rng.uniform(), rng.uniform()]);
                Some([p.x as f64, p.y as f64])
            },
            |p| d.pdf_continuous(Vec2::new(p[0] as f32, p[1] as f32)) as f64,
        );
        assert!(r.passed, "{}", r.message);
        let total = chi2::integrate_2d(
            |p| d.pdf_continuous(Vec2::new(p[0] as f32, p[1] as f32)) as f64,
            [0.0, 1.0],
            [0.0, 1.0],
            13,
            7,
        );
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        let mut rng = Rng::new(3, 3);
        for _ in 0..10_000 {
            let u = [rng.uniform(), rng.uniform()];
            let (p, pdf) = d.sample_continuous(u);
            assert!(pdf > 0.0 && (pdf - d.pdf_continuous(p)).abs() <= 1e-4 * pdf);
            let v = d.invert_continuous(p).unwrap();
            assert!((u[0] - v[0]).abs() < 1e-4 && (u[1] - v[1]).abs() < 1e-4, "{u:?} -> {p} -> {v:?}");
            // Jacobian away from cell boundaries (the map is piecewise linear with jumps between cells).
            let ud = [u[0] as f64, u[1] as f64];
            let h_step = 1e-3;
            let map = |x: [f64; 2]| {
                let (p, _) = d.sample_continuous([x[0] as f32, x[1] as f32]);
                [p.x as f64, p.y as f64]
            };
            let same_cells = [[h_step, 0.0], [-h_step, 0.0], [0.0, h_step], [0.0, -h_step]].iter().all(|o| {
                let q = map([ud[0] + o[0], ud[1] + o[1]]);
                (q[0] * w as f64) as usize == (p.x as f64 * w as f64) as usize
                    && (q[1] * h as f64) as usize == (p.y as f64 * h as f64) as usize
            });
            if same_cells && (h_step..1.0 - h_step).contains(&ud[0]) && (h_step..1.0 - h_step).contains(&ud[1]) {
                let det = chi2::jacobian_det_2d(map, ud, h_step);
                assert!((det * pdf as f64 - 1.0).abs() < 1e-2, "|J| {det} vs 1/pdf {}", 1.0 / pdf);
            }
        }
        // Points in a zero-weight texel or the empty row have no preimage.
        assert_eq!(d.invert_continuous(Vec2::new(0.5 / 13.0, 0.5 / 7.0)), None);
        assert_eq!(d.invert_continuous(Vec2::new(0.5, 3.5 / 7.0)), None);
        assert_eq!(d.pdf_continuous(Vec2::new(0.5, 3.5 / 7.0)), 0.0);
    }
}
