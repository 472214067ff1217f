//! Builds `plexus bench`'s scene with the in-house BVH (and optionally Embree) only, for perf and
//! callgrind runs of the build and for A/B timings without the ray measurements.
//!
//! Usage: cargo run --release --example bvh-build -- [--threads N] [--reps R] [--triangles T]
//! [--embree]
//!
//! The scene is the bench's default (1.2M triangles, seed 1). Each repetition builds the BVH (then
//! Embree, with `--embree`) on a rayon pool of N threads and prints its wall-clock and CPU seconds;
//! the last lines give the medians and the BVH's node count and memory (equal node counts and
//! bytes on every thread count are a quick check that the tree did not change).
//! `valgrind --tool=callgrind --toggle-collect='*Bvh*build_with*'` counts only the BVH build.

use anyhow::{bail, Context, Result};
use plexus::accel::bvh::Bvh;
use plexus::accel::embree::EmbreeAccel;
use plexus::accel::Accel;
use plexus::bench::timing::{median, timed};
use plexus::bench::BenchScene;

fn main() -> Result<()> {
    let (mut threads, mut reps, mut triangles, mut embree) = (1usize, 5u32, 1_200_000usize, false);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--threads" => threads = value()?.parse().context("--threads")?,
            "--reps" => reps = value()?.parse().context("--reps")?,
            "--triangles" => triangles = value()?.parse().context("--triangles")?,
            "--embree" => embree = true,
            _ => bail!("unknown argument {a}"),
        }
    }
    let scene = BenchScene::new(triangles, 640, 480, 1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
    let config = format!("threads={threads}");
    eprintln!("{} triangles, {threads} thread(s)", scene.triangle_count());
    let (mut bvh_wall, mut bvh_cpu, mut e_wall, mut e_cpu) = (vec![], vec![], vec![], vec![]);
    let mut shape = (0, 0);
    for _ in 0..reps.max(1) {
        let (t, bvh) = pool.install(|| timed(|| Bvh::build(&scene.meshes)));
        shape = (bvh.node_count(), bvh.memory_bytes());
        drop(bvh);
        println!("bvh: wall_s {:.4} cpu_s {:.4}", t.wall.as_secs_f64(), t.cpu.as_secs_f64());
        bvh_wall.push(t.wall.as_secs_f64());
        bvh_cpu.push(t.cpu.as_secs_f64());
        if embree {
            let (t, e) = pool.install(|| timed(|| EmbreeAccel::build_with_config(&scene.meshes, &config)));
            drop(e?);
            println!("embree: wall_s {:.4} cpu_s {:.4}", t.wall.as_secs_f64(), t.cpu.as_secs_f64());
            e_wall.push(t.wall.as_secs_f64());
            e_cpu.push(t.cpu.as_secs_f64());
        }
    }
    println!(
        "bvh median: wall_s {:.4} cpu_s {:.4} nodes {} bytes {}",
        median(bvh_wall),
        median(bvh_cpu),
        shape.0,
        shape.1
    );
    if embree {
        println!("embree median: wall_s {:.4} cpu_s {:.4}", median(e_wall), median(e_cpu));
    }
    Ok(())
}
