//! `plexus bench`: throughput of the accelerators on a deterministic, procedurally generated scene
//! of more than a million triangles.
//!
//! Measures, for Embree and the in-house BVH on each requested thread count: build time, and
//! rays per second for (a) camera rays, one per pixel, and (b) bounce rays, the rays of a
//! cosine-weighted diffuse random walk of a few bounces from the camera hits. The bounce rays are
//! recorded once (traced with Embree) so that every accelerator traces the identical set. A bare
//! loop over Embree's `rtcIntersect1` (through the concrete, inlined wrapper rather than `dyn
//! Accel`) on the same rays measures what the trait object costs. Every timing is the median of
//! several repetitions. docs/bench.md explains the output; docs/lab/performance.md holds dated
//! measurements.
//!
//! The scene is in `workload`, process timing in `timing`; `run` measures and reports progress as
//! [`BenchEvent`]s, and the CLI (`cli::bench`) turns events and the report into text and Markdown.

pub mod timing;
pub mod workload;

use std::time::Instant;

use rayon::prelude::*;
use rayon::ThreadPool;
use serde::Serialize;
use thiserror::Error;

use crate::accel::bvh::Bvh;
use crate::accel::embree::EmbreeAccel;
use crate::accel::{Accel, AccelError};
use crate::geometry::{Hit, Ray};
use crate::integrator::RenderError;
use crate::process::denormals::set_flush_denormals;
use crate::scene::{Scene, SceneError};

use timing::{cpu_model, load_average, median_seconds, process_cpu_time, time_median, timed, Timing};
pub use workload::BenchScene;

/// What to measure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchOptions {
    /// Approximate number of triangles of the generated scene.
    pub triangles: usize,
    /// Camera resolution: one camera ray per pixel, and one random walk per pixel.
    pub width: u32,
    pub height: u32,
    /// Bounces of each random walk (each bounce is one recorded ray).
    pub bounces: u32,
    /// Repetitions of every measurement; the median is reported.
    pub repetitions: u32,
    /// Thread counts to measure.
    pub threads: Vec<usize>,
    /// Seed of the scene's displacements and of the random walks.
    pub seed: u64,
    /// Samples per pixel of the path-tracer measurement (0 skips it).
    pub pt_spp: u64,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            triangles: 1_200_000,
            width: 640,
            height: 480,
            bounces: 4,
            repetitions: 5,
            threads: vec![1, 2],
            seed: 1,
            pt_spp: 1,
        }
    }
}

/// One accelerator on one thread count.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    /// "embree", "bvh", or "embree bare loop".
    pub accel: String,
    pub threads: usize,
    /// Median build time (none for the bare loop, which reuses Embree's scene).
    pub build_seconds: Option<f64>,
    /// Median CPU time of the build, all threads together.
    pub build_cpu_seconds: Option<f64>,
    /// Median million rays per second of wall-clock time.
    pub camera_mrays_per_s: f64,
    pub bounce_mrays_per_s: f64,
    /// Median million rays per CPU-second (all threads together): the throughput of one core,
    /// insensitive to other processes competing for the cores, unlike the wall-clock figures.
    pub camera_mrays_per_cpu_s: f64,
    pub bounce_mrays_per_cpu_s: f64,
}

/// The path tracer (`integrator::pt`) rendering the benchmark scene with Embree.
#[derive(Clone, Debug, Serialize)]
pub struct PtRow {
    pub threads: usize,
    /// Closest-hit and shadow queries of one render.
    pub rays: u64,
    pub shadow_rays: u64,
    /// Median render time (the integrator's own wall time) and process CPU time.
    pub seconds: f64,
    pub cpu_seconds: f64,
    /// All queries (closest hit and shadow) per second of wall-clock time and per CPU-second.
    pub mrays_per_s: f64,
    pub mrays_per_cpu_s: f64,
    /// The bare Embree loop's bounce-ray rate (million per second of wall-clock time and per
    /// CPU-second) in passes interleaved with the renders: one pass after each render.
    pub bare_loop_mrays_per_s: f64,
    pub bare_loop_mrays_per_cpu_s: f64,
    /// `mrays_per_s` over `bare_loop_mrays_per_s` (the path tracer's target: at least 0.85), and
    /// the same ratio per CPU-second.
    pub ratio_to_bare_loop: f64,
    pub ratio_to_bare_loop_cpu: f64,
}

/// Everything `run` measured.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub options: BenchOptions,
    /// CPU model from /proc/cpuinfo.
    pub cpu: String,
    pub triangles: usize,
    pub camera_rays: usize,
    pub bounce_rays: usize,
    pub bvh_nodes: usize,
    pub bvh_bytes: usize,
    pub embree_bytes: usize,
    pub rows: Vec<BenchRow>,
    /// The path tracer on the same scene with Embree, per thread count.
    pub path_tracer: Vec<PtRow>,
    /// 1-minute load average (/proc/loadavg) when the benchmark started and ended: other work on
    /// the machine slows the wall-clock figures, not the per-CPU-second ones.
    pub load_before: String,
    pub load_after: String,
}

impl BenchReport {
    /// The row for `accel` on `threads`.
    pub fn row(&self, accel: &str, threads: usize) -> Option<&BenchRow> {
        self.rows.iter().find(|r| r.accel == accel && r.threads == threads)
    }
}

/// Hits one accelerator found among the camera and the bounce rays (the same for every
/// accelerator when they agree).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HitCounts {
    pub accel: String,
    pub camera_hits: usize,
    pub bounce_hits: usize,
}

/// Progress of `run`, in the order it happens, for the caller to show.
#[derive(Clone, Copy, Debug)]
pub enum BenchEvent<'a> {
    /// The scene was generated.
    SceneGenerated { triangles: usize, meshes: usize, seconds: f64 },
    /// The camera rays and the random walks' bounce rays were recorded.
    RaysRecorded { camera: usize, bounce: usize, bounces: u32 },
    /// One accelerator on one thread count was measured.
    Accelerator(&'a BenchRow),
    /// Every accelerator on one thread count was measured: the hits each found.
    HitCounts(&'a [HitCounts]),
    /// The path tracer on one thread count was measured.
    PathTracer(&'a PtRow),
}

/// Why the benchmark could not run.
#[derive(Debug, Error)]
pub enum BenchError {
    #[error("bench: no thread counts to measure")]
    NoThreadCounts,
    #[error("bench: thread counts must be at least 1, got {0}")]
    ZeroThreads(usize),
    #[error("bench: creating a pool of {threads} threads: {source}")]
    ThreadPool { threads: usize, source: rayon::ThreadPoolBuildError },
    #[error("bench: building Embree on {threads} thread(s): {source}")]
    Embree { threads: usize, source: AccelError },
    #[error(
        "bench: {accel} on {threads} thread(s) found {got} hits among {rays} rays in one repetition and {first} in \
         the first (the rays and the scene are fixed)"
    )]
    InconsistentHits { accel: String, threads: usize, rays: usize, first: usize, got: usize },
    #[error("bench: building the benchmark scene for the path tracer: {0}")]
    Scene(#[from] SceneError),
    #[error("bench: the path tracer on {threads} thread(s): {source}")]
    PathTracer { threads: usize, source: RenderError },
    #[error("bench: reporting progress: {0}")]
    Report(#[from] std::io::Error),
}

/// A rayon pool of `threads` workers, each with flush-to-zero and denormals-are-zero set as Embree
/// wants.
pub fn thread_pool(threads: usize) -> Result<ThreadPool, BenchError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .start_handler(|_| set_flush_denormals())
        .build()
        .map_err(|source| BenchError::ThreadPool { threads, source })
}

/// Rays handed to a worker at a time: large enough to amortise rayon's scheduling, small enough
/// to balance two threads.
const RAY_CHUNK: usize = 1024;

/// Traces every ray with `f` on `pool`; returns the timing and the number of hits (which also
/// keeps the work from being optimised away).
fn trace(pool: &ThreadPool, rays: &[Ray], f: &(dyn Fn(&Ray) -> Option<Hit> + Sync)) -> (Timing, usize) {
    pool.install(|| timed(|| rays.par_chunks(RAY_CHUNK).map(|c| c.iter().filter(|r| f(r).is_some()).count()).sum()))
}

/// Median million rays per wall-clock second and per CPU-second of tracing `rays` with `f`, and
/// the number of hits, which must be the same in every repetition: the rays and the scene are
/// fixed. `accel` and `threads` name the measurement in the error.
fn mrays(
    pool: &ThreadPool,
    reps: u32,
    rays: &[Ray],
    f: &(dyn Fn(&Ray) -> Option<Hit> + Sync),
    (accel, threads): (&str, usize),
) -> Result<(f64, f64, usize), BenchError> {
    let (_, first) = trace(pool, rays, f); // warm-up
    let mut inconsistent = None;
    let (wall, cpu) = time_median(reps, || {
        let (t, hits) = trace(pool, rays, f);
        if hits != first {
            inconsistent.get_or_insert(hits);
        }
        t
    });
    if let Some(got) = inconsistent {
        return Err(BenchError::InconsistentHits { accel: accel.to_string(), threads, rays: rays.len(), first, got });
    }
    let n = rays.len() as f64;
    Ok((n / wall / 1e6, n / cpu / 1e6, first))
}

/// What `measure_path_tracer` measured: median render time (wall, CPU), the ray and shadow-ray
/// counts of a render, and the median wall and CPU seconds of the bare loop's interleaved passes.
struct PtMeasurement {
    render: (f64, f64),
    rays: u64,
    shadow_rays: u64,
    bare_loop: (f64, f64),
}

/// Renders `scene` with the path tracer (`max_depth` bounces, `spp` samples per pixel) on
/// `threads` threads, `reps` times, each render followed by one pass of the bare Embree loop
/// (`bare`) over `bounce_rays` on `pool`: the ratio of the two then compares runs that saw the
/// same load. Measured apart (all the accelerators first, then the path tracer), the ratio moved
/// with the machine's drift: on the 2-core VM the bare loop's rate alone ranges over ±8% between
/// runs of one binary.
#[allow(clippy::too_many_arguments)]
fn measure_path_tracer(
    scene: &Scene,
    threads: usize,
    spp: u64,
    max_depth: u32,
    reps: u32,
    seed: u64,
    pool: &ThreadPool,
    bounce_rays: &[Ray],
    bare: &(dyn Fn(&Ray) -> Option<Hit> + Sync),
) -> Result<PtMeasurement, BenchError> {
    use crate::integrator::{create, Budget, NoProgress, RenderJob};
    let failed = |source| BenchError::PathTracer { threads, source };
    let mut params = toml::Table::new();
    params.insert("max_depth".into(), toml::Value::Integer(i64::from(max_depth.max(1))));
    let pt = create("pt", &params).map_err(failed)?;
    let job = RenderJob { budget: Budget::SamplesPerPixel(spp), seed, threads };
    let mut rays = (0, 0);
    let mut renders = Vec::new();
    let mut bare_passes = Vec::new();
    trace(pool, bounce_rays, bare); // warm-up, as `mrays`
    for _ in 0..reps.max(1) {
        let cpu = process_cpu_time();
        let out = pt.render(scene, &job, &NoProgress).map_err(failed)?;
        renders.push(Timing { wall: out.wall_time, cpu: process_cpu_time().saturating_sub(cpu) });
        rays = (out.counters.rays, out.counters.shadow_rays);
        bare_passes.push(trace(pool, bounce_rays, bare).0);
    }
    Ok(PtMeasurement {
        render: median_seconds(&renders),
        rays: rays.0,
        shadow_rays: rays.1,
        bare_loop: median_seconds(&bare_passes),
    })
}

/// Runs the benchmark, reporting progress to `on_event` as it goes (an error it returns stops
/// the run).
pub fn run(
    opts: &BenchOptions,
    on_event: &mut dyn FnMut(BenchEvent<'_>) -> std::io::Result<()>,
) -> Result<BenchReport, BenchError> {
    if opts.threads.is_empty() {
        return Err(BenchError::NoThreadCounts);
    }
    if let Some(&t) = opts.threads.iter().find(|&&t| t == 0) {
        return Err(BenchError::ZeroThreads(t));
    }
    let reps = opts.repetitions.max(1);
    let load_before = load_average();
    let start = Instant::now();
    let scene = BenchScene::new(opts.triangles, opts.width, opts.height, opts.seed);
    let triangles = scene.triangle_count();
    on_event(BenchEvent::SceneGenerated {
        triangles,
        meshes: scene.meshes.len(),
        seconds: start.elapsed().as_secs_f64(),
    })?;

    let max_threads = *opts.threads.iter().max().unwrap_or(&1);
    let reference = thread_pool(max_threads)?
        .install(|| EmbreeAccel::build(&scene.meshes))
        .map_err(|source| BenchError::Embree { threads: max_threads, source })?;
    let camera_rays = scene.camera_rays();
    let bounce_rays =
        thread_pool(max_threads)?.install(|| scene.bounce_rays(&reference, &camera_rays, opts.bounces, opts.seed));
    // Embree's task scheduler runs on as many threads as the most any live device asks for: with
    // this device (no thread limit) still alive, a device made with `threads=1` builds on every
    // core (0.76 CPU s in 0.41 s of wall time for the "1-thread" build). Dropped
    // here, so that each measured device is the only one and its `threads=` holds.
    drop(reference);
    on_event(BenchEvent::RaysRecorded { camera: camera_rays.len(), bounce: bounce_rays.len(), bounces: opts.bounces })?;

    let mut rows = Vec::new();
    let mut bvh_nodes = 0;
    let mut bvh_bytes = 0;
    let mut embree_bytes = 0;
    let mut path_tracer = Vec::new();
    for &threads in &opts.threads {
        let pool = thread_pool(threads)?;

        let config = format!("threads={threads}");
        let (embree_build, embree_build_cpu) = time_median(reps, || {
            pool.install(|| timed(|| EmbreeAccel::build_with_config(&scene.meshes, &config).map(drop))).0
        });
        let embree = pool
            .install(|| EmbreeAccel::build_with_config(&scene.meshes, &config))
            .map_err(|source| BenchError::Embree { threads, source })?;
        embree_bytes = embree.memory_bytes();
        let (bvh_build, bvh_build_cpu) =
            time_median(reps, || pool.install(|| timed(|| drop(Bvh::build(&scene.meshes)))).0);
        let bvh = pool.install(|| Bvh::build(&scene.meshes));
        bvh_nodes = bvh.node_count();
        bvh_bytes = bvh.memory_bytes();

        let embree_dyn: &dyn Accel = &embree;
        let bvh_dyn: &dyn Accel = &bvh;
        let bare = embree.scene();
        let mut hit_counts = Vec::new();
        let mut measure = |name: &str,
                           build: Option<(f64, f64)>,
                           f: &(dyn Fn(&Ray) -> Option<Hit> + Sync)|
         -> Result<BenchRow, BenchError> {
            let (camera, camera_cpu, camera_hits) = mrays(&pool, reps, &camera_rays, f, (name, threads))?;
            let (bounce, bounce_cpu, bounce_hits) = mrays(&pool, reps, &bounce_rays, f, (name, threads))?;
            hit_counts.push(HitCounts { accel: name.to_string(), camera_hits, bounce_hits });
            let row = BenchRow {
                accel: name.to_string(),
                threads,
                build_seconds: build.map(|b| b.0),
                build_cpu_seconds: build.map(|b| b.1),
                camera_mrays_per_s: camera,
                bounce_mrays_per_s: bounce,
                camera_mrays_per_cpu_s: camera_cpu,
                bounce_mrays_per_cpu_s: bounce_cpu,
            };
            on_event(BenchEvent::Accelerator(&row))?;
            Ok(row)
        };
        rows.push(measure("embree", Some((embree_build, embree_build_cpu)), &|r| embree_dyn.intersect(r))?);
        rows.push(measure("bvh", Some((bvh_build, bvh_build_cpu)), &|r| bvh_dyn.intersect(r))?);
        rows.push(measure("embree bare loop", None, &|r| bare.intersect(r))?);
        on_event(BenchEvent::HitCounts(&hit_counts))?;
        drop(bvh);

        if opts.pt_spp > 0 {
            // Built after the accelerator timings, which it would otherwise share memory with,
            // and dropped with this thread count's devices at the end of the iteration: Embree's
            // task scheduler runs on as many threads as the most any live device asks for, so a
            // renderable scene (no thread limit) kept alive would let a later `threads=1` device
            // build on every core (the same reason as `reference` above).
            let renderable = scene.renderable()?;
            let renderable = &renderable;
            let m = measure_path_tracer(
                renderable,
                threads,
                opts.pt_spp,
                opts.bounces + 1,
                reps,
                opts.seed,
                &pool,
                &bounce_rays,
                &|r| bare.intersect(r),
            )?;
            let total = (m.rays + m.shadow_rays) as f64;
            let bounce = bounce_rays.len() as f64;
            let (bare_mrays, bare_mrays_cpu) = (bounce / m.bare_loop.0 / 1e6, bounce / m.bare_loop.1 / 1e6);
            let (mrays_per_s, mrays_per_cpu_s) = (total / m.render.0 / 1e6, total / m.render.1 / 1e6);
            let row = PtRow {
                threads,
                rays: m.rays,
                shadow_rays: m.shadow_rays,
                seconds: m.render.0,
                cpu_seconds: m.render.1,
                mrays_per_s,
                mrays_per_cpu_s,
                bare_loop_mrays_per_s: bare_mrays,
                bare_loop_mrays_per_cpu_s: bare_mrays_cpu,
                ratio_to_bare_loop: mrays_per_s / bare_mrays,
                ratio_to_bare_loop_cpu: mrays_per_cpu_s / bare_mrays_cpu,
            };
            on_event(BenchEvent::PathTracer(&row))?;
            path_tracer.push(row);
        }
    }

    Ok(BenchReport {
        options: opts.clone(),
        cpu: cpu_model(),
        triangles,
        camera_rays: camera_rays.len(),
        bounce_rays: bounce_rays.len(),
        bvh_nodes,
        bvh_bytes,
        embree_bytes,
        rows,
        path_tracer,
        load_before,
        load_after: load_average(),
    })
}
