//! Convergence studies: render a scene with several integrators at several wall-clock budgets and
//! seeds, measure each image's error against a reference, and summarise the speed/accuracy trade as
//! a CSV, an equal-time Markdown table and a log–log plot (`metrics::plot`).
//!
//! Integrators are created by name through `integrator::create`, so every integrator in the
//! registry works here without changes to this file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use thiserror::Error;

use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::RenderError;
use crate::job::{Budget, NoProgress, RenderJob};
use crate::metrics::compare::{compare_images, CompareError};
use crate::scene::Scene;

/// What a study renders.
#[derive(Clone, Debug)]
pub struct StudyConfig {
    /// Integrator names as the registry knows them (`pt`, `bdpt`, ...).
    pub integrators: Vec<String>,
    /// Wall-clock budgets in seconds, one render per integrator, budget and seed.
    pub budgets: Vec<f64>,
    /// Seeds `first_seed .. first_seed + seeds`. Keep them apart from the reference's seed: a
    /// render sharing the reference's random streams is correlated with it and looks too good.
    pub first_seed: u64,
    pub seeds: u64,
    pub threads: usize,
    /// ε of the relative MSE.
    pub epsilon: f64,
}

/// One render of a study and its error.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunRecord {
    pub integrator: String,
    pub seed: u64,
    /// Requested budget in seconds.
    pub budget: f64,
    /// Measured wall time of the render in seconds (as the integrator reports it).
    pub wall_time: f64,
    /// Camera samples (path tracer, BDPT) or Markov chain iterations (MCMC).
    pub samples_or_mutations: u64,
    /// Closest-hit plus shadow rays.
    pub rays: u64,
    pub mse: f64,
    pub relmse: f64,
    /// Contributions the integrator dropped as NaN/Inf (should be 0).
    pub nonfinite_dropped: u64,
}

/// Mean and sample standard deviation over the seeds of one (integrator, budget) cell.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CellSummary {
    pub integrator: String,
    pub budget: f64,
    pub runs: usize,
    pub wall_time_mean: f64,
    pub samples_mean: f64,
    pub rays_mean: f64,
    pub mse_mean: f64,
    /// Sample standard deviation (n − 1 in the denominator); NaN for a single seed.
    pub mse_std: f64,
    pub relmse_mean: f64,
    pub relmse_std: f64,
}

/// Why a study failed.
#[derive(Debug, Error)]
pub enum ConvergeError {
    #[error("no integrators given (known: {0})")]
    NoIntegrators(String),
    #[error("no time budgets given")]
    NoBudgets,
    #[error("time budget must be positive and finite, got {0}")]
    BadBudget(f64),
    #[error("--seeds must be at least 1")]
    NoSeeds,
    #[error("integrator '{name}': {source}")]
    Integrator { name: String, source: RenderError },
    #[error(
        "reference is {ref_w}x{ref_h} but the scene renders {scene_w}x{scene_h}; render the reference from \
         the same scene"
    )]
    ReferenceSize { ref_w: usize, ref_h: usize, scene_w: usize, scene_h: usize },
    #[error(
        "resolution {width}x{height} has aspect ratio {:.4} but the scene's camera is {scene_w}x{scene_h} \
         (aspect {:.4}); expected the same aspect ratio within 1%",
        *width as f64 / *height as f64, *scene_w as f64 / *scene_h as f64
    )]
    AspectRatio { width: u32, height: u32, scene_w: u32, scene_h: u32 },
    #[error("resolution must be at least 1x1, got {width}x{height}")]
    BadResolution { width: u32, height: u32 },
    #[error("comparing against the reference: {0}")]
    Compare(#[from] CompareError),
    #[error("writing {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

impl StudyConfig {
    /// Checks the configuration before any rendering starts, including that every integrator name
    /// is known to the registry (so a typo fails in a second, not after an hour).
    pub fn validate(&self) -> Result<(), ConvergeError> {
        if self.integrators.is_empty() {
            return Err(ConvergeError::NoIntegrators(crate::integrator::INTEGRATOR_NAMES.join(", ")));
        }
        if self.budgets.is_empty() {
            return Err(ConvergeError::NoBudgets);
        }
        if let Some(&b) = self.budgets.iter().find(|b| !(**b > 0.0 && b.is_finite())) {
            return Err(ConvergeError::BadBudget(b));
        }
        if self.seeds == 0 {
            return Err(ConvergeError::NoSeeds);
        }
        Ok(())
    }
    /// Number of renders the study performs.
    pub fn run_count(&self) -> usize {
        self.integrators.len() * self.budgets.len() * self.seeds as usize
    }
}

/// The same camera with a `width`×`height` film: references and studies may run below a scene's
/// resolution to fit a time budget. The aspect ratio must match within 1% so that the field of
/// view (vertical, fixed) frames the same picture.
pub fn camera_at_resolution(camera: &Camera, width: u32, height: u32) -> Result<Camera, ConvergeError> {
    if width == 0 || height == 0 {
        return Err(ConvergeError::BadResolution { width, height });
    }
    let (scene_w, scene_h) = (camera.width, camera.height);
    let want = scene_w as f64 / scene_h as f64;
    let got = width as f64 / height as f64;
    if ((got - want) / want).abs() > 0.01 {
        return Err(ConvergeError::AspectRatio { width, height, scene_w, scene_h });
    }
    Ok(Camera::new(camera.position, camera.position + camera.forward, camera.up, camera.fov_y_degrees, width, height))
}

/// Parses `WxH` (e.g. `128x128`).
pub fn parse_resolution(text: &str) -> Result<(u32, u32), String> {
    let parse = |s: &str| s.trim().parse::<u32>().ok().filter(|&v| v > 0);
    match text.split_once(['x', 'X']) {
        Some((w, h)) => match (parse(w), parse(h)) {
            (Some(w), Some(h)) => Ok((w, h)),
            _ => Err(format!("resolution '{text}': expected WIDTHxHEIGHT with positive integers, e.g. 128x128")),
        },
        None => Err(format!("resolution '{text}': expected WIDTHxHEIGHT, e.g. 128x128")),
    }
}

/// Runs the study: for each seed × budget × integrator, creates the integrator through the registry
/// with `params(name)` (the scene's settings for it, or an empty table for defaults), renders with
/// a wall-clock budget and compares with `reference`. `on_run` sees every record as it completes
/// (the CLI prints progress from it). Every integrator is created once before rendering starts, so
/// a bad name or bad setting fails early.
pub fn run_study(
    scene: &Scene,
    reference: &Image,
    config: &StudyConfig,
    params: &dyn Fn(&str) -> toml::Table,
    on_run: &mut dyn FnMut(usize, usize, &RunRecord),
) -> Result<Vec<RunRecord>, ConvergeError> {
    config.validate()?;
    let (scene_w, scene_h) = (scene.camera.width as usize, scene.camera.height as usize);
    if (reference.width, reference.height) != (scene_w, scene_h) {
        return Err(ConvergeError::ReferenceSize { ref_w: reference.width, ref_h: reference.height, scene_w, scene_h });
    }
    let mut integrators = Vec::with_capacity(config.integrators.len());
    for name in &config.integrators {
        let integ = crate::integrator::create(name, &params(name))
            .map_err(|source| ConvergeError::Integrator { name: name.clone(), source })?;
        integrators.push((name.clone(), integ));
    }
    let total = config.run_count();
    let mut records = Vec::with_capacity(total);
    // Seeds outermost and integrators innermost: the integrators compared at one budget run side by
    // side in time, so a change of machine load during a long study hits them alike.
    for seed in config.first_seed..config.first_seed + config.seeds {
        for &budget in &config.budgets {
            for (name, integ) in &integrators {
                let job = RenderJob { budget: Budget::Seconds(budget), seed, threads: config.threads };
                let start = Instant::now();
                let out = integ
                    .render(scene, &job, &NoProgress)
                    .map_err(|source| ConvergeError::Integrator { name: name.clone(), source })?;
                // Prefer the integrator's own timing (it excludes nothing we care about); fall back
                // to ours if it reported none.
                let wall = if out.wall_time.is_zero() { start.elapsed() } else { out.wall_time };
                let m = compare_images(&out.image, reference, config.epsilon)?;
                let rec = RunRecord {
                    integrator: name.clone(),
                    seed,
                    budget,
                    wall_time: wall.as_secs_f64(),
                    samples_or_mutations: out.counters.samples,
                    rays: out.counters.total_rays(),
                    mse: m.mse,
                    relmse: m.relmse,
                    nonfinite_dropped: out.counters.nonfinite_dropped,
                };
                on_run(records.len() + 1, total, &rec);
                records.push(rec);
            }
        }
    }
    Ok(records)
}

/// The CSV header of [`write_csv`].
pub const CSV_HEADER: &str = "integrator,seed,budget,wall_time,samples_or_mutations,rays,mse,relmse,nonfinite_dropped";

/// The records as CSV text (one header line, one line per render; times in seconds).
pub fn csv_string(records: &[RunRecord]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in records {
        // Integrator names are identifiers from the registry: no commas or quotes to escape.
        let _ = writeln!(
            s,
            "{},{},{},{:.6},{},{},{:e},{:e},{}",
            r.integrator,
            r.seed,
            r.budget,
            r.wall_time,
            r.samples_or_mutations,
            r.rays,
            r.mse,
            r.relmse,
            r.nonfinite_dropped
        );
    }
    s
}

/// Writes [`csv_string`] to `path`.
pub fn write_csv(records: &[RunRecord], path: &Path) -> Result<(), ConvergeError> {
    std::fs::write(path, csv_string(records)).map_err(|source| ConvergeError::Io { path: path.to_owned(), source })
}

/// Reads records back from [`csv_string`]'s format (to redraw tables and plots without
/// rendering again). Errors name the line and field.
pub fn parse_csv(text: &str) -> Result<Vec<RunRecord>, String> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    match lines.next() {
        Some((_, h)) if h.trim() == CSV_HEADER => {}
        other => {
            return Err(format!("line 1: expected the header '{CSV_HEADER}', found '{}'", other.map_or("", |(_, l)| l)))
        }
    }
    let mut records = Vec::new();
    for (i, line) in lines {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 9 {
            return Err(format!("line {}: expected 9 comma-separated fields, found {}", i + 1, f.len()));
        }
        fn num<T: std::str::FromStr>(line: usize, name: &str, v: &str) -> Result<T, String> {
            v.parse().map_err(|_| format!("line {line}: field '{name}': expected a number, found '{v}'"))
        }
        let n = i + 1;
        records.push(RunRecord {
            integrator: f[0].to_string(),
            seed: num(n, "seed", f[1])?,
            budget: num(n, "budget", f[2])?,
            wall_time: num(n, "wall_time", f[3])?,
            samples_or_mutations: num(n, "samples_or_mutations", f[4])?,
            rays: num(n, "rays", f[5])?,
            mse: num(n, "mse", f[6])?,
            relmse: num(n, "relmse", f[7])?,
            nonfinite_dropped: num(n, "nonfinite_dropped", f[8])?,
        });
    }
    Ok(records)
}

/// Mean and sample standard deviation (n − 1); the deviation is NaN for fewer than two values.
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, f64::NAN);
    }
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1) as f64;
    (mean, var.sqrt())
}

/// Groups records by (integrator, budget), in the order they first appear.
pub fn summarize(records: &[RunRecord]) -> Vec<CellSummary> {
    let mut keys: Vec<(String, f64)> = Vec::new();
    for r in records {
        if !keys.iter().any(|(n, b)| *n == r.integrator && *b == r.budget) {
            keys.push((r.integrator.clone(), r.budget));
        }
    }
    keys.into_iter()
        .map(|(integrator, budget)| {
            let cell: Vec<&RunRecord> =
                records.iter().filter(|r| r.integrator == integrator && r.budget == budget).collect();
            let col = |f: &dyn Fn(&RunRecord) -> f64| cell.iter().map(|r| f(r)).collect::<Vec<f64>>();
            let (mse_mean, mse_std) = mean_std(&col(&|r| r.mse));
            let (relmse_mean, relmse_std) = mean_std(&col(&|r| r.relmse));
            CellSummary {
                runs: cell.len(),
                wall_time_mean: mean_std(&col(&|r| r.wall_time)).0,
                samples_mean: mean_std(&col(&|r| r.samples_or_mutations as f64)).0,
                rays_mean: mean_std(&col(&|r| r.rays as f64)).0,
                integrator,
                budget,
                mse_mean,
                mse_std,
                relmse_mean,
                relmse_std,
            }
        })
        .collect()
}

fn fmt_mean_std(mean: f64, std: f64) -> String {
    if std.is_nan() {
        format!("{mean:.3e}")
    } else {
        format!("{mean:.3e} ± {std:.2e}")
    }
}

fn fmt_budget(b: f64) -> String {
    if b.fract() == 0.0 {
        format!("{b:.0} s")
    } else {
        format!("{b} s")
    }
}

/// Equal-time tables in Markdown: relMSE and MSE (mean ± sample std over seeds; the lowest mean in
/// each column in bold), then the work each integrator did in that time.
pub fn markdown_tables(summaries: &[CellSummary], epsilon: f64) -> String {
    let mut integrators: Vec<&str> = Vec::new();
    let mut budgets: Vec<f64> = Vec::new();
    for s in summaries {
        if !integrators.contains(&s.integrator.as_str()) {
            integrators.push(&s.integrator);
        }
        if !budgets.contains(&s.budget) {
            budgets.push(s.budget);
        }
    }
    budgets.sort_by(f64::total_cmp);
    let cell = |i: &str, b: f64| summaries.iter().find(|s| s.integrator == i && s.budget == b);
    let header = |out: &mut String| {
        out.push_str("| integrator |");
        for b in &budgets {
            let _ = write!(out, " {} |", fmt_budget(*b));
        }
        out.push_str("\n|---|");
        for _ in &budgets {
            out.push_str("---:|");
        }
        out.push('\n');
    };
    let mut out = String::new();
    let metric_table = |out: &mut String, title: &str, get: &dyn Fn(&CellSummary) -> (f64, f64)| {
        let _ = writeln!(out, "{title}\n");
        header(out);
        for i in &integrators {
            let _ = write!(out, "| {i} |");
            for &b in &budgets {
                match cell(i, b) {
                    Some(s) => {
                        let (m, sd) = get(s);
                        let best = integrators
                            .iter()
                            .filter_map(|j| cell(j, b))
                            .map(|t| get(t).0)
                            .fold(f64::INFINITY, f64::min);
                        // Time budgets are met in whole passes, so the time actually spent is shown
                        // beside each error: "equal time" is only as equal as those times.
                        let text = format!("{} ({:.1} s)", fmt_mean_std(m, sd), s.wall_time_mean);
                        if m == best && integrators.len() > 1 {
                            let _ = write!(out, " **{text}** |");
                        } else {
                            let _ = write!(out, " {text} |");
                        }
                    }
                    None => out.push_str(" – |"),
                }
            }
            out.push('\n');
        }
        out.push('\n');
    };
    metric_table(
        &mut out,
        &format!("relMSE (ε = {epsilon:e}), mean ± std over seeds (mean wall time); lower is better:"),
        &|s| (s.relmse_mean, s.relmse_std),
    );
    metric_table(&mut out, "MSE, mean ± std over seeds (mean wall time):", &|s| (s.mse_mean, s.mse_std));
    let _ = writeln!(out, "Work done (mean over seeds): wall time, samples or mutations, rays:\n");
    header(&mut out);
    for i in &integrators {
        let _ = write!(out, "| {i} |");
        for &b in &budgets {
            match cell(i, b) {
                Some(s) => {
                    let _ = write!(
                        out,
                        " {:.2} s, {:.3e} samples, {:.3e} rays |",
                        s.wall_time_mean, s.samples_mean, s.rays_mean
                    );
                }
                None => out.push_str(" – |"),
            }
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn rec(integrator: &str, seed: u64, budget: f64, mse: f64) -> RunRecord {
        RunRecord {
            integrator: integrator.into(),
            seed,
            budget,
            wall_time: budget,
            samples_or_mutations: 100 * seed,
            rays: 1000,
            mse,
            relmse: 2.0 * mse,
            nonfinite_dropped: 0,
        }
    }

    #[test]
    fn resolution_override_keeps_the_view() {
        let c = Camera::new(Vec3::new(0.0, 1.0, 5.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 40.0, 256, 256);
        let small = camera_at_resolution(&c, 64, 64).expect("same aspect");
        assert_eq!((small.width, small.height), (64, 64));
        assert!((small.forward - c.forward).length() < 1e-6 && (small.up - c.up).length() < 1e-6);
        assert_eq!(small.tan_half_fov, c.tan_half_fov);
        assert!(camera_at_resolution(&c, 64, 32).is_err());
        assert!(camera_at_resolution(&c, 0, 0).is_err());
        assert_eq!(parse_resolution("128x96"), Ok((128, 96)));
        assert!(
            parse_resolution("128").is_err() && parse_resolution("0x5").is_err() && parse_resolution("ax5").is_err()
        );
    }

    #[test]
    fn mean_and_sample_std() {
        let (m, s) = mean_std(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        // Σ(x−2.5)² = 5, /(n−1) = 5/3.
        assert!((s - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!(mean_std(&[7.0]).1.is_nan());
    }

    #[test]
    fn summaries_group_by_integrator_and_budget() {
        let records = vec![
            rec("pt", 0, 5.0, 1.0),
            rec("pt", 1, 5.0, 3.0),
            rec("pt", 0, 10.0, 0.5),
            rec("pt", 1, 10.0, 0.5),
            rec("bdpt", 0, 5.0, 0.25),
        ];
        let s = summarize(&records);
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].integrator.as_str(), s[0].budget, s[0].runs), ("pt", 5.0, 2));
        assert_eq!(s[0].mse_mean, 2.0);
        assert!((s[0].mse_std - 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(s[0].relmse_mean, 4.0);
        assert_eq!(s[1].mse_std, 0.0);
        assert_eq!(s[2].runs, 1);
        let md = markdown_tables(&s, 1e-2);
        assert!(md.contains("| integrator | 5 s | 10 s |"), "{md}");
        // bdpt has the lowest 5 s error: bold; it has no 10 s cell.
        assert!(md.contains("| bdpt | **5.000e-1 (5.0 s)** | – |"), "{md}");
        assert!(md.contains("| pt | 4.000e0 ± 2.83e0 (5.0 s) | **1.000e0 ± 0.00e0 (10.0 s)** |"), "{md}");
        let csv = csv_string(&records);
        assert_eq!(parse_csv(&csv), Ok(records.clone()));
        assert!(parse_csv("nope").is_err());
        assert!(parse_csv(&format!("{CSV_HEADER}\npt,x,5,5,0,1,1,1,0")).unwrap_err().contains("line 2: field 'seed'"));
        assert_eq!(csv.lines().next(), Some(CSV_HEADER));
        assert_eq!(csv.lines().nth(1), Some("pt,0,5,5.000000,0,1000,1e0,2e0,0"));
        assert_eq!(csv.lines().count(), 6);
    }
}
