//! `plexus bench`: accelerator and path-tracer throughput on a generated 1M+ triangle scene
//! (the measurement itself lives in `plexus::bench`; docs/bench.md explains the output). This
//! file turns its progress events into lines and its report into the Markdown table.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use plexus::bench::{run, BenchEvent, BenchOptions, BenchReport, BenchRow};

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
    let mut out = std::io::stdout().lock();
    let report = run(&opts, &mut |event| print_event(&mut out, event))?;
    writeln!(out)?;
    write!(out, "{}", markdown_table(&report))?;
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// One progress line (or a few) per event, as the benchmark runs.
fn print_event(out: &mut dyn Write, event: BenchEvent<'_>) -> std::io::Result<()> {
    match event {
        BenchEvent::SceneGenerated { triangles, meshes, seconds } => {
            writeln!(out, "scene: {triangles} triangles in {meshes} meshes ({seconds:.1} s to generate)")
        }
        BenchEvent::RaysRecorded { camera, bounce, bounces } => {
            writeln!(out, "rays: {camera} camera, {bounce} bounce ({bounces} bounces per path at most)")
        }
        BenchEvent::Accelerator(row) => writeln!(out, "{}", row_line(row)),
        BenchEvent::HitCounts(counts) => {
            for c in counts {
                writeln!(out, "  {}: {} camera hits, {} bounce hits", c.accel, c.camera_hits, c.bounce_hits)?;
            }
            Ok(())
        }
        BenchEvent::PathTracer(row) => writeln!(
            out,
            "  path tracer {} thread(s): {} rays + {} shadow rays in {:.3} s: {:.2} Mrays/s ({:.2} per CPU-s), {:.0}% of \
             the bare loop's {:.2} bounce Mrays/s between the renders",
            row.threads,
            row.rays,
            row.shadow_rays,
            row.seconds,
            row.mrays_per_s,
            row.mrays_per_cpu_s,
            100.0 * row.ratio_to_bare_loop,
            row.bare_loop_mrays_per_s
        ),
    }
}

fn row_line(r: &BenchRow) -> String {
    format!(
        "{:>17} {} thread(s): build {}, camera {:.2} Mrays/s ({:.2} per CPU-s), bounce {:.2} Mrays/s ({:.2} per CPU-s)",
        r.accel,
        r.threads,
        r.build_seconds.map_or("-".to_string(), |s| format!("{s:.3} s")),
        r.camera_mrays_per_s,
        r.camera_mrays_per_cpu_s,
        r.bounce_mrays_per_s,
        r.bounce_mrays_per_cpu_s
    )
}

/// The report as a Markdown table, with the BVH/Embree ratios.
fn markdown_table(report: &BenchReport) -> String {
    let mut s = String::new();
    s += &format!(
        "{} triangles, {} camera rays, {} bounce rays; {}; median of {} runs; load average {} before, {} after\n\n",
        report.triangles,
        report.camera_rays,
        report.bounce_rays,
        report.cpu,
        report.options.repetitions,
        report.load_before,
        report.load_after
    );
    s += "| accelerator | threads | build s (CPU s) | camera Mrays/s | camera Mrays/CPU-s | bounce Mrays/s | bounce Mrays/CPU-s |\n";
    s += "| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for r in &report.rows {
        let build = match (r.build_seconds, r.build_cpu_seconds) {
            (Some(b), Some(c)) => format!("{b:.3} ({c:.3})"),
            _ => "–".to_string(),
        };
        s += &format!(
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} |\n",
            r.accel,
            r.threads,
            build,
            r.camera_mrays_per_s,
            r.camera_mrays_per_cpu_s,
            r.bounce_mrays_per_s,
            r.bounce_mrays_per_cpu_s
        );
    }
    for &t in &report.options.threads {
        if let (Some(b), Some(e)) = (report.row("bvh", t), report.row("embree", t)) {
            let ratio = |x: Option<f64>, y: Option<f64>| x.zip(y).map_or(f64::NAN, |(x, y)| x / y);
            s += &format!(
                "| BVH / Embree | {} | {:.2} ({:.2}) | {:.2} | {:.2} | {:.2} | {:.2} |\n",
                t,
                ratio(e.build_seconds, b.build_seconds),
                ratio(e.build_cpu_seconds, b.build_cpu_seconds),
                b.camera_mrays_per_s / e.camera_mrays_per_s,
                b.camera_mrays_per_cpu_s / e.camera_mrays_per_cpu_s,
                b.bounce_mrays_per_s / e.bounce_mrays_per_s,
                b.bounce_mrays_per_cpu_s / e.bounce_mrays_per_cpu_s
            );
        }
    }
    if !report.path_tracer.is_empty() {
        s += "\n| path tracer (Embree) | threads | Mrays/s | Mrays/CPU-s | share of shadow rays | bare loop between the renders: bounce Mrays/s | vs bare loop | same, per CPU-s |\n";
        s += "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
        for p in &report.path_tracer {
            s += &format!(
                "| pt, {} spp | {} | {:.2} | {:.2} | {:.0}% | {:.2} | {:.0}% | {:.0}% |\n",
                report.options.pt_spp,
                p.threads,
                p.mrays_per_s,
                p.mrays_per_cpu_s,
                100.0 * p.shadow_rays as f64 / (p.rays + p.shadow_rays).max(1) as f64,
                p.bare_loop_mrays_per_s,
                100.0 * p.ratio_to_bare_loop,
                100.0 * p.ratio_to_bare_loop_cpu
            );
        }
    }
    s += "\nBVH / Embree rows: speed ratios (target ≥ 0.67): build, Embree's time over the BVH's (wall, \
          and CPU in parentheses); rays, the BVH's rate over Embree's.\n";
    s += &format!(
        "\nMemory: BVH {:.1} MB ({} nodes), Embree {:.1} MB.\n",
        report.bvh_bytes as f64 / 1e6,
        report.bvh_nodes,
        report.embree_bytes as f64 / 1e6
    );
    s
}
