//! Budgets and limits are checked before any work (issue 19): every input below once panicked,
//! aborted on allocation, rendered black or ran for ever on main, and is now one line
//! `error: ...` with exit code 2 naming the option or key, the value and the valid range.
//!
//! Each test gives the binary a 4×4 scene, so a refusal costs only the scene load (the whole file
//! runs in about a second). The old behaviour, checked once by hand with `timeout 5`: `--time 1e20`
//! panicked (exit 1); `--integrator mmlt --spp 18014398509481984`, `--spp 2^63`,
//! `--set max_depth=100000` (mmlt) and `converge --times 1e30` were still running after 5 s;
//! `--set chains=10^12` aborted (exit 134); `--threads 2000` took 4.4 s for 16 pixels. No test waits
//! on a clock: a regression shows as a hang the suite's runner reports, not as a flaky bound.

use std::path::Path;

use crate::common::binary::{plexus, temp_dir, tiny_scene};

/// Writes the scene at `resolution` with `extra` into `dir` as `scene.toml`.
fn write_scene(dir: &Path, resolution: &str, extra: &str) {
    let text = tiny_scene(resolution, extra);
    std::fs::write(dir.join("scene.toml"), text).expect("write scene");
}

/// Runs `args` (after the verb, on `scene.toml` at `resolution`) and asserts a refusal: exit code
/// 2, exactly one stderr line starting `error: ` that contains every one of `culprits`, and no
/// output written.
fn assert_refused(name: &str, resolution: &str, extra: &str, args: &[&str], culprits: &[&str]) {
    let dir = temp_dir(name);
    write_scene(dir.path(), resolution, extra);
    let o = plexus(args, dir.path());
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: one line expected: {err}");
    assert!(err.starts_with("error: "), "{err}");
    for c in culprits {
        assert!(err.contains(c), "{args:?}: the message should name '{c}': {err}");
    }
    assert!(!dir.path().join("o.exr").exists(), "{args:?}: nothing may be written");
}

fn render<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["render", "scene.toml", "--out", "o.exr"];
    args.extend_from_slice(extra);
    args
}

#[test]
fn time_budgets_beyond_30_days_or_not_positive_are_refused() {
    for time in ["1e20", "-1", "NaN", "inf", "2592001"] {
        assert_refused("time", "[4, 4]", "", &render(&["--time", time]), &["--time", "2592000"]);
    }
    assert_refused("render-time", "[4, 4]", "[render]\ntime = 1e20", &render(&[]), &["render.time", "1e20"]);
}

#[test]
fn an_mlt_budget_whose_mutations_times_pixels_overflows_is_refused() {
    // 2^54 mutations per pixel × 16 pixels overflows u64: it once rendered black with "0 samples".
    let args = render(&["--integrator", "mmlt", "--spp", "18014398509481984"]);
    assert_refused("mmlt-spp", "[4, 4]", "", &args, &["--spp", "18014398509481984", "2^53"]);
}

#[test]
fn a_sample_budget_beyond_2_to_the_53_total_samples_is_refused() {
    // 2^63 samples per pixel: the path tracer ran for ever. 2^53 / 16 pixels = 2^49 is the most.
    let args = render(&["--spp", "9223372036854775808"]);
    assert_refused("pt-spp", "[4, 4]", "", &args, &["--spp", "9223372036854775808", "562949953421312"]);
    assert_refused("pt-spp-edge", "[4, 4]", "", &render(&["--spp", "562949953421313"]), &["562949953421312"]);
}

#[test]
fn a_converge_study_beyond_30_days_is_refused() {
    // Refused before the reference is read, so the reference need not exist.
    let args = ["converge", "scene.toml", "--reference", "ref.exr", "--integrators", "pt", "--times", "1e30"];
    assert_refused("converge", "[4, 4]", "", &args, &["--times", "1e30", "2592000"]);
    // Each budget within the limit, the study (3 seeds × 2 integrators × 2e6 s) not.
    let args = ["converge", "scene.toml", "--reference", "ref.exr", "--integrators", "pt,bdpt", "--times", "2e6"];
    assert_refused("converge-total", "[4, 4]", "", &args, &["--times", "6 renders"]);
}

#[test]
fn thread_counts_beyond_1024_are_refused() {
    assert_refused("threads", "[4, 4]", "", &render(&["--threads", "2000"]), &["--threads", "2000", "1024"]);
    let extra = "[render]\nthreads = 4611686018427387904";
    assert_refused("render-threads", "[4, 4]", extra, &render(&[]), &["render.threads", "4611686018427387904", "1024"]);
}

#[test]
fn mlt_chains_depth_and_bootstrap_beyond_their_bounds_are_refused() {
    for integrator in ["pssmlt", "mmlt", "rjmlt"] {
        let cases = [
            ("chains=1000000000000", "16777216"),
            ("max_depth=100000", "1024"),
            ("bootstrap=1000000000000000", "4294967296"),
        ];
        for (set, bound) in cases {
            let key = set.split('=').next().expect("key");
            let args = render(&["--integrator", integrator, "--set", set]);
            assert_refused("mlt-set", "[4, 4]", "", &args, &[integrator, key, bound]);
        }
    }
}

/// The memory refusals need more memory than the machine may give the process: 208 GiB for the
/// 65536² film (film sums 144 GiB, one pass of splat buffers 64 GiB), 484 GiB for 100000². A test
/// machine with that much available memory would render instead (and fail this test).
#[test]
fn a_film_larger_than_the_available_memory_is_refused_with_the_estimate() {
    let args = render(&["--spp", "1"]);
    assert_refused("film-65536", "[65536, 65536]", "", &args, &["65536x65536", "208.00 GiB", "available"]);
    let args = ["reference", "scene.toml", "--spp", "1", "--resolution", "100000x100000", "--out", "o.exr"];
    assert_refused("reference-100000", "[4, 4]", "", &args, &["100000x100000", "484.29 GiB", "available"]);
}

#[test]
fn an_mlt_bootstrap_that_does_not_fit_is_refused_with_the_estimate() {
    // Within the bootstrap's bound, but 4·10^9 paths × 9 depths × 12 bytes = 402 GiB.
    let args = render(&["--integrator", "mmlt", "--set", "bootstrap=4000000000"]);
    assert_refused("mlt-memory", "[4, 4]", "", &args, &["4x4", "402.34 GiB", "bootstrap"]);
}

/// emlt's ensembles are in the estimate: 2 × 2^23 chains of two paths of 1026 vertices each (and
/// the views of Y) are petabytes, refused before the bootstrap starts. Before emlt had a branch in
/// `integrator::memory_estimate`, the same command started rendering (its bootstrap, then 2^24 chains'
/// allocations).
#[test]
fn emlt_ensembles_that_do_not_fit_are_refused_with_the_estimate() {
    let args = render(&["--integrator", "emlt", "--set", "ensemble_size=8388608", "--set", "max_depth=1024"]);
    assert_refused("emlt-memory", "[4, 4]", "", &args, &["4x4", "chains", "available", "ensemble_size"]);
}

#[test]
fn info_prints_the_render_memory_estimate() {
    let dir = temp_dir("info");
    write_scene(dir.path(), "[65536, 65536]", "");
    let o = plexus(&["info", "scene.toml"], dir.path());
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("render:      212992.00 MiB for pt at 65536x65536 (scene 0.00, film"), "{out}");
}

/// The estimate counts the scene (meshes, accelerator, lights, textures) with the render's
/// buffers: a sphere of 2^16 triangles shows in `info --json` and in the total the refusal checks.
/// Fails on the old code (94429d5), whose render estimate had no scene part. The corner copies
/// (36 bytes a triangle) are made after the accelerator's build, so the larger of them and the
/// build's temporaries counts.
#[test]
fn the_estimate_counts_the_scene_meshes_and_accelerator() {
    let dir = temp_dir("info-scene");
    let sphere = "[[shapes]]\ntype = \"sphere\"\nsubdivisions = 128\nmaterial = \"floor\"\n";
    write_scene(dir.path(), "[4, 4]", sphere);
    for accel in ["embree", "bvh"] {
        let o = plexus(&["info", "scene.toml", "--json", "--accel", accel], dir.path());
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
        let m = &v["render_memory"];
        let part = |k: &str| m["scene"][k].as_u64().unwrap_or_else(|| panic!("scene.{k} in {m}"));
        // 128 rings × 256 segments × 2 triangles: 12 bytes of indices each, plus the vertices.
        assert!(part("meshes") > 65536 * 12, "{accel}: {m}");
        assert!(part("accel") > 0, "{accel}: {m}");
        assert_eq!(part("textures"), 0, "{accel}: {m}");
        assert_eq!(Some(part("corners")), v["triangles"].as_u64().map(|t| t * 36), "{accel}: {m}");
        let transient = part("accel_build").max(part("corners"));
        let scene = part("meshes") + part("accel") + transient + part("lights") + part("textures");
        let render = ["film", "pass_buffers", "chains"].iter().map(|k| m[k].as_u64().expect("part")).sum::<u64>();
        assert_eq!(m["total"].as_u64(), Some(scene + render), "{accel}: {m}");
    }
}
