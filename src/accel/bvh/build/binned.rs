//! The binned SAH's split choice (Wald 2007): centroid extents, the bins and their parallel
//! filling, and the sweep over bin boundaries (scalar, and all three axes at once in SIMD) that
//! picks the cheapest split. `build` partitions by what this picks.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::{packets, BuildParams, BuildPrim, BINS, CHUNK, PARALLEL_PRIMS};
use crate::geometry::Aabb;

/// A bin: bounds and centroid bounds of its primitives, and their number (the bins of `bin_seq`
/// leave the centroid bounds empty).
#[derive(Clone, Copy)]
pub(super) struct Bin {
    pub(super) bounds: Aabb,
    pub(super) centroids: Aabb,
    pub(super) count: u32,
}

impl Bin {
    pub(super) const EMPTY: Bin = Bin { bounds: Aabb::EMPTY, centroids: Aabb::EMPTY, count: 0 };
    pub(super) fn merge(&self, o: &Bin) -> Bin {
        Bin {
            bounds: self.bounds.union(&o.bounds),
            centroids: self.centroids.union(&o.centroids),
            count: self.count + o.count,
        }
    }
}

/// Bounds and centroid bounds of `prims`, in SIMD vectors; the centroid bounds over the corner
/// sums, halved at the end (exactly the bounds of the centroids: halving is monotonic).
pub(super) fn extent_seq(prims: &[BuildPrim]) -> Bin {
    let (mut min, mut max) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    let (mut cmin, mut cmax) = (min, max);
    for p in prims {
        let (lo, hi) = bounds_of(p);
        let sum = lo + hi;
        (min, max) = (min.min(lo), max.max(hi));
        (cmin, cmax) = (cmin.min(sum), cmax.max(sum));
    }
    Bin {
        bounds: Aabb { min: min.into(), max: max.into() },
        centroids: Aabb { min: (cmin * 0.5).into(), max: (cmax * 0.5).into() },
        count: prims.len() as u32,
    }
}

/// Bounds and centroid bounds of `prims`.
pub(super) fn extent(prims: &[BuildPrim]) -> Bin {
    if prims.len() > PARALLEL_PRIMS * 4 {
        prims.par_chunks(CHUNK).map(extent_seq).reduce(|| Bin::EMPTY, |a, b| a.merge(&b))
    } else {
        extent_seq(prims)
    }
}

/// Maps a centroid coordinate to its bin on one axis.
#[derive(Clone, Copy)]
pub(super) struct Binner {
    pub(super) origin: Vec3,
    /// `bins / extent` per axis (0 on axes without extent, which are not split).
    pub(super) scale: Vec3,
    /// Bins in use (at most `BINS`): fewer for small ranges, where a split is one of few anyway
    /// and the sweep over the bins would cost more than the binning.
    pub(super) bins: usize,
}

impl Binner {
    /// The bins of centroid `c` on the three axes: `⌊(c − origin) · scale⌋` clamped to
    /// `[0, bins − 1]`, a negative or NaN coordinate in bin 0 (the clamp catches `x == bins`
    /// from rounding). The clamp is done in f32, so that the conversion is one instruction.
    #[inline(always)]
    pub(super) fn bins_of(&self, c: Vec3A) -> [usize; 3] {
        let k = (c - Vec3A::from(self.origin)) * Vec3A::from(self.scale);
        let last = Vec3A::splat((self.bins - 1) as f32);
        // glam's `max` and `min` are `maxps` and `minps` on x86-64: `k > 0 ? k : 0`, then
        // `k < last ? k : last`, the second operand when one is NaN, so a NaN lane becomes 0.
        #[cfg(target_arch = "x86_64")]
        let k = k.max(Vec3A::ZERO).min(last);
        // Elsewhere (NEON's `vmaxq` returns NaN for NaN) with selects on ordered comparisons,
        // which are false for NaN: a NaN lane becomes 0, then stays below `last`.
        #[cfg(not(target_arch = "x86_64"))]
        let k = Vec3A::select(k.cmpge(Vec3A::ZERO), k, Vec3A::ZERO);
        #[cfg(not(target_arch = "x86_64"))]
        let k = Vec3A::select(k.cmplt(last), k, last);
        // SAFETY: every lane is now finite and within [0, bins − 1] ⊂ [0, 16), where the
        // unchecked float-to-integer conversion is defined (it truncates, as `as` does).
        k.to_array().map(|x| unsafe { x.to_int_unchecked::<u32>() } as usize)
    }

    /// Whether centroid `c` falls in a bin below `bin` on `axis` (`bins_of(c)[axis] < bin`, for
    /// `1 ≤ bin ≤ bins − 1`), without the conversion: for `x = (c − origin) · scale`,
    /// `⌊x⌋ < bin ⇔ x < bin`; a negative or NaN `x` is bin 0, below (`!(x >= bin)` holds for NaN);
    /// and the clamp to `bins − 1 ≥ bin` changes no answer.
    #[inline(always)]
    pub(super) fn below(&self, c: Vec3A, axis: usize, bin: usize) -> bool {
        let x = (c[axis] - self.origin[axis]) * self.scale[axis];
        !(x >= bin as f32)
    }
}

/// A bin while binning: its primitives' bounds in SIMD vectors (one `minps`/`maxps` each per
/// update) and their number. Centroid bounds are not binned: the partition computes the two
/// halves' (`partition`), one update per primitive instead of one per axis.
#[derive(Clone, Copy)]
pub(super) struct BinA {
    pub(super) min: Vec3A,
    pub(super) max: Vec3A,
    pub(super) count: u32,
}

impl BinA {
    pub(super) const EMPTY: BinA = BinA { min: Vec3A::INFINITY, max: Vec3A::NEG_INFINITY, count: 0 };
    #[inline(always)]
    pub(super) fn merge(&self, o: &BinA) -> BinA {
        BinA { min: self.min.min(o.min), max: self.max.max(o.max), count: self.count + o.count }
    }
}

pub(super) type Bins = [[BinA; BINS]; 3];

/// Half the surface area of the box `[min, max]` (0 for an empty box), in SIMD: the SAH compares
/// ratios of areas, which the factor 2 leaves exactly as they are.
#[inline(always)]
pub(super) fn half_area(min: Vec3A, max: Vec3A) -> f32 {
    let e = (max - min).max(Vec3A::ZERO);
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Bins `prims` into `out`. Alternate primitives go to two sets of bins, merged at the end:
/// consecutive primitives are often neighbours (meshes are stored in order) and fall in the same
/// bins, and with one set each update would wait for the previous one's store to the same bin.
/// (Written into the caller's bins rather than returned: the returned and destructured arrays,
/// 2.3 kB each, were eight `memcpy` calls per binning, 4% of the build's instructions.)
pub(super) fn bin_seq(prims: &[BuildPrim], binner: &Binner, out: &mut Bins) {
    let nb = binner.bins;
    *out = [[BinA::EMPTY; BINS]; 3];
    let mut odd = [[BinA::EMPTY; BINS]; 3];
    let pairs = prims.chunks_exact(2);
    for p in pairs.remainder() {
        bin_one(out, p, binner);
    }
    for pair in pairs {
        bin_one(out, &pair[0], binner);
        bin_one(&mut odd, &pair[1], binner);
    }
    for (o, b) in out.iter_mut().zip(&odd) {
        for (o, b) in o[..nb].iter_mut().zip(&b[..nb]) {
            *o = o.merge(b);
        }
    }
}

/// The bounds of `p` in SIMD vectors. On x86-64 two unaligned loads of its halves (each box
/// corner sits in the first three lanes, an id in the fourth) with the id lane cleared, which
/// keeps integer bits, denormals as floats, out of the arithmetic; elsewhere from the fields.
#[inline(always)]
pub(super) fn bounds_of(p: &BuildPrim) -> (Vec3A, Vec3A) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_and_ps, _mm_castsi128_ps, _mm_loadu_ps, _mm_set_epi32};
        // SAFETY: SSE2 is part of the x86-64 baseline; `BuildPrim` is `repr(C)`, 32 bytes: `min`
        // and `geom` are its first 16 bytes, `max` and `prim` its last 16, all readable.
        unsafe {
            let xyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
            let at = (p as *const BuildPrim).cast::<f32>();
            (Vec3A::from(_mm_and_ps(_mm_loadu_ps(at), xyz)), Vec3A::from(_mm_and_ps(_mm_loadu_ps(at.add(4)), xyz)))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    (Vec3A::from(p.min), Vec3A::from(p.max))
}

/// Adds `p` to its bin on each axis.
#[inline(always)]
pub(super) fn bin_one(bins: &mut Bins, p: &BuildPrim, binner: &Binner) {
    let (lo, hi) = bounds_of(p);
    let k = binner.bins_of((lo + hi) * 0.5);
    for (axis, axis_bins) in bins.iter_mut().enumerate() {
        // `bins_of` is below `BINS`: the mask only spares the bounds check.
        let b = &mut axis_bins[k[axis] & (BINS - 1)];
        b.count += 1;
        b.min = b.min.min(lo);
        b.max = b.max.max(hi);
    }
}

pub(super) fn merge_bins(mut a: Bins, b: Bins) -> Bins {
    for (aa, ba) in a.iter_mut().zip(b.iter()) {
        for (x, y) in aa.iter_mut().zip(ba.iter()) {
            *x = x.merge(y);
        }
    }
    a
}

pub(super) fn bin_all(prims: &[BuildPrim], binner: &Binner, out: &mut Bins) {
    if prims.len() > PARALLEL_PRIMS * 4 {
        *out = prims
            .par_chunks(CHUNK)
            .map(|c| {
                let mut bins = [[BinA::EMPTY; BINS]; 3];
                bin_seq(c, binner, &mut bins);
                bins
            })
            .reduce(|| [[BinA::EMPTY; BINS]; 3], merge_bins);
    } else {
        bin_seq(prims, binner, out);
    }
}

/// The best split found: axis, first bin of the right side, and its SAH cost.
pub(super) struct Split {
    pub(super) axis: usize,
    pub(super) bin: usize,
    pub(super) cost: f32,
}

/// Sweeps the bins of every axis and returns the split with the least SAH cost
/// `C_trav + (A_L P(N_L) + A_R P(N_R)) / A` in units of one packet test, `P(n) = ceil(n / 4)` the
/// packets of `n` triangles (the leaf alternative costs `P(N)`); `parent_half_area` is `A / 2`, and
/// the sweep compares the numerators, dividing once at the end.
pub(super) fn best_split(
    bins: &Bins,
    nb: usize,
    parent_half_area: f32,
    centroid_extent: Vec3,
    params: &BuildParams,
) -> Option<Split> {
    let mut best: Option<(usize, usize, f32)> = None;
    for (axis, axis_bins) in bins.iter().enumerate() {
        let axis_bins = &axis_bins[..nb];
        if centroid_extent[axis].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        // right_cost[i] = A_R · P(N_R) for the right side made of bins i..nb.
        let mut right_cost = [0.0f32; BINS];
        let mut right_count = [0u32; BINS];
        let mut acc = BinA::EMPTY;
        for i in (1..nb).rev() {
            acc = acc.merge(&axis_bins[i]);
            right_count[i] = acc.count;
            right_cost[i] = half_area(acc.min, acc.max) * packets(acc.count as usize);
        }
        let mut acc = BinA::EMPTY;
        for i in 1..nb {
            acc = acc.merge(&axis_bins[i - 1]);
            if acc.count == 0 || right_count[i] == 0 {
                continue;
            }
            let cost = half_area(acc.min, acc.max) * packets(acc.count as usize) + right_cost[i];
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, i, cost));
            }
        }
    }
    best.map(|(axis, bin, cost)| Split { axis, bin, cost: params.traversal_cost + cost / parent_half_area })
}

/// `best_split` with the three axes in the lanes of SIMD vectors: the same candidates, the same
/// f32 operations on each (areas `e.x e.y + e.y e.z + e.z e.x` of `max(max − min, 0)`, the
/// packets `⌈N / 4⌉`, one product and one sum per candidate) and the same choice (the least cost,
/// the first axis then the first bin among equals), so the same split bit for bit
/// (`simd_sweep_picks_the_scalar_split` compares them). The bins are transposed once (lane `a` of
/// each row from axis `a`'s bin), and the sweeps then do one vector operation where the scalar one
/// did three and extracted lanes for the areas. Counts are summed as f32, exact below 2^24; larger
/// ranges, and any candidate of infinite or NaN cost (bounds that overflow), go to `best_split`,
/// whose choice among those (the first candidate even if NaN) the vectors do not reproduce.
#[cfg(target_arch = "x86_64")]
pub(super) fn best_split_simd(
    bins: &Bins,
    nb: usize,
    n: usize,
    parent_half_area: f32,
    centroid_extent: Vec3,
    params: &BuildParams,
) -> Option<Split> {
    use glam::{BVec4A, Vec4};
    use std::arch::x86_64::{
        __m128, _mm_cvtepi32_ps, _mm_cvttps_epi32, _mm_movehl_ps, _mm_movelh_ps, _mm_setr_epi32, _mm_unpackhi_ps,
        _mm_unpacklo_ps,
    };
    if n >= 1 << 24 {
        return best_split(bins, nb, parent_half_area, centroid_extent, params);
    }
    /// One row: the bounds of a box per lane (min x, y, z, max x, y, z) and its count.
    #[derive(Clone, Copy)]
    struct Row {
        min: [Vec4; 3],
        max: [Vec4; 3],
        count: Vec4,
    }
    impl Row {
        const EMPTY: Row = Row { min: [Vec4::INFINITY; 3], max: [Vec4::NEG_INFINITY; 3], count: Vec4::ZERO };
        #[inline(always)]
        fn merge(&self, o: &Row) -> Row {
            let f = |i: usize| (self.min[i].min(o.min[i]), self.max[i].max(o.max[i]));
            let (a, b, c) = (f(0), f(1), f(2));
            Row { min: [a.0, b.0, c.0], max: [a.1, b.1, c.1], count: self.count + o.count }
        }
        /// `half_area(min, max) · packets(count)` in each lane.
        #[inline(always)]
        fn cost(&self) -> Vec4 {
            let e = |i: usize| (self.max[i] - self.min[i]).max(Vec4::ZERO);
            let (x, y, z) = (e(0), e(1), e(2));
            // ⌈c / 4⌉ = ⌊(c + 3) / 4⌋: exact in f32 below 2^24, and truncation is the floor here.
            // SAFETY: SSE2 is part of the x86-64 baseline.
            let packets = unsafe {
                Vec4::from(_mm_cvtepi32_ps(_mm_cvttps_epi32(((self.count + Vec4::splat(3.0)) * 0.25).into())))
            };
            (x * y + y * z + z * x) * packets
        }
    }
    // Lanes a = 0, 1, 2 of (x, y, z) gathered from the three vectors (x_a, y_a, z_a, _).
    // SAFETY (both): SSE2 is part of the x86-64 baseline.
    let transpose = |v0: __m128, v1: __m128, v2: __m128| unsafe {
        let zero = Vec4::ZERO.into();
        let (a, b) = (_mm_unpacklo_ps(v0, v1), _mm_unpacklo_ps(v2, zero));
        let (c, d) = (_mm_unpackhi_ps(v0, v1), _mm_unpackhi_ps(v2, zero));
        [Vec4::from(_mm_movelh_ps(a, b)), Vec4::from(_mm_movehl_ps(b, a)), Vec4::from(_mm_movelh_ps(c, d))]
    };
    let mut rows = [Row::EMPTY; BINS];
    for (i, row) in rows.iter_mut().enumerate().take(nb) {
        let [b0, b1, b2] = [&bins[0][i], &bins[1][i], &bins[2][i]];
        let count = unsafe {
            Vec4::from(_mm_cvtepi32_ps(_mm_setr_epi32(b0.count as i32, b1.count as i32, b2.count as i32, 0)))
        };
        *row = Row {
            min: transpose(b0.min.into(), b1.min.into(), b2.min.into()),
            max: transpose(b0.max.into(), b1.max.into(), b2.max.into()),
            count,
        };
    }
    let mut right_cost = [Vec4::ZERO; BINS];
    let mut right_count = [Vec4::ZERO; BINS];
    let mut acc = Row::EMPTY;
    for i in (1..nb).rev() {
        acc = acc.merge(&rows[i]);
        right_count[i] = acc.count;
        right_cost[i] = acc.cost();
    }
    let extent = Vec4::new(centroid_extent.x, centroid_extent.y, centroid_extent.z, 0.0);
    let axes = extent.cmpgt(Vec4::ZERO);
    let mut best_cost = Vec4::INFINITY;
    let mut best_bin = Vec4::ZERO;
    let mut not_finite = BVec4A::FALSE;
    let mut acc = Row::EMPTY;
    for i in 1..nb {
        acc = acc.merge(&rows[i - 1]);
        let cost = acc.cost() + right_cost[i];
        let valid = axes & acc.count.cmpgt(Vec4::ZERO) & right_count[i].cmpgt(Vec4::ZERO);
        // `!(cost < ∞)`: infinite or NaN.
        not_finite |= valid & !cost.cmplt(Vec4::INFINITY);
        let better = valid & cost.cmplt(best_cost);
        best_cost = Vec4::select(better, cost, best_cost);
        best_bin = Vec4::select(better, Vec4::splat(i as f32), best_bin);
    }
    if not_finite.any() {
        return best_split(bins, nb, parent_half_area, centroid_extent, params);
    }
    let (costs, bins_at) = (best_cost.to_array(), best_bin.to_array());
    let mut best: Option<(usize, f32)> = None;
    for (axis, &cost) in costs.iter().enumerate().take(3) {
        if cost < f32::INFINITY && best.is_none_or(|b| cost < b.1) {
            best = Some((axis, cost));
        }
    }
    best.map(|(axis, cost)| Split {
        axis,
        bin: bins_at[axis] as usize,
        cost: params.traversal_cost + cost / parent_half_area,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The SIMD sweep picks the scalar one's split, bit for bit, on random bins: some empty, some
    /// axes without centroid extent, ties between axes (copied bins), and bounds large enough that
    /// areas overflow to infinity (the fallback to the scalar sweep).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn simd_sweep_picks_the_scalar_split() {
        let mut rng = Rng::new(20, 14);
        let params = BuildParams::default();
        let (mut found, mut overflowed) = (0, 0);
        for case in 0..20_000 {
            let nb = 2 + (rng.next_u64() % (BINS as u64 - 1)) as usize;
            let scale = match case % 4 {
                0 => 1e-3,
                1 | 2 => 10.0,
                _ => 1e19,
            };
            let mut bins = [[BinA::EMPTY; BINS]; 3];
            let mut n = 0;
            for axis_bins in bins.iter_mut() {
                for bin in axis_bins.iter_mut().take(nb) {
                    if rng.uniform() < 0.25 {
                        continue;
                    }
                    let c = Vec3A::new(rng.uniform(), rng.uniform(), rng.uniform()) * scale;
                    let e = Vec3A::new(rng.uniform(), rng.uniform(), rng.uniform()) * scale * 0.2;
                    // Coarse values, so that equal costs happen.
                    let q = |v: Vec3A| (v * 8.0).round() / 8.0;
                    *bin = BinA { min: q(c - e), max: q(c + e), count: 1 + (rng.next_u64() % 9) as u32 };
                    n += bin.count as usize;
                }
            }
            if rng.uniform() < 0.3 {
                // The same bins on two axes: equal costs, the first axis must win.
                bins[1] = bins[0];
            }
            let extent = Vec3::new(
                if rng.uniform() < 0.15 { 0.0 } else { 1.0 },
                if rng.uniform() < 0.15 { 0.0 } else { 1.0 },
                if rng.uniform() < 0.15 { 0.0 } else { 1.0 },
            );
            let parent = 3.0 * scale * scale;
            let a = best_split(&bins, nb, parent, extent, &params);
            let b = best_split_simd(&bins, nb, n, parent, extent, &params);
            let key = |s: &Option<Split>| s.as_ref().map(|s| (s.axis, s.bin, s.cost.to_bits()));
            assert_eq!(key(&a), key(&b), "case {case}: nb {nb}");
            found += a.is_some() as usize;
            overflowed += a.as_ref().is_some_and(|s| !s.cost.is_finite()) as usize;
        }
        assert!(found > 15_000 && overflowed > 100, "{found} splits, {overflowed} overflowed");
    }
}
