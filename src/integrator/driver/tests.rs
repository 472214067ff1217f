use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use super::*;
use crate::integrator::{Budget, NoProgress};
use crate::spectrum::Rgb;

/// A clock that only moves when told: kernels advance it by what their work "costs", so a
/// pass's duration is the sum of its items' costs, whatever the threads and the machine's load.
#[derive(Default)]
struct FakeClock(AtomicU64);

impl FakeClock {
    fn advance(&self, by: Duration) {
        self.0.fetch_add(by.as_nanos() as u64, Ordering::SeqCst);
    }
}

impl Clock for FakeClock {
    fn now(&self) -> Duration {
        Duration::from_nanos(self.0.load(Ordering::SeqCst))
    }
}

const MS: Duration = Duration::from_millis(1);

fn job(threads: usize, seed: u64) -> RenderJob {
    RenderJob { budget: Budget::SamplesPerPixel(1), seed, threads }
}

/// A kernel that splats random values to random pixels: the worst case for determinism.
fn splat_run(threads: usize, seed: u64) -> (Accumulator, Counters, u64) {
    let driver = Driver::new(&job(threads, seed), 7, 5).expect("pool");
    let out = driver.run(
        vec![0u32; 13],
        Passes::Count(3),
        &NoProgress,
        |_| (),
        |item, visits, slot| {
            let mut rng = item.rng();
            for _ in 0..50 {
                let x = (rng.uniform() * 7.0) as usize;
                let y = (rng.uniform() * 5.0) as usize;
                // Values over 2^±30: wider than f64 can sum exactly, so the order of the
                // additions shows in the film's bits.
                let value = rng.uniform() * 2f32.powi((rng.uniform() * 60.0) as i32 - 30);
                slot.film.add(x, y, Rgb::splat(value));
            }
            *visits += 1;
            slot.counters.samples += 50;
            50
        },
        None,
    );
    assert!(out.units.iter().all(|&v| v == 3), "every unit runs once per pass");
    (out.film, out.counters, out.passes)
}

fn film_bits(film: &Accumulator) -> Vec<[u64; 3]> {
    film.sums().iter().map(|s| s.map(f64::to_bits)).collect()
}

/// Same seed: a bit-identical film for 1, 2 and 3 threads (units applied in unit order);
/// other seed: another film. With a film per slot merged in slot order instead (the wrong
/// variant), the film sums of 1 and 3 threads differ at 18 of the 35 pixels.
#[test]
fn splatting_run_depends_on_seed_only_not_on_threads() {
    let (a, ca, pa) = splat_run(3, 11);
    assert_eq!(pa, 3);
    assert_eq!(ca.samples, 13 * 3 * 50);
    for threads in [1, 2, 3] {
        let (b, cb, _) = splat_run(threads, 11);
        assert_eq!(film_bits(&a), film_bits(&b), "{threads} threads");
        assert_eq!(cb.samples, ca.samples);
    }
    let (c, _, _) = splat_run(3, 12);
    assert_ne!(film_bits(&a), film_bits(&c));
}

/// Runs 4 units on 2 threads; the unit of pass p costs `cost(p)` on the fake clock and adds 1
/// to pixel (0, 0). Returns the run and the clock.
fn timed_run(
    passes: Passes,
    progress: &dyn Progress,
    clock: Arc<FakeClock>,
    cost: impl Fn(u64) -> Duration + Sync,
) -> RunOutput<(), ()> {
    let driver = Driver::with_clock(&job(2, 1), 4, 4, clock.clone()).expect("pool");
    driver.run(
        vec![(); 4],
        passes,
        progress,
        |_| (),
        |item, _, slot| {
            clock.advance(cost(item.pass));
            slot.film.add(0, 0, Rgb::ONE);
            1
        },
        // Four units per pass each add 1 to pixel (0, 0): the normalised image reads 1.
        Some(&|at: &PassBoundary<'_, (), ()>| at.film.to_image(1.0 / (4 * at.passes_done) as f64)),
    )
}

/// 4 units × 5 ms = 20 ms per pass: a 0.1 s budget holds exactly 5 passes (the fifth is
/// predicted to end at 100 ms, which fits; a sixth would end at 120 ms).
#[test]
fn time_budget_runs_exactly_the_passes_that_fit() {
    let clock = Arc::new(FakeClock::default());
    let out = timed_run(Passes::Seconds(0.1), &NoProgress, clock.clone(), |_| 5 * MS);
    assert_eq!(out.passes, 5);
    assert_eq!(out.elapsed, 100 * MS);
    assert_eq!(clock.now(), 100 * MS);
    // A deadline on the clock, with 30 ms gone before the run (setup): 3 passes fit in 70 ms.
    let clock = Arc::new(FakeClock::default());
    clock.advance(30 * MS);
    let out = timed_run(Passes::Deadline(100 * MS), &NoProgress, clock.clone(), |_| 5 * MS);
    assert_eq!((out.passes, clock.now()), (3, 90 * MS));
    // `counted_from` turns a budget into a deadline from the render's start.
    assert_eq!(Passes::Seconds(0.1).counted_from(30 * MS), Passes::Deadline(130 * MS));
    assert_eq!(Passes::Count(3).counted_from(30 * MS), Passes::Count(3));
    assert_eq!(Passes::Seconds(1e300).counted_from(MS), Passes::Seconds(1e300));
}

/// A pass starts only if predicted to fit, the prediction being the longer of the last pass
/// and the mean pass. Budget 0.1 s:
/// - passes of 10, 10, 10, 50 ms end at 80 ms; the next is predicted at 50 ms (the last) and
///   does not start, where a mean-only rule (20 ms) would start a fifth (which, were it as slow
///   as the fourth, would end at 130 ms);
/// - two passes of 30 ms, then passes of 1 ms: the 40th ends at 98 ms, when the mean (2.45 ms)
///   predicts an end at 100.45 ms, so no 41st starts; a last-only rule would run 42 passes.
#[test]
fn a_pass_starts_only_if_predicted_to_fit() {
    let slow_fourth = |p: u64| if p == 3 { 50 * MS / 4 } else { 10 * MS / 4 };
    let clock = Arc::new(FakeClock::default());
    let out = timed_run(Passes::Seconds(0.1), &NoProgress, clock.clone(), slow_fourth);
    assert_eq!((out.passes, clock.now()), (4, 80 * MS));
    let slow_start = |p: u64| if p < 2 { 30 * MS / 4 } else { MS / 4 };
    let clock = Arc::new(FakeClock::default());
    let out = timed_run(Passes::Seconds(0.1), &NoProgress, clock.clone(), slow_start);
    assert_eq!((out.passes, clock.now()), (40, 98 * MS));
}

/// At least one pass always runs, so there is an image: a zero budget, and a deadline that
/// setup has already passed.
#[test]
fn at_least_one_pass_runs() {
    let out = timed_run(Passes::Seconds(0.0), &NoProgress, Arc::new(FakeClock::default()), |_| MS);
    assert_eq!(out.passes, 1);
    let clock = Arc::new(FakeClock::default());
    clock.advance(200 * MS);
    let out = timed_run(Passes::Deadline(100 * MS), &NoProgress, clock, |_| MS);
    assert_eq!(out.passes, 1);
}

/// Records the preview images' pixel (0, 0) and the clock when each arrived.
struct Recorder {
    every: f64,
    clock: Arc<FakeClock>,
    previews: Mutex<Vec<(Duration, f32)>>,
}

impl Progress for Recorder {
    fn set_total(&self, _: u64) {}
    fn advance(&self, _: u64) {}
    fn message(&self, _: &str) {}
    fn preview_interval(&self) -> Option<f64> {
        Some(self.every)
    }
    fn preview(&self, image: &Image) {
        self.previews.lock().expect("lock").push((self.clock.now(), image.pixels[0].x));
    }
}

/// Previews arrive at pass boundaries once at least the interval has passed since the last
/// (or the start), and show the normalised image so far. 20 ms passes, 50 ms interval, 30
/// passes: a preview after every third pass (60, 120, ..., 600 ms), each reading exactly 1.
#[test]
fn previews_are_rate_limited_and_normalised() {
    let clock = Arc::new(FakeClock::default());
    let recorder = Recorder { every: 0.05, clock: clock.clone(), previews: Mutex::new(Vec::new()) };
    let out = timed_run(Passes::Count(30), &recorder, clock, |_| 5 * MS);
    assert_eq!(out.passes, 30);
    let previews = recorder.previews.into_inner().expect("lock");
    let expected: Vec<(Duration, f32)> = (1..=10).map(|k| (60 * k * MS, 1.0)).collect();
    assert_eq!(previews, expected);
}

/// The image-space render on the fake clock: setup between `new` and `run` counts in the time
/// budget; the image and previews are the film over the samples per pixel. 16×16 pixels (one
/// tile), 0.1 ms per sample: 25.6 ms per pass. With 40 ms of setup in a 0.1 s budget, two
/// passes fit (ending at 91.2 ms); counted from the run's start instead, three would.
#[test]
fn image_render_counts_setup_in_the_budget_and_normalises() {
    let clock = Arc::new(FakeClock::default());
    let recorder = Recorder { every: 1e-9, clock: clock.clone(), previews: Mutex::new(Vec::new()) };
    let job = RenderJob { budget: Budget::Seconds(0.1), seed: 5, threads: 2 };
    let render = ImageRender::with_clock(&job, 16, 16, &recorder, clock.clone()).expect("render");
    clock.advance(40 * MS);
    let (run, _) = render.run(
        |_| (),
        |x, y, _, slot| {
            clock.advance(Duration::from_micros(100));
            slot.film.add(x as usize, y as usize, Rgb::splat(0.5));
        },
    );
    assert_eq!(run.output.extra_stats["passes"], 2);
    assert_eq!(run.output.extra_stats["spp"], 2);
    assert_eq!(run.scale, 0.5);
    assert_eq!(run.output.wall_time, Duration::from_micros(91_200));
    assert_eq!(run.output.counters.samples, 2 * 256);
    assert!(run.output.image.pixels.iter().all(|p| *p == Rgb::splat(0.5)));
    let previews = recorder.previews.into_inner().expect("lock");
    let times: Vec<Duration> = previews.iter().map(|p| p.0).collect();
    assert_eq!(times, [Duration::from_micros(65_600), Duration::from_micros(91_200)]);
    assert!(previews.iter().all(|p| p.1 == 0.5), "{previews:?}");
}

#[test]
fn a_film_beyond_u32_pixel_indices_is_an_error() {
    let err = Driver::new(&job(1, 1), 70_000, 70_000).err().expect("too large");
    assert!(err.to_string().contains("70000×70000"), "{err}");
}

/// The library refuses what the CLI refuses, for callers that skip the CLI: a sample budget
/// whose product with the pixels passes 2^53 (it overflowed `progress.set_total` before), a
/// time budget beyond 30 days, more than 1024 threads.
#[test]
fn budgets_and_threads_beyond_the_limits_are_errors_before_any_work() {
    let over = RenderJob { budget: Budget::SamplesPerPixel(1 << 50), seed: 1, threads: 1 };
    let err = ImageRender::new(&over, 16, 16, &crate::integrator::NoProgress).err().expect("too many samples");
    assert!(err.to_string().contains("2^53"), "{err}");
    let long = RenderJob { budget: Budget::Seconds(1e20), seed: 1, threads: 1 };
    assert!(ImageRender::new(&long, 4, 4, &crate::integrator::NoProgress).is_err());
    let err = Driver::new(&job(2000, 1), 4, 4).err().expect("too many threads");
    assert!(err.to_string().contains("1024"), "{err}");
}

#[test]
fn image_plan_covers_the_film_and_the_budget() {
    let plan = ImagePlan::new(37, 20, Budget::SamplesPerPixel(1000));
    let covered: u64 = plan.tiles.iter().map(Tile::pixel_count).sum();
    assert_eq!(covered, 37 * 20);
    let Passes::Count(n) = plan.passes else { panic!("sample budget gives a pass count") };
    assert_eq!((0..n).map(|p| plan.spp_in_pass(p)).sum::<u64>(), 1000);
    assert_eq!(plan.spp_after(n), 1000);
    assert_eq!(plan.spp_after(0), 0);
    // Shards: the passes' samples split between the sets and add up to the budget.
    let per_set = |k| plan.spp_in_set(PassSet { index: k, count: 3 }, n);
    assert_eq!(per_set(0) + per_set(1) + per_set(2), 1000);
    // A resumed plan after 2 full passes continues the same schedule to the same end.
    let resumed =
        ImagePlan::resumed(37, 20, Budget::SamplesPerPixel(1000), plan.spp_per_pass, 2, 2 * plan.spp_per_pass);
    assert_eq!(resumed.passes, plan.passes);
    assert_eq!(
        (2..n).map(|p| resumed.spp_in_pass(p)).collect::<Vec<_>>(),
        (2..n).map(|p| plan.spp_in_pass(p)).collect::<Vec<_>>()
    );
    let small = ImagePlan::new(1920, 1080, Budget::SamplesPerPixel(4));
    assert_eq!(small.spp_per_pass, 1);
}
