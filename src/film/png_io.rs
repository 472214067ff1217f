//! Writing PNG with the `png` crate: the default render's second output, so that it needs no
//! OpenImageIO (src/film/oiio_library.rs says what loading that costs).

use std::io::Write;

/// Writes `width`×`height` 8-bit sRGB RGB `codes` (row 0 at the top, as
/// `tonemap::tonemap_srgb8` makes them) to `file`: the chunks OpenImageIO's PNG writer, which
/// plexus used before, wrote for them (sRGB with the gAMA and cHRM fallbacks of PNG 11.3.2.5, a
/// `Software` text), and the same pixels.
pub fn write_png(file: &mut std::fs::File, width: u32, height: u32, codes: &[u8]) -> Result<(), png::EncodingError> {
    let mut writer = std::io::BufWriter::new(file);
    {
        let mut encoder = png::Encoder::new(&mut writer, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        // Each row's filter chosen by the smallest sum of absolute differences, as libpng (under
        // OpenImageIO) does: the default render's image is 99.5 KB (105 KB with the crate's fixed
        // filter, 101 KB from OpenImageIO). The default deflate level; `Best` made a noisy
        // 3000×2000 image 13% smaller for 75% more CPU time in the whole render.
        encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        encoder.set_source_srgb(png::SrgbRenderingIntent::AbsoluteColorimetric);
        encoder.set_source_gamma(png::ScaledFloat::from_scaled(45455));
        encoder.set_source_chromaticities(png::SourceChromaticities::new(
            (0.3127, 0.3290),
            (0.64, 0.33),
            (0.30, 0.60),
            (0.15, 0.06),
        ));
        encoder.add_text_chunk("Software".into(), "plexus".into())?;
        let mut png = encoder.write_header()?;
        png.write_image_data(codes)?;
        png.finish()?;
    }
    writer.flush()?;
    Ok(())
}
