//! Image error metrics: MSE, relative MSE, PSNR and the ratio of image means, plus a false-colour
//! map of the per-pixel relative error.
//!
//! Conventions (stated once here; docs/benchmarks.md repeats them):
//! - `a` is the image under test, `b` the reference.
//! - MSE = mean over pixels p and channels c of (a_pc − b_pc)².
//! - relative MSE = mean over pixels and channels of (a_pc − b_pc)² / (b_pc² + ε), with
//!   ε = [`DEFAULT_EPSILON`] = 1e-2 unless chosen otherwise. ε keeps black reference pixels from
//!   dividing by zero: a pixel whose reference is well below √ε = 0.1 is judged by its absolute
//!   rather than its relative error, so dark, noisy pixels do not dominate the mean.
//! - PSNR = 10·log10(peak² / MSE) with peak = the largest channel value of the reference `b`
//!   (the images are HDR, so there is no fixed white; the reference's maximum is the only scale
//!   both images share). Infinite when MSE = 0; undefined (None) when the reference has no positive
//!   value.
//! - ratio of means = (mean of a over pixels and channels) / (mean of b over pixels and channels):
//!   1 for an unbiased estimate up to noise; the quantity MCMC normalisation errors show up in.

use glam::Vec3;
use thiserror::Error;

use crate::film::Image;
use crate::spectrum::Rgb;

/// The default ε of the relative MSE: (a−b)²/(b²+ε).
pub const DEFAULT_EPSILON: f64 = 1e-2;

/// Why two images could not be compared.
#[derive(Debug, Error, PartialEq)]
pub enum CompareError {
    #[error("image sizes differ: {a_w}x{a_h} (test image) vs {b_w}x{b_h} (reference)")]
    SizeMismatch { a_w: usize, a_h: usize, b_w: usize, b_h: usize },
    #[error("cannot compare empty images (0 pixels)")]
    Empty,
    #[error("relative-MSE epsilon must be positive and finite, got {0}")]
    BadEpsilon(f64),
}

/// The error of a test image against a reference.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ErrorMetrics {
    /// Mean squared error over pixels and channels.
    pub mse: f64,
    /// Mean over pixels and channels of (a−b)²/(b²+ε).
    pub relmse: f64,
    /// The ε used in `relmse`.
    pub epsilon: f64,
    /// 10·log10(peak²/mse) in dB; +∞ when the images are equal; None when `peak` ≤ 0.
    pub psnr: Option<f64>,
    /// The largest channel value of the reference (the PSNR peak).
    pub peak: f64,
    /// Mean of the test image over pixels and channels.
    pub mean_a: f64,
    /// Mean of the reference over pixels and channels.
    pub mean_b: f64,
    /// `mean_a / mean_b` (NaN when the reference mean is 0).
    pub mean_ratio: f64,
    /// Per-channel ratio of means (R, G, B).
    pub mean_ratio_rgb: [f64; 3],
    /// Pixels of the test image with a NaN or infinite channel (they make every metric non-finite,
    /// which is the honest answer; the count says why).
    pub nonfinite_a: usize,
    /// Pixels of the reference with a NaN or infinite channel.
    pub nonfinite_b: usize,
}

fn check_sizes(a: &Image, b: &Image) -> Result<(), CompareError> {
    if a.width != b.width || a.height != b.height {
        return Err(CompareError::SizeMismatch { a_w: a.width, a_h: a.height, b_w: b.width, b_h: b.height });
    }
    if a.pixels.is_empty() {
        return Err(CompareError::Empty);
    }
    Ok(())
}

fn check_epsilon(epsilon: f64) -> Result<(), CompareError> {
    if epsilon > 0.0 && epsilon.is_finite() {
        Ok(())
    } else {
        Err(CompareError::BadEpsilon(epsilon))
    }
}

#[inline]
fn channels(p: Rgb) -> [f64; 3] {
    [p.x as f64, p.y as f64, p.z as f64]
}

/// Compares `a` (under test) with `b` (the reference); see the module documentation for the
/// definitions. Accumulates in f64.
pub fn compare_images(a: &Image, b: &Image, epsilon: f64) -> Result<ErrorMetrics, CompareError> {
    check_sizes(a, b)?;
    check_epsilon(epsilon)?;
    let mut se = 0.0f64;
    let mut rel = 0.0f64;
    let mut sum_a = [0.0f64; 3];
    let mut sum_b = [0.0f64; 3];
    let mut peak = f64::NEG_INFINITY;
    let (mut nonfinite_a, mut nonfinite_b) = (0, 0);
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        nonfinite_a += usize::from(!crate::spectrum::is_finite(*pa));
        nonfinite_b += usize::from(!crate::spectrum::is_finite(*pb));
        let (ca, cb) = (channels(*pa), channels(*pb));
        for c in 0..3 {
            let d = ca[c] - cb[c];
            se += d * d;
            rel += d * d / (cb[c] * cb[c] + epsilon);
            sum_a[c] += ca[c];
            sum_b[c] += cb[c];
            // f64::max ignores NaN, so a NaN reference pixel does not hide the real peak.
            peak = peak.max(cb[c]);
        }
    }
    let n = (a.pixels.len() * 3) as f64;
    let mse = se / n;
    let mean_a = (sum_a[0] + sum_a[1] + sum_a[2]) / n;
    let mean_b = (sum_b[0] + sum_b[1] + sum_b[2]) / n;
    let psnr = psnr_from_mse(mse, peak);
    Ok(ErrorMetrics {
        mse,
        relmse: rel / n,
        epsilon,
        psnr,
        peak,
        mean_a,
        mean_b,
        mean_ratio: mean_a / mean_b,
        mean_ratio_rgb: [sum_a[0] / sum_b[0], sum_a[1] / sum_b[1], sum_a[2] / sum_b[2]],
        nonfinite_a,
        nonfinite_b,
    })
}

/// PSNR in dB for a given MSE and peak: 10·log10(peak²/mse). +∞ for mse = 0, None for peak ≤ 0
/// (or a non-finite peak), where no meaningful signal scale exists.
pub fn psnr_from_mse(mse: f64, peak: f64) -> Option<f64> {
    if !(peak > 0.0) || !peak.is_finite() {
        return None;
    }
    if mse == 0.0 {
        return Some(f64::INFINITY);
    }
    Some(10.0 * (peak * peak / mse).log10())
}

/// Per-pixel relative squared error, averaged over the three channels:
/// (1/3)·Σ_c (a_c − b_c)²/(b_c² + ε). Its image mean is `compare_images(..).relmse`.
pub fn relative_error_map(a: &Image, b: &Image, epsilon: f64) -> Result<Vec<f64>, CompareError> {
    check_sizes(a, b)?;
    check_epsilon(epsilon)?;
    Ok(a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(pa, pb)| {
            let (ca, cb) = (channels(*pa), channels(*pb));
            (0..3).map(|c| (ca[c] - cb[c]).powi(2) / (cb[c] * cb[c] + epsilon)).sum::<f64>() / 3.0
        })
        .collect())
}

/// The range of per-pixel relative squared error the false-colour map spans, as log10 values:
/// 1e-4 (darkest) to 1 (brightest). Fixed rather than fitted to each image so that maps of
/// different renders against one reference can be compared by eye; values outside are clamped,
/// NaN/Inf pixels are drawn magenta.
pub const FALSE_COLOUR_LOG10_RANGE: (f64, f64) = (-4.0, 0.0);

/// Viridis (van der Walt and Smith, matplotlib; CC0) sampled at ten evenly spaced stops, as
/// sRGB-encoded 8-bit values. Viridis is perceptually uniform and stays readable for common colour
/// vision deficiencies and in greyscale.
const VIRIDIS_STOPS: [[u8; 3]; 10] = [
    [0x44, 0x01, 0x54],
    [0x48, 0x28, 0x78],
    [0x3e, 0x49, 0x89],
    [0x31, 0x68, 0x8e],
    [0x26, 0x82, 0x8e],
    [0x1f, 0x9e, 0x89],
    [0x35, 0xb7, 0x79],
    [0x6e, 0xce, 0x58],
    [0xb5, 0xde, 0x2b],
    [0xfd, 0xe7, 0x25],
];

/// The colour map at `t` in [0, 1] (clamped), as linear RGB: interpolated between the stops in sRGB
/// (where they were designed to be even) and then linearised, because images leave plexus through
/// a writer that sRGB-encodes linear values for 8-bit formats.
pub fn colour_map(t: f64) -> Rgb {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS_STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS_STOPS.len() - 2);
    let f = (x - i as f64) as f32;
    let (s0, s1) = (VIRIDIS_STOPS[i], VIRIDIS_STOPS[i + 1]);
    let c = |k: usize| {
        let v = (s0[k] as f32 * (1.0 - f) + s1[k] as f32 * f) / 255.0;
        crate::film::tonemap::srgb_eotf(v)
    };
    Vec3::new(c(0), c(1), c(2))
}

/// A false-colour image of the per-pixel relative squared error (see [`relative_error_map`]),
/// log-scaled over [`FALSE_COLOUR_LOG10_RANGE`] through the viridis map. Linear RGB, ready for
/// `film::oiio::write_image`.
pub fn false_colour_error(a: &Image, b: &Image, epsilon: f64) -> Result<Image, CompareError> {
    let errors = relative_error_map(a, b, epsilon)?;
    let (lo, hi) = FALSE_COLOUR_LOG10_RANGE;
    let pixels = errors
        .iter()
        .map(|&e| {
            if !e.is_finite() {
                return Vec3::new(1.0, 0.0, 1.0);
            }
            // log10(0) = −∞ clamps to the bottom of the range, as it should.
            colour_map((e.log10() - lo) / (hi - lo))
        })
        .collect();
    Ok(Image { width: a.width, height: a.height, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_map_ends_are_the_viridis_ends_and_lightness_increases() {
        let lum = |c: Rgb| crate::spectrum::luminance(c);
        let lo = colour_map(0.0);
        assert!((lo.x - crate::film::tonemap::srgb_eotf(0x44 as f32 / 255.0)).abs() < 1e-6);
        let hi = colour_map(1.0);
        assert!((hi.z - crate::film::tonemap::srgb_eotf(0x25 as f32 / 255.0)).abs() < 1e-6);
        let mut prev = -1.0;
        for i in 0..=100 {
            let l = lum(colour_map(i as f64 / 100.0));
            assert!(l > prev, "luminance must increase along the map (t = {})", i as f64 / 100.0);
            prev = l;
        }
    }

    #[test]
    fn bad_epsilon_is_rejected() {
        let a = Image::new(2, 2);
        assert_eq!(compare_images(&a, &a, 0.0), Err(CompareError::BadEpsilon(0.0)));
        assert!(compare_images(&a, &a, f64::NAN).is_err());
    }
}
