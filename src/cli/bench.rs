//! `plexus bench`: accelerator and path-tracer throughput on a generated 1M+ triangle scene
//! (the measurement itself lives in `plexus::bench`; docs/bench.md explains the output).

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use plexus::bench::{run, BenchOptions};

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Approximate number of triangles of the generated scene.
    #[arg(long, default_value_t = BenchOptions::default().triangles)]
    triangles: usize,
    /// Camera resolution as WIDTHxHEIGHT (one camera ray and one random walk per pixel).
    #[arg(long, default_value = "640x480", value_parser = parse_resolution)]
    resolution: (u32, u32),
    /// Bounces of each recorded random walk.
    #[arg(long, default_value_t = BenchOptions::default().bounces)]
    bounces: u32,
    /// Repetitions of every measurement (the median is reported).
    #[arg(long, default_value_t = BenchOptions::default().repetitions)]
    repetitions: u32,
    /// Thread counts to measure, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = BenchOptions::default().threads)]
    threads: Vec<usize>,
    /// Seed of the scene and of the random walks.
    #[arg(long, default_value_t = BenchOptions::default().seed)]
    seed: u64,
    /// Samples per pixel of the path-tracer measurement (0 skips it).
    #[arg(long, default_value_t = BenchOptions::default().pt_spp)]
    pt_spp: u64,
    /// Also write the full report as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
}

fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once('x').ok_or_else(|| format!("expected WIDTHxHEIGHT (e.g. 640x480), got '{s}'"))?;
    let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|&v| v > 0);
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("expected two positive integers WIDTHxHEIGHT, got '{s}'")),
    }
}

pub fn run_bench(args: &BenchArgs) -> anyhow::Result<()> {
    if args.threads.contains(&0) {
        return Err(super::bad_input("--threads: thread counts must be at least 1"));
    }
    let opts = BenchOptions {
        triangles: args.triangles,
        width: args.resolution.0,
        height: args.resolution.1,
        bounces: args.bounces,
        repetitions: args.repetitions,
        threads: args.threads.clone(),
        seed: args.seed,
        pt_spp: args.pt_spp,
    };
    let report = run(&opts, &mut std::io::stdout())?;
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
