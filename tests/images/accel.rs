//! Embree and the in-house BVH answer the same queries: the same closest primitive (geometry and
//! primitive id) with `t` within 1e-5 relative, and the same occlusion, for 100k random rays
//! against a procedurally generated mesh of more than 100k triangles.
//!
//! "Relative" has a floor: a `t` computed from f32 coordinates of magnitude `m` cannot be more
//! accurate than a few ulps of `m`, whatever algorithm computes it, so for hits a hair away from
//! the origin (t → 0) the tolerance is `8 ε m` instead of `1e-5 t` (see `close`).
//!
//! The only other disagreement allowed is a genuine tie: two triangles hit at the same distance,
//! the ray passing through (or within rounding error of) their shared edge or vertex, where either
//! answer is right and each accelerator's rounding picks a side. A tie is recognised by testing the
//! other accelerator's primitive alone, in double precision: the ray must meet its plane at the
//! same `t` and inside the triangle up to 1e-5 in barycentric coordinates. Anything else fails.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use plexus::accel::bvh::Bvh;
use plexus::accel::embree::EmbreeAccel;
use plexus::accel::Accel;
use plexus::geometry::{Ray, TriangleMesh};
use plexus::sampling::Rng;
use plexus::scene::procedural::{displaced_sphere, terrain};

const RAYS: usize = 100_000;
const REL_T: f32 = 1e-5;

fn meshes() -> Vec<Arc<TriangleMesh>> {
    vec![
        // 2 · 230 · 229 = 105,340 triangles, closed, bumpy enough for grazing hits.
        Arc::new(displaced_sphere(Vec3::ZERO, 1.0, 230, 230, 0.2, 7)),
        // A second geometry (so geometry ids are compared too), cutting through the sphere.
        Arc::new(terrain(Vec2::splat(-1.5), Vec2::splat(1.5), -0.3, 0.2, 60, 3)),
    ]
}

/// Whether two distances along `ray` agree: 1e-5 relative, with the floor explained above.
fn close(ray: &Ray, a: f32, b: f32) -> bool {
    let m = ray.o.abs().max_element().max(ray.at(a.max(b)).abs().max_element());
    (a - b).abs() <= (REL_T * a.abs().max(b.abs())).max(8.0 * f32::EPSILON * m)
}

/// Random rays from origins in and around the scene's bounds towards random points inside them.
fn rays(seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed, 0);
    let mut point = |half: f32| Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * (2.0 * half) - half;
    (0..RAYS)
        .map(|_| {
            let o = point(2.0);
            let target = point(1.2);
            Ray::new(o, (target - o).normalize())
        })
        .collect()
}

/// Where `ray` meets `(geom, prim)`'s plane, in double precision (Möller–Trumbore): `t` and the
/// smallest of the three barycentric coordinates (negative outside the triangle).
fn plane_hit(meshes: &[Arc<TriangleMesh>], ray: &Ray, geom: u32, prim: u32) -> Option<(f32, f64)> {
    let [a, b, c] = meshes[geom as usize].triangle(prim).map(|v| v.as_dvec3());
    let (o, d) = (ray.o.as_dvec3(), ray.d.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let s = o - a;
    let b1 = s.dot(p) / det;
    let q = s.cross(e1);
    let b2 = d.dot(q) / det;
    let t = e2.dot(q) / det;
    Some((t as f32, b1.min(b2).min(1.0 - b1 - b2)))
}

/// Whether `ray` hits `(geom, prim)` at distance `t` up to the tolerances of a tie.
fn also_hit_at(meshes: &[Arc<TriangleMesh>], ray: &Ray, geom: u32, prim: u32, t: f32) -> bool {
    plane_hit(meshes, ray, geom, prim).is_some_and(|(t_plane, b_min)| close(ray, t_plane, t) && b_min >= -1e-5)
}

#[test]
fn embree_and_bvh_agree_on_closest_hits() {
    let meshes = meshes();
    let triangles: usize = meshes.iter().map(|m| m.triangle_count()).sum();
    assert!(meshes[0].triangle_count() >= 100_000, "the main mesh has {} triangles", meshes[0].triangle_count());
    let embree = EmbreeAccel::build(&meshes).expect("Embree builds the scene");
    let bvh = Bvh::build(&meshes);
    assert_eq!(bvh.triangle_count(), triangles, "no triangle of these meshes has zero area");

    let (mut hits, mut ties) = (0usize, 0usize);
    let mut failures = Vec::new();
    for (i, ray) in rays(11).iter().enumerate() {
        let e = embree.intersect(ray);
        let b = bvh.intersect(ray);
        match (e, b) {
            (None, None) => {}
            (Some(e), Some(b)) if (e.geom_id, e.prim_id) == (b.geom_id, b.prim_id) => {
                hits += 1;
                if !close(ray, e.t, b.t) {
                    failures.push(format!("ray {i}: same primitive, t {} (Embree) vs {} (BVH)", e.t, b.t));
                }
            }
            (Some(e), Some(b)) => {
                hits += 1;
                // A tie: each accelerator's primitive is also hit at the other's t.
                if close(ray, e.t, b.t)
                    && also_hit_at(&meshes, ray, e.geom_id, e.prim_id, b.t)
                    && also_hit_at(&meshes, ray, b.geom_id, b.prim_id, e.t)
                {
                    ties += 1;
                } else {
                    failures.push(format!("ray {i} {ray:?}: Embree {e:?}, BVH {b:?}"));
                }
            }
            (e, b) => failures.push(format!("ray {i} {ray:?}: Embree {e:?}, BVH {b:?}")),
        }
    }
    assert!(
        failures.is_empty(),
        "{} disagreements, first ones:\n{}",
        failures.len(),
        failures[..failures.len().min(10)].join("\n")
    );
    // Most rays must hit for the comparison to mean anything; ties are rare with random rays.
    assert!(hits > RAYS / 2, "only {hits} hits");
    assert!(ties < RAYS / 1000, "{ties} ties");
    eprintln!("{hits} hits, {ties} ties among {RAYS} rays against {triangles} triangles");
}

#[test]
fn embree_and_bvh_agree_on_occlusion() {
    let meshes = meshes();
    let embree = EmbreeAccel::build(&meshes).expect("Embree builds the scene");
    let bvh = Bvh::build(&meshes);
    let mut rng = Rng::new(12, 1);
    let (mut occluded, mut failures) = (0usize, Vec::new());
    for (i, mut ray) in rays(12).into_iter().enumerate() {
        // Segments of random length, half of them starting away from the origin: about half are
        // blocked. A segment ending (or starting) within 1e-5 relative of a surface could go
        // either way in exact arithmetic; such rays are skipped, the others must agree.
        ray.t_min = if i % 2 == 0 { 0.0 } else { rng.uniform() };
        ray.t_max = ray.t_min + 3.0 * rng.uniform();
        let e = embree.occluded(&ray);
        let b = bvh.occluded(&ray);
        occluded += b as usize;
        if e != b {
            // Whether a surface lies within 1e-5 relative of `t` along the ray.
            let surface_near =
                |t: f32| t > 0.0 && bvh.occluded(&Ray { t_min: t * (1.0 - REL_T), t_max: t * (1.0 + REL_T), ..ray });
            let near_end = surface_near(ray.t_min) || surface_near(ray.t_max);
            if !near_end {
                failures.push(format!("ray {i} {ray:?}: Embree {e}, BVH {b}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} disagreements:\n{}",
        failures.len(),
        failures[..failures.len().min(10)].join("\n")
    );
    assert!((RAYS / 5..RAYS * 4 / 5).contains(&occluded), "{occluded} occluded: the test needs both outcomes");
}
