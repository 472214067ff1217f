//! `plexus info SCENE`: what a scene contains and what it costs, without rendering it.

use std::path::PathBuf;

use clap::Args;
use plexus::accel::AccelKind;
use plexus::scene::{load_scene, scene_info};

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Accelerator to build (its memory is part of the estimate): embree or bvh.
    #[arg(long)]
    pub accel: Option<AccelKind>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: InfoArgs) -> anyhow::Result<()> {
    let loaded = load_scene(&args.scene, args.accel)?;
    let info = scene_info(&loaded.scene);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print!("{info}");
    }
    Ok(())
}
