//! Texture lookups: bilinear interpolation between texel centres with wrap-around, the uv
//! convention (v = 0 at the bottom row, Mitsuba's), uscale/vscale, the checkerboard's layout, and
//! images read back through OpenImageIO with their sRGB decoding.

use std::sync::Arc;

use glam::Vec2;

use super::*;
use crate::film::oiio::{read_image, read_image_as_float, write_image, WriteOptions};
use crate::film::tonemap::srgb_oetf;
use crate::film::Image;

/// A 4×2 image with distinct texels: texel (i, j) = (i, j, 1)/8.
fn image() -> TexelImage {
    let (w, h) = (4, 2);
    let texels = (0..h).flat_map(|j| (0..w).map(move |i| Rgb::new(i as f32 / 8.0, j as f32 / 8.0, 0.125))).collect();
    TexelImage::from_texels(w, h, texels)
}

fn close(a: Rgb, b: Rgb) -> bool {
    (a - b).abs().max_element() < 1e-6
}

/// At texel centres the lookup is the texel; halfway between two centres it is their mean; across
/// the seam (s = 0) it blends the first and the last column (wrap), never a clamped edge. The
/// wrong variant (clamp to edge) differs at the seam.
#[test]
fn bilinear_hits_centres_and_wraps() {
    let img = image();
    for j in 0..2 {
        for i in 0..4 {
            let s = (i as f32 + 0.5) / 4.0;
            let t = (j as f32 + 0.5) / 2.0;
            assert!(close(img.bilinear(s, t), img.texel(i, j)), "texel ({i}, {j})");
            // One period away, the same.
            assert!(close(img.bilinear(s + 3.0, t - 2.0), img.texel(i, j)));
        }
    }
    let mid = img.bilinear(0.25, 0.25);
    assert!(close(mid, (img.texel(0, 0) + img.texel(1, 0)) * 0.5));
    let seam = img.bilinear(0.0, 0.25);
    let wrapped = (img.texel(0, 0) + img.texel(3, 0)) * 0.5;
    assert!(close(seam, wrapped), "{seam:?} vs {wrapped:?}");
    assert!(!close(seam, img.texel(0, 0)), "a clamped edge would give the first column");
}

/// (u, v) = (½W⁻¹, ½H⁻¹) is the centre of the bottom-left texel: v = 0 is the bottom (OBJ's
/// convention, which Mitsuba reaches by flipping v at load and looking up from the top). uscale
/// and vscale multiply before the wrap.
#[test]
fn uv_convention_and_scales() {
    let img = Arc::new(image());
    let t = Texture::Bitmap { image: img.clone(), uscale: 1.0, vscale: 1.0 };
    assert!(close(t.eval(Vec2::new(0.125, 0.25)), img.texel(0, 1)), "bottom-left texel");
    assert!(close(t.eval(Vec2::new(0.125, 0.75)), img.texel(0, 0)), "top-left texel");
    let scaled = Texture::Bitmap { image: img.clone(), uscale: 2.0, vscale: 3.0 };
    // u = 0.0625·2 = 0.125 (first column centre); 1 − v = 0.25/3·3 = 0.25 (top row centre).
    assert!(close(scaled.eval(Vec2::new(0.0625, 1.0 - 0.25 / 3.0)), img.texel(0, 0)));
}

/// colour0 on the squares where s and t are in the same half of their period.
#[test]
fn checkerboard_layout() {
    let c = Texture::Checkerboard { colour0: Rgb::ONE, colour1: Rgb::ZERO, uscale: 2.0, vscale: 2.0 };
    // (u, v) → (s, t) = (2u, 2(1 − v)).
    assert_eq!(c.eval(Vec2::new(0.1, 0.9)), Rgb::ONE); // s 0.2, t 0.2
    assert_eq!(c.eval(Vec2::new(0.3, 0.9)), Rgb::ZERO); // s 0.6, t 0.2
    assert_eq!(c.eval(Vec2::new(0.3, 0.7)), Rgb::ONE); // s 0.6, t 0.6
    assert_eq!(c.eval(Vec2::new(0.6, 0.9)), Rgb::ONE); // s 1.2, t 0.2
    assert_eq!(c.mean(), Rgb::splat(0.5));
}

/// An 8-bit PNG written with the sRGB encoding reads back, decoded, as the linear values within
/// half an 8-bit step of the encoding (slope of the decoding × 0.5/255); a float EXR reads back
/// exactly and is not decoded. Reading the PNG without decoding (the wrong variant) is off by far
/// more (0.5 encodes to 0.735).
#[test]
fn images_read_through_oiio_with_their_encoding() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut img = Image::new(3, 2);
    let values = [0.02f32, 0.2, 0.5, 0.8, 0.95, 1.0];
    for (p, &v) in img.pixels.iter_mut().zip(&values) {
        *p = Rgb::new(v, v * 0.5, 1.0 - v);
    }
    let png = dir.path().join("t.png");
    write_image(&png, &img, &WriteOptions::default()).expect("png");
    let read = read_image(&png).expect("read png");
    assert!(!read.is_float);
    let decoded = TexelImage::from_read(read.clone(), read.srgb.unwrap_or(true));
    let raw = TexelImage::from_read(read.clone(), false);
    for (k, p) in img.pixels.iter().enumerate() {
        for c in 0..3 {
            let v = p[c];
            let slope =
                if v > 0.0031308 { 2.4 * (srgb_oetf(v) + 0.055).powf(1.4) / 1.055f32.powf(2.4) } else { 1.0 / 12.92 };
            let tol = slope * 0.5 / 255.0 + 1e-6;
            assert!(
                (decoded.texel(k % 3, k / 3)[c] - v).abs() <= tol,
                "texel {k} channel {c}: {} vs {v}",
                decoded.texel(k % 3, k / 3)[c]
            );
        }
    }
    assert!((raw.texel(2, 0).x - 0.5).abs() > 0.2);
    let exr = dir.path().join("t.exr");
    write_image(&exr, &img, &WriteOptions::default()).expect("exr");
    let read = read_image(&exr).expect("read exr");
    assert!(read.is_float && read.srgb != Some(true));
    let linear = TexelImage::from_read(read.clone(), false);
    let texels: Vec<Rgb> = (0..6).map(|k| linear.texel(k % 3, k / 3)).collect();
    assert_eq!(texels, img.pixels);
    assert!(!linear.is_coded(), "a float image is held as f32");
    assert!(read_image(&dir.path().join("missing.png")).is_err());
}

/// A PNG's colours read as stored, whatever its alpha: plexus ignores a texture's alpha channel
/// (opacity is its own parameter), as Mitsuba 3 does. The file is 2×1 RGBA, 8 bits, unassociated
/// as PNG always is: (255, 255, 255, 0) and (255, 0, 0, 128). OpenImageIO's default multiplies
/// the colours by alpha on read, which made the first texel black and the second half red: the
/// living room's leaves (leaf.png, white where alpha is 0, an opacity mask read from the colours)
/// were see-through where Mitsuba 3 renders them opaque, 9.5% too dark in the crosscheck's region 8.
#[test]
fn png_colours_are_read_unassociated_from_alpha() {
    const RGBA_PNG: [u8; 74] = [
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
        0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x08, 0x06, 0x00, 0x00, 0x00, 0xf4, 0x22, 0x7f, 0x8a, 0x00, 0x00, 0x00,
        0x11, 0x49, 0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0xf8, 0xff, 0xff, 0x3f, 0xc3, 0x7f, 0x06, 0x86, 0x06, 0x00,
        0x19, 0x70, 0x04, 0x7d, 0x5e, 0x3e, 0xdb, 0xa4, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42,
        0x60, 0x82,
    ];
    let dir = tempfile::tempdir().expect("temp dir");
    let png = dir.path().join("rgba.png");
    std::fs::write(&png, RGBA_PNG).expect("write png");
    let read = read_image(&png).expect("read png");
    assert_eq!((read.width, read.height, read.channels), (2, 1, 4));
    let texels = TexelImage::from_read(read.clone(), read.srgb.unwrap_or(true));
    assert_eq!(texels.texel(0, 0), Rgb::ONE, "alpha 0 must not blacken the colour");
    assert_eq!(texels.texel(1, 0), Rgb::new(1.0, 0.0, 0.0), "alpha 0.5 must not halve the colour");
    // Four channels are read as codes too, alpha left out, with the float read's texels.
    assert!(matches!(read.data, ReadPixels::Rgb8 { .. }));
    let floats = TexelImage::from_read(read_image_as_float(&png).expect("read as float"), true);
    assert_eq!((floats.texel(0, 0), floats.texel(1, 0)), (texels.texel(0, 0), texels.texel(1, 0)));
}

/// The lookup as it was written first (f64 `rem_euclid`, `floor`, each texel index wrapped by an
/// integer `rem_euclid`): the oracle for the faster `TexelImage::bilinear`.
fn bilinear_reference(img: &TexelImage, s: f32, t: f32) -> Rgb {
    let texel = |i: i64, j: i64| {
        let x = i.rem_euclid(img.width as i64) as usize;
        let y = j.rem_euclid(img.height as i64) as usize;
        img.texel(x, y)
    };
    let x = f64::from(s).rem_euclid(1.0) * img.width as f64 - 0.5;
    let y = f64::from(t).rem_euclid(1.0) * img.height as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let (i, j) = (x0 as i64, y0 as i64);
    let top = texel(i, j) * (1.0 - fx) + texel(i + 1, j) * fx;
    let bottom = texel(i, j + 1) * (1.0 - fx) + texel(i + 1, j + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Coordinates that probe every branch of the wrap: random ones over several periods either side
/// of 0, random bit patterns (any magnitude, ±∞, NaN), integers, values within an ulp of an integer
/// (whose reduction rounds to 1), texel centres and the midpoints between them.
fn probe_coordinates(n: usize) -> Vec<f32> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(20);
    let mut v: Vec<f32> = (0..20_000).map(|_| rng.gen_range(-5.0f32..5.0)).collect();
    v.extend((0..20_000).map(|_| f32::from_bits(rng.gen())));
    for k in -3i32..=3 {
        let k = k as f32;
        v.extend([k, -0.0, 0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-30, -1e-30, 3e7, -3e7]);
        v.extend([k.next_up(), k.next_down(), k + 0.5, (k + 1e-7).next_down()]);
    }
    for i in 0..=2 * n {
        v.push(i as f32 / (2 * n) as f32);
        v.push(-(i as f32) / (2 * n) as f32);
    }
    v
}

/// The fast lookup gives the reference's result bit for bit (NaN where it gives NaN) on images of
/// one texel, a row, a column and the 4×2 test image. The wrong variant (the coordinate reduced in
/// f32, `s - s.floor()`, which loses the fraction of large uvs and rounds differently) differs on
/// the same probes, so the comparison can see a change of arithmetic.
#[test]
fn bilinear_is_bit_identical_to_the_reference() {
    let same = |a: Rgb, b: Rgb| (0..3).all(|c| a[c].to_bits() == b[c].to_bits() || (a[c].is_nan() && b[c].is_nan()));
    let single = TexelImage::from_texels(1, 1, vec![Rgb::new(0.25, 0.5, 0.75)]);
    let row = TexelImage::from_texels(3, 1, vec![Rgb::X, Rgb::Y, Rgb::Z]);
    let column = TexelImage::from_texels(1, 3, vec![Rgb::X, Rgb::Y, Rgb::Z]);
    for img in [image(), single, row, column] {
        let coords = probe_coordinates(img.width.max(img.height));
        let mut wrong_differs = 0usize;
        for (k, &s) in coords.iter().enumerate() {
            let t = coords[(k * 7919 + 13) % coords.len()];
            let fast = img.bilinear(s, t);
            let reference = bilinear_reference(&img, s, t);
            assert!(same(fast, reference), "({s:e}, {t:e}) on {}×{}: {fast:?} vs {reference:?}", img.width, img.height);
            let wrong = bilinear_reference(&img, s - s.floor(), t - t.floor());
            if !same(wrong, reference) {
                wrong_differs += 1;
            }
        }
        if img.width * img.height > 1 {
            assert!(wrong_differs > 100, "the f32 reduction differs on only {wrong_differs} probes");
        }
    }
}

/// An 8-bit image (as OpenImageIO hands out a PNG or JPEG) is held as byte codes and decodes to the
/// texels of the f32 form bit for bit, sRGB-decoded or not, at every texel and in bilinear lookups,
/// in a quarter of the memory; values that are not 8-bit levels (the wrong input for the coded
/// form: 0.5 + 1e-3, or the same level given as two different f32s) keep the f32 form.
#[test]
fn eight_bit_images_are_held_as_codes_bit_for_bit() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(8);
    let (w, h) = (37, 23);
    // Levels as OpenImageIO converts them (c · (1/255) in f32) for RGB, grey and grey+alpha.
    for channels in [3usize, 4, 1, 2] {
        let data: Vec<f32> = (0..w * h * channels).map(|_| f32::from(rng.gen::<u8>()) * (1.0 / 255.0)).collect();
        let img = ReadImage {
            width: w,
            height: h,
            channels,
            data: ReadPixels::Float(data.clone()),
            is_float: false,
            srgb: None,
        };
        for srgb in [true, false] {
            let coded = TexelImage::from_read(img.clone(), srgb);
            assert!(coded.is_coded(), "{channels} channels");
            let decode = |v: f32| if srgb { srgb_eotf(v) } else { v };
            let linear = TexelImage::from_texels(
                w,
                h,
                data.chunks_exact(channels)
                    .map(|p| {
                        if channels >= 3 {
                            Rgb::new(decode(p[0]), decode(p[1]), decode(p[2]))
                        } else {
                            Rgb::splat(decode(p[0]))
                        }
                    })
                    .collect(),
            );
            // 3 bytes a texel and the 256-entry table, against 12 bytes a texel.
            assert_eq!((coded.memory_bytes(), linear.memory_bytes()), (w * h * 3 + 256 * 4, w * h * 12));
            for j in 0..h {
                for i in 0..w {
                    assert_eq!(
                        coded.texel(i, j).to_array().map(f32::to_bits),
                        linear.texel(i, j).to_array().map(f32::to_bits)
                    );
                }
            }
            for _ in 0..2000 {
                let (s, t) = (rng.gen_range(-2.0f32..2.0), rng.gen_range(-2.0f32..2.0));
                let (a, b) = (coded.bilinear(s, t), linear.bilinear(s, t));
                assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "({s}, {t})");
            }
            assert_eq!(coded.mean(), linear.mean());
        }
    }
    let off_level = ReadImage {
        width: 2,
        height: 1,
        channels: 1,
        data: ReadPixels::Float(vec![0.5 + 1e-3, 0.2]),
        is_float: false,
        srgb: None,
    };
    assert!(!TexelImage::from_read(off_level, false).is_coded());
    let level = 100.0f32 / 255.0;
    let twice = ReadImage {
        width: 2,
        height: 1,
        channels: 1,
        data: ReadPixels::Float(vec![level, level.next_up()]),
        is_float: false,
        srgb: None,
    };
    let t = TexelImage::from_read(twice, false);
    assert!(!t.is_coded());
    assert_eq!((t.texel(0, 0).x, t.texel(1, 0).x), (level, level.next_up()));
}

/// An 8-bit file (PNG, JPEG; RGB, grey, grey and alpha) is read as its byte codes
/// (`ReadPixels::Rgb8`), and its texels are those of reading it as floats, bit for bit,
/// sRGB-decoded or not: the table of levels is OpenImageIO's own conversion, and a grey file's
/// colour its first channel. Random colours, so that nearly every code occurs. Levels computed as
/// c / 255 (a division, not OpenImageIO's product c · (1/255)) fail it; so does a grey and alpha
/// file read from its second channel (alpha 255, 0, 128 under grey 0, 100, 255).
#[test]
fn eight_bit_files_are_read_as_codes_with_the_float_reads_texels() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(20);
    let dir = tempfile::tempdir().expect("temp dir");
    let (w, h) = (97, 61);
    let mut img = Image::new(w, h);
    for p in img.pixels.iter_mut() {
        *p = Rgb::new(rng.gen(), rng.gen(), rng.gen());
    }
    // 3×1 PNGs of 8-bit grey (0, 100, 255) and grey with alpha ((0, 255), (100, 0), (255, 128)).
    const GREY_PNG: [u8; 69] = [
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
        0x00, 0x03, 0x00, 0x00, 0x00, 0x01, 0x08, 0x00, 0x00, 0x00, 0x00, 0x3e, 0x8b, 0x4b, 0x68, 0x00, 0x00, 0x00,
        0x0c, 0x49, 0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0x60, 0x48, 0xf9, 0x0f, 0x00, 0x01, 0xcb, 0x01, 0x64, 0x6f,
        0xf3, 0x01, 0xae, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
    ];
    const GREY_ALPHA_PNG: [u8; 72] = [
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
        0x00, 0x03, 0x00, 0x00, 0x00, 0x01, 0x08, 0x04, 0x00, 0x00, 0x00, 0xb1, 0xe9, 0xdc, 0x3f, 0x00, 0x00, 0x00,
        0x0f, 0x49, 0x44, 0x41, 0x54, 0x78, 0xda, 0x63, 0x60, 0xf8, 0x9f, 0xc2, 0xf0, 0xbf, 0x01, 0x00, 0x09, 0x10,
        0x02, 0xe3, 0x07, 0x9f, 0xbc, 0x60, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
    ];
    std::fs::write(dir.path().join("grey.png"), GREY_PNG).expect("write");
    std::fs::write(dir.path().join("grey-alpha.png"), GREY_ALPHA_PNG).expect("write");
    for name in ["t.png", "t.jpg", "grey.png", "grey-alpha.png"] {
        let path = dir.path().join(name);
        if name.starts_with('t') {
            write_image(&path, &img, &WriteOptions::default()).expect("write");
        }
        let codes = read_image(&path).expect("read");
        assert!(matches!(codes.data, ReadPixels::Rgb8 { .. }), "{name} is read as codes");
        let floats = read_image_as_float(&path).expect("read as float");
        assert!(matches!(floats.data, ReadPixels::Float(_)));
        for srgb in [true, false] {
            let (a, b) = (TexelImage::from_read(codes.clone(), srgb), TexelImage::from_read(floats.clone(), srgb));
            assert!(a.is_coded() && b.is_coded());
            for j in 0..codes.height {
                for i in 0..codes.width {
                    let (x, y) = (a.texel(i, j), b.texel(i, j));
                    assert_eq!(x.to_array().map(f32::to_bits), y.to_array().map(f32::to_bits), "{name} ({i}, {j})");
                }
            }
        }
    }
}
