//! Warnings about a finished render, on stderr: one line `warning: ...` each, for every
//! integrator, so that a black image (a light facing away, a bootstrap that found no light) is
//! never silent. The stats JSON keeps the integrator's own warnings too.

use plexus::job::RenderOutput;

/// The lines to print for `output`: the integrator's warnings (MLT's bootstrap), then, when the
/// image is black and no warning said so already, one saying it is.
pub fn render_warnings(output: &RenderOutput) -> Vec<String> {
    let mut lines: Vec<String> = output
        .extra_stats
        .get("warnings")
        .and_then(|w| w.as_array())
        .map(|w| w.iter().filter_map(|m| m.as_str()).map(one_line).collect())
        .unwrap_or_default();
    let black = output.image.pixels.iter().all(|p| *p == glam::Vec3::ZERO);
    if black && !lines.iter().any(|l| l.contains("black")) {
        lines.push(
            "the image is black: no light reached the camera. Check that emitters face the scene (a one-sided \
             emitter emits on the side its normal points to; `two_sided = true` or `flip_normals`) and are not \
             enclosed"
                .to_string(),
        );
    }
    let nonfinite = output.image.pixels.iter().filter(|p| !p.is_finite()).count();
    if nonfinite > 0 {
        lines.push(format!("{nonfinite} pixels of the image are not finite (their sums overflow f32)"));
    }
    lines
}

/// Prints `render_warnings(output)` on stderr.
pub fn print_render_warnings(output: &RenderOutput) {
    for line in render_warnings(output) {
        eprintln!("warning: {line}");
    }
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
