//! `plexus info SCENE`: what a scene contains and what it costs, without rendering it.

use std::path::PathBuf;

use clap::Args;
use plexus::accel::AccelKind;
use plexus::integrator::registry::render_memory;
use plexus::job::memory;
use plexus::scene::scene_info;

use super::bad_input;

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Scene file (TOML, or Mitsuba XML).
    pub scene: PathBuf,
    /// Accelerator to build (its memory is part of the estimate): embree or bvh.
    #[arg(long)]
    pub accel: Option<AccelKind>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: InfoArgs) -> anyhow::Result<()> {
    let loaded = super::import::load_any(&args.scene, args.accel)?;
    let info = scene_info(&loaded.scene);
    // What rendering it would allocate on top of the scene: the one estimate `render` checks.
    let (width, height) = (loaded.scene.camera.width, loaded.scene.camera.height);
    let render = &loaded.render;
    let scene = loaded.scene.memory();
    let needed = render_memory(&render.integrator, &render.integrator_params, width, height)
        .map_err(bad_input)?
        .with_scene(scene);
    let available = memory::available_memory(scene.total());
    if args.json {
        let mut value = serde_json::to_value(&info)?;
        if let Some(map) = value.as_object_mut() {
            map.insert(
                "render_memory".to_string(),
                serde_json::json!({
                    "integrator": render.integrator,
                    "scene": needed.scene,
                    "film": needed.film,
                    "pass_buffers": needed.pass_buffers,
                    "chains": needed.chains,
                    "total": needed.total(),
                    "available": available,
                }),
            );
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        let text = info.to_string();
        print!("{text}");
        if !text.ends_with('\n') {
            println!();
        }
        // MiB, as the scene's own memory line above.
        let mib = |bytes: u64| bytes as f64 / (1u64 << 20) as f64;
        let available = available.map_or_else(|| "unknown".to_string(), |a| format!("{:.2} MiB", mib(a)));
        println!(
            "render:      {:.2} MiB for {} at {width}x{height} (scene {:.2}, film {:.2}, pass buffers {:.2}, chains {:.2}); available {available}",
            mib(needed.total()),
            render.integrator,
            mib(needed.scene.total()),
            mib(needed.film),
            mib(needed.pass_buffers),
            mib(needed.chains),
        );
    }
    Ok(())
}
