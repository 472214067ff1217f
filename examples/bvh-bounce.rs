//! Traces `plexus bench`'s recorded bounce rays through the in-house BVH (and Embree) alone, for
//! callgrind and perf runs and for huge-page A/B comparisons in one process.
//!
//! Usage: cargo run --release --example bvh-bounce -- [--accel bvh|embree|both] [--rays N]
//! [--reps R] [--triangles T] [--thp-ab]
//!
//! The scene, camera rays and bounce rays are the bench's defaults (1.2M triangles, 640×480,
//! 4 bounces, seed 1), recorded with Embree as `plexus bench` does. `--rays N` traces the first N
//! bounce rays only (callgrind). Tracing is single-threaded and sits in `trace` (not inlined), so
//! `valgrind --tool=callgrind --toggle-collect='*bvh_bounce*trace*'` counts only the queries.
//! `--thp-ab` builds the BVH twice, once with transparent huge pages turned off for the process
//! (`PR_SET_THP_DISABLE`) and once with them on, and times the same rays through each, alternating.
//! Prints one line per measurement: accelerator, rays, hits, CPU seconds, Mrays per CPU-second.

use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use plexus::accel::bvh::Bvh;
use plexus::accel::embree::EmbreeAccel;
use plexus::accel::Accel;
use plexus::bench::timing::process_cpu_time;
use plexus::bench::BenchScene;
use plexus::geometry::{Ray, TriangleMesh};

/// Closest-hit queries of `rays` through `accel`, one thread; the number of hits.
#[inline(never)]
fn trace(accel: &dyn Accel, rays: &[Ray]) -> usize {
    rays.iter().filter(|r| accel.intersect(r).is_some()).count()
}

fn measure(name: &str, accel: &dyn Accel, rays: &[Ray], reps: u32) {
    let mut best = Duration::MAX;
    let mut hits = 0;
    for _ in 0..reps.max(1) {
        let cpu = process_cpu_time();
        hits = trace(accel, rays);
        best = best.min(process_cpu_time().saturating_sub(cpu));
    }
    let s = best.as_secs_f64();
    println!("{name}: rays {} hits {hits} cpu_s {s:.4} mrays_per_cpu_s {:.3}", rays.len(), rays.len() as f64 / s / 1e6);
}

/// Lets (or stops) the kernel back this process's new memory with transparent huge pages.
fn set_thp(allowed: bool) {
    // SAFETY: PR_SET_THP_DISABLE takes an integer flag and changes only the kernel's choice of
    // page size for this process's later faults.
    unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, (!allowed) as libc::c_ulong, 0, 0, 0) };
}

/// AnonHugePages of this process, in kB (`/proc/self/smaps_rollup`).
fn anon_huge_kb() -> u64 {
    let s = std::fs::read_to_string("/proc/self/smaps_rollup").unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix("AnonHugePages:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0)
}

fn main() -> Result<()> {
    let mut accel = "bvh".to_string();
    let (mut rays_limit, mut reps, mut triangles, mut thp_ab) = (usize::MAX, 3u32, 1_200_000usize, false);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--accel" => accel = value()?,
            "--rays" => rays_limit = value()?.parse().context("--rays")?,
            "--reps" => reps = value()?.parse().context("--reps")?,
            "--triangles" => triangles = value()?.parse().context("--triangles")?,
            "--thp-ab" => thp_ab = true,
            _ => bail!("unknown argument {a}"),
        }
    }
    let scene = BenchScene::new(triangles, 640, 480, 1);
    let reference = EmbreeAccel::build(&scene.meshes)?;
    let camera = scene.camera_rays();
    let mut bounce = scene.bounce_rays(&reference, &camera, 4, 1);
    bounce.truncate(rays_limit);
    let meshes: &[Arc<TriangleMesh>] = &scene.meshes;
    eprintln!("{} triangles, {} bounce rays", scene.triangle_count(), bounce.len());
    if thp_ab {
        set_thp(false);
        let before = anon_huge_kb();
        let small = Bvh::build(meshes);
        let small_huge = anon_huge_kb() - before;
        set_thp(true);
        let before = anon_huge_kb();
        let huge = Bvh::build(meshes);
        eprintln!("AnonHugePages added by the build: THP off {small_huge} kB, on {} kB", anon_huge_kb() - before);
        for _ in 0..3 {
            measure("bvh thp-off", &small, &bounce, reps);
            measure("bvh thp-on", &huge, &bounce, reps);
        }
        return Ok(());
    }
    if accel == "embree" || accel == "both" {
        measure("embree", &reference, &bounce, reps);
    }
    if accel == "bvh" || accel == "both" {
        let bvh = Bvh::build(meshes);
        measure("bvh", &bvh, &bounce, reps);
    }
    Ok(())
}
