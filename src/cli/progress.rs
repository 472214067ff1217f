//! The progress bar on stderr: an ETA for sample budgets, elapsed and remaining time for time
//! budgets. Hidden when stderr is not a terminal or when `CI=true`, so logs stay clean.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use plexus::film::oiio::{write_image, WriteOptions};
use plexus::film::Image;
use plexus::job::Progress;

/// `--preview-every`: write the current image to the render's outputs this often.
pub struct Previews {
    pub every_seconds: f64,
    pub outputs: Vec<PathBuf>,
}

/// An indicatif bar driven by an integrator's `Progress` calls.
pub struct BarProgress {
    bar: ProgressBar,
    /// For time budgets: the budget, against which the bar advances with the clock.
    time_budget: Option<Duration>,
    start: Instant,
    previews: Option<Previews>,
}

/// Whether a progress bar should be drawn at all.
pub fn bar_wanted() -> bool {
    let ci = std::env::var("CI").map(|v| v.eq_ignore_ascii_case("true") || v == "1").unwrap_or(false);
    std::io::stderr().is_terminal() && !ci
}

impl BarProgress {
    /// A bar for a render with a time budget of `seconds`, or a sample budget when `None`.
    pub fn new(time_budget_seconds: Option<f64>, visible: bool) -> BarProgress {
        let target = if visible { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
        let bar = ProgressBar::with_draw_target(None, target);
        let time_budget = time_budget_seconds.map(Duration::from_secs_f64);
        let template = if time_budget.is_some() {
            "{spinner} [{elapsed_precise}] [{wide_bar}] {prefix} {msg}"
        } else {
            "{spinner} [{elapsed_precise}] [{wide_bar}] {percent:>3}% ETA {eta} {msg}"
        };
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        if let Some(budget) = time_budget {
            bar.set_length(budget.as_millis().max(1) as u64);
        }
        bar.enable_steady_tick(Duration::from_millis(200));
        BarProgress { bar, time_budget, start: Instant::now(), previews: None }
    }

    /// Also write previews during the render.
    pub fn with_previews(mut self, previews: Option<Previews>) -> BarProgress {
        self.previews = previews;
        self
    }

    /// Removes the bar from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl Progress for BarProgress {
    fn set_total(&self, total: u64) {
        if self.time_budget.is_none() {
            self.bar.set_length(total);
        }
    }
    fn advance(&self, units: u64) {
        match self.time_budget {
            None => self.bar.inc(units),
            Some(budget) => {
                let elapsed = self.start.elapsed();
                self.bar.set_position(elapsed.min(budget).as_millis() as u64);
                let left = budget.saturating_sub(elapsed).as_secs_f64();
                self.bar.set_prefix(format!("{left:.1} s left"));
            }
        }
    }
    fn message(&self, msg: &str) {
        self.bar.set_message(msg.to_string());
    }
    fn preview_interval(&self) -> Option<f64> {
        self.previews.as_ref().map(|p| p.every_seconds)
    }
    /// Writes the preview to every output (each through a temporary file and a rename, so a
    /// viewer never sees half an image). A failed write is reported on the bar, not fatal: the
    /// final image is written (and its errors reported) when the render ends.
    fn preview(&self, image: &Image) {
        let Some(previews) = &self.previews else { return };
        for path in &previews.outputs {
            if let Err(e) = write_image(path, image, &WriteOptions::default()) {
                self.bar.set_message(format!("preview not written: {e}"));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A preview is written to every output, readable, with the image it was given.
    #[test]
    fn preview_writes_every_output() {
        let dir = std::env::temp_dir().join(format!("plexus-preview-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let outputs = vec![dir.join("p.exr"), dir.join("p.png")];
        let progress = BarProgress::new(None, false)
            .with_previews(Some(Previews { every_seconds: 1.0, outputs: outputs.clone() }));
        let mut image = Image::new(3, 2);
        image.pixels[4] = glam::Vec3::new(0.25, 0.5, 1.0);
        progress.preview(&image);
        let read = plexus::film::exr_io::read_exr(&outputs[0]).expect("preview EXR readable");
        assert_eq!(read.pixels, image.pixels);
        assert!(outputs[1].exists());
        std::fs::remove_dir_all(&dir).ok();
    }
}
