//! `plexus bench`: throughput of the accelerators on a deterministic, procedurally generated scene
//! of more than a million triangles.
//!
//! Measures, for Embree and the in-house BVH on each requested thread count: build time, and
//! rays per second for (a) camera rays, one per pixel, and (b) bounce rays, the rays of a
//! cosine-weighted diffuse random walk of a few bounces from the camera hits. The bounce rays are
//! recorded once (traced with Embree) so that every accelerator traces the identical set. A bare
//! loop over Embree's `rtcIntersect1` (through the concrete, inlined wrapper rather than `dyn
//! Accel`) on the same rays measures what the trait object costs. Every timing is the median of
//! several repetitions. docs/bench.md explains the output and shows measured figures.

use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use rayon::ThreadPool;
use serde::Serialize;

use crate::accel::bvh::Bvh;
use crate::accel::embree::{set_flush_denormals, EmbreeAccel};
use crate::accel::Accel;
use crate::camera::Camera;
use crate::geometry::{Frame, Hit, Ray, SurfaceInteraction, TriangleMesh};
use crate::sampling::{sample_cosine_hemisphere, Rng};

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
    /// `mrays_per_s` over the bare Embree loop's bounce-ray rate on the same thread count (target
    /// ≥ 0.7), and the same ratio per CPU-second.
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

// -------------------------------------------------------------------------------------------------
// Procedural geometry
// -------------------------------------------------------------------------------------------------

/// A smooth, deterministic pseudo-random function on the unit sphere (or plane): a sum of a few
/// sinusoids with random directions, frequencies and phases drawn from `seed`, in [-1, 1].
#[derive(Clone, Debug)]
pub struct Waves {
    waves: Vec<(Vec3, f32)>,
}

impl Waves {
    pub fn new(seed: u64, count: usize, frequency: f32) -> Waves {
        let mut rng = Rng::new(seed, 0x5741_5645);
        let waves = (0..count)
            .map(|k| {
                let dir = crate::sampling::sample_uniform_sphere([rng.uniform(), rng.uniform()]);
                let f = frequency * (1.0 + k as f32 * 0.7) * (0.75 + 0.5 * rng.uniform());
                (dir * f, rng.uniform() * std::f32::consts::TAU)
            })
            .collect();
        Waves { waves }
    }
    pub fn eval(&self, p: Vec3) -> f32 {
        let sum: f32 =
            self.waves.iter().enumerate().map(|(k, (w, phase))| (w.dot(p) + phase).sin() / (k + 1) as f32).sum();
        let norm: f32 = (1..=self.waves.len()).map(|k| 1.0 / k as f32).sum();
        sum / norm
    }
}

/// A closed latitude–longitude sphere of `2 · n_phi · (n_theta − 1)` triangles whose radius is
/// displaced by `amplitude · radius · Waves(seed)`; poles and the seam share their vertices.
pub fn displaced_sphere(
    center: Vec3,
    radius: f32,
    n_theta: u32,
    n_phi: u32,
    amplitude: f32,
    seed: u64,
) -> TriangleMesh {
    let n_theta = n_theta.max(2);
    let n_phi = n_phi.max(3);
    let waves = Waves::new(seed, 6, 3.0);
    let point = |dir: Vec3| center + dir * radius * (1.0 + amplitude * waves.eval(dir));
    let mut p = vec![point(Vec3::Y)];
    for i in 1..n_theta {
        let theta = std::f32::consts::PI * i as f32 / n_theta as f32;
        for j in 0..n_phi {
            let phi = std::f32::consts::TAU * j as f32 / n_phi as f32;
            let dir = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            p.push(point(dir));
        }
    }
    p.push(point(-Vec3::Y));
    let south = p.len() as u32 - 1;
    let ring = |i: u32, j: u32| 1 + (i - 1) * n_phi + j % n_phi;
    let mut f = Vec::with_capacity(2 * (n_phi * (n_theta - 1)) as usize);
    for j in 0..n_phi {
        f.push([0, ring(1, j + 1), ring(1, j)]);
        f.push([south, ring(n_theta - 1, j), ring(n_theta - 1, j + 1)]);
    }
    for i in 1..n_theta - 1 {
        for j in 0..n_phi {
            let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    TriangleMesh::new(p, f, None, None).expect("the generated sphere is a valid mesh")
}

/// A height field over `[min.x, max.x] × [min.y, max.y]` (in x and z) with `n × n` quads, height
/// `base + amplitude · Waves(seed)`.
pub fn terrain(min: Vec2, max: Vec2, base: f32, amplitude: f32, n: u32, seed: u64) -> TriangleMesh {
    let n = n.max(1);
    let waves = Waves::new(seed, 8, 0.6);
    let mut p = Vec::with_capacity(((n + 1) * (n + 1)) as usize);
    for i in 0..=n {
        for j in 0..=n {
            let x = min.x + (max.x - min.x) * j as f32 / n as f32;
            let z = min.y + (max.y - min.y) * i as f32 / n as f32;
            let h = base + amplitude * waves.eval(Vec3::new(x, 0.0, z));
            p.push(Vec3::new(x, h, z));
        }
    }
    let v = |i: u32, j: u32| i * (n + 1) + j;
    let mut f = Vec::with_capacity((2 * n * n) as usize);
    for i in 0..n {
        for j in 0..n {
            f.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            f.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    TriangleMesh::new(p, f, None, None).expect("the generated terrain is a valid mesh")
}

/// The inside of the box `[min, max]` as 12 triangles.
pub fn room(min: Vec3, max: Vec3) -> TriangleMesh {
    let p = (0..8)
        .map(|k| {
            Vec3::new(
                if k & 1 == 0 { min.x } else { max.x },
                if k & 2 == 0 { min.y } else { max.y },
                if k & 4 == 0 { min.z } else { max.z },
            )
        })
        .collect();
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    let f = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
    TriangleMesh::new(p, f, None, None).expect("the generated room is a valid mesh")
}

/// The benchmark scene: a closed room holding a finely tessellated terrain and a 5×5 grid of
/// displaced spheres, about `triangles` triangles in all (60% terrain, 40% spheres), and a camera
/// inside the room looking down at them. Deterministic for a given `seed`.
pub struct BenchScene {
    pub meshes: Vec<Arc<TriangleMesh>>,
    pub camera: Camera,
}

impl BenchScene {
    pub fn new(triangles: usize, width: u32, height: u32, seed: u64) -> BenchScene {
        let t = triangles.max(1000) as f32;
        let n_terrain = (0.6 * t / 2.0).sqrt().round() as u32;
        // A sphere has 2 n_phi (n_theta − 1) ≈ 4 n_theta² triangles with n_phi = 2 n_theta.
        let n_theta = ((0.4 * t / 25.0) / 4.0).sqrt().round().max(3.0) as u32;
        let mut meshes = vec![
            Arc::new(room(Vec3::new(-10.0, -1.0, -10.0), Vec3::new(10.0, 10.0, 10.0))),
            Arc::new(terrain(Vec2::splat(-10.0), Vec2::splat(10.0), 0.0, 0.8, n_terrain, seed)),
        ];
        for i in 0..5 {
            for j in 0..5 {
                let center = Vec3::new(-6.0 + 3.0 * j as f32, 2.5 + 0.3 * ((i + j) % 3) as f32, -6.0 + 3.0 * i as f32);
                let s = seed.wrapping_mul(31).wrapping_add((i * 5 + j) as u64 + 1);
                meshes.push(Arc::new(displaced_sphere(center, 1.1, n_theta, 2 * n_theta, 0.15, s)));
            }
        }
        let camera = Camera::new(
            Vec3::new(0.0, 7.0, 9.5),
            Vec3::new(0.0, 1.0, -1.0),
            Vec3::Y,
            60.0,
            width.max(1),
            height.max(1),
        );
        BenchScene { meshes, camera }
    }

    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.triangle_count()).sum()
    }

    /// One ray through the centre of every pixel, in scanline order.
    pub fn camera_rays(&self) -> Vec<Ray> {
        let (w, h) = (self.camera.width, self.camera.height);
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| self.camera.ray_through(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)))
            .collect()
    }

    /// The rays of a cosine-weighted diffuse random walk of up to `bounces` bounces from each
    /// camera ray's hit, traced with `accel`; stream `k` of `seed` drives pixel `k`'s walk.
    pub fn bounce_rays(&self, accel: &dyn Accel, camera_rays: &[Ray], bounces: u32, seed: u64) -> Vec<Ray> {
        camera_rays
            .par_iter()
            .enumerate()
            .flat_map_iter(|(k, ray)| {
                let mut rng = Rng::new(seed, k as u64);
                let mut rays = Vec::with_capacity(bounces as usize);
                let mut hit = accel.intersect(ray);
                let mut d = ray.d;
                for _ in 0..bounces {
                    let Some(h) = hit else { break };
                    let si = SurfaceInteraction::from_hit(&self.meshes[h.geom_id as usize], &h);
                    // Scatter on the side the ray came from (every surface here is two-sided).
                    let n = if si.ng.dot(d) > 0.0 { -si.ng } else { si.ng };
                    let local = sample_cosine_hemisphere([rng.uniform(), rng.uniform()]);
                    d = Frame::from_normal(n).to_world(local).normalize();
                    let next = si.spawn(d);
                    rays.push(next);
                    hit = accel.intersect(&next);
                }
                rays
            })
            .collect()
    }
}

/// The benchmark scene as a renderable [`Scene`](crate::scene::Scene): the generated meshes, all
/// diffuse white (reflectance 0.7), lit by a 6 × 6 quad light under the room's ceiling, on Embree.
/// The light, camera and material come from the scene loader (so they are built exactly as a
/// scene file would build them); the generated meshes are appended after the light.
pub fn renderable_scene(bench: &BenchScene) -> anyhow::Result<crate::scene::Scene> {
    let c = &bench.camera;
    let look_at = c.position + c.forward;
    let toml = format!(
        r#"
[camera]
position = [{}, {}, {}]
look_at = [{}, {}, {}]
up = [0.0, 1.0, 0.0]
fov = {}
resolution = [{}, {}]

[materials.white]
type = "diffuse"
reflectance = 0.7

[[shapes]]
type = "quad"
material = "white"
emission = {{ radiance = [20.0, 20.0, 20.0] }}
transform = {{ scale = [3.0, 3.0, 1.0], rotate = {{ axis = [1, 0, 0], angle = 90 }}, translate = [0.0, 9.9, 0.0] }}
"#,
        c.position.x, c.position.y, c.position.z, look_at.x, look_at.y, look_at.z, c.fov_y_degrees, c.width, c.height
    );
    let mut scene = crate::scene::load_scene_str(
        &toml,
        std::path::Path::new(""),
        "<bench scene>",
        Some(crate::accel::AccelKind::Embree),
    )
    .context("building the benchmark scene's light and camera")?
    .scene;
    anyhow::ensure!(scene.materials.len() == 1, "bench: expected one material in the benchmark scene");
    for (k, mesh) in bench.meshes.iter().enumerate() {
        scene.bounds = scene.bounds.union(&mesh.bounds());
        scene.meshes.push(Arc::clone(mesh));
        scene.shapes.push(crate::scene::ShapeInfo { name: format!("bench mesh {k}"), material: 0, light: None });
    }
    scene.accel = crate::accel::build(crate::accel::AccelKind::Embree, &scene.meshes)?;
    Ok(scene)
}

/// Renders `scene` with the path tracer (`max_depth` bounces, `spp` samples per pixel) on
/// `threads` threads, `reps` times; returns the median timings and the ray counts.
fn measure_path_tracer(
    scene: &crate::scene::Scene,
    threads: usize,
    spp: u64,
    max_depth: u32,
    reps: u32,
    seed: u64,
) -> anyhow::Result<(f64, f64, u64, u64)> {
    use crate::integrator::{create, Budget, NoProgress, RenderJob};
    let mut params = toml::Table::new();
    params.insert("max_depth".into(), toml::Value::Integer(i64::from(max_depth.max(1))));
    let pt = create("pt", &params)?;
    let job = RenderJob { budget: Budget::SamplesPerPixel(spp), seed, threads };
    let mut rays = (0, 0);
    let mut runs = Vec::new();
    for _ in 0..reps.max(1) {
        let cpu = process_cpu_time();
        let out = pt.render(scene, &job, &NoProgress)?;
        runs.push(Timing { wall: out.wall_time, cpu: process_cpu_time().saturating_sub(cpu) });
        rays = (out.counters.rays, out.counters.shadow_rays);
    }
    let (wall, cpu) = time_median(runs.len() as u32, {
        let mut it = runs.into_iter();
        move || it.next().unwrap_or(Timing { wall: Duration::ZERO, cpu: Duration::ZERO })
    });
    Ok((wall, cpu, rays.0, rays.1))
}

// -------------------------------------------------------------------------------------------------
// Measurement
// -------------------------------------------------------------------------------------------------

/// A rayon pool of `threads` workers, each with flush-to-zero and denormals-are-zero set as Embree
/// wants.
pub fn thread_pool(threads: usize) -> anyhow::Result<ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .start_handler(|_| set_flush_denormals())
        .build()
        .with_context(|| format!("creating a pool of {threads} threads"))
}

/// Rays handed to a worker at a time: large enough to amortise rayon's scheduling, small enough
/// to balance two threads.
const RAY_CHUNK: usize = 1024;

/// CPU time consumed so far by every thread of the process.
pub fn process_cpu_time() -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `clock_gettime` only writes one `timespec` into the valid, exclusively borrowed `ts`.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if status != 0 {
        return Duration::ZERO;
    }
    Duration::new(ts.tv_sec.max(0) as u64, ts.tv_nsec.clamp(0, 999_999_999) as u32)
}

/// Wall-clock and process CPU time of one run.
#[derive(Clone, Copy, Debug)]
struct Timing {
    wall: Duration,
    cpu: Duration,
}

/// Runs `f`, timing it.
fn timed<T>(f: impl FnOnce() -> T) -> (Timing, T) {
    let (wall, cpu) = (Instant::now(), process_cpu_time());
    let value = f();
    (Timing { wall: wall.elapsed(), cpu: process_cpu_time().saturating_sub(cpu) }, value)
}

/// Traces every ray with `f` on `pool`; returns the timing and the number of hits (which also
/// keeps the work from being optimised away).
fn trace(pool: &ThreadPool, rays: &[Ray], f: &(dyn Fn(&Ray) -> Option<Hit> + Sync)) -> (Timing, usize) {
    pool.install(|| timed(|| rays.par_chunks(RAY_CHUNK).map(|c| c.iter().filter(|r| f(r).is_some()).count()).sum()))
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Medians over `reps` runs of `f`'s wall-clock and CPU seconds.
fn time_median(reps: u32, mut f: impl FnMut() -> Timing) -> (f64, f64) {
    let runs: Vec<Timing> = (0..reps.max(1)).map(|_| f()).collect();
    (
        median(runs.iter().map(|t| t.wall.as_secs_f64()).collect()),
        median(runs.iter().map(|t| t.cpu.as_secs_f64()).collect()),
    )
}

/// Median million rays per wall-clock second and per CPU-second of tracing `rays` with `f`, and
/// the number of hits (the same in every repetition: the rays and the scene are fixed).
fn mrays(
    pool: &ThreadPool,
    reps: u32,
    rays: &[Ray],
    f: &(dyn Fn(&Ray) -> Option<Hit> + Sync),
) -> anyhow::Result<(f64, f64, usize)> {
    let (_, hits) = trace(pool, rays, f); // warm-up
    let mut consistent = true;
    let (wall, cpu) = time_median(reps, || {
        let (t, h) = trace(pool, rays, f);
        consistent &= h == hits;
        t
    });
    anyhow::ensure!(consistent, "bench: the same rays found a different number of hits in another repetition");
    let n = rays.len() as f64;
    Ok((n / wall / 1e6, n / cpu / 1e6, hits))
}

/// The CPU model name (Linux), for the report.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string())
}

/// The 1-minute load average (Linux), for the report.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".to_string())
}

/// Runs the benchmark, printing progress and the final Markdown table to `out`.
pub fn run(opts: &BenchOptions, out: &mut dyn Write) -> anyhow::Result<BenchReport> {
    anyhow::ensure!(!opts.threads.is_empty(), "bench: no thread counts to measure");
    anyhow::ensure!(opts.threads.iter().all(|&t| t > 0), "bench: thread counts must be at least 1");
    let reps = opts.repetitions.max(1);
    let load_before = load_average();
    let start = Instant::now();
    let scene = BenchScene::new(opts.triangles, opts.width, opts.height, opts.seed);
    let triangles = scene.triangle_count();
    writeln!(
        out,
        "scene: {triangles} triangles in {} meshes ({:.1} s to generate)",
        scene.meshes.len(),
        start.elapsed().as_secs_f64()
    )?;

    let max_threads = *opts.threads.iter().max().unwrap_or(&1);
    let reference = thread_pool(max_threads)?.install(|| EmbreeAccel::build(&scene.meshes))?;
    let camera_rays = scene.camera_rays();
    let bounce_rays =
        thread_pool(max_threads)?.install(|| scene.bounce_rays(&reference, &camera_rays, opts.bounces, opts.seed));
    writeln!(
        out,
        "rays: {} camera, {} bounce ({} bounces per path at most)",
        camera_rays.len(),
        bounce_rays.len(),
        opts.bounces
    )?;

    let mut rows = Vec::new();
    let mut bvh_nodes = 0;
    let mut bvh_bytes = 0;
    let mut embree_bytes = 0;
    let mut path_tracer = Vec::new();
    let mut pt_scene: Option<anyhow::Result<crate::scene::Scene>> = None;
    for &threads in &opts.threads {
        let pool = thread_pool(threads)?;

        let config = format!("threads={threads}");
        let (embree_build, embree_build_cpu) = time_median(reps, || {
            pool.install(|| timed(|| EmbreeAccel::build_with_config(&scene.meshes, &config).map(drop))).0
        });
        let embree = pool.install(|| EmbreeAccel::build_with_config(&scene.meshes, &config))?;
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
                           f: &(dyn Fn(&Ray) -> Option<Hit> + Sync),
                           out: &mut dyn Write|
         -> anyhow::Result<BenchRow> {
            let (camera, camera_cpu, camera_hits) = mrays(&pool, reps, &camera_rays, f)?;
            let (bounce, bounce_cpu, bounce_hits) = mrays(&pool, reps, &bounce_rays, f)?;
            hit_counts.push((name.to_string(), camera_hits, bounce_hits));
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
            writeln!(out, "{}", row_line(&row))?;
            Ok(row)
        };
        rows.push(measure("embree", Some((embree_build, embree_build_cpu)), &|r| embree_dyn.intersect(r), out)?);
        rows.push(measure("bvh", Some((bvh_build, bvh_build_cpu)), &|r| bvh_dyn.intersect(r), out)?);
        rows.push(measure("embree bare loop", None, &|r| bare.intersect(r), out)?);
        for (name, c, b) in &hit_counts {
            writeln!(out, "  {name}: {c} camera hits, {b} bounce hits")?;
        }
        drop((embree, bvh));

        if opts.pt_spp > 0 {
            let renderable = pt_scene.get_or_insert_with(|| renderable_scene(&scene));
            let renderable = renderable.as_ref().map_err(|e| anyhow::anyhow!("{e:#}"))?;
            let (seconds, cpu_seconds, r, shadow) =
                measure_path_tracer(renderable, threads, opts.pt_spp, opts.bounces + 1, reps, opts.seed)?;
            let total = (r + shadow) as f64;
            let bare = rows.iter().find(|row| row.accel == "embree bare loop" && row.threads == threads);
            let row = PtRow {
                threads,
                rays: r,
                shadow_rays: shadow,
                seconds,
                cpu_seconds,
                mrays_per_s: total / seconds / 1e6,
                mrays_per_cpu_s: total / cpu_seconds / 1e6,
                ratio_to_bare_loop: bare.map_or(f64::NAN, |b| total / seconds / 1e6 / b.bounce_mrays_per_s),
                ratio_to_bare_loop_cpu: bare.map_or(f64::NAN, |b| total / cpu_seconds / 1e6 / b.bounce_mrays_per_cpu_s),
            };
            writeln!(
                out,
                "  path tracer {} thread(s): {} rays + {} shadow rays in {:.3} s: {:.2} Mrays/s ({:.2} per CPU-s), {:.0}% of the bare loop",
                threads,
                r,
                shadow,
                seconds,
                row.mrays_per_s,
                row.mrays_per_cpu_s,
                100.0 * row.ratio_to_bare_loop
            )?;
            path_tracer.push(row);
        }
    }

    let report = BenchReport {
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
    };
    writeln!(out)?;
    write!(out, "{}", markdown_table(&report))?;
    Ok(report)
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
pub fn markdown_table(report: &BenchReport) -> String {
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
                ratio(b.build_seconds, e.build_seconds),
                ratio(b.build_cpu_seconds, e.build_cpu_seconds),
                b.camera_mrays_per_s / e.camera_mrays_per_s,
                b.camera_mrays_per_cpu_s / e.camera_mrays_per_cpu_s,
                b.bounce_mrays_per_s / e.bounce_mrays_per_s,
                b.bounce_mrays_per_cpu_s / e.bounce_mrays_per_cpu_s
            );
        }
    }
    if !report.path_tracer.is_empty() {
        s += "\n| path tracer (Embree) | threads | Mrays/s | Mrays/CPU-s | share of shadow rays | vs bare loop (bounce rays) | same, per CPU-s |\n";
        s += "| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n";
        for p in &report.path_tracer {
            s += &format!(
                "| pt, {} spp | {} | {:.2} | {:.2} | {:.0}% | {:.0}% | {:.0}% |\n",
                report.options.pt_spp,
                p.threads,
                p.mrays_per_s,
                p.mrays_per_cpu_s,
                100.0 * p.shadow_rays as f64 / (p.rays + p.shadow_rays).max(1) as f64,
                100.0 * p.ratio_to_bare_loop,
                100.0 * p.ratio_to_bare_loop_cpu
            );
        }
    }
    s += &format!(
        "\nMemory: BVH {:.1} MB ({} nodes), Embree {:.1} MB.\n",
        report.bvh_bytes as f64 / 1e6,
        report.bvh_nodes,
        report.embree_bytes as f64 / 1e6
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_meshes_are_closed_and_sized_as_documented() {
        let s = displaced_sphere(Vec3::ZERO, 1.0, 8, 16, 0.1, 3);
        assert_eq!(s.triangle_count(), 2 * 16 * 7);
        // Closed: every edge is shared by exactly two triangles, in opposite directions.
        let mut edges = std::collections::HashMap::new();
        for [a, b, c] in s.indices() {
            for e in [(*a, *b), (*b, *c), (*c, *a)] {
                *edges.entry(e).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used twice in the same direction");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
        assert_eq!(terrain(Vec2::ZERO, Vec2::ONE, 0.0, 0.1, 10, 1).triangle_count(), 200);
        let scene = BenchScene::new(100_000, 8, 6, 1);
        let n = scene.triangle_count();
        assert!((90_000..110_000).contains(&n), "{n}");
        assert_eq!(scene.camera_rays().len(), 48);
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
    }
}
