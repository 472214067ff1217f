//! Embree's single-ray and 8-wide packet queries on incoherent rays: what tracing the bounce rays
//! of several paths together (`rtcIntersect8`) would cost against one query per ray.
//!
//! Usage: cargo run --release --example embree-packets -- SCENE [RAYS]
//!
//! The rays start just before the camera's hits (pixels drawn uniformly) and leave in uniformly
//! random directions, as diffuse bounces do. One thread; prints per repetition the CPU time per
//! ray of each query kind and their ratio, and checks that both find the same number of hits.

use std::path::Path;

use anyhow::{bail, Context, Result};
use glam::{Vec2, Vec3};
use plexus::accel::embree::{EmbreeAccel, PACKET_WIDTH};
use plexus::bench::timing::process_cpu_time;
use plexus::geometry::Ray;
use plexus::sampling::Rng;
use plexus::scene::load_scene;

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next() else { bail!("usage: embree-packets SCENE [RAYS]") };
    let count: usize = args.next().map(|n| n.parse()).transpose().context("RAYS")?.unwrap_or(1_000_000);
    let loaded = load_scene(Path::new(&path), None)?;
    let scene = &loaded.scene;
    let embree = EmbreeAccel::build(&scene.meshes)?;
    let queries = embree.scene();
    let mut rng = Rng::new(1, 0);
    let (w, h) = (scene.camera.width as f32, scene.camera.height as f32);
    let mut rays = Vec::with_capacity(count);
    while rays.len() < count {
        let camera = scene.camera.ray_through(Vec2::new(rng.uniform() * w, rng.uniform() * h));
        if let Some(hit) = queries.intersect(&camera) {
            let origin = camera.o + camera.d * (hit.t * 0.999);
            let z = 2.0 * rng.uniform() - 1.0;
            let phi = std::f32::consts::TAU * rng.uniform();
            let r = (1.0 - z * z).max(0.0).sqrt();
            rays.push(Ray::new(origin, Vec3::new(r * phi.cos(), r * phi.sin(), z)));
        }
    }
    for repetition in 0..3 {
        let start = process_cpu_time();
        let single_hits = rays.iter().filter(|r| queries.intersect(r).is_some()).count();
        let single = process_cpu_time().saturating_sub(start).as_secs_f64();
        let start = process_cpu_time();
        let mut packet_hits = 0;
        let mut hits = [None; PACKET_WIDTH];
        for chunk in rays.chunks(PACKET_WIDTH) {
            queries.intersect_packet(chunk, &mut hits);
            packet_hits += hits[..chunk.len()].iter().filter(|h| h.is_some()).count();
        }
        let packet = process_cpu_time().saturating_sub(start).as_secs_f64();
        let per_ray = |s: f64| s * 1e9 / rays.len() as f64;
        println!(
            "repetition {repetition}: single {:.1} ns/ray ({single_hits} hits), packets of {PACKET_WIDTH} {:.1} ns/ray ({packet_hits} hits), ratio {:.3}",
            per_ray(single),
            per_ray(packet),
            packet / single
        );
    }
    Ok(())
}
