//! The BVH's tests: agreement with brute force, watertightness, the tree's invariants.

use super::*;
use crate::sampling::Rng;
use std::collections::HashMap;

fn mesh(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Arc<TriangleMesh> {
    Arc::new(TriangleMesh::new(positions, indices, None, None).unwrap())
}

/// An icosphere: the icosahedron subdivided `levels` times, vertices shared between triangles.
fn icosphere(levels: u32) -> Arc<TriangleMesh> {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                p.len() as u32 - 1
            })
        };
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut p);
            let bc = midpoint(b, c, &mut p);
            let ca = midpoint(c, a, &mut p);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    mesh(p, f)
}

/// The closed surface of the cube [0, m]³, each face an m×m grid of unit squares split into
/// two triangles, vertices on integer coordinates and shared along the cube's edges.
fn cube_grid(m: u32) -> Arc<TriangleMesh> {
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut p = Vec::new();
    let mut f = Vec::new();
    let mut vertex = |q: [u32; 3], p: &mut Vec<Vec3>| {
        *index.entry(q).or_insert_with(|| {
            p.push(Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32));
            p.len() as u32 - 1
        })
    };
    for axis in 0..3 {
        for side in [0, m] {
            for i in 0..m {
                for j in 0..m {
                    let at = |di: u32, dj: u32| {
                        let mut q = [0; 3];
                        q[axis] = side;
                        q[(axis + 1) % 3] = i + di;
                        q[(axis + 2) % 3] = j + dj;
                        q
                    };
                    let v00 = vertex(at(0, 0), &mut p);
                    let v10 = vertex(at(1, 0), &mut p);
                    let v11 = vertex(at(1, 1), &mut p);
                    let v01 = vertex(at(0, 1), &mut p);
                    // Alternate the diagonal so that both orientations are exercised.
                    if (i + j) % 2 == 0 {
                        f.extend([[v00, v10, v11], [v00, v11, v01]]);
                    } else {
                        f.extend([[v00, v10, v01], [v10, v11, v01]]);
                    }
                }
            }
        }
    }
    mesh(p, f)
}

fn brute_force(meshes: &[Arc<TriangleMesh>], ray: &Ray) -> Option<Hit> {
    let pre = RayPre::new(ray)?;
    let mut best: Option<Hit> = None;
    for (g, m) in meshes.iter().enumerate() {
        for prim in 0..m.triangle_count() as u32 {
            let [a, b, c] = m.triangle(prim);
            let t_max = best.map_or(ray.t_max, |h| h.t);
            if let Some((t, b1, b2)) = intersect_triangle(&pre, a, b, c, ray.t_min, t_max) {
                if best.is_none_or(|h| t < h.t) {
                    best = Some(Hit { t, geom_id: g as u32, prim_id: prim, b1, b2 });
                }
            }
        }
    }
    best
}

fn random_point(rng: &mut Rng, lo: f32, hi: f32) -> Vec3 {
    Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * (hi - lo) + Vec3::splat(lo)
}

#[test]
fn node_is_four_cache_lines() {
    assert_eq!(std::mem::size_of::<Node>(), 256);
    assert_eq!(std::mem::align_of::<Node>(), 64);
}

#[test]
fn icosphere_is_watertight_at_vertices_and_edges() {
    let sphere = icosphere(4);
    let mut bvh = Bvh::build(std::slice::from_ref(&sphere));
    let p = sphere.positions();
    let mut targets: Vec<Vec3> = p.to_vec();
    for [a, b, c] in sphere.indices() {
        for (x, y) in [(a, b), (b, c), (c, a)] {
            let (x, y) = (p[*x as usize], p[*y as usize]);
            targets.push((x + y) * 0.5);
            targets.push(x * 0.25 + y * 0.75);
        }
    }
    // From the centre and from off-centre interior points, every ray must leave through the
    // surface; from outside, every ray aimed at a surface point must hit.
    let origins = [Vec3::ZERO, Vec3::new(0.3, -0.2, 0.1), Vec3::new(-0.51, 0.37, -0.29)];
    let mut rays = 0;
    for (k, &target) in targets.iter().enumerate() {
        // Every other target through the baseline (SSE) code, the rest through AVX2.
        bvh.avx2 = k % 2 == 0 && has_avx2();
        for &o in &origins {
            let ray = Ray::new(o, target - o);
            assert!(bvh.intersect(&ray).is_some(), "slipped through from {o} towards {target}");
            assert!(bvh.occluded(&ray));
            rays += 1;
        }
        let outside = target * 3.0 + Vec3::new(0.1, 0.2, -0.05);
        let ray = Ray::new(outside, target - outside);
        assert!(bvh.intersect(&ray).is_some(), "slipped through from {outside} towards {target}");
        rays += 1;
    }
    assert!(rays > 30_000);
}

#[test]
fn cube_grid_is_watertight_for_axis_aligned_rays_through_vertices_and_edges() {
    // Axis-aligned rays through grid vertices and edges: the hardest case for the triangle
    // test (exact zeros of the edge functions) and for the slab test (origins on box planes
    // with zero direction components, i.e. 0·∞).
    let m = 8;
    let mut bvh = Bvh::build(&[cube_grid(m)]);
    let mf = m as f32;
    let mut rays = 0;
    for (axis, avx2) in (0..6).map(|k| (k % 3, k >= 3 && has_avx2())) {
        // Each axis through the baseline (SSE) code, then through the AVX2 code.
        bvh.avx2 = avx2;
        for i in 0..=2 * m {
            for j in 0..=2 * m {
                // Coordinates on the half-integer lattice: vertices, edge midpoints, centres.
                let (u, v) = (i as f32 * 0.5, j as f32 * 0.5);
                for (from, sign) in [(0.5 * mf, 1.0f32), (0.5 * mf, -1.0), (-1.0, 1.0), (mf + 1.0, -1.0)] {
                    let mut o = Vec3::ZERO;
                    o[axis] = from;
                    o[(axis + 1) % 3] = u;
                    o[(axis + 2) % 3] = v;
                    let mut d = Vec3::ZERO;
                    d[axis] = sign;
                    let ray = Ray::new(o, d);
                    let hit = bvh.intersect(&ray);
                    assert!(hit.is_some(), "slipped through: {ray:?}");
                    // From inside, the ray leaves through the face ahead; from outside (one
                    // unit away), it enters through the nearest face.
                    let expected = match (from < 0.0 || from > mf, sign > 0.0) {
                        (true, _) => 1.0,
                        (false, true) => mf - from,
                        (false, false) => from,
                    };
                    assert_eq!(hit.unwrap().t, expected, "{ray:?}");
                    assert!(bvh.occluded(&ray));
                    rays += 1;
                }
            }
        }
    }
    assert_eq!(rays, 2 * 3 * 17 * 17 * 4);
}

#[test]
fn agrees_with_brute_force_on_random_soups() {
    let mut rng = Rng::new(7, 0);
    for (soup, count) in [(0, 1), (1, 7), (2, 300), (3, 6000)] {
        let mut meshes = Vec::new();
        for _ in 0..3 {
            let mut p = Vec::new();
            let mut f = Vec::new();
            for k in 0..count {
                let c = random_point(&mut rng, -1.0, 1.0);
                let size = 0.02 + 0.3 * rng.uniform();
                for _ in 0..3 {
                    p.push(c + random_point(&mut rng, -size, size));
                }
                f.push([3 * k, 3 * k + 1, 3 * k + 2]);
            }
            meshes.push(mesh(p, f));
        }
        let mut bvh = Bvh::build(&meshes);
        let mut hits = 0;
        for r in 0..2000 {
            // Every other ray through the baseline (SSE) code, the rest through the AVX2
            // code where the CPU has it: both must agree with the brute force.
            bvh.avx2 = r % 2 == 0 && has_avx2();
            let o = random_point(&mut rng, -1.5, 1.5);
            let d = random_point(&mut rng, -1.0, 1.0) - o;
            let mut ray = Ray::new(o, d);
            if r % 3 == 1 {
                ray.t_min = 0.3 * rng.uniform();
                ray.t_max = ray.t_min + rng.uniform();
            }
            let expected = brute_force(&meshes, &ray);
            let got = bvh.intersect(&ray);
            assert_eq!(got, expected, "soup {soup}, ray {r}: {ray:?}");
            assert_eq!(bvh.occluded(&ray), expected.is_some(), "soup {soup}, ray {r}: {ray:?}");
            hits += expected.is_some() as u32;
        }
        if count >= 300 {
            assert!(hits > 500, "the test must exercise hits: {hits}");
        }
    }
}

#[test]
fn tree_invariants_hold() {
    let sphere = icosphere(5); // 20480 triangles: exercises the parallel build
    check_tree(&Bvh::build(std::slice::from_ref(&sphere)), &sphere);
}

#[test]
fn tree_split_in_parallel_rounds_is_sound() {
    // The parallel rounds of `build_node` run only above 2M triangles by default: lowered
    // here so that the top levels of a 20480-triangle sphere take that path.
    let sphere = icosphere(5);
    let params = BuildParams { parallel_split_prims: 1024, ..BuildParams::default() };
    let bvh = Bvh::build_with(std::slice::from_ref(&sphere), &params);
    check_tree(&bvh, &sphere);
    let meshes = [sphere];
    let mut rng = Rng::new(11, 0);
    for r in 0..500 {
        let o = random_point(&mut rng, -1.5, 1.5);
        let ray = Ray::new(o, random_point(&mut rng, -1.0, 1.0) - o);
        let expected = brute_force(&meshes, &ray);
        assert_eq!(bvh.intersect(&ray), expected, "ray {r}: {ray:?}");
        assert_eq!(bvh.occluded(&ray), expected.is_some(), "ray {r}: {ray:?}");
    }
}

/// Checks the structure of `bvh`, built over `sphere` alone: every triangle in one leaf, in
/// its slot's box, copied exactly; every node reachable once; child boxes inside their slots.
fn check_tree(bvh: &Bvh, sphere: &Arc<TriangleMesh>) {
    assert_eq!(bvh.triangle_count(), sphere.triangle_count());
    // Every (geom, prim) of the mesh in exactly one packet lane.
    let mut seen = vec![false; bvh.triangle_count()];
    let mut packets_seen = vec![false; bvh.packets.len()];
    let mut visited = vec![false; bvh.node_count()];
    let mut stack = vec![(0usize, 0usize)];
    let mut max_depth = 0;
    let mut leaves = 0;
    while let Some((i, depth)) = stack.pop() {
        assert!(!visited[i], "node {i} reached twice");
        visited[i] = true;
        max_depth = max_depth.max(depth);
        let n = bvh.nodes[i];
        for k in 0..WIDTH {
            let (child, count) = (n.child[k] as usize, n.count[k]);
            let b = n.slot_bounds(k);
            if count == EMPTY {
                assert!(b.is_empty(), "an unused slot has an empty box");
            } else if count == 0 {
                let c = bvh.nodes[child];
                for j in (0..WIDTH).filter(|&j| c.count[j] != EMPTY) {
                    let cb = c.slot_bounds(j);
                    assert!(cb.min.cmpge(b.min).all() && cb.max.cmple(b.max).all(), "child box outside slot");
                }
                stack.push((child, depth + 1));
            } else {
                leaves += 1;
                assert!(count as usize <= BuildParams::default().max_leaf);
                let count = count as usize;
                assert!(child + count.div_ceil(PACKET) <= bvh.packets.len(), "leaf past the packets");
                let leaf_packets = packets_seen.iter_mut().enumerate().skip(child).take(count.div_ceil(PACKET));
                for (packet, packet_seen) in leaf_packets {
                    assert!(!*packet_seen, "packet {packet} in two leaves");
                    *packet_seen = true;
                    for lane in 0..PACKET {
                        let [g, p] = bvh.ids[PACKET * packet + lane];
                        if PACKET * (packet - child) + lane >= count {
                            assert_eq!([g, p], [u32::MAX; 2], "an unused lane has no ids");
                            continue;
                        }
                        assert!(!seen[p as usize], "triangle {p} in two leaves");
                        seen[p as usize] = true;
                        let tri = bvh.packets[packet].get(lane);
                        for v in tri {
                            assert!(v.cmpge(b.min).all() && v.cmple(b.max).all());
                        }
                        assert_eq!(tri, bvh.meshes[g as usize].triangle(p));
                    }
                }
            }
        }
    }
    assert!(seen.iter().all(|&s| s), "every triangle in a leaf");
    assert!(packets_seen.iter().all(|&s| s), "every packet in a leaf");
    assert!(visited.iter().all(|&v| v), "every node reachable");
    assert!(max_depth < 20, "depth {max_depth} (the bound is {MAX_DEPTH})");
    // Every node but the root has 2 to 8 children, so there are fewer nodes than leaves.
    assert!(bvh.node_count() < leaves, "{} nodes for {leaves} leaves", bvh.node_count());
    assert!(bvh.memory_bytes() >= bvh.node_count() * 256 + bvh.triangle_count() * 44);
}

/// The arrays that rays read ask for huge pages when they are between the bounds (the bench
/// scene's all are), and are 2 MiB-aligned, so that whole huge pages can back them; the arrays
/// of a small tree stay on the heap.
#[cfg(target_os = "linux")]
#[test]
fn ray_arrays_ask_for_huge_pages() {
    use crate::process::huge_pages::{advised_for_huge_pages, HUGE_PAGE, HUGE_PAGE_ARRAY_BYTES, HUGE_PAGE_MIN_BYTES};
    let sphere = icosphere(7); // 327,680 triangles: every array over 1 MiB
    let bvh = Bvh::build(std::slice::from_ref(&sphere));
    let arrays = [
        ("nodes", bvh.nodes.as_ptr() as usize, std::mem::size_of_val(&bvh.nodes[..])),
        ("packets", bvh.packets.as_ptr() as usize, std::mem::size_of_val(&bvh.packets[..])),
        ("ids", bvh.ids.as_ptr() as usize, std::mem::size_of_val(&bvh.ids[..])),
    ];
    for (name, start, bytes) in arrays {
        assert!((HUGE_PAGE_MIN_BYTES..=HUGE_PAGE_ARRAY_BYTES).contains(&bytes), "{name}: {bytes} bytes");
        assert_eq!(start % HUGE_PAGE, 0, "{name} not aligned to a huge page");
        assert!(advised_for_huge_pages(start as *const u8), "{name} not advised for huge pages");
    }
    let small = Bvh::build(&[icosphere(2)]);
    assert!(!advised_for_huge_pages(small.packets.as_ptr()), "a 320-triangle tree's packets advised");
}

#[test]
fn degenerate_inputs() {
    // No meshes at all.
    let empty = Bvh::build(&[]);
    let ray = Ray::new(Vec3::ZERO, Vec3::X);
    assert!(empty.intersect(&ray).is_none() && !empty.occluded(&ray));
    // Only zero-area triangles.
    let flat = mesh(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2], [0, 0, 0]]);
    let bvh = Bvh::build(std::slice::from_ref(&flat));
    assert_eq!(bvh.triangle_count(), 0);
    assert!(bvh.intersect(&Ray::new(Vec3::new(1.0, 0.0, 1.0), -Vec3::Z)).is_none());
    // Many coincident triangles (all centroids equal): the build must still split them.
    let n = 1000;
    let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
    let same = mesh(p, vec![[0, 1, 2]; n]);
    let bvh = Bvh::build(&[flat, same]);
    assert_eq!(bvh.triangle_count(), n);
    let hit = bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
    assert_eq!((hit.geom_id, hit.t), (1, 1.0));
    // Invalid rays hit nothing.
    for bad in [
        Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::ZERO),
        Ray::new(Vec3::new(f32::NAN, 0.2, 1.0), -Vec3::Z),
        Ray { o: Vec3::new(0.2, 0.2, 1.0), d: -Vec3::Z, t_min: 2.0, t_max: 1.0 },
        Ray { o: Vec3::new(0.2, 0.2, 1.0), d: -Vec3::Z, t_min: f32::NAN, t_max: 5.0 },
    ] {
        assert!(bvh.intersect(&bad).is_none() && !bvh.occluded(&bad), "{bad:?}");
    }
}

#[test]
fn geometry_ids_and_barycentrics_match_embree_convention() {
    let quad = |z: f32| {
        let p =
            vec![Vec3::new(-1.0, -1.0, z), Vec3::new(1.0, -1.0, z), Vec3::new(1.0, 1.0, z), Vec3::new(-1.0, 1.0, z)];
        mesh(p, vec![[0, 1, 2], [0, 2, 3]])
    };
    let bvh = Bvh::build(&[quad(0.0), quad(-1.0), quad(-2.0)]);
    for (i, t_min) in [0.0f32, 1.5, 2.5].into_iter().enumerate() {
        let ray = Ray { o: Vec3::new(0.25, -0.5, 1.0), d: -Vec3::Z, t_min, t_max: f32::INFINITY };
        let hit = bvh.intersect(&ray).unwrap();
        assert_eq!((hit.geom_id as usize, hit.prim_id), (i, 0));
        assert_eq!(hit.t, 1.0 + i as f32);
        assert!((hit.b1 - 0.375).abs() < 1e-6 && (hit.b2 - 0.25).abs() < 1e-6, "{hit:?}");
    }
    assert!(bvh.intersect(&Ray::segment(Vec3::new(0.25, -0.5, 1.0), -Vec3::Z, 0.99)).is_none());
    assert!(!bvh.occluded(&Ray::segment(Vec3::new(0.25, -0.5, 1.0), -Vec3::Z, 0.99)));
}

/// The tree does not depend on the thread count: the build's parallel passes (centroid bounds,
/// binning, partition, leaf packing) reduce in a fixed order, so 1, 2 and 3 threads give the same
/// nodes and the same leaf order, on a sphere and on a regular grid whose many equal centroid
/// coordinates make the partition break ties. A build whose result depended on how rayon split the
/// work (an unordered collect, a reduce whose order follows the scheduling) would differ here.
#[test]
fn tree_is_the_same_on_any_thread_count() {
    let n = 300u32;
    let grid_positions: Vec<Vec3> =
        (0..=n).flat_map(|j| (0..=n).map(move |i| Vec3::new(i as f32, 0.1 * ((i + j) % 3) as f32, j as f32))).collect();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let grid_indices: Vec<[u32; 3]> = (0..n)
        .flat_map(|j| {
            (0..n).flat_map(move |i| {
                [[at(i, j), at(i + 1, j), at(i, j + 1)], [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]]
            })
        })
        .collect();
    let scenes = [vec![icosphere(7)], vec![mesh(grid_positions, grid_indices), icosphere(5)]];
    for meshes in &scenes {
        let build_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| Bvh::build(meshes))
        };
        let one = build_on(1);
        for threads in [2, 3] {
            let other = build_on(threads);
            assert!(one.nodes[..] == other.nodes[..], "nodes differ on {threads} threads");
            assert!(one.ids[..] == other.ids[..], "leaf order differs on {threads} threads");
        }
    }
}
