//! Log–log plots of error against wall time (plotters, PNG), one line per integrator with its mean
//! over seeds and a ±1 standard deviation band.
//!
//! Text needs a TrueType font at run time (plotters' `ab_glyph` backend has none built in): the
//! first of `PLEXUS_FONT` and a few common system paths that loads is registered as "sans-serif".
//! Without one the plot is drawn without any text (no axis labels, captions or legend) rather than
//! failing.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::prelude::*;
use thiserror::Error;

use crate::metrics::converge::CellSummary;

/// Font files tried in order after `$PLEXUS_FONT` (Debian's fonts-dejavu-core, fonts-liberation,
/// Fedora's DejaVu).
const FONT_CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
];

static FONT: OnceLock<Option<PathBuf>> = OnceLock::new();

/// Registers a system font for plot text, once per process; returns the file used, or None when
/// no usable font exists (plots then carry no text).
pub fn ensure_font() -> Option<&'static Path> {
    FONT.get_or_init(|| {
        let env = std::env::var_os("PLEXUS_FONT").map(PathBuf::from);
        let candidates = env.into_iter().chain(FONT_CANDIDATES.iter().map(PathBuf::from));
        for path in candidates {
            let Ok(bytes) = std::fs::read(&path) else { continue };
            // plotters keeps fonts for the life of the process and wants 'static bytes: leaking one
            // font file (a few hundred kB, once) is the cost.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                return Some(path);
            }
        }
        None
    })
    .as_deref()
}

/// Why a plot could not be drawn.
#[derive(Debug, Error)]
#[error("drawing plot {path}: {message}")]
pub struct PlotError {
    pub path: PathBuf,
    pub message: String,
}

/// One panel: a title and which statistic of a cell it shows (mean, std).
pub struct Panel<'a> {
    pub title: &'a str,
    pub value: &'a dyn Fn(&CellSummary) -> (f64, f64),
}

/// One line of a panel: (mean wall time, mean error, std of the error) per budget, sorted by time.
fn series(
    summaries: &[CellSummary],
    integrator: &str,
    value: &dyn Fn(&CellSummary) -> (f64, f64),
) -> Vec<(f64, f64, f64)> {
    let mut pts: Vec<(f64, f64, f64)> = summaries
        .iter()
        .filter(|s| s.integrator == integrator)
        .map(|s| {
            let (m, sd) = value(s);
            (s.wall_time_mean, m, if sd.is_nan() { 0.0 } else { sd })
        })
        // A log axis cannot show zero or negative values; such points (a perfect render, or a
        // failed one) are left out of the plot, not of the CSV or table.
        .filter(|&(t, m, _)| t > 0.0 && t.is_finite() && m > 0.0 && m.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts
}

/// Colours chosen to stay distinguishable for common colour vision deficiencies (Okabe–Ito): all
/// eight, one per integrator, so no two integrators of `converge --integrators all` share one.
const COLOURS: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(240, 228, 66),
];

/// Draws the panels side by side into a PNG at `path`: x = mean wall time (s), y = error, both
/// logarithmic; per integrator a line through the means and a shaded band from mean − std to
/// mean + std (the lower edge clipped to the bottom of the axis where mean − std ≤ 0). `with_text`
/// false draws no text at all (for machines without fonts; see [`ensure_font`]).
pub fn plot_error_vs_time(
    path: &Path,
    summaries: &[CellSummary],
    panels: &[Panel],
    heading: &str,
    with_text: bool,
) -> Result<(), PlotError> {
    let perr = |e: &dyn std::fmt::Display| PlotError { path: path.to_owned(), message: e.to_string() };
    let mut integrators: Vec<&str> = Vec::new();
    for s in summaries {
        if !integrators.contains(&s.integrator.as_str()) {
            integrators.push(&s.integrator);
        }
    }
    let panel_w = 640u32;
    let root = BitMapBackend::new(path, (panel_w * panels.len().max(1) as u32, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| perr(&e))?;
    let root = if with_text {
        root.titled(heading, ("sans-serif", 20)).map_err(|e| perr(&e))?
    } else {
        root.margin(24, 0, 0, 0)
    };
    let areas = root.split_evenly((1, panels.len().max(1)));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let all: Vec<Vec<(f64, f64, f64)>> = integrators.iter().map(|i| series(summaries, i, panel.value)).collect();
        let pts = all.iter().flatten();
        let (mut t0, mut t1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for &(t, m, sd) in pts {
            t0 = t0.min(t);
            t1 = t1.max(t);
            y0 = y0.min(if m - sd > 0.0 { m - sd } else { m });
            y1 = y1.max(m + sd);
        }
        if !(t0 < f64::INFINITY) {
            // Nothing plottable: an empty decade keeps the axes valid.
            (t0, t1, y0, y1) = (1.0, 10.0, 0.1, 1.0);
        }
        // Pad by a fraction of a decade so that end points and bands are not on the frame.
        let (x_lo, x_hi, y_lo, y_hi) = (t0 / 1.25, t1 * 1.25, y0 / 1.5, y1 * 1.5);
        let mut builder = ChartBuilder::on(area);
        builder.margin(12);
        if with_text {
            builder.caption(panel.title, ("sans-serif", 18)).x_label_area_size(44).y_label_area_size(72);
        } else {
            builder.x_label_area_size(4).y_label_area_size(4);
        }
        let mut chart =
            builder.build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo..y_hi).log_scale()).map_err(|e| perr(&e))?;
        if with_text {
            chart
                .configure_mesh()
                .x_desc("wall time [s]")
                .y_desc(panel.title)
                .x_label_formatter(&|v| trim_number(*v))
                .y_label_formatter(&|v| format!("{v:.1e}"))
                .draw()
                .map_err(|e| perr(&e))?;
        } else {
            // plotters' mesh measures label text even when asked for none, so without a font the
            // frame and the decade grid lines are drawn by hand.
            let grey = RGBColor(200, 200, 200);
            let decades =
                |lo: f64, hi: f64| (lo.log10().ceil() as i32..=hi.log10().floor() as i32).map(|e| 10f64.powi(e));
            for x in decades(x_lo, x_hi) {
                chart
                    .draw_series(std::iter::once(PathElement::new(vec![(x, y_lo), (x, y_hi)], grey)))
                    .map_err(|e| perr(&e))?;
            }
            for y in decades(y_lo, y_hi) {
                chart
                    .draw_series(std::iter::once(PathElement::new(vec![(x_lo, y), (x_hi, y)], grey)))
                    .map_err(|e| perr(&e))?;
            }
            let frame = vec![(x_lo, y_lo), (x_hi, y_lo), (x_hi, y_hi), (x_lo, y_hi), (x_lo, y_lo)];
            chart.draw_series(std::iter::once(PathElement::new(frame, BLACK))).map_err(|e| perr(&e))?;
        }
        for (k, (name, pts)) in integrators.iter().zip(&all).enumerate() {
            if pts.is_empty() {
                continue;
            }
            let colour = COLOURS[k % COLOURS.len()];
            let mut band: Vec<(f64, f64)> = pts.iter().map(|&(t, m, sd)| (t, m + sd)).collect();
            band.extend(pts.iter().rev().map(|&(t, m, sd)| (t, if m - sd > y_lo { m - sd } else { y_lo })));
            chart.draw_series(std::iter::once(Polygon::new(band, colour.mix(0.2).filled()))).map_err(|e| perr(&e))?;
            let line = chart
                .draw_series(LineSeries::new(pts.iter().map(|&(t, m, _)| (t, m)), colour.stroke_width(2)))
                .map_err(|e| perr(&e))?;
            if with_text {
                line.label(*name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            }
            chart
                .draw_series(pts.iter().map(|&(t, m, _)| Circle::new((t, m), 3, colour.filled())))
                .map_err(|e| perr(&e))?;
        }
        if with_text {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(|e| perr(&e))?;
        }
    }
    root.present().map_err(|e| perr(&e))?;
    Ok(())
}

/// `v` with at most three decimals and no trailing zeros (1.000 → "1", 2.500 → "2.5").
fn trim_number(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// The standard convergence figure: relMSE and MSE against wall time, text if a font is found.
pub fn plot_convergence(path: &Path, summaries: &[CellSummary], heading: &str) -> Result<(), PlotError> {
    let with_text = ensure_font().is_some();
    let panels = [
        Panel { title: "relMSE", value: &|s: &CellSummary| (s.relmse_mean, s.relmse_std) },
        Panel { title: "MSE", value: &|s: &CellSummary| (s.mse_mean, s.mse_std) },
    ];
    plot_error_vs_time(path, summaries, &panels, heading, with_text)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(integrator: &str, t: f64, mse: f64, sd: f64) -> CellSummary {
        CellSummary {
            integrator: integrator.into(),
            budget: t,
            runs: 3,
            wall_time_mean: t,
            samples_mean: 10.0,
            rays_mean: 100.0,
            mse_mean: mse,
            mse_std: sd,
            relmse_mean: mse * 2.0,
            relmse_std: sd * 2.0,
        }
    }

    /// Without text (no font is ever registered in this test binary, so any text drawing would
    /// fail) the plot is still drawn and non-blank where the lines are.
    #[test]
    fn plot_without_font_draws_lines_and_no_text() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let dir = tmp.path().to_path_buf();
        let path = dir.join("notext.png");
        let s = vec![
            cell("pt", 1.0, 1e-1, 5e-2),
            cell("pt", 4.0, 2.5e-2, 3e-2), // std > mean: band clipped to the axis
            cell("bdpt", 1.0, 5e-2, f64::NAN),
            cell("bdpt", 4.0, 0.0, 0.0), // zero error: left out of a log plot
        ];
        let panels = [Panel { title: "MSE", value: &|c: &CellSummary| (c.mse_mean, c.mse_std) }];
        plot_error_vs_time(&path, &s, &panels, "test", false).expect("plot without text");
        let meta = std::fs::metadata(&path).expect("png written");
        assert!(meta.len() > 1000, "png has content: {} bytes", meta.len());
        std::fs::remove_dir_all(&dir).ok();
    }
}
