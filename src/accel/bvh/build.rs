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
//! scenes of ten million triangles (`scripts/large-scene.sh`).

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::geometry::Aabb;

mod binned;
use binned::*;

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
/// half the dependent node loads (measured against a 4-wide tree: docs/lab/performance.md).
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
    /// Chosen by measurement on the `plexus bench` scene (docs/lab/performance.md).
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
/// once and at most the misplaced ones are written (runs already in place are not reversed by
/// swaps). The bounds grow in SIMD vectors over the sums `min + max` and are halved at
/// the end: halving is monotonic, so the halved extremes are the extremes of the halved sums, the
/// centroids, exactly (a NaN sum leaves a bound as it was, as `Aabb::grow`).
/// (Lomuto's branch-free scheme with an unconditional swap measured 4% slower on the whole
/// build: docs/lab/performance.md.)
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
