//! Ensemble MLT part 2 (issue 17): the anisotropic path and environment perturbations on real
//! scenes. The kernels' densities, Eq. 12's G ratio and the toy ensemble are tested inside the
//! library (`integrator::ensemble::{anisotropic, directional, toy_anisotropic}`); here the
//! strategies run in `emlt` and their images are compared with the path tracer's by region shares
//! (tests/common/agreement.rs states the bound: Welch's |z| < 5 with the power check).

mod common;
use common::agreement::{assert_shares_agree, render_regions, RENDERS};
use common::scenes::scene;

use plexus::integrator::{create, Budget, NoProgress, RenderJob};
use plexus::scene::Scene;

/// One render's JSON statistics.
fn stats(scene: &Scene, params: &str, mpp: u64) -> serde_json::Value {
    let params: toml::Table = toml::from_str(params).expect("test parameters");
    let job = RenderJob { budget: Budget::SamplesPerPixel(mpp), seed: 1, threads: 2 };
    let out = create("emlt", &params).expect("integrator").render(scene, &job, &NoProgress).expect("render");
    assert!(out.image.all_finite());
    out.extra_stats
}

/// (selected, accepted) of the strategy `name`.
fn acceptance(stats: &serde_json::Value, name: &str) -> (u64, u64) {
    let s = stats["strategies"].as_array().expect("strategies").iter().find(|s| s["name"] == name).expect(name);
    (s["selected"].as_u64().unwrap_or(0), s["accepted"].as_u64().unwrap_or(0))
}

/// (guided, fallback) counts of the guided strategy `name`.
fn guided(stats: &serde_json::Value, name: &str) -> (u64, u64) {
    let g = stats["ensemble"]["guided"].as_array().expect("guided").iter().find(|g| g["name"] == name).expect(name);
    (g["guided"].as_u64().unwrap_or(0), g["fallback"].as_u64().unwrap_or(0))
}

/// The ablation switch turns strategies off (they are never selected), and each new strategy runs,
/// is accepted and mostly uses its Gaussian (or vMF) fit rather than the degenerate fallback:
/// the anisotropic path perturbation on the Cornell box, the environment perturbation on the
/// environment-lit scene (both kernels).
#[test]
fn new_strategies_run_and_the_ablation_switch_turns_them_off() {
    let cornell = scene("cornell-box", 16);
    let base = "max_depth = 6\nbootstrap = 5000\nensemble_size = 64";
    let s = stats(&cornell, &format!("{base}\nperturbations = \"anisotropic\""), 64);
    let (sel, acc) = acceptance(&s, "anisotropic_path");
    let (g, f) = guided(&s, "anisotropic_path");
    println!("cornell, anisotropic only: anisotropic_path selected {sel}, accepted {acc}; fits {g} Gaussian, {f} vMF");
    assert!(sel > 1000 && acc > sel / 20, "anisotropic_path: selected {sel}, accepted {acc}");
    assert!(g > f, "more degenerate fits ({f}) than Gaussian ones ({g})");
    assert_eq!(acceptance(&s, "linear_lens").0, 0);
    assert_eq!(acceptance(&s, "linear_caustic").0, 0);
    let s = stats(&cornell, &format!("{base}\nperturbations = \"linear\""), 16);
    assert_eq!(acceptance(&s, "anisotropic_path").0, 0);
    assert!(acceptance(&s, "linear_lens").0 > 0);

    let env = scene("environment", 16);
    for kernel in ["directional", "hemispherical"] {
        let s = stats(&env, &format!("{base}\nperturbations = \"all\"\nenvironment_kernel = \"{kernel}\""), 32);
        let (sel, acc) = acceptance(&s, "environment");
        let (g, f) = guided(&s, "environment");
        println!("environment, {kernel}: selected {sel}, accepted {acc}; guided {g}, fallback {f}");
        assert!(sel > 500 && acc > sel / 20, "environment ({kernel}): selected {sel}, accepted {acc}");
        assert!(g > f, "environment ({kernel}): guided {g}, fallback {f}");
    }
}

/// emlt with only the anisotropic path perturbation (and the bidirectional mutation) agrees with
/// the path tracer by region shares on the Cornell box (|X| = |Y| = 128, 16 × 16, 2048 mutations
/// per pixel against pt at 2048 spp). Measured (2026-12-03): worst |z| = 1.89, the power check
/// passing (at 1024 both ways it failed in two regions: a 10% error reached only |z| = 4.3).
/// With the environment test below, about 100 CPU s.
#[test]
fn anisotropic_only_agrees_with_pt_on_cornell_box() {
    let cornell = scene("cornell-box", 16);
    let params = "max_depth = 8\nbootstrap = 20000\nensemble_size = 128\nperturbations = \"anisotropic\"";
    let reference = render_regions(&cornell, "pt", "max_depth = 8", 2048, 3, RENDERS);
    let renders = render_regions(&cornell, "emlt", params, 2048, 3, RENDERS);
    assert_shares_agree("emlt (anisotropic only) vs pt on cornell-box", &renders, &reference);
}

/// emlt with all strategies agrees with the path tracer by region shares on the environment-lit
/// scene (the environment perturbation's scene; 3072 mutations per pixel and pt at 3072 spp).
/// Measured: worst |z| = 1.85, the weakest region's 10% error at |z| = 5.3 (at 1024 the power
/// check failed in 11 regions).
#[test]
fn all_strategies_agree_with_pt_on_the_environment_scene() {
    let env = scene("environment", 16);
    let params = "max_depth = 8\nbootstrap = 20000\nensemble_size = 128\nperturbations = \"all\"";
    let reference = render_regions(&env, "pt", "max_depth = 8", 3072, 3, RENDERS);
    let renders = render_regions(&env, "emlt", params, 3072, 3, RENDERS);
    assert_shares_agree("emlt (all) vs pt on environment", &renders, &reference);
}

/// emlt with all strategies on the glossy and the glass Cornell boxes (2048 mutations per pixel
/// against pt at 2048 spp), by region shares. Not run by default: beyond this share of the
/// suite. Measured (2026-12-03): the glossy box agrees (worst |z| = 2.60) but the power check
/// fails in 3 regions (a 10% error reaches |z| = 2.4 … 4.6), so about 4× more mutations are
/// needed; the glass box was not reached.
#[test]
#[ignore = "beyond the suite's budget, and short of power at 2048 (see doc comment)"]
fn all_strategies_agree_with_pt_on_cornell_glossy_and_glass() {
    let params = "max_depth = 8\nbootstrap = 20000\nensemble_size = 128\nperturbations = \"all\"";
    for name in ["cornell-glossy", "cornell-glass"] {
        let s = scene(name, 16);
        let reference = render_regions(&s, "pt", "max_depth = 8", 2048, 3, RENDERS);
        let renders = render_regions(&s, "emlt", params, 2048, 3, RENDERS);
        assert_shares_agree(&format!("emlt (all) vs pt on {name}"), &renders, &reference);
    }
}
