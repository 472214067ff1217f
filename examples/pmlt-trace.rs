//! Chain 0's image-plane trajectory under `pmlt` (the portal paper's Fig. 4c/d), as CSV, and the
//! integrated autocorrelation time of its raster y. Used by docs/lab/scripts/bench-portals.sh.
//!
//! Usage: cargo run --release --example pmlt-trace -- SCENE SEED MUTATIONS EVERY OUT.csv [KEY=VALUE ...]
//! (KEY=VALUE: pmlt settings, as TOML values; e.g. portal=0.0). Prints one line:
//! `points N every E tau_y T tau_y_mutations T·E`.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use plexus::integrator::path_space::trace::{integrated_autocorrelation_time, raster_trace};
use plexus::integrator::path_space::Pmlt;
use plexus::scene::load_scene;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 5 {
        bail!("usage: pmlt-trace SCENE SEED MUTATIONS EVERY OUT.csv [KEY=VALUE ...]");
    }
    let scene = load_scene(&PathBuf::from(&args[0]), None).with_context(|| args[0].clone())?.scene;
    let seed: u64 = args[1].parse().context("SEED")?;
    let mutations: u64 = args[2].parse().context("MUTATIONS")?;
    let every: u64 = args[3].parse().context("EVERY")?;
    let settings: toml::Table = toml::from_str(&args[5..].join("\n")).context("settings")?;
    let pmlt = Pmlt::from_params(&settings)?;
    let trace = raster_trace(&pmlt, &scene, seed, mutations, every)?;
    let mut csv = String::from("index,mutation,x,y\n");
    for (i, p) in trace.iter().enumerate() {
        csv += &format!("{i},{},{},{}\n", (i as u64 + 1) * every, p.x, p.y);
    }
    std::fs::write(&args[4], csv).with_context(|| args[4].clone())?;
    let ys: Vec<f64> = trace.iter().map(|p| p.y as f64).collect();
    let tau = integrated_autocorrelation_time(&ys).unwrap_or(f64::NAN);
    println!("points {} every {every} tau_y {tau:.3} tau_y_mutations {:.1}", trace.len(), tau * every as f64);
    Ok(())
}
