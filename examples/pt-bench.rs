//! Renders `plexus bench`'s scene with the path tracer alone (one thread), for perf and callgrind:
//! the `pt` row of `plexus bench` without the accelerator measurements around it.
//!
//! Usage: cargo run --release --example pt-bench -- [SPP] [REPS]
//! Prints per repetition: rays, shadow rays, CPU seconds, Mrays (both kinds) per CPU-second.

use plexus::bench::timing::process_cpu_time;
use plexus::bench::BenchScene;
use plexus::integrator::{create, Budget, NoProgress, RenderJob};

fn main() -> anyhow::Result<()> {
    let args: Vec<u64> = std::env::args().skip(1).map(|a| a.parse()).collect::<Result<_, _>>()?;
    let spp = args.first().copied().unwrap_or(4);
    let reps = args.get(1).copied().unwrap_or(3);
    let defaults = plexus::bench::BenchOptions::default();
    let bench = BenchScene::new(defaults.triangles, defaults.width, defaults.height, defaults.seed);
    let scene = bench.renderable()?;
    let mut params = toml::Table::new();
    params.insert("max_depth".into(), toml::Value::Integer(i64::from(defaults.bounces + 1)));
    let pt = create("pt", &params)?;
    let job = RenderJob { budget: Budget::SamplesPerPixel(spp), seed: defaults.seed, threads: 1 };
    for _ in 0..reps {
        let cpu = process_cpu_time();
        let out = pt.render(&scene, &job, &NoProgress)?;
        let s = process_cpu_time().saturating_sub(cpu).as_secs_f64();
        let (rays, shadow) = (out.counters.rays, out.counters.shadow_rays);
        println!(
            "pt: {rays} rays + {shadow} shadow rays, {s:.3} CPU-s, {:.3} Mrays/CPU-s",
            (rays + shadow) as f64 / s / 1e6
        );
    }
    Ok(())
}
