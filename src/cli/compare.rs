//! `plexus compare A.exr B.exr`: the error of a test image against a reference (definitions in
//! `plexus::metrics::compare`), optionally with a false-colour map of the per-pixel error.

use std::path::PathBuf;

use clap::Args;

use plexus::film::exr_io::read_exr;
use plexus::film::oiio::{check_output_path, write_image, WriteOptions};
use plexus::metrics::compare::{compare_images, false_colour_error, DEFAULT_EPSILON, FALSE_COLOUR_LOG10_RANGE};

use super::bad_input;

#[derive(Debug, Args)]
pub struct CompareArgs {
    /// The image under test (EXR).
    pub a: PathBuf,
    /// The reference image (EXR).
    pub b: PathBuf,
    /// Write a false-colour map of the per-pixel relative squared error (viridis, log scale from
    /// 1e-4 to 1; NaN/Inf magenta); format from the extension (.png, .exr, ...).
    #[arg(long, value_name = "PATH")]
    pub out: Option<PathBuf>,
    /// ε of the relative MSE (a−b)²/(b²+ε).
    #[arg(long, value_name = "E", default_value_t = DEFAULT_EPSILON)]
    pub epsilon: f64,
    /// Print the metrics as one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

pub fn run_compare(args: &CompareArgs) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        check_output_path(out).map_err(bad_input)?;
    }
    let a = read_exr(&args.a).map_err(bad_input)?;
    let b = read_exr(&args.b).map_err(bad_input)?;
    let m = compare_images(&a, &b, args.epsilon)
        .map_err(|e| bad_input(format!("comparing '{}' with '{}': {e}", args.a.display(), args.b.display())))?;
    if m.nonfinite_a > 0 || m.nonfinite_b > 0 {
        eprintln!(
            "warning: non-finite pixels: {} in '{}', {} in '{}'; the metrics are not finite",
            m.nonfinite_a,
            args.a.display(),
            m.nonfinite_b,
            args.b.display()
        );
    }
    if args.json {
        let mut v = serde_json::to_value(m)?;
        v["width"] = a.width.into();
        v["height"] = a.height.into();
        // JSON has no infinity: identical images get psnr null plus this flag.
        v["identical"] = (m.mse == 0.0).into();
        println!("{v}");
    } else {
        let psnr = match m.psnr {
            Some(p) if p.is_infinite() => "inf (identical)".to_string(),
            Some(p) => format!("{p:.2} dB"),
            None => "undefined (reference has no positive value)".to_string(),
        };
        println!("size        {}x{}", a.width, a.height);
        println!("MSE         {:.6e}", m.mse);
        println!("relMSE      {:.6e}   (mean of (a-b)^2/(b^2+eps), eps = {:e})", m.relmse, m.epsilon);
        println!("PSNR        {psnr}   (peak = max channel of the reference = {:.6e})", m.peak);
        println!(
            "mean ratio  {:.6}   (mean a / mean b; R {:.6}, G {:.6}, B {:.6})",
            m.mean_ratio, m.mean_ratio_rgb[0], m.mean_ratio_rgb[1], m.mean_ratio_rgb[2]
        );
        println!("means       a {:.6e}, b {:.6e}", m.mean_a, m.mean_b);
    }
    if let Some(out) = &args.out {
        let img = false_colour_error(&a, &b, args.epsilon).map_err(bad_input)?;
        write_image(out, &img, &WriteOptions::default())?;
        let (lo, hi) = FALSE_COLOUR_LOG10_RANGE;
        eprintln!("error map (relative squared error, 1e{lo} .. 1e{hi}, log scale) -> {}", out.display());
    }
    Ok(())
}
