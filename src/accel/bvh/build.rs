//! Binned-SAH construction (Wald 2007, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies") of an 8-wide hierarchy (`WIDTH`), built directly as Embree's builders do: a node
//! starts with its primitives as one child, and the child with the largest surface area is split by
//! the binned SAH until the node has `WIDTH` children or none can be split; each child is then a leaf or the
//! root of a subtree. Split candidates are the boundaries of `BINS` equal-width bins over the
//! centroid bounds on each axis; the bins also carry their primitives' bounds, and the partition
//! the centroid bounds of both halves, so the two halves of a split know their extents without
//! another pass over the primitives. Ranges of at most `SWEEP_PRIMS` are split by the exact SAH
//! over their sorted centroids instead (most splits are of small ranges, where setting up 3 × 16
//! bins cost more than the binning).
//!
//! Subtrees over more than `PARALLEL_PRIMS` primitives are built in parallel with rayon, each into
//! its own node array that the parent appends to its own (renumbering child indices); smaller
//! subtrees append straight to their parent's array. At the root's append the subtrees and the
//! final array are alive together: the build holds up to twice the nodes (`Bvh::build_with`
//! counts it). The nodes array grows to what the tree
//! needs (about one node per three leaves) instead of a worst-case preallocation, which matters for
//! the 10M-triangle scene of issue 20.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::geometry::Aabb;

/// A primitive during the build: its bounds and where it comes from. 32 bytes (`bounds_of` reads
/// its halves as SIMD vectors).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(super) struct BuildPrim {
    pub min: Vec3,
    pub geom: u32,
    pub max: Vec3,
    pub prim: u32,
}

impl BuildPrim {
    #[inline]
    fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
}

/// `Node::count` of a slot that holds nothing (its box is empty, so no ray enters it either).
pub(super) const EMPTY: u32 = u32::MAX;

/// Children per node. Eight, as Embree's BVH8: one AVX visit tests all eight boxes
/// (`triangle::slab8`), and the tree is about half as deep as a 4-wide one, so a ray makes about
/// half the dependent node loads (measured against 4-wide in docs/bench.md, session 10).
pub(super) const WIDTH: usize = 8;

/// An 8-wide node: 256 bytes, four cache lines, laid out for testing the eight boxes at once.
/// `bounds` holds min x, min y, min z, max x, max y, max z, each for the eight slots. A slot with
/// `count == 0` is an interior child (node index in `child`); with `count == EMPTY` it is unused;
/// otherwise a leaf of `count` triangles starting at `child` in the leaf-ordered triangle arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(super) struct Node {
    pub bounds: [[f32; WIDTH]; 6],
    pub child: [u32; WIDTH],
    pub count: [u32; WIDTH],
}

impl Node {
    const UNUSED: Node = Node {
        bounds: [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
        child: [0; WIDTH],
        count: [EMPTY; WIDTH],
    };

    fn set(&mut self, slot: usize, b: &Aabb, child: u32, count: u32) {
        for axis in 0..3 {
            self.bounds[axis][slot] = b.min[axis];
            self.bounds[axis + 3][slot] = b.max[axis];
        }
        self.child[slot] = child;
        self.count[slot] = count;
    }

    /// The box of slot `k`.
    #[cfg(test)]
    pub fn slot_bounds(&self, k: usize) -> Aabb {
        let b = &self.bounds;
        Aabb { min: Vec3::new(b[0][k], b[1][k], b[2][k]), max: Vec3::new(b[3][k], b[4][k], b[5][k]) }
    }
}

/// Tuning of the build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildParams {
    /// Leaves hold at most this many triangles (≥ 1).
    pub max_leaf: usize,
    /// SAH cost of visiting an interior node, relative to one test of a packet of four triangles
    /// (`triangle::intersect4_k`): a leaf of `n` triangles costs `ceil(n / 4)` (`packets`).
    pub traversal_cost: f32,
    /// Nodes over more primitives than this split their children in rounds, in parallel
    /// (`build_node`), since a partition is sequential. Only the top of very large scenes by
    /// default: splitting in rounds rather than largest first changes the tree (with 64k the
    /// benchmark scene's tree had 14% more nodes).
    pub parallel_split_prims: usize,
}

/// Triangles per leaf packet (`triangle::Tri4`).
pub(super) const PACKET: usize = 4;

/// The SAH cost of intersecting `n` triangles: the number of packets they fill.
#[inline]
fn packets(n: usize) -> f32 {
    n.div_ceil(PACKET) as f32
}

impl Default for BuildParams {
    /// Measured on the benchmark scene (docs/bench.md).
    fn default() -> Self {
        BuildParams { max_leaf: 8, traversal_cost: 1.0, parallel_split_prims: 2 * 1024 * 1024 }
    }
}

/// Number of SAH bins per axis.
const BINS: usize = 16;
/// Subtrees (and binning passes) over more primitives than this run in parallel; below it rayon's
/// task overhead outweighs the work.
const PARALLEL_PRIMS: usize = 4096;
/// Chunk size of the parallel binning and bounds passes.
const CHUNK: usize = 16 * 1024;
/// Below this many binary splits from the root the SAH decides; deeper, splits are forced to the
/// object median so that the depth stays below `MAX_DEPTH` (a median split halves the count: ≤ 32
/// more levels for < 2^32 primitives), which bounds the traversal stack. Every level of the wide
/// tree is at least one binary split, so its depth is bounded by `MAX_DEPTH` too.
const SAH_DEPTH: usize = 64;
/// Bound on the tree depth (root at depth 0), hence on the traversal stack.
pub(super) const MAX_DEPTH: usize = SAH_DEPTH + 33;

/// A bin: bounds and centroid bounds of its primitives, and their number (the bins of `bin_seq`
/// leave the centroid bounds empty).
#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    centroids: Aabb,
    count: u32,
}

impl Bin {
    const EMPTY: Bin = Bin { bounds: Aabb::EMPTY, centroids: Aabb::EMPTY, count: 0 };
    fn merge(&self, o: &Bin) -> Bin {
        Bin {
            bounds: self.bounds.union(&o.bounds),
            centroids: self.centroids.union(&o.centroids),
            count: self.count + o.count,
        }
    }
}

/// Bounds and centroid bounds of `prims`, in SIMD vectors; the centroid bounds over the corner
/// sums, halved at the end (exactly the bounds of the centroids: halving is monotonic).
fn extent_seq(prims: &[BuildPrim]) -> Bin {
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
fn extent(prims: &[BuildPrim]) -> Bin {
    if prims.len() > PARALLEL_PRIMS * 4 {
        prims.par_chunks(CHUNK).map(extent_seq).reduce(|| Bin::EMPTY, |a, b| a.merge(&b))
    } else {
        extent_seq(prims)
    }
}

/// Maps a centroid coordinate to its bin on one axis.
#[derive(Clone, Copy)]
struct Binner {
    origin: Vec3,
    /// `bins / extent` per axis (0 on axes without extent, which are not split).
    scale: Vec3,
    /// Bins in use (at most `BINS`): fewer for small ranges, where a split is one of few anyway
    /// and the sweep over the bins would cost more than the binning.
    bins: usize,
}

impl Binner {
    /// The bins of centroid `c` on the three axes: `⌊(c − origin) · scale⌋` clamped to
    /// `[0, bins − 1]`, a negative or NaN coordinate in bin 0 (the clamp catches `x == bins`
    /// from rounding). The clamp is done in f32, so that the conversion is one instruction.
    #[inline(always)]
    fn bins_of(&self, c: Vec3A) -> [usize; 3] {
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
    fn below(&self, c: Vec3A, axis: usize, bin: usize) -> bool {
        let x = (c[axis] - self.origin[axis]) * self.scale[axis];
        !(x >= bin as f32)
    }
}

/// A bin while binning: its primitives' bounds in SIMD vectors (one `minps`/`maxps` each per
/// update) and their number. Centroid bounds are not binned: the partition computes the two
/// halves' (`partition`), one update per primitive instead of one per axis.
#[derive(Clone, Copy)]
struct BinA {
    min: Vec3A,
    max: Vec3A,
    count: u32,
}

impl BinA {
    const EMPTY: BinA = BinA { min: Vec3A::INFINITY, max: Vec3A::NEG_INFINITY, count: 0 };
    #[inline(always)]
    fn merge(&self, o: &BinA) -> BinA {
        BinA { min: self.min.min(o.min), max: self.max.max(o.max), count: self.count + o.count }
    }
}

type Bins = [[BinA; BINS]; 3];

/// Half the surface area of the box `[min, max]` (0 for an empty box), in SIMD: the SAH compares
/// ratios of areas, which the factor 2 leaves exactly as they are.
#[inline(always)]
fn half_area(min: Vec3A, max: Vec3A) -> f32 {
    let e = (max - min).max(Vec3A::ZERO);
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Bins `prims` into `out`. Alternate primitives go to two sets of bins, merged at the end:
/// consecutive primitives are often neighbours (meshes are stored in order) and fall in the same
/// bins, and with one set each update would wait for the previous one's store to the same bin.
/// (Written into the caller's bins rather than returned: the returned and destructured arrays,
/// 2.3 kB each, were eight `memcpy` calls per binning, 4% of the build's instructions.)
fn bin_seq(prims: &[BuildPrim], binner: &Binner, out: &mut Bins) {
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
fn bounds_of(p: &BuildPrim) -> (Vec3A, Vec3A) {
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
fn bin_one(bins: &mut Bins, p: &BuildPrim, binner: &Binner) {
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

fn merge_bins(mut a: Bins, b: Bins) -> Bins {
    for (aa, ba) in a.iter_mut().zip(b.iter()) {
        for (x, y) in aa.iter_mut().zip(ba.iter()) {
            *x = x.merge(y);
        }
    }
    a
}

fn bin_all(prims: &[BuildPrim], binner: &Binner, out: &mut Bins) {
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
struct Split {
    axis: usize,
    bin: usize,
    cost: f32,
}

/// Sweeps the bins of every axis and returns the split with the least SAH cost
/// `C_trav + (A_L P(N_L) + A_R P(N_R)) / A` in units of one packet test, `P(n) = ceil(n / 4)` the
/// packets of `n` triangles (the leaf alternative costs `P(N)`); `parent_half_area` is `A / 2`, and
/// the sweep compares the numerators, dividing once at the end.
fn best_split(
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
fn best_split_simd(
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

/// Reorders `prims` so that those whose centroid falls in a bin below `bin` on `axis`
/// (`Binner::below`) come first; returns how many they are and the centroid bounds of both sides.
fn partition(prims: &mut [BuildPrim], binner: &Binner, axis: usize, bin: usize) -> (usize, Aabb, Aabb) {
    match axis {
        0 => partition_on::<0>(prims, binner, bin),
        1 => partition_on::<1>(prims, binner, bin),
        _ => partition_on::<2>(prims, binner, bin),
    }
}

/// `partition` on axis `AXIS` (a constant, so that the side test reads its lane directly).
/// Hoare's scheme: the left end advances over primitives that stay left, the right end over those
/// that stay right, and only a pair that is on the wrong sides is swapped, so each primitive is read
/// once and at most the misplaced ones are written (the scheme before swapped every right one,
/// reversing runs that were already in place). The bounds grow in SIMD vectors over the sums `min + max` and are halved at
/// the end: halving is monotonic, so the halved extremes are the extremes of the halved sums, the
/// centroids, exactly (a NaN sum leaves a bound as it was, as `Aabb::grow`).
/// (A branch-free variant, Lomuto's scheme with an unconditional swap, measured 4% slower on the
/// whole build, session 11.)
fn partition_on<const AXIS: usize>(prims: &mut [BuildPrim], binner: &Binner, bin: usize) -> (usize, Aabb, Aabb) {
    // The centroid's corner sum and whether the centroid goes left.
    let side = |p: &BuildPrim| {
        let (lo, hi) = bounds_of(p);
        let sum = lo + hi;
        (sum, binner.below(sum * 0.5, AXIS, bin))
    };
    let (mut lmin, mut lmax) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    let (mut rmin, mut rmax) = (lmin, lmax);
    let mut i = 0;
    let mut j = prims.len();
    'scan: loop {
        // Invariant: prims[..i] go left and prims[j..] right, all of them counted in the bounds.
        loop {
            if i == j {
                break 'scan;
            }
            let (sum, left) = side(&prims[i]);
            if left {
                (lmin, lmax) = (sum.min(lmin), sum.max(lmax));
                i += 1;
            } else {
                (rmin, rmax) = (sum.min(rmin), sum.max(rmax));
                break;
            }
        }
        // prims[i] goes right (counted).
        loop {
            j -= 1;
            if j == i {
                break 'scan;
            }
            let (sum, left) = side(&prims[j]);
            if left {
                (lmin, lmax) = (sum.min(lmin), sum.max(lmax));
                break;
            }
            (rmin, rmax) = (sum.min(rmin), sum.max(rmax));
        }
        prims.swap(i, j);
        i += 1;
    }
    let aabb = |min: Vec3A, max: Vec3A| Aabb { min: (min * 0.5).into(), max: (max * 0.5).into() };
    (i, aabb(lmin, lmax), aabb(rmin, rmax))
}

/// Below this many primitives a range is split by the exact SAH over its sorted centroids instead
/// of by bins: as cheap as binning there, and the best split rather than a bin boundary's.
const SWEEP_PRIMS: usize = 12;

/// The exact-SAH split of a small range: on each axis, the primitives sorted by centroid (stably)
/// and every one of the `n - 1` cuts evaluated (`C_trav + (A_L P(N_L) + A_R P(N_R)) / A`, as
/// `best_split`). Leaves `prims` sorted on the best axis and returns the cut and its cost. The
/// sorts order a small index array by centroids computed once, and the primitives themselves
/// move once, into the best axis's order (sorting the 32-byte primitives three times, their
/// centroids recomputed per comparison, was 10% of the build).
fn sweep_split(prims: &mut [BuildPrim], parent_half_area: f32, params: &BuildParams) -> Option<(usize, f32)> {
    let n = prims.len();
    debug_assert!((2..=SWEEP_PRIMS).contains(&n));
    // keys[axis][i]: the centroid of primitive i on `axis`.
    let mut keys = [[0.0f32; SWEEP_PRIMS]; 3];
    for (i, p) in prims.iter().enumerate() {
        for (k, c) in keys.iter_mut().zip(p.centroid().to_array()) {
            k[i] = c;
        }
    }
    let mut best: Option<(usize, f32)> = None;
    let mut best_order = [0u8; SWEEP_PRIMS];
    let mut right_area = [0.0f32; SWEEP_PRIMS];
    for key in &keys {
        // Insertion sort of the indices, stable: an index moves only past strictly greater keys.
        let mut order = [0u8; SWEEP_PRIMS];
        for (i, k) in key[..n].iter().enumerate() {
            let mut j = i;
            while j > 0 && key[order[j - 1] as usize].total_cmp(k).is_gt() {
                order[j] = order[j - 1];
                j -= 1;
            }
            order[j] = i as u8;
        }
        let bounds = |i: usize| {
            let p = &prims[order[i] as usize];
            (Vec3A::from(p.min), Vec3A::from(p.max))
        };
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for i in (1..n).rev() {
            let (a, b) = bounds(i);
            (lo, hi) = (lo.min(a), hi.max(b));
            right_area[i] = half_area(lo, hi);
        }
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for (i, &right) in right_area.iter().enumerate().take(n).skip(1) {
            let (a, b) = bounds(i - 1);
            (lo, hi) = (lo.min(a), hi.max(b));
            let cost = half_area(lo, hi) * packets(i) + right * packets(n - i);
            if best.is_none_or(|b| cost < b.1) {
                best = Some((i, cost));
                best_order = order;
            }
        }
    }
    let (cut, cost) = best?;
    let cost = params.traversal_cost + cost / parent_half_area;
    let mut copy = [prims[0]; SWEEP_PRIMS];
    copy[..n].copy_from_slice(prims);
    for (p, &k) in prims.iter_mut().zip(&best_order[..n]) {
        *p = copy[k as usize];
    }
    Some((cut, cost))
}

/// A contiguous range of a node's primitives, with its extents.
#[derive(Clone, Copy)]
struct Range {
    start: usize,
    len: usize,
    /// Bounds, centroid bounds and count (`ext.count == len`).
    ext: Bin,
    /// Binary splits from the root.
    depth: usize,
    /// Decided: this range is a leaf.
    leaf: bool,
}

/// Splits `r` (a range of `prims`) in two by the binned SAH, or by the object median when the SAH
/// cannot; `None` when it should be a leaf. Reorders the range's primitives.
fn split(prims: &mut [BuildPrim], r: &Range, params: &BuildParams) -> Option<(Range, Range)> {
    let n = r.len;
    if n <= 1 {
        return None;
    }
    let slice = &mut prims[r.start..r.start + n];
    let c_extent = r.ext.centroids.extent();
    let half = |start: usize, len: usize, ext: Bin| Range { start, len, ext, depth: r.depth + 1, leaf: false };
    if r.depth < SAH_DEPTH && c_extent.max_element() > 0.0 {
        let parent_half_area = half_area(r.ext.bounds.min.into(), r.ext.bounds.max.into());
        if n <= SWEEP_PRIMS {
            // A split costs `C_trav` plus a non-negative term, so where one packet's test costs no
            // more than `C_trav` (`P(n) = 1 ≤ C_trav`) the sweep would find no split cheaper than
            // the leaf: decided without it (about half of all `split` calls, the leaves of up to
            // four triangles). The area guard keeps the case where the term could be NaN
            // (an infinite or zero parent area) with the sweep, as before.
            if n <= params.max_leaf
                && packets(n) <= params.traversal_cost
                && parent_half_area.is_finite()
                && parent_half_area > 0.0
            {
                return None;
            }
            let (mid, cost) = sweep_split(slice, parent_half_area, params)?;
            if n <= params.max_leaf && cost >= packets(n) {
                return None;
            }
            let (l, rt) = (extent_seq(&slice[..mid]), extent_seq(&slice[mid..]));
            return Some((half(r.start, mid, l), half(r.start + mid, n - mid, rt)));
        }
        let nb = n.clamp(4, BINS);
        let scale = Vec3::select(c_extent.cmpgt(Vec3::ZERO), Vec3::splat(nb as f32) / c_extent, Vec3::ZERO);
        let binner = Binner { origin: r.ext.centroids.min, scale, bins: nb };
        let mut bins = [[BinA::EMPTY; BINS]; 3];
        bin_all(slice, &binner, &mut bins);
        #[cfg(target_arch = "x86_64")]
        let best = best_split_simd(&bins, nb, n, parent_half_area, c_extent, params);
        #[cfg(not(target_arch = "x86_64"))]
        let best = best_split(&bins, nb, parent_half_area, c_extent, params);
        if let Some(s) = best {
            if n <= params.max_leaf && s.cost >= packets(n) {
                return None;
            }
            let (mid, lc, rc) = partition(slice, &binner, s.axis, s.bin);
            if mid > 0 && mid < n {
                let fold = |bins: &[BinA], centroids: Aabb| {
                    let b = bins.iter().fold(BinA::EMPTY, |a, b| a.merge(b));
                    Bin { bounds: Aabb { min: b.min.into(), max: b.max.into() }, centroids, count: b.count }
                };
                let (l, rt) = (fold(&bins[s.axis][..s.bin], lc), fold(&bins[s.axis][s.bin..nb], rc));
                debug_assert_eq!((l.count as usize, rt.count as usize), (mid, n - mid));
                return Some((half(r.start, mid, l), half(r.start + mid, n - mid, rt)));
            }
        }
    }
    // No SAH split: all centroids coincide, the SAH depth is exhausted, or the bounds overflowed to
    // infinity. Small sets become a leaf; larger ones are halved at the object median of the widest
    // centroid axis so that leaves stay small.
    if n <= params.max_leaf {
        return None;
    }
    let axis = if c_extent.x >= c_extent.y && c_extent.x >= c_extent.z {
        0
    } else if c_extent.y >= c_extent.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    slice.select_nth_unstable_by(mid, |a, b| a.centroid()[axis].total_cmp(&b.centroid()[axis]));
    let (l, rt) = (extent(&slice[..mid]), extent(&slice[mid..]));
    Some((half(r.start, mid, l), half(r.start + mid, n - mid, rt)))
}

/// Builds the hierarchy over `prims` (reordered in place into leaf order) and returns its nodes,
/// the root first; empty for no primitives. `prims.len()` must be below 2^31 so that indices fit
/// in `u32` (2^31 triangles would need well over 100 GB).
pub(super) fn build(prims: &mut [BuildPrim], params: &BuildParams) -> Vec<Node> {
    let n = prims.len();
    if n == 0 {
        return Vec::new();
    }
    assert!(n < (1 << 31), "{n} triangles exceed the BVH's 2^31 limit");
    let params = BuildParams { max_leaf: params.max_leaf.max(1), ..*params };
    let root = Range { start: 0, len: n, ext: extent(prims), depth: 0, leaf: false };
    let mut nodes = Vec::new();
    build_node(prims, 0, vec![root], &mut nodes, &params);
    nodes.shrink_to_fit();
    nodes
}

/// `split` of each of `ranges` (disjoint ranges of `prims`, in order), in parallel on rayon.
fn split_all(prims: &mut [BuildPrim], ranges: &[Range], params: &BuildParams) -> Vec<Option<(Range, Range)>> {
    let mut slices = Vec::with_capacity(ranges.len());
    let mut rest = prims;
    let mut offset = 0;
    for r in ranges {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(r.start + r.len - offset);
        slices.push(&mut head[r.start - offset..]);
        rest = tail;
        offset = r.start + r.len;
    }
    ranges
        .par_iter()
        .zip(slices)
        .map(|(r, slice)| {
            let (mut l, mut rt) = split(slice, &Range { start: 0, ..*r }, params)?;
            l.start += r.start;
            rt.start += r.start;
            Some((l, rt))
        })
        .collect()
}

/// Appends the subtree over `prims` (which start at `base` in the whole array) to `out`, its
/// root first; `children` are its first children (one range, or the two halves of a split the
/// parent already made). Returns the root's index in `out`.
fn build_node(
    prims: &mut [BuildPrim],
    base: usize,
    mut children: Vec<Range>,
    out: &mut Vec<Node>,
    params: &BuildParams,
) -> u32 {
    if prims.len() > params.parallel_split_prims {
        // A large node: its partitions are sequential, so they are made in rounds, the open
        // children of a round split in parallel (all of them, or the largest if they would make
        // more than `WIDTH`). On 2 cores this halves the time of the top levels, where the
        // subtrees are not yet parallel.
        loop {
            let room = WIDTH - children.len();
            let mut open: Vec<usize> =
                (0..children.len()).filter(|&i| !children[i].leaf && children[i].len > 1).collect();
            if room == 0 || open.is_empty() {
                break;
            }
            let area = |i: usize| children[i].ext.bounds.surface_area();
            open.sort_by(|&a, &b| area(b).total_cmp(&area(a)));
            open.truncate(room);
            open.sort_unstable();
            let ranges: Vec<Range> = open.iter().map(|&i| children[i]).collect();
            // In reverse, so that an insertion does not move the children still to update.
            for (&i, halves) in open.iter().zip(split_all(prims, &ranges, params)).rev() {
                match halves {
                    None => children[i].leaf = true,
                    Some((l, r)) => {
                        children[i] = l;
                        children.insert(i + 1, r);
                    }
                }
            }
        }
    } else {
        // Split the largest open child until there are `WIDTH` (Embree's wide-BVH builders do
        // the same).
        while children.len() < WIDTH {
            let open = children
                .iter()
                .enumerate()
                .filter(|(_, c)| !c.leaf && c.len > 1)
                .max_by(|a, b| a.1.ext.bounds.surface_area().total_cmp(&b.1.ext.bounds.surface_area()));
            let Some((i, _)) = open else { break };
            match split(prims, &children[i], params) {
                None => children[i].leaf = true,
                Some((l, r)) => {
                    children[i] = l;
                    children.insert(i + 1, r);
                }
            }
        }
    }
    // Decide what the undecided children are: a leaf, or a node whose first split is made here
    // (in parallel for a large node).
    let undecided: Vec<Range> = children.iter().filter(|c| !c.leaf).copied().collect();
    let mut firsts = if prims.len() > params.parallel_split_prims {
        split_all(prims, &undecided, params)
    } else {
        undecided.iter().map(|c| split(prims, c, params)).collect()
    }
    .into_iter();
    let mut sub: Vec<Option<Vec<Range>>> = Vec::with_capacity(children.len());
    for c in &mut children {
        let first = if c.leaf { None } else { firsts.next().flatten() };
        c.leaf = first.is_none();
        sub.push(first.map(|(l, r)| vec![l, r]));
    }
    let me = out.len();
    out.push(Node::UNUSED);
    let mut slots = [(0u32, 0u32); WIDTH];
    if prims.len() > PARALLEL_PRIMS {
        // Disjoint slices, one per child, for the parallel subtrees.
        let mut rest = &mut *prims;
        let mut offset = 0;
        let mut work = Vec::new();
        for (k, (c, first)) in children.iter().zip(sub).enumerate() {
            let (slice, tail) = std::mem::take(&mut rest).split_at_mut(c.start + c.len - offset);
            rest = tail;
            let slice = &mut slice[c.start - offset..];
            offset = c.start + c.len;
            match first {
                None => slots[k] = ((base + c.start) as u32, c.len as u32),
                Some(mut first) => {
                    for f in &mut first {
                        f.start -= c.start;
                    }
                    work.push((k, slice, base + c.start, first));
                }
            }
        }
        let subtrees: Vec<(usize, Vec<Node>)> = work
            .into_par_iter()
            .map(|(k, slice, b, first)| {
                let mut nodes = Vec::new();
                build_node(slice, b, first, &mut nodes, params);
                (k, nodes)
            })
            .collect();
        // One allocation of the exact size: growing by doubling while the subtrees are alive
        // would hold up to three times the nodes at once.
        out.reserve_exact(subtrees.iter().map(|(_, nodes)| nodes.len()).sum());
        for (k, nodes) in subtrees {
            let at = out.len() as u32;
            out.extend(nodes.into_iter().map(|mut n| {
                for (child, count) in n.child.iter_mut().zip(n.count) {
                    if count == 0 {
                        *child += at;
                    }
                }
                n
            }));
            slots[k] = (at, 0);
        }
    } else {
        for (k, (c, first)) in children.iter().zip(sub).enumerate() {
            slots[k] = match first {
                None => ((base + c.start) as u32, c.len as u32),
                Some(first) => (build_node(prims, base, first, out, params), 0),
            };
        }
    }
    for (k, (c, (child, count))) in children.iter().zip(slots).enumerate() {
        out[me].set(k, &c.ext.bounds, child, count);
    }
    me as u32
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
