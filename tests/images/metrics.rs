//! `metrics::compare` on synthetic images whose errors are known in closed form.
//!
//! Every value used (0.5, 0.25, 0.125, ...) is exact in f32, and the metrics accumulate in f64, so
//! the closed forms hold to rounding of a few f64 operations: a relative tolerance of 1e-12 fails
//! on any real mistake (a wrong denominator, a missing channel, an off-by-one pixel count) while
//! admitting summation rounding.

use glam::Vec3;
use plexus::film::Image;
use plexus::metrics::compare::{
    colour_map, compare_images, false_colour_error, psnr_from_mse, relative_error_map, CompareError, DEFAULT_EPSILON,
};

fn close(got: f64, want: f64, what: &str) {
    let tol = 1e-12 * want.abs().max(1e-300);
    assert!((got - want).abs() <= tol, "{what}: got {got:e}, want {want:e}");
}

fn constant(w: usize, h: usize, v: Vec3) -> Image {
    Image { width: w, height: h, pixels: vec![v; w * h] }
}

/// B constant c, A = B + δ (all channels) on every fourth pixel: a fraction f = 1/4 exactly.
#[test]
fn constant_reference_with_offset_on_a_quarter_of_pixels() {
    let (w, h) = (16, 12);
    let (c, delta, f) = (0.5f64, 0.25f64, 0.25f64);
    let b = constant(w, h, Vec3::splat(c as f32));
    let mut a = b.clone();
    for (i, p) in a.pixels.iter_mut().enumerate() {
        if i % 4 == 0 {
            *p += Vec3::splat(delta as f32);
        }
    }
    let eps = DEFAULT_EPSILON;
    let m = compare_images(&a, &b, eps).unwrap();
    close(m.mse, f * delta * delta, "mse = f·δ²");
    close(m.relmse, f * delta * delta / (c * c + eps), "relmse = f·δ²/(c²+ε)");
    close(m.peak, c, "peak = max of reference");
    close(m.psnr.unwrap(), 10.0 * (c * c / (f * delta * delta)).log10(), "psnr = 10·log10(c²/mse)");
    close(m.mean_ratio, (c + f * delta) / c, "ratio of means = (c + f·δ)/c");
    for k in 0..3 {
        close(m.mean_ratio_rgb[k], (c + f * delta) / c, "per-channel ratio of means");
    }
    close(m.mean_a, c + f * delta, "mean of A");
    close(m.mean_b, c, "mean of B");
    assert_eq!((m.nonfinite_a, m.nonfinite_b), (0, 0));
    // The per-pixel map averages to the same relMSE.
    let map = relative_error_map(&a, &b, eps).unwrap();
    close(map.iter().sum::<f64>() / map.len() as f64, m.relmse, "mean of per-pixel map = relmse");
}

/// An error in one channel only counts a third of a pixel's channels: MSE = f·δ²/3.
#[test]
fn error_in_one_channel_is_averaged_over_three() {
    let (c, delta) = (0.5f64, 0.125f64);
    let b = constant(8, 8, Vec3::new(c as f32, 2.0 * c as f32, 0.0));
    let mut a = b.clone();
    // Half the pixels (the left half of every row) get +δ in green.
    for y in 0..8 {
        for x in 0..4 {
            a.pixels[y * 8 + x].y += delta as f32;
        }
    }
    let eps = 0.5; // a non-default ε, to show it is honoured
    let m = compare_images(&a, &b, eps).unwrap();
    close(m.mse, 0.5 * delta * delta / 3.0, "mse");
    let g = 2.0 * c;
    close(m.relmse, 0.5 * delta * delta / (g * g + eps) / 3.0, "relmse uses the green reference value");
    close(m.peak, g, "peak is the largest channel of the reference");
    close(m.mean_ratio_rgb[0], 1.0, "red ratio");
    close(m.mean_ratio_rgb[1], (g + 0.5 * delta) / g, "green ratio");
    assert!(m.mean_ratio_rgb[2].is_nan(), "blue reference mean is 0: ratio undefined");
    close(m.mean_ratio, (c + g + 0.5 * delta) / (c + g), "overall ratio");
}

/// A = k·B for a non-constant B: ratio of means is exactly k, MSE = (k−1)²·mean(B²).
#[test]
fn scaled_image_has_ratio_k() {
    let (w, h) = (10, 7);
    let b = Image {
        width: w,
        height: h,
        pixels: (0..w * h).map(|i| Vec3::new(i as f32 * 0.125, (i % 5) as f32 * 0.25, 1.0 + (i % 3) as f32)).collect(),
    };
    let k = 1.5f64;
    let a = Image { width: w, height: h, pixels: b.pixels.iter().map(|p| *p * k as f32).collect() };
    let m = compare_images(&a, &b, DEFAULT_EPSILON).unwrap();
    close(m.mean_ratio, k, "ratio of means");
    let mean_b2: f64 = b.pixels.iter().flat_map(|p| [p.x as f64, p.y as f64, p.z as f64]).map(|v| v * v).sum::<f64>()
        / (3 * w * h) as f64;
    close(m.mse, (k - 1.0) * (k - 1.0) * mean_b2, "mse = (k-1)^2 mean(B^2)");
    let rel: f64 = b
        .pixels
        .iter()
        .flat_map(|p| [p.x as f64, p.y as f64, p.z as f64])
        .map(|v| (k - 1.0) * (k - 1.0) * v * v / (v * v + DEFAULT_EPSILON))
        .sum::<f64>()
        / (3 * w * h) as f64;
    close(m.relmse, rel, "relmse");
}

#[test]
fn identical_images_have_zero_error_and_infinite_psnr() {
    let b = constant(5, 3, Vec3::new(0.25, 0.5, 4.0));
    let m = compare_images(&b, &b, DEFAULT_EPSILON).unwrap();
    assert_eq!(m.mse, 0.0);
    assert_eq!(m.relmse, 0.0);
    assert_eq!(m.psnr, Some(f64::INFINITY));
    assert_eq!(m.mean_ratio, 1.0);
}

/// On a black reference relMSE reduces to δ²/ε and PSNR has no peak to refer to.
#[test]
fn black_reference_relmse_is_delta_squared_over_epsilon() {
    let b = Image::new(4, 4);
    let a = constant(4, 4, Vec3::splat(0.25));
    let m = compare_images(&a, &b, DEFAULT_EPSILON).unwrap();
    close(m.relmse, 0.0625 / DEFAULT_EPSILON, "relmse on black");
    close(m.mse, 0.0625, "mse on black");
    assert_eq!(m.psnr, None);
    assert_eq!(psnr_from_mse(1.0, 0.0), None);
    close(psnr_from_mse(0.01, 1.0).unwrap(), 20.0, "psnr for mse 1e-2 at peak 1 is 20 dB");
}

#[test]
fn nonfinite_pixels_are_counted_and_poison_the_metrics() {
    let b = constant(3, 3, Vec3::splat(1.0));
    let mut a = b.clone();
    a.pixels[4].x = f32::NAN;
    a.pixels[5].z = f32::INFINITY;
    let m = compare_images(&a, &b, DEFAULT_EPSILON).unwrap();
    assert_eq!((m.nonfinite_a, m.nonfinite_b), (2, 0));
    assert!(!m.mse.is_finite());
}

#[test]
fn size_mismatch_is_a_clear_error() {
    let a = Image::new(4, 3);
    let b = Image::new(3, 4);
    let err = compare_images(&a, &b, DEFAULT_EPSILON).unwrap_err();
    assert_eq!(err, CompareError::SizeMismatch { a_w: 4, a_h: 3, b_w: 3, b_h: 4 });
    assert_eq!(err.to_string(), "image sizes differ: 4x3 (test image) vs 3x4 (reference)");
    assert!(relative_error_map(&a, &b, DEFAULT_EPSILON).is_err());
    assert!(false_colour_error(&a, &b, DEFAULT_EPSILON).is_err());
    assert_eq!(compare_images(&Image::new(0, 0), &Image::new(0, 0), 1e-2), Err(CompareError::Empty));
}

/// Zero error maps to the bottom of the colour map, relative error ≥ 1 to the top, 1e-2 (the middle
/// of the log range [1e-4, 1]) to the middle, and a NaN pixel to magenta.
#[test]
fn false_colour_image_uses_the_log_range() {
    let b = constant(4, 1, Vec3::splat(1.0));
    let eps = DEFAULT_EPSILON;
    // (a−1)²/(1+ε) per channel: 0, 10 (clamped to top), 1e-2, NaN.
    let d_mid = (1e-2 * (1.0 + eps)).sqrt() as f32;
    let a = Image {
        width: 4,
        height: 1,
        pixels: vec![Vec3::splat(1.0), Vec3::splat(5.0), Vec3::splat(1.0 + d_mid), Vec3::splat(f32::NAN)],
    };
    let img = false_colour_error(&a, &b, eps).unwrap();
    assert_eq!((img.width, img.height), (4, 1));
    assert_eq!(img.pixels[0], colour_map(0.0));
    assert_eq!(img.pixels[1], colour_map(1.0));
    assert!((img.pixels[2] - colour_map(0.5)).abs().max_element() < 1e-5);
    assert_eq!(img.pixels[3], Vec3::new(1.0, 0.0, 1.0));
}

/// The full figure with text (a system font when one exists, else none) is written and non-trivial.
#[test]
fn convergence_plot_is_written() {
    use plexus::metrics::converge::{summarize, RunRecord};
    let mut records = Vec::new();
    for (name, k) in [("pt", 1.0), ("bdpt", 0.5)] {
        for &t in &[1.0, 2.0, 4.0] {
            for seed in 0..3u64 {
                let mse = k / t * (1.0 + 0.1 * seed as f64);
                records.push(RunRecord {
                    integrator: name.into(),
                    seed,
                    budget: t,
                    wall_time: t * 1.01,
                    samples_or_mutations: (t * 16.0) as u64,
                    rays: 1000,
                    mse,
                    relmse: 3.0 * mse,
                    nonfinite_dropped: 0,
                });
            }
        }
    }
    let tmp = tempfile::tempdir().expect("temp dir");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("converge.png");
    plexus::metrics::plot::plot_convergence(&path, &summarize(&records), "synthetic 1/t").expect("plot");
    assert!(std::fs::metadata(&path).expect("png").len() > 1000);
    if let Ok(keep) = std::env::var("PLEXUS_KEEP_PLOT") {
        std::fs::copy(&path, keep).expect("copy plot");
    }
}

/// The wall time a render reports is its own: never more than the time measured around the call.
/// (That a time budget is kept — passes start only if predicted to fit, setup inside the budget —
/// is tested exactly on a fake clock in `integrator::driver`'s unit tests; the wall-clock figures
/// of `--time` renders are measured by scripts/bench-time-budgets.sh.) Every integrator, 1 spp on
/// a 32×32 Cornell box, MLT with a 2000-path bootstrap: about 1 s in all.
#[test]
fn reported_wall_time_is_within_the_measured_time() {
    use plexus::camera::Camera;
    use plexus::integrator::{create, Budget, NoProgress, RenderJob, INTEGRATOR_NAMES};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml");
    let mut scene = plexus::scene::load_scene(&path, None).expect("scene").scene;
    let c = &scene.camera;
    scene.camera = Camera::new(c.position, c.position + c.forward, c.up, c.fov_y_degrees, 32, 32);
    for name in INTEGRATOR_NAMES {
        let params: toml::Table =
            if name.ends_with("mlt") { toml::from_str("bootstrap = 2000").expect("toml") } else { toml::Table::new() };
        let integrator = create(name, &params).expect("integrator");
        let job = RenderJob { budget: Budget::SamplesPerPixel(1), seed: 1, threads: 2 };
        let start = std::time::Instant::now();
        let out = integrator.render(&scene, &job, &NoProgress).expect("render");
        let wall = start.elapsed().as_secs_f64();
        assert!(out.wall_time.as_secs_f64() <= wall + 1e-3, "{name}: reported time exceeds the measured one");
    }
}

/// Previews (`Progress::preview`, behind `plexus render --preview-every`) are the render's
/// normalised image so far: for every integrator, with an interval of 1 ns (so a preview at every
/// pass boundary, whatever the machine's speed) and a sample budget of at least 3 passes, at least
/// 3 arrive, and the last one's mean is within 10% of the final image's (an unnormalised film
/// would be off by the sample count; for MLT the remaining difference is b's refinement by the
/// last pass). A sample-budget render with previews is bit-identical to one without: previews only
/// read the films. 48×48: 87 spp (3 passes of 29) for pt, bdpt and light, 16 mutations per pixel
/// (16 passes) for MLT; 13 s in all on 2 cores at load average 15.
#[test]
fn previews_are_normalised_and_do_not_change_the_image() {
    use plexus::camera::Camera;
    use plexus::integrator::{create, Budget, NoProgress, Progress, RenderJob, INTEGRATOR_NAMES};
    use std::sync::Mutex;
    struct Recorder(Mutex<Vec<f64>>);
    impl Progress for Recorder {
        fn set_total(&self, _: u64) {}
        fn advance(&self, _: u64) {}
        fn message(&self, _: &str) {}
        fn preview_interval(&self) -> Option<f64> {
            Some(1e-9)
        }
        fn preview(&self, image: &Image) {
            let m = image.mean();
            self.0.lock().expect("lock").push((m[0] + m[1] + m[2]) / 3.0);
        }
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml");
    let mut scene = plexus::scene::load_scene(&path, None).expect("scene").scene;
    let c = &scene.camera;
    scene.camera = Camera::new(c.position, c.position + c.forward, c.up, c.fov_y_degrees, 48, 48);
    for name in INTEGRATOR_NAMES {
        let params: toml::Table =
            if name.ends_with("mlt") { toml::from_str("bootstrap = 20000").unwrap() } else { toml::Table::new() };
        let integrator = create(name, &params).expect("integrator");
        let recorder = Recorder(Mutex::new(Vec::new()));
        let spp = if name.ends_with("mlt") { 16 } else { 87 };
        let job = RenderJob { budget: Budget::SamplesPerPixel(spp), seed: 1, threads: 2 };
        let out = integrator.render(&scene, &job, &recorder).expect("render");
        let m = out.image.mean();
        let final_mean = (m[0] + m[1] + m[2]) / 3.0;
        let previews = recorder.0.into_inner().expect("lock");
        println!("{name}: {} previews, last mean {:?}, final {final_mean}", previews.len(), previews.last());
        assert!(previews.len() >= 3, "{name}: {} previews", previews.len());
        let last = *previews.last().expect("a preview");
        assert!((last / final_mean - 1.0).abs() < 0.1, "{name}: preview mean {last} vs final {final_mean}");
        if *name == "pt" || *name == "mmlt" {
            let job = RenderJob { budget: Budget::SamplesPerPixel(16), seed: 3, threads: 2 };
            let with = integrator.render(&scene, &job, &Recorder(Mutex::new(Vec::new()))).expect("render").image;
            let without = integrator.render(&scene, &job, &NoProgress).expect("render").image;
            assert!(with.pixels == without.pixels, "{name}: previews changed the image");
        }
    }
}
