//! `plexus converge SCENE --reference REF.exr --integrators pt,... --times 5,10 --seeds N`: the
//! speed/accuracy trade of every named integrator on one scene (see `plexus::metrics::converge`).
//! The scene is rendered at the reference's resolution (same aspect ratio as the scene's camera),
//! so a small reference makes a fast study. Writes `<stem>-converge.csv`, `<stem>-converge.md` and `<stem>-converge.png` into `--out-dir`.

use std::path::PathBuf;

use clap::Args;

use plexus::film::exr_io::read_exr;
use plexus::integrator::{self, INTEGRATOR_NAMES};
use plexus::metrics::compare::DEFAULT_EPSILON;
use plexus::metrics::converge::{
    camera_at_resolution, markdown_tables, parse_csv, run_study, summarize, write_csv, ConvergeError, RunRecord,
    StudyConfig,
};
use plexus::metrics::plot::plot_convergence;

use super::bad_input;
use super::options::RenderOptions;

#[derive(Debug, Args)]
pub struct ConvergeArgs {
    /// Scene file (TOML, or Mitsuba XML imported on the fly, its warnings printed).
    pub scene: PathBuf,
    /// Reference image (EXR) of the same scene and resolution; see docs/reference-images.md.
    #[arg(long, value_name = "REF.exr", required_unless_present = "replot")]
    pub reference: Option<PathBuf>,
    /// Integrators to compare, comma-separated.
    #[arg(long, value_delimiter = ',', required_unless_present = "replot", value_name = "NAMES",
          help = format!("Integrators to compare, comma-separated, or 'all': {}", INTEGRATOR_NAMES.join(", ")))]
    pub integrators: Vec<String>,
    /// Wall-clock budgets in seconds, comma-separated.
    #[arg(long, value_delimiter = ',', required_unless_present = "replot", value_name = "SECONDS")]
    pub times: Vec<f64>,
    /// Number of seeds per integrator and budget (seeds first-seed .. first-seed + N).
    #[arg(long, value_name = "N", default_value_t = 3)]
    pub seeds: u64,
    /// First seed. Keep the range apart from the reference's seed.
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub first_seed: u64,
    /// Directory for the CSV, Markdown table and plot (must exist).
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub out_dir: PathBuf,
    #[command(flatten)]
    pub options: RenderOptions,
    /// ε of the relative MSE (a−b)²/(b²+ε).
    #[arg(long, value_name = "E", default_value_t = DEFAULT_EPSILON)]
    pub epsilon: f64,
    /// Do not render: redraw the Markdown tables and the plot from a CSV an earlier run wrote.
    #[arg(long, value_name = "CSV")]
    pub replot: Option<PathBuf>,
}

pub fn run_converge(args: &ConvergeArgs) -> anyhow::Result<()> {
    let overrides = args.options.overrides()?;
    args.options.check_threads()?;
    // Every budget within the render limits, and the whole study too: --times 1e30 ran for ever.
    for &t in &args.times {
        plexus::job::check_budget(plexus::job::Budget::Seconds(t), 1, 1, "--times").map_err(bad_input)?;
    }
    let runs = (args.times.len() as u64).saturating_mul(args.seeds).saturating_mul(args.integrators.len() as u64);
    let study_seconds = args.times.iter().sum::<f64>() * runs as f64;
    if study_seconds > plexus::job::MAX_SECONDS {
        return Err(bad_input(format!(
            "--times, --seeds and --integrators: {runs} renders of {} s in all is {study_seconds:.0} s, more than the \
             limit of {} s (30 days)",
            args.times.iter().sum::<f64>(),
            plexus::job::MAX_SECONDS
        )));
    }
    if !(args.epsilon > 0.0 && args.epsilon.is_finite()) {
        return Err(bad_input(format!("--epsilon must be positive, got {}", args.epsilon)));
    }
    if !args.out_dir.is_dir() {
        return Err(bad_input(format!("--out-dir '{}' is not an existing directory", args.out_dir.display())));
    }
    let stem = args.scene.file_stem().map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    if let Some(csv) = &args.replot {
        let text = plexus::input_file::read_regular_text(csv, plexus::input_file::MAX_SCENE_TEXT_BYTES)
            .map_err(|e| bad_input(format!("reading {}: {e}", csv.display())))?;
        let records = parse_csv(&text).map_err(|e| bad_input(format!("{}: {e}", csv.display())))?;
        return write_reports(args, &stem, &records, None);
    }
    let Some(reference_path) = &args.reference else { return Err(bad_input("--reference is required")) };
    let reference = read_exr(reference_path).map_err(bad_input)?;
    let mut loaded = super::import::load_any(&args.scene, args.options.accel)?;
    let (ref_w, ref_h) = (reference.width as u32, reference.height as u32);
    let cam = &loaded.scene.camera;
    if (cam.width, cam.height) != (ref_w, ref_h) {
        eprintln!(
            "note: rendering at the reference's {ref_w}x{ref_h} instead of the scene's {}x{}",
            cam.width, cam.height
        );
        loaded.scene.camera = camera_at_resolution(cam, ref_w, ref_h).map_err(bad_input)?;
    }
    let threads = args.options.threads_or(loaded.render.threads)?;
    let config = StudyConfig {
        integrators: if args.integrators.len() == 1 && args.integrators[0].trim() == "all" {
            INTEGRATOR_NAMES.iter().map(|s| s.to_string()).collect()
        } else {
            args.integrators.iter().map(|s| s.trim().to_string()).collect()
        },
        budgets: args.times.clone(),
        first_seed: args.first_seed,
        seeds: args.seeds,
        threads,
        epsilon: args.epsilon,
    };
    config.validate().map_err(bad_input)?;
    // The scene's [integrator] table configures the scene's own integrator; the others start from
    // their defaults. --set applies to all of them.
    let render = &loaded.render;
    let params = |name: &str| {
        let base = if name == render.integrator { render.integrator_params.clone() } else { toml::Table::new() };
        integrator::merge_params(&base, &overrides)
    };
    let csv = args.out_dir.join(format!("{stem}-converge.csv"));

    let total_time: f64 = config.budgets.iter().sum::<f64>() * (config.seeds * config.integrators.len() as u64) as f64;
    eprintln!(
        "converge {}: {} renders ({} integrators x {} budgets x {} seeds), about {:.0} s of rendering, {} threads",
        args.scene.display(),
        config.run_count(),
        config.integrators.len(),
        config.budgets.len(),
        config.seeds,
        total_time,
        threads
    );
    let records = run_study(&loaded.scene, &reference, &config, &params, &mut |i, n, r| {
        let dropped = if r.nonfinite_dropped > 0 {
            format!(", {} non-finite dropped", r.nonfinite_dropped)
        } else {
            String::new()
        };
        eprintln!(
            "[{i}/{n}] {} seed {} budget {} s: {:.2} s, {} samples, {:.3e} rays, MSE {:.4e}, relMSE {:.4e}{dropped}",
            r.integrator, r.seed, r.budget, r.wall_time, r.samples_or_mutations, r.rays, r.mse, r.relmse
        );
    })
    .map_err(|e| match e {
        ConvergeError::Integrator { .. } | ConvergeError::ReferenceSize { .. } => bad_input(e),
        other => anyhow::Error::new(other),
    })?;
    write_csv(&records, &csv)?;
    write_reports(args, &stem, &records, Some((&config, threads)))?;
    eprintln!("-> {}", csv.display());
    Ok(())
}

/// Writes `<stem>-converge.md` (the equal-time tables) and `<stem>-converge.png` (the plot).
fn write_reports(
    args: &ConvergeArgs,
    stem: &str,
    records: &[RunRecord],
    run: Option<(&StudyConfig, usize)>,
) -> anyhow::Result<()> {
    let md = args.out_dir.join(format!("{stem}-converge.md"));
    let png = args.out_dir.join(format!("{stem}-converge.png"));
    let summaries = summarize(records);
    let command: Vec<String> = std::env::args().collect();
    let mut text = format!("# Convergence: {}\n\n", args.scene.display());
    if let Some((config, threads)) = run {
        let reference = args.reference.as_ref().map_or_else(String::new, |r| r.display().to_string());
        text += &format!(
            "Reference: `{reference}`. Seeds {}..{} ({} per cell), {threads} threads. Command:\n\n```\n{}\n```\n\n",
            config.first_seed,
            config.first_seed + config.seeds - 1,
            config.seeds,
            command.join(" ")
        );
    } else {
        text += &format!("Redrawn from a CSV:\n\n```\n{}\n```\n\n", command.join(" "));
    }
    text.push_str(&markdown_tables(&summaries, args.epsilon));
    std::fs::write(&md, text).map_err(|e| anyhow::anyhow!("writing {}: {e}", md.display()))?;
    plot_convergence(&png, &summaries, &format!("{stem}: error vs wall time"))?;
    eprintln!("-> {}, {}", md.display(), png.display());
    Ok(())
}
