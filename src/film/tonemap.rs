//! The display transform for 8-bit outputs (PNG, JPEG, ...): scale by the exposure, clamp to
//! [0, 1], encode with the sRGB transfer function, round to the nearest 8-bit code.
//!
//! This is deliberately the plainest transform: no curve compresses highlights, so a pixel's code
//! value is a direct, invertible function of its radiance below the clipping point, and a PNG can be
//! compared against the EXR it came from. Float outputs (EXR, HDR, TIFF) are written linear and
//! untouched.

use super::Image;

/// The sRGB opto-electronic transfer function (IEC 61966-2-1): linear `[0, 1]` to encoded
/// `[0, 1]`. A linear segment of slope 12.92 near black, a 1/2.4 power above 0.0031308.
#[inline]
pub fn srgb_oetf(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of [`srgb_oetf`] (the sRGB EOTF): encoded `[0, 1]` to linear.
#[inline]
pub fn srgb_eotf(encoded: f32) -> f32 {
    if encoded <= 0.040_45 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

/// The multiplier for an exposure of `stops` (each stop doubles the brightness).
#[inline]
pub fn exposure_scale(stops: f32) -> f32 {
    stops.exp2()
}

/// One linear value, already multiplied by the exposure scale, to its 8-bit sRGB code. Negative
/// values and NaN map to 0, values of 1 and above (and +inf) to 255.
#[inline]
pub fn encode_srgb8(linear: f32) -> u8 {
    // Written so that NaN fails the first test.
    let clamped = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
    // In [0, 255.5): the cast truncates, so adding 0.5 rounds to nearest.
    (srgb_oetf(clamped) * 255.0 + 0.5) as u8
}

/// The image as interleaved 8-bit sRGB triples (row 0 first), after multiplying by
/// `2^exposure_stops`.
pub fn tonemap_srgb8(image: &Image, exposure_stops: f32) -> Vec<u8> {
    let scale = exposure_scale(exposure_stops);
    let mut out = Vec::with_capacity(image.pixels.len() * 3);
    for p in &image.pixels {
        out.push(encode_srgb8(p.x * scale));
        out.push(encode_srgb8(p.y * scale));
        out.push(encode_srgb8(p.z * scale));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::Rgb;

    #[test]
    fn oetf_and_eotf_are_inverse_and_continuous() {
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            assert!((srgb_eotf(srgb_oetf(x)) - x).abs() < 1e-5, "x = {x}");
        }
        // The two pieces meet at the break point (to the precision of the standard's constants).
        let b = 0.003_130_8f32;
        assert!((12.92 * b - (1.055 * b.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
    }

    #[test]
    fn codes_round_clamp_and_reject_nan() {
        assert_eq!(encode_srgb8(0.0), 0);
        assert_eq!(encode_srgb8(-3.0), 0);
        assert_eq!(encode_srgb8(f32::NAN), 0);
        assert_eq!(encode_srgb8(1.0), 255);
        assert_eq!(encode_srgb8(7.0), 255);
        assert_eq!(encode_srgb8(f32::INFINITY), 255);
        // Mid grey (18%) encodes to 0.4613 → 117.6 → 118.
        assert_eq!(encode_srgb8(0.18), 118);
        // Every code is reproduced by decoding it and encoding again (rounding is to nearest).
        for code in 0..=255u8 {
            assert_eq!(encode_srgb8(srgb_eotf(code as f32 / 255.0)), code);
        }
    }

    #[test]
    fn exposure_doubles_per_stop() {
        let mut img = Image::new(2, 1);
        img.pixels[0] = Rgb::splat(0.25);
        img.pixels[1] = Rgb::new(0.5, 0.0, 2.0);
        let plus_one = tonemap_srgb8(&img, 1.0);
        assert_eq!(&plus_one[0..3], &[encode_srgb8(0.5); 3]);
        assert_eq!(&plus_one[3..6], &[255, 0, 255]);
        assert_eq!(tonemap_srgb8(&img, -1.0)[3], encode_srgb8(0.25));
    }
}
