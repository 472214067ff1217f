//! The in-house BVH: an 8-wide hierarchy built directly by binned SAH (see `build`), whose nodes
//! hold their eight children's boxes in SIMD-friendly rows so that one node visit tests all eight
//! (`triangle::slab8`, one AVX pass where the CPU has AVX2, chosen at run time), an ordered stack traversal (nearest child first, entries farther than the current
//! hit skipped when popped), and leaves of packets of four triangles tested at once by the
//! watertight ray–triangle test of Woop et al. 2013 (see `triangle`; a leaf of two packets in one
//! AVX pass where the CPU has AVX2, `triangle::intersect8_k_avx`). Answers the same queries as
//! Embree behind [`Accel`], with the same hit convention.

mod build;
mod triangle;

use std::mem::MaybeUninit;
use std::sync::Arc;

use glam::Vec3;
use rayon::prelude::*;

pub use build::BuildParams;
use build::{BuildPrim, Node, EMPTY, MAX_DEPTH, PACKET, WIDTH};
use triangle::{intersect4_k, Tri4};
pub use triangle::{intersect_triangle, RayPre};

use super::{Accel, AccelKind};
use crate::geometry::{Hit, Ray, TriangleMesh};
use crate::prefetch::prefetch_line;
use crate::process::huge_pages::HugeArray;

/// A bounding volume hierarchy over a list of shared meshes.
///
/// A leaf of `n` triangles references `ceil(n / 4)` consecutive packets of four (`Tri4`), its
/// last packet's unused lanes masked off. The vertices of each triangle are copied there (36 bytes
/// per triangle plus 8 for its ids) rather than read through the mesh's index and position arrays,
/// which saves two dependent loads (index, then three positions) per triangle and lets one SIMD
/// test take four triangles; `tree_invariants_hold` checks the copies equal the meshes' triangles.
///
/// The three arrays that rays read are `HugeArray`s: on transparent huge pages when each holds at
/// most `HUGE_PAGE_ARRAY_BYTES` (64 MB; the bench scene's are 18, 44 and 10 MB), since bounce rays
/// read them at random places and with 4 KiB pages most such reads also miss the TLB (Embree asks
/// for huge pages for its tree too). Larger arrays (10M-triangle scenes) stay on 4 KiB pages.
pub struct Bvh {
    meshes: Vec<Arc<TriangleMesh>>,
    nodes: HugeArray<Node>,
    /// Triangle vertices in packets of four, in leaf order.
    packets: HugeArray<Tri4>,
    /// `(geom_id, prim_id)` of each packet lane (`4 * packet + lane`); `[u32::MAX; 2]` in unused
    /// lanes.
    ids: HugeArray<[u32; 2]>,
    /// Triangles in the hierarchy.
    triangle_count: usize,
    /// The most bytes the build held at once (see `build_with`).
    build_peak: usize,
    /// Whether queries run the AVX2 code (`closest_avx2`, `any_avx2`): set where the CPU has AVX2
    /// and FMA (`is_x86_feature_detected!`; the build targets baseline x86-64), which is what makes
    /// calling those functions sound. The tests also clear it to check the baseline code.
    avx2: bool,
}

/// Enough for any traversal: a node visit pushes at most `WIDTH - 1` entries and descends one
/// level, and the tree is at most `MAX_DEPTH` levels deep.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + WIDTH;

/// A traversal stack entry: a node slot's `child | count << 32` (count 0 for an interior node).
type Entry = u64;

impl Bvh {
    /// Builds over `meshes` (kept, not copied) with the default parameters; `Hit::geom_id` is the
    /// index in `meshes`. Triangles with exactly zero area are left out: they can never be hit.
    pub fn build(meshes: &[Arc<TriangleMesh>]) -> Bvh {
        Bvh::build_with(meshes, &BuildParams::default())
    }

    /// As [`Bvh::build`], with explicit build parameters. Runs on the current rayon pool.
    pub fn build_with(meshes: &[Arc<TriangleMesh>], params: &BuildParams) -> Bvh {
        // Allocated once at its final size (an unindexed parallel collect would hold the
        // primitives twice while it concatenates); zero-area triangles are then dropped in place.
        let total: usize = meshes.iter().map(|m| m.triangle_count()).sum();
        let mut prims: Vec<BuildPrim> = Vec::with_capacity(total);
        for (geom, mesh) in meshes.iter().enumerate() {
            prims.par_extend((0..mesh.triangle_count() as u32).into_par_iter().map(|prim| {
                let [a, b, c] = mesh.triangle(prim);
                let (min, max) = if crate::geometry::triangle_is_degenerate(a, b, c) {
                    (Vec3::NAN, Vec3::NAN)
                } else {
                    (a.min(b).min(c), a.max(b).max(c))
                };
                BuildPrim { min, geom: geom as u32, max, prim }
            }));
        }
        prims.retain(|p| !p.min.x.is_nan());
        let mut nodes = build::build(&mut prims, params);
        let ids = packet_ids(&mut nodes, &prims);
        // The build's primitives (32 bytes each) are freed before the triangles (36) are copied,
        // so that the two never coexist: on 10M triangles that is 320 MB less at the peak.
        // The peak is while the primitives are alive: beside the nodes twice over (the subtrees
        // and the final array, at the build's last append) or beside the nodes and the ids; or
        // else the finished structure, whichever is most.
        let node_bytes = nodes.capacity() * std::mem::size_of::<Node>();
        let id_bytes = ids.capacity() * std::mem::size_of::<[u32; 2]>();
        let held = prims.capacity() * std::mem::size_of::<BuildPrim>() + node_bytes + node_bytes.max(id_bytes);
        let triangle_count = prims.len();
        drop(prims);
        // Moved to huge pages where their size calls for it (a copy of at most 64 MB each, while
        // the primitives are gone); the packets are written there directly.
        let (nodes, ids) = (HugeArray::from_vec(nodes), HugeArray::from_vec(ids));
        let packets = HugeArray::from_par_iter(ids.par_chunks(PACKET).map(|lanes| {
            let mut packet = Tri4::EMPTY;
            for (lane, &[g, p]) in lanes.iter().enumerate().filter(|(_, id)| id[0] != u32::MAX) {
                packet.set(lane, meshes[g as usize].triangle(p));
            }
            packet
        }));
        let mut bvh =
            Bvh { meshes: meshes.to_vec(), nodes, packets, ids, triangle_count, build_peak: 0, avx2: has_avx2() };
        bvh.build_peak = held.max(bvh.memory_bytes());
        bvh
    }

    /// The meshes, indexed by geometry id.
    pub fn meshes(&self) -> &[Arc<TriangleMesh>] {
        &self.meshes
    }

    /// Number of (8-wide) nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of triangles in the hierarchy (zero-area triangles are left out).
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Walks the slots whose box the ray overlaps and calls `leaf` on each leaf's first packet and
    /// triangle count with the current `t_max`; `leaf` returns the new `t_max` and whether to stop.
    /// With `NEAREST_FIRST` (closest-hit queries) the slots a node visit finds are visited nearest
    /// first, and popped entries whose box starts beyond the (scaled) current `t_max` are skipped:
    /// they cannot hold a nearer hit. Without it (occlusion, which stops at the first hit and never
    /// lowers `t_max`) they are visited in slot order, which spares the sort.
    /// With `AVX2` the node test is `triangle::slab8_ray_avx`: only instantiated inside the
    /// `#[target_feature(enable = "avx2,fma")]` functions `closest_avx2` and `any_avx2`.
    #[inline(always)]
    fn traverse<const NEAREST_FIRST: bool, const AVX2: bool>(
        &self,
        ray: &Ray,
        pre: &RayPre,
        mut leaf: impl FnMut(usize, usize, f32) -> (f32, bool),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let t_min = ray.t_min;
        let mut t_max = ray.t_max;
        let scale = triangle::far_scale();
        // Popped entries farther than this are skipped (`t_max` scaled as the slab test's far
        // distances are); recomputed only when `t_max` changes.
        let mut t_far = t_max * scale;
        // The slab test's per-ray constants, once per ray rather than at each node.
        #[cfg(target_arch = "x86_64")]
        let slab_ray = triangle::SlabRay::new(pre, t_min);
        // Not initialised: a memset of its 4.7 kB per ray would cost more than a short ray's
        // traversal. Only entries below `sp` are read, and each was written before.
        let mut stack = [MaybeUninit::<(Entry, f32)>::uninit(); STACK];
        let stack = stack.as_mut_ptr();
        let mut sp = 0;
        let mut cur: Entry = 0;
        'visit: loop {
            let (child, count) = (cur as u32 as usize, (cur >> 32) as u32);
            if count == 0 {
                debug_assert!(child < self.nodes.len());
                // SAFETY: `child` is 0 (the tree is not empty) or an interior slot's child index,
                // which the builder writes only below `nodes.len()` (`tree_invariants_hold`).
                let node = unsafe { self.nodes.get_unchecked(child) };
                // The used slots whose box the ray overlaps, and every slot's entry distance.
                // Unused slots have empty boxes, which no ray overlaps; masked all the same, since
                // following one would read past the arrays.
                #[cfg(target_arch = "x86_64")]
                let (mut mask, near) = if AVX2 {
                    let mut near = [0f32; WIDTH];
                    // SAFETY: `AVX2` traversals run only inside `closest_avx2` and `any_avx2`, which
                    // are called only when `self.avx2`, i.e. the CPU has AVX2 and FMA.
                    let mask =
                        unsafe { triangle::slab8_ray_avx(&slab_ray, &node.bounds, &node.count, t_max, &mut near) };
                    (mask, near)
                } else {
                    let (mask, near) = triangle::slab8(pre, &node.bounds, t_min, t_max);
                    (mask & used_slots(node), near)
                };
                #[cfg(not(target_arch = "x86_64"))]
                let (mut mask, near) = {
                    let (mask, near) = triangle::slab8(pre, &node.bounds, t_min, t_max);
                    (mask & used_slots(node), near)
                };
                let entry = |slot: usize| (node.child[slot] as Entry | (node.count[slot] as Entry) << 32, near[slot]);
                if mask != 0 {
                    let first = entry(mask.trailing_zeros() as usize);
                    mask &= mask - 1;
                    if mask == 0 {
                        // One child overlapped (the most frequent case): no stack traffic.
                        cur = first.0;
                        continue 'visit;
                    }
                    debug_assert!(sp + WIDTH <= STACK);
                    // SAFETY (the stack writes and reads below): a visit of a node at depth `d`
                    // finds at most `(WIDTH - 1) * d` entries on the stack (each ancestor's visit
                    // left at most `WIDTH - 1`), and pushes at most `WIDTH` before it pops one; the
                    // builder keeps `d < MAX_DEPTH`, so `sp + WIDTH <= STACK` here.
                    if !NEAREST_FIRST {
                        // Slot order: the first slot is visited now, the rest pushed.
                        while mask != 0 {
                            unsafe { stack.add(sp).write(MaybeUninit::new(entry(mask.trailing_zeros() as usize))) };
                            sp += 1;
                            mask &= mask - 1;
                        }
                        cur = first.0;
                        continue 'visit;
                    }
                    // Nearest first: the entries are insertion-sorted straight onto the stack,
                    // farthest at the bottom, so that the nearest is on top; equal distances
                    // keep slot order (the earlier slot above). An entry moves up past those
                    // that are to be visited before it.
                    let base = sp;
                    self.prefetch_entry(first.0);
                    unsafe { stack.add(sp).write(MaybeUninit::new(first)) };
                    sp += 1;
                    while mask != 0 {
                        let e = entry(mask.trailing_zeros() as usize);
                        mask &= mask - 1;
                        self.prefetch_entry(e.0);
                        let mut j = sp;
                        unsafe {
                            while j > base {
                                let above = (*stack.add(j - 1)).assume_init();
                                if above.1 > e.1 {
                                    break;
                                }
                                stack.add(j).write(MaybeUninit::new(above));
                                j -= 1;
                            }
                            stack.add(j).write(MaybeUninit::new(e));
                        }
                        sp += 1;
                    }
                    sp -= 1;
                    cur = unsafe { (*stack.add(sp)).assume_init().0 };
                    continue 'visit;
                }
            } else {
                let (t, stop) = leaf(child, count as usize, t_max);
                if stop {
                    return;
                }
                t_max = t;
                t_far = t_max * scale;
            }
            while sp > 0 {
                sp -= 1;
                // SAFETY: every entry below `sp` was written by a push.
                let (e, near) = unsafe { (*stack.add(sp)).assume_init() };
                if !NEAREST_FIRST || near <= t_far {
                    cur = e;
                    continue 'visit;
                }
            }
            return;
        }
    }
}

impl Bvh {
    /// Asks the cache for what visiting `e` reads first, when a node visit finds two or more
    /// children overlapped: the child node's four cache lines, or the three lines that hold a
    /// leaf's first packet. Bounce rays go to random places in the tree, so most of these are
    /// misses; the loads start while the nearer children are visited. A prefetch never faults,
    /// so the addresses are computed without bounds checks (`wrapping_add`).
    #[inline(always)]
    fn prefetch_entry(&self, e: Entry) {
        let (child, count) = (e as u32 as usize, (e >> 32) as u32);
        let (p, lines) = if count == 0 {
            (self.nodes.as_ptr().wrapping_add(child).cast::<u8>(), 4)
        } else {
            (self.packets.as_ptr().wrapping_add(child).cast::<u8>(), 3)
        };
        for line in 0..lines {
            prefetch_line(p.wrapping_add(64 * line));
        }
    }
}

/// The mask of a node's used slots (the baseline node test's; `triangle::slab8_ray_avx` masks
/// them itself).
#[inline(always)]
fn used_slots(node: &Node) -> u32 {
    (0..WIDTH).fold(0, |m, k| m | ((node.count[k] != EMPTY) as u32) << k)
}

/// Whether a ray's interval is usable (a NaN or reversed interval hits nothing).
#[inline]
fn valid_interval(ray: &Ray) -> bool {
    ray.t_min <= ray.t_max
}

impl Bvh {
    /// Closest hit for rays whose dominant axis is `KZ`.
    #[inline(always)]
    fn closest<const KZ: usize, const AVX2: bool>(&self, ray: &Ray, pre: &RayPre) -> Option<Hit> {
        let mut best: Option<(usize, f32, f32, f32)> = None;
        self.traverse::<true, AVX2>(ray, pre, |first, count, mut t_max| {
            #[cfg(target_arch = "x86_64")]
            if AVX2 && count > PACKET && count <= 2 * PACKET {
                // SAFETY: as below for both packets; `AVX2` traversals run only where the CPU has
                // AVX2 and FMA (see `traverse`).
                let hits = unsafe {
                    let (lo, hi) = (self.packets.get_unchecked(first), self.packets.get_unchecked(first + 1));
                    triangle::intersect8_k_avx::<KZ>(pre, lo, hi, lanes8(count), ray.t_min, t_max)
                };
                if let Some(lane) = hits.nearest() {
                    t_max = hits.t[lane];
                    best = Some((PACKET * first + lane, t_max, hits.b1[lane], hits.b2[lane]));
                    prefetch(&self.ids, PACKET * first + lane);
                }
                return (t_max, false);
            }
            for (k, packet) in (first..first + count.div_ceil(PACKET)).enumerate() {
                debug_assert!(packet < self.packets.len());
                // SAFETY: leaf packets lie within the packet array (checked by
                // `tree_invariants_hold`): `packet_ids` numbers them from the same leaves.
                let tri = unsafe { self.packets.get_unchecked(packet) };
                let hits = intersect4_k::<KZ>(pre, tri, lanes(count - k * PACKET), ray.t_min, t_max);
                if let Some(lane) = hits.nearest() {
                    t_max = hits.t[lane];
                    best = Some((PACKET * packet + lane, t_max, hits.b1[lane], hits.b2[lane]));
                    prefetch(&self.ids, PACKET * packet + lane);
                }
            }
            (t_max, false)
        });
        best.map(|(i, t, b1, b2)| {
            let [geom_id, prim_id] = self.ids[i];
            Hit { t, geom_id, prim_id, b1, b2 }
        })
    }

    /// Whether anything is hit, for rays whose dominant axis is `KZ`.
    #[inline(always)]
    fn any<const KZ: usize, const AVX2: bool>(&self, ray: &Ray, pre: &RayPre) -> bool {
        let mut hit = false;
        self.traverse::<false, AVX2>(ray, pre, |first, count, t_max| {
            #[cfg(target_arch = "x86_64")]
            if AVX2 && count > PACKET && count <= 2 * PACKET {
                // SAFETY: as in `closest`.
                hit = unsafe {
                    let (lo, hi) = (self.packets.get_unchecked(first), self.packets.get_unchecked(first + 1));
                    triangle::intersect8_k_avx::<KZ>(pre, lo, hi, lanes8(count), ray.t_min, t_max).mask != 0
                };
                return (t_max, hit);
            }
            hit = (first..first + count.div_ceil(PACKET)).enumerate().any(|(k, packet)| {
                debug_assert!(packet < self.packets.len());
                // SAFETY: as in `closest`.
                let tri = unsafe { self.packets.get_unchecked(packet) };
                intersect4_k::<KZ>(pre, tri, lanes(count - k * PACKET), ray.t_min, t_max).mask != 0
            });
            (t_max, hit)
        });
        hit
    }
}

/// Asks the cache for `v[i]` ahead of its use: the ids of the current nearest hit are read only
/// after the traversal, and waiting for them then cost about a tenth of a bounce ray's time
/// (`perf annotate`, the load of `ids` after the loop).
#[inline(always)]
fn prefetch<T>(v: &[T], i: usize) {
    if let Some(x) = v.get(i) {
        prefetch_line(x as *const T);
    }
}

/// The lane mask of a leaf's packet with `remaining` of the leaf's triangles at or after its first
/// lane.
#[inline(always)]
fn lanes(remaining: usize) -> u32 {
    (1u32 << remaining.min(PACKET)) - 1
}

/// The lane mask of a leaf of `count` (5 to 8) triangles over its two packets, as one 8-lane mask
/// (`triangle::intersect8_k_avx`).
#[inline(always)]
fn lanes8(count: usize) -> u32 {
    lanes(count) | lanes(count - PACKET) << PACKET
}

/// Lays the leaves out in packets: gives each leaf slot of `nodes` (written by the build as first
/// primitive and count) its first packet instead, numbering the packets in node order, and returns
/// the `(geom, prim)` ids of the packets' lanes, `[u32::MAX; 2]` in unused ones. Sequential: it is
/// a copy of 8 bytes per triangle, a few per cent of the build.
fn packet_ids(nodes: &mut [Node], prims: &[BuildPrim]) -> Vec<[u32; 2]> {
    let is_leaf = |count: u32| count != 0 && count != EMPTY;
    let total: usize =
        nodes.iter().flat_map(|n| n.count).filter(|&c| is_leaf(c)).map(|c| (c as usize).div_ceil(PACKET)).sum();
    let mut ids = Vec::with_capacity(total * PACKET);
    for node in nodes.iter_mut() {
        for k in 0..WIDTH {
            let (start, count) = (node.child[k] as usize, node.count[k]);
            if is_leaf(count) {
                node.child[k] = (ids.len() / PACKET) as u32;
                ids.extend(prims[start..start + count as usize].iter().map(|p| [p.geom, p.prim]));
                ids.resize(ids.len().next_multiple_of(PACKET), [u32::MAX; 2]);
            }
        }
    }
    debug_assert_eq!(ids.len(), total * PACKET);
    ids
}

impl Bvh {
    /// Closest hit, the traversal instantiated for the ray's dominant axis.
    #[inline(always)]
    fn closest_any_axis<const AVX2: bool>(&self, ray: &Ray, pre: &RayPre) -> Option<Hit> {
        match pre.kz {
            0 => self.closest::<0, AVX2>(ray, pre),
            1 => self.closest::<1, AVX2>(ray, pre),
            _ => self.closest::<2, AVX2>(ray, pre),
        }
    }

    /// Occlusion, the traversal instantiated for the ray's dominant axis.
    #[inline(always)]
    fn any_any_axis<const AVX2: bool>(&self, ray: &Ray, pre: &RayPre) -> bool {
        match pre.kz {
            0 => self.any::<0, AVX2>(ray, pre),
            1 => self.any::<1, AVX2>(ray, pre),
            _ => self.any::<2, AVX2>(ray, pre),
        }
    }

    /// The closest-hit query compiled for AVX2 and FMA: the node test in one AVX pass, and the
    /// rest (triangle packets, stack) in VEX-encoded SSE. No FMA is formed: Rust does not contract
    /// `a * b + c`, so every result is the baseline code's bit for bit (the tests compare both).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn closest_avx2(&self, ray: &Ray, pre: &RayPre) -> Option<Hit> {
        self.closest_any_axis::<true>(ray, pre)
    }

    /// The occlusion query compiled for AVX2 and FMA (see `closest_avx2`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn any_avx2(&self, ray: &Ray, pre: &RayPre) -> bool {
        self.any_any_axis::<true>(ray, pre)
    }
}

/// Whether this CPU runs the AVX2 queries (`Bvh::avx2`).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    return is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
    #[cfg(not(target_arch = "x86_64"))]
    return false;
}

impl Accel for Bvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !valid_interval(ray) {
            return None;
        }
        let pre = RayPre::new(ray)?;
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2 and FMA (`has_avx2`).
            return unsafe { self.closest_avx2(ray, &pre) };
        }
        self.closest_any_axis::<false>(ray, &pre)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        if !valid_interval(ray) {
            return false;
        }
        let Some(pre) = RayPre::new(ray) else {
            return false;
        };
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `intersect`.
            return unsafe { self.any_avx2(ray, &pre) };
        }
        self.any_any_axis::<false>(ray, &pre)
    }

    fn kind(&self) -> AccelKind {
        AccelKind::Bvh
    }

    fn memory_bytes(&self) -> usize {
        self.nodes.bytes()
            + self.packets.bytes()
            + self.ids.bytes()
            + self.meshes.capacity() * std::mem::size_of::<Arc<TriangleMesh>>()
    }

    fn peak_memory_bytes(&self) -> usize {
        self.build_peak
    }
}

#[cfg(test)]
mod tests;
