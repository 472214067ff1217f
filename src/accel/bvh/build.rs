//! Binned-SAH construction (Wald 2007, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies"): split candidates are the boundaries of `BINS` equal-width bins over the centroid
//! bounds on each axis, costed with the surface-area heuristic; subtrees are built in parallel with
//! rayon and the result is flattened in depth-first order.
//!
//! Nodes are written straight into their final array: a subtree over `n` primitives has at most
//! `2n − 1` nodes, so each recursive call owns a disjoint slice of that size (left child right
//! after its parent, right child after the left child's slice), and parallel subtrees write without
//! synchronisation. Slots left unused by leaves holding several primitives are squeezed out by one
//! depth-first pass at the end, which keeps the order (left child at `parent + 1`).

use glam::Vec3;
use rayon::prelude::*;

use crate::geometry::Aabb;

/// A primitive during the build: its bounds and where it comes from. 32 bytes.
#[derive(Clone, Copy, Debug)]
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

/// A flattened node: 32 bytes, aligned so that one node never straddles two cache lines.
/// Interior nodes (`count == 0`) have their first child at the next index and their second child
/// at `offset`; `axis` is the split axis, which picks the visiting order. Leaves hold `count`
/// triangles starting at `offset` in the leaf-ordered triangle arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub(super) struct Node {
    pub min: Vec3,
    pub offset: u32,
    pub max: Vec3,
    pub count: u16,
    pub axis: u16,
}

/// Tuning of the build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildParams {
    /// Leaves hold at most this many triangles (≤ 255).
    pub max_leaf: usize,
    /// SAH cost of visiting an interior node, relative to one ray–triangle test.
    pub traversal_cost: f32,
}

impl Default for BuildParams {
    /// Measured on the benchmark scene (docs/bench.md): see `Bvh`'s documentation.
    fn default() -> Self {
        BuildParams { max_leaf: 8, traversal_cost: 1.0 }
    }
}

/// Number of SAH bins per axis.
const BINS: usize = 16;
/// Subtrees (and bounds/binning passes) over more primitives than this run in parallel; below it
/// rayon's task overhead outweighs the work.
const PARALLEL_PRIMS: usize = 4096;
/// Chunk size of the parallel binning and bounds passes.
const CHUNK: usize = 16 * 1024;
/// Below this depth the SAH decides; deeper, splits are forced to the object median so that the
/// depth stays below `MAX_DEPTH` (a median split halves the count: ≤ 32 more levels for < 2^32
/// primitives), which bounds the traversal stack.
const SAH_DEPTH: usize = 64;
/// Bound on the tree depth (root at depth 0), hence on the traversal stack.
pub(super) const MAX_DEPTH: usize = SAH_DEPTH + 33;

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

impl Default for Bin {
    fn default() -> Self {
        Bin { bounds: Aabb::EMPTY, count: 0 }
    }
}

/// Bounds of the primitives and of their centroids.
#[derive(Clone, Copy)]
struct Extent {
    bounds: Aabb,
    centroids: Aabb,
}

impl Extent {
    const EMPTY: Extent = Extent { bounds: Aabb::EMPTY, centroids: Aabb::EMPTY };
    fn merge(self, o: Extent) -> Extent {
        Extent { bounds: self.bounds.union(&o.bounds), centroids: self.centroids.union(&o.centroids) }
    }
}

fn extent_seq(prims: &[BuildPrim]) -> Extent {
    let mut e = Extent::EMPTY;
    for p in prims {
        e.bounds.min = e.bounds.min.min(p.min);
        e.bounds.max = e.bounds.max.max(p.max);
        e.centroids.grow(p.centroid());
    }
    e
}

fn extent(prims: &[BuildPrim]) -> Extent {
    if prims.len() > PARALLEL_PRIMS * 4 {
        prims.par_chunks(CHUNK).map(extent_seq).reduce(|| Extent::EMPTY, Extent::merge)
    } else {
        extent_seq(prims)
    }
}

/// Maps a centroid coordinate to its bin on one axis.
#[derive(Clone, Copy)]
struct Binner {
    origin: Vec3,
    /// `BINS / extent` per axis (0 on axes without extent, which are not split).
    scale: Vec3,
}

impl Binner {
    #[inline]
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        let x = (c[axis] - self.origin[axis]) * self.scale[axis];
        // `as` saturates (and maps NaN to 0); the `min` catches x == BINS from rounding.
        (x as usize).min(BINS - 1)
    }
}

type Bins = [[Bin; BINS]; 3];

fn bin_seq(prims: &[BuildPrim], binner: &Binner) -> Bins {
    let mut bins = [[Bin::default(); BINS]; 3];
    for p in prims {
        let c = p.centroid();
        for (axis, axis_bins) in bins.iter_mut().enumerate() {
            let b = &mut axis_bins[binner.bin(c, axis)];
            b.count += 1;
            b.bounds.min = b.bounds.min.min(p.min);
            b.bounds.max = b.bounds.max.max(p.max);
        }
    }
    bins
}

fn merge_bins(mut a: Bins, b: Bins) -> Bins {
    for (aa, ba) in a.iter_mut().zip(b.iter()) {
        for (x, y) in aa.iter_mut().zip(ba.iter()) {
            x.count += y.count;
            x.bounds = x.bounds.union(&y.bounds);
        }
    }
    a
}

fn bin_all(prims: &[BuildPrim], binner: &Binner) -> Bins {
    if prims.len() > PARALLEL_PRIMS * 4 {
        prims.par_chunks(CHUNK).map(|c| bin_seq(c, binner)).reduce(|| [[Bin::default(); BINS]; 3], merge_bins)
    } else {
        bin_seq(prims, binner)
    }
}

/// The best split found: axis, first bin of the right side, and its SAH cost.
struct Split {
    axis: usize,
    bin: usize,
    cost: f32,
}

/// Sweeps the bins of every axis and returns the split with the least SAH cost
/// `C_trav + (A_L N_L + A_R N_R) / A` in units of one triangle test (the leaf alternative costs `N`).
fn best_split(bins: &Bins, parent_area: f32, centroid_extent: Vec3, params: &BuildParams) -> Option<Split> {
    let mut best: Option<Split> = None;
    for (axis, axis_bins) in bins.iter().enumerate() {
        if centroid_extent[axis].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        // right_cost[i] = A_R · N_R for the right side made of bins i..BINS.
        let mut right_cost = [0.0f32; BINS];
        let mut right_count = [0u32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut count = 0u32;
        for i in (1..BINS).rev() {
            acc = acc.union(&axis_bins[i].bounds);
            count += axis_bins[i].count;
            right_count[i] = count;
            right_cost[i] = acc.surface_area() * count as f32;
        }
        let mut acc = Aabb::EMPTY;
        let mut left_count = 0u32;
        for i in 1..BINS {
            acc = acc.union(&axis_bins[i - 1].bounds);
            left_count += axis_bins[i - 1].count;
            if left_count == 0 || right_count[i] == 0 {
                continue;
            }
            let cost = params.traversal_cost + (acc.surface_area() * left_count as f32 + right_cost[i]) / parent_area;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split { axis, bin: i, cost });
            }
        }
    }
    best
}

/// Reorders `prims` so that those for which `left` holds come first; returns how many they are.
fn partition(prims: &mut [BuildPrim], left: impl Fn(&BuildPrim) -> bool) -> usize {
    let mut i = 0;
    let mut j = prims.len();
    while i < j {
        if left(&prims[i]) {
            i += 1;
        } else {
            j -= 1;
            prims.swap(i, j);
        }
    }
    i
}

/// Builds the hierarchy over `prims` (reordered in place into leaf order) and returns the
/// flattened nodes; empty for no primitives. `prims.len()` must be below 2^31 so that node
/// indices fit in `u32` (2^31 triangles would need well over 100 GB).
pub(super) fn build(prims: &mut [BuildPrim], params: &BuildParams) -> Vec<Node> {
    let n = prims.len();
    if n == 0 {
        return Vec::new();
    }
    assert!(n < (1 << 31), "{n} triangles exceed the BVH's 2^31 limit");
    let mut nodes = vec![Node::default(); 2 * n - 1];
    let params = BuildParams { max_leaf: params.max_leaf.clamp(1, 255), ..*params };
    build_rec(prims, &mut nodes, 0, 0, 0, &params);
    compact(&nodes)
}

fn build_rec(
    prims: &mut [BuildPrim],
    nodes: &mut [Node],
    node_base: usize,
    prim_base: usize,
    depth: usize,
    params: &BuildParams,
) {
    let n = prims.len();
    debug_assert_eq!(nodes.len(), 2 * n - 1);
    let Extent { bounds, centroids } = extent(prims);
    let leaf = Node { min: bounds.min, offset: prim_base as u32, max: bounds.max, count: n as u16, axis: 0 };
    if n == 1 {
        nodes[0] = leaf;
        return;
    }
    let c_extent = centroids.extent();
    let axis_of_largest = if c_extent.x >= c_extent.y && c_extent.x >= c_extent.z {
        0
    } else if c_extent.y >= c_extent.z {
        1
    } else {
        2
    };

    let mut split_at = None;
    if depth < SAH_DEPTH && c_extent.max_element() > 0.0 {
        let scale = Vec3::select(c_extent.cmpgt(Vec3::ZERO), Vec3::splat(BINS as f32) / c_extent, Vec3::ZERO);
        let binner = Binner { origin: centroids.min, scale };
        let bins = bin_all(prims, &binner);
        if let Some(split) = best_split(&bins, bounds.surface_area(), c_extent, params) {
            if n <= params.max_leaf && split.cost >= n as f32 {
                nodes[0] = leaf;
                return;
            }
            let mid = partition(prims, |p| binner.bin(p.centroid(), split.axis) < split.bin);
            split_at = Some((mid, split.axis));
        }
    }
    let (mid, axis) = match split_at {
        Some((mid, axis)) if mid > 0 && mid < n => (mid, axis),
        _ => {
            // No SAH split: all centroids coincide, the SAH depth is exhausted, or the bounds
            // overflowed to infinity. Small sets become a leaf; larger ones are halved at the
            // object median of the widest centroid axis so that leaves stay small.
            if n <= params.max_leaf {
                nodes[0] = leaf;
                return;
            }
            let mid = n / 2;
            prims.select_nth_unstable_by(mid, |a, b| {
                a.centroid()[axis_of_largest].total_cmp(&b.centroid()[axis_of_largest])
            });
            (mid, axis_of_largest)
        }
    };

    let right_index = node_base + 2 * mid;
    nodes[0] = Node { min: bounds.min, offset: right_index as u32, max: bounds.max, count: 0, axis: axis as u16 };
    let (left_nodes, right_nodes) = nodes[1..].split_at_mut(2 * mid - 1);
    let (left_prims, right_prims) = prims.split_at_mut(mid);
    let left = |lp: &mut [BuildPrim], ln: &mut [Node]| build_rec(lp, ln, node_base + 1, prim_base, depth + 1, params);
    let right =
        |rp: &mut [BuildPrim], rn: &mut [Node]| build_rec(rp, rn, right_index, prim_base + mid, depth + 1, params);
    if n > PARALLEL_PRIMS {
        rayon::join(|| left(left_prims, left_nodes), || right(right_prims, right_nodes));
    } else {
        left(left_prims, left_nodes);
        right(right_prims, right_nodes);
    }
}

/// Squeezes out the unused slots, keeping depth-first order, and renumbers second children.
fn compact(nodes: &[Node]) -> Vec<Node> {
    let mut out: Vec<Node> = Vec::with_capacity(nodes.len());
    // (index in `nodes`, index in `out` of the parent whose second child this is)
    let mut stack: Vec<(usize, Option<usize>)> = vec![(0, None)];
    while let Some((old, parent)) = stack.pop() {
        let new = out.len();
        if let Some(p) = parent {
            out[p].offset = new as u32;
        }
        let node = nodes[old];
        out.push(node);
        if node.count == 0 {
            stack.push((node.offset as usize, Some(new)));
            stack.push((old + 1, None));
        }
    }
    out.shrink_to_fit();
    out
}
