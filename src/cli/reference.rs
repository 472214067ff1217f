//! `plexus reference SCENE --out REF.exr`: a long, seeded render to measure other renders against
//! (docs/reference-images.md). It differs from `plexus render` in one way: `--resolution WxH` renders
//! below the scene's resolution (same aspect ratio), so references for studies stay small and
//! affordable. Next to the EXR it writes the usual JSON stats, which record how it was made.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use plexus::film::oiio::{check_output_path, write_image, WriteOptions};
use plexus::integrator::{self, INTEGRATOR_NAMES};
use plexus::job::{Budget, RenderJob};
use plexus::metrics::converge::{camera_at_resolution, parse_resolution};

use super::bad_input;
use super::options::RenderOptions;
use super::progress::{bar_wanted, BarProgress};
use super::stats_json::{self, RenderStats};

#[derive(Debug, Args)]
pub struct ReferenceArgs {
    /// Scene file (TOML, or Mitsuba XML imported on the fly, its warnings printed).
    pub scene: PathBuf,
    /// Output image (EXR recommended: references must stay linear and unclipped).
    #[arg(long = "out", short = 'o', value_name = "PATH")]
    pub out: PathBuf,
    /// Integrator (default pt: the simplest unbiased estimator is the safest reference).
    #[arg(long, value_name = "NAME", default_value = "pt",
          help = format!("Integrator: {}", INTEGRATOR_NAMES.join(", ")))]
    pub integrator: String,
    /// Samples per pixel.
    #[arg(long, value_name = "N", conflicts_with = "time", required_unless_present = "time")]
    pub spp: Option<u64>,
    /// Time budget in seconds instead of samples (not reproducible bit for bit).
    #[arg(long, value_name = "SECONDS")]
    pub time: Option<f64>,
    /// Seed. Use one that studies do not use (they default to seeds 0, 1, 2, ...).
    #[arg(long, value_name = "S", default_value_t = 1_000_003)]
    pub seed: u64,
    /// Film resolution WIDTHxHEIGHT (default: the scene's); must keep the scene's aspect ratio.
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    pub resolution: Option<(u32, u32)>,
    #[command(flatten)]
    pub options: RenderOptions,
}

pub fn run_reference(args: &ReferenceArgs) -> anyhow::Result<()> {
    let overrides = args.options.overrides()?;
    let budget = match (args.spp, args.time) {
        (Some(0), _) => return Err(bad_input("--spp must be at least 1")),
        (Some(n), _) => Budget::SamplesPerPixel(n),
        (None, Some(s)) if s.is_finite() && s > 0.0 => Budget::Seconds(s),
        (None, Some(s)) => return Err(bad_input(format!("--time must be a positive number of seconds, got {s}"))),
        (None, None) => return Err(bad_input("give --spp N or --time SECONDS")),
    };
    // A reference does not read the scene's thread count: all cores unless told.
    let threads = args.options.threads_or(None)?;
    check_output_path(&args.out).map_err(bad_input)?;
    for path in stats_json::stats_paths(std::slice::from_ref(&args.out)) {
        super::outputs::check_stats_path(&path)?;
    }
    let load_start = Instant::now();
    let mut loaded = super::import::load_any(&args.scene, args.options.accel)?;
    if let Some((w, h)) = args.resolution {
        loaded.scene.camera = camera_at_resolution(&loaded.scene.camera, w, h).map_err(bad_input)?;
    }
    let render = &loaded.render;
    let base = if args.integrator == render.integrator { render.integrator_params.clone() } else { toml::Table::new() };
    let params = integrator::merge_params(&base, &overrides);
    let row = integrator::registry::lookup(&args.integrator)?;
    let integ = (row.create)(&params)?;
    let budget_option = if args.spp.is_some() { "--spp" } else { "--time" };
    row.check_limits(&loaded.scene, &params, budget, budget_option).map_err(bad_input)?;
    let load_time = load_start.elapsed().as_secs_f64();

    let job = RenderJob { budget, seed: args.seed, threads };
    let progress = BarProgress::new(
        match budget {
            Budget::Seconds(s) => Some(s),
            Budget::SamplesPerPixel(_) => None,
        },
        bar_wanted(),
    );
    let output = integ.render(&loaded.scene, &job, &progress);
    progress.finish();
    let output = output?;
    super::warnings::print_render_warnings(&output);
    if !output.image.all_finite() {
        anyhow::bail!("the reference has non-finite pixels; not writing {}", args.out.display());
    }
    write_image(&args.out, &output.image, &WriteOptions::default())?;
    let stats = RenderStats::new(
        args.scene.display().to_string(),
        integ.name().to_string(),
        integ.settings_json(),
        budget,
        args.seed,
        threads,
        loaded.scene.accel.kind().to_string(),
        load_time,
        Some(loaded.scene.features()),
        &output,
        vec![args.out.clone()],
    );
    let stats_files = stats_json::stats_paths(std::slice::from_ref(&args.out));
    for path in &stats_files {
        stats_json::write(path, &stats)?;
    }
    eprintln!(
        "reference {}x{}: {} samples in {:.1} s, {} non-finite contributions dropped -> {}",
        output.image.width,
        output.image.height,
        output.counters.samples,
        output.wall_time.as_secs_f64(),
        output.counters.nonfinite_dropped,
        args.out.display()
    );
    Ok(())
}
