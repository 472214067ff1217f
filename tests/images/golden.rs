//! Every integrator's image of one small scene at a fixed seed, as hashes: the record of what
//! [`plexus::state::SAMPLING_REVISION`] means. States carry the revision, and `resume` and `merge`
//! refuse another one, because a render continued with other random numbers would blend two
//! estimators with exit 0. That gate works only if the revision moves whenever the numbers do:
//! this test fails on any change to an image until the revision is bumped and the table below is
//! regenerated (`GOLDEN_PRINT=1 cargo test --release --test images golden:: -- --nocapture` prints it).
//!
//! The renders use the in-house BVH (`accel = "bvh"`), whose arithmetic is plexus's own, not
//! Embree's (whose kernels differ between CPU generations), on one thread. The BVH's triangle test
//! takes an AVX2+FMA path where the CPU has one, and its roundings differ from the portable path:
//! the table holds for x86-64 CPUs with AVX2 and FMA, and the test says so and stops elsewhere.

use plexus::integrator::{create, Budget, NoProgress, RenderJob};
use plexus::scene::load_scene_str;
use sha2::{Digest, Sha256};

/// The table's revision and each integrator's image hash at it.
const GOLDEN_REVISION: u32 = 4;
const GOLDEN: &[(&str, &str)] = &[
    ("pt", "2ea8e3e3700a6bd8"),
    ("bdpt", "98648d7d2e0dee10"),
    ("light", "20f2525990beb762"),
    ("pssmlt", "4476875c61a1fbbd"),
    ("mmlt", "4622adef7204f63a"),
    ("rjmlt", "53f88c18754d79a7"),
    ("pmlt", "116aa2e771e52a3e"),
    ("emlt", "1f5ae60b1f57c971"),
];

/// The built-in Cornell box at 12×12, accelerated by the BVH.
fn scene() -> plexus::scene::Scene {
    let text = plexus::scene::CORNELL_BOX_TOML.replace("resolution = [256, 256]", "resolution = [12, 12]");
    assert!(text.contains("[12, 12]"), "the built-in scene's resolution line moved");
    let loaded = load_scene_str(&text, std::path::Path::new(""), "golden", Some(plexus::accel::AccelKind::Bvh))
        .expect("the built-in scene loads");
    loaded.scene
}

/// SHA-256 (first 16 hex digits) of the image's f32 bits, rendered by `integrator` at 4 samples
/// (mutations) per pixel, seed 3, one thread, with small chain settings.
fn image_hash(scene: &plexus::scene::Scene, integrator: &str) -> String {
    let params = match integrator {
        "pssmlt" | "mmlt" | "rjmlt" | "pmlt" => "max_depth = 5\nbootstrap = 2000\nchains = 16",
        "emlt" => "max_depth = 5\nbootstrap = 2000",
        _ => "max_depth = 5",
    };
    let table: toml::Table = toml::from_str(params).expect("parameters");
    let job = RenderJob { budget: Budget::SamplesPerPixel(4), seed: 3, threads: 1 };
    let out = create(integrator, &table).expect("integrator").render(scene, &job, &NoProgress).expect("render");
    let mut h = Sha256::new();
    for p in &out.image.pixels {
        for c in p.to_array() {
            h.update(c.to_bits().to_le_bytes());
        }
    }
    h.finalize().iter().take(8).map(|b| format!("{b:02x}")).collect()
}

#[test]
fn images_change_only_with_the_sampling_revision() {
    if !(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")) {
        eprintln!("golden: this CPU has no AVX2+FMA; the table is for CPUs that do (see the module doc)");
        return;
    }
    let scene = scene();
    let hashes: Vec<(&str, String)> =
        plexus::integrator::INTEGRATOR_NAMES.iter().map(|name| (*name, image_hash(&scene, name))).collect();
    if std::env::var_os("GOLDEN_PRINT").is_some() {
        println!("const GOLDEN_REVISION: u32 = {};", plexus::state::SAMPLING_REVISION);
        println!("const GOLDEN: &[(&str, &str)] = &[");
        for (name, hash) in &hashes {
            println!("    (\"{name}\", \"{hash}\"),");
        }
        println!("];");
    }
    assert_eq!(
        plexus::state::SAMPLING_REVISION,
        GOLDEN_REVISION,
        "the sampling revision moved: regenerate the table (GOLDEN_PRINT=1, see the module doc)"
    );
    for (name, hash) in &hashes {
        let golden = GOLDEN.iter().find(|(n, _)| n == name).map(|(_, h)| *h);
        assert_eq!(
            golden,
            Some(hash.as_str()),
            "{name}'s image changed at sampling revision {GOLDEN_REVISION}: bump state::SAMPLING_REVISION (states of \
             the old numbers must not resume or merge with the new) and regenerate this table"
        );
    }
}

/// The hash sees a change of the numbers: another seed gives another image.
#[test]
fn the_hash_sees_another_seed() {
    let scene = scene();
    let table: toml::Table = toml::from_str("max_depth = 5").expect("parameters");
    let render = |seed| {
        let job = RenderJob { budget: Budget::SamplesPerPixel(4), seed, threads: 1 };
        create("pt", &table).expect("pt").render(&scene, &job, &NoProgress).expect("render").image.pixels
    };
    assert_ne!(render(3), render(4));
    assert_eq!(render(3), render(3));
}
