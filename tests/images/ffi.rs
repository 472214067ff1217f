//! Round trips through the FFI: images written by the OpenImageIO shim and read back with the `exr`
//! crate, the writer's error paths and temporary-file hygiene, and Embree's error path.

use std::path::Path;
use std::sync::Arc;

use exr::prelude::{read_first_flat_layer_from_file, FlatSamples};
use glam::Vec3;
use plexus::accel::{self, embree::EmbreeAccel, AccelError, AccelKind};
use plexus::film::exr_io::read_exr;
use plexus::film::oiio::{check_output_path, write_image, ImageWriteError, WriteOptions};
use plexus::film::Image;
use plexus::geometry::{Ray, TriangleMesh};
use plexus::spectrum::Rgb;

/// A fresh, empty directory for one test.
fn scratch_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("plexus-ffi-{name}-")).tempdir().expect("create temp dir")
}

/// Names of the entries of `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

/// A 7×5 image whose values exercise every part of an f32: fractional bits, signs, large and tiny
/// magnitudes (a subnormal included) and exact zeros.
fn test_image() -> Image {
    let (w, h) = (7, 5);
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as f32;
            img.pixels[y * w + x] = Rgb::new(0.1 + i * 0.013_7, -(i * 1.234_567e3) - 0.333, (i - 17.0) * 3.3e30);
        }
    }
    img.pixels[0] = Rgb::new(f32::MIN_POSITIVE, 1.0e-42, -0.0);
    img.pixels[1] = Rgb::new(f32::MAX, -f32::MAX, std::f32::consts::PI);
    img
}

/// The R, G, B planes of the first layer of an EXR file, as the `exr` crate reads them, plus the
/// layer size and whether every channel was stored as half.
fn read_planes(path: &Path) -> ((usize, usize), [Vec<f32>; 3], bool) {
    let image = read_first_flat_layer_from_file(path).unwrap();
    let layer = image.layer_data;
    let get = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .unwrap_or_else(|| panic!("no channel {name}"))
    };
    let (r, g, b) = (get("R"), get("G"), get("B"));
    let all_half = [r, g, b].iter().all(|c| matches!(c.sample_data, FlatSamples::F16(_)));
    let plane = |c: &exr::prelude::AnyChannel<FlatSamples>| c.sample_data.values_as_f32().collect::<Vec<f32>>();
    ((layer.size.width(), layer.size.height()), [plane(r), plane(g), plane(b)], all_half)
}

#[test]
fn float_exr_round_trips_bit_for_bit() {
    let tmp = scratch_dir("float-exr");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("image.exr");
    let img = test_image();
    write_image(&path, &img, &WriteOptions::default()).unwrap();

    let (size, planes, all_half) = read_planes(&path);
    assert_eq!(size, (img.width, img.height));
    assert!(!all_half, "the default EXR pixel type is 32-bit float");
    for (i, p) in img.pixels.iter().enumerate() {
        for c in 0..3 {
            assert_eq!(planes[c][i].to_bits(), p[c].to_bits(), "pixel {i} channel {c}: {} vs {}", planes[c][i], p[c]);
        }
    }
    // The crate's own reader agrees (it is what `compare` and environment maps use).
    let back = read_exr(&path).unwrap();
    assert_eq!(
        back.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>(),
        img.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>()
    );
    assert_eq!(entries(&dir), ["image.exr"]);
    // And OpenImageIO, which reads EXR textures, reads the file the `exr` crate wrote as it is.
    let oiio = plexus::film::oiio::read_image(&path).unwrap();
    let plexus::film::oiio::ReadPixels::Float(values) = oiio.data else { panic!("an EXR is read as floats") };
    assert_eq!((oiio.width, oiio.height, oiio.channels), (img.width, img.height, 3));
    assert_eq!(
        values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        img.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>()
    );
}

/// EXR and PNG outputs (the default render writes both), and the check of their paths before a
/// render, must not load OpenImageIO (0.22 s and 130 MB per process, src/film/oiio_library.rs); a
/// JPEG output does. The dynamic loader's own log (`LD_DEBUG=libs`, on stderr) tells which
/// libraries a `plexus render` initialised: the JPEG render shows the check can fail.
#[test]
fn only_outputs_that_need_it_load_openimageio() {
    let tmp = scratch_dir("lazy-oiio");
    let loads_oiio = |out: &str| {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_plexus"))
            .args(["render", "--spp", "1", "--threads", "1", "--out"])
            .arg(tmp.path().join(out))
            .env("LD_DEBUG", "libs")
            .output()
            .unwrap();
        assert!(output.status.success(), "{out}: {}", String::from_utf8_lossy(&output.stderr));
        assert!(tmp.path().join(out).is_file(), "{out} was not written");
        let log = String::from_utf8_lossy(&output.stderr);
        assert!(log.contains("libembree3"), "{out}: no loader log on stderr:\n{log}");
        log.contains("libOpenImageIO")
    };
    assert!(!loads_oiio("image.exr"), "an EXR render loaded OpenImageIO");
    assert!(!loads_oiio("image.png"), "a PNG render loaded OpenImageIO");
    assert!(loads_oiio("image.jpg"), "a JPEG render did not load OpenImageIO");
}

/// Without a usable OpenImageIO (here a broken `libOpenImageIO.so.2.4` found first through
/// `LD_LIBRARY_PATH`), EXR and PNG renders still work, and a JPEG output is refused before
/// rendering with the loader's reason, once.
#[test]
fn without_openimageio_exr_and_png_still_work_and_jpeg_is_refused_with_the_reason() {
    let tmp = scratch_dir("no-oiio");
    let libs = tmp.path().join("lib");
    std::fs::create_dir(&libs).unwrap();
    std::fs::write(libs.join("libOpenImageIO.so.2.4"), b"not a library").unwrap();
    let render = |out: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_plexus"))
            .args(["render", "--spp", "1", "--threads", "1", "--out"])
            .arg(tmp.path().join(out))
            .env("LD_LIBRARY_PATH", &libs)
            .output()
            .unwrap()
    };
    for out in ["image.exr", "image.png"] {
        let done = render(out);
        assert!(done.status.success(), "{out}: {}", String::from_utf8_lossy(&done.stderr));
    }
    let jpeg = render("image.jpg");
    let err = String::from_utf8_lossy(&jpeg.stderr);
    assert_eq!(jpeg.status.code(), Some(2), "{err}");
    assert!(err.contains("OpenImageIO could not be loaded") && err.contains("file too short"), "{err}");
    assert!(err.contains("EXR and PNG files are written without it") && !err.contains("in-memory"), "{err}");
    // Refused before rendering: nothing new beside the two renders' images and JSON.
    assert_eq!(entries(tmp.path()), ["image.exr", "image.json", "image.png", "lib"]);
}

/// A PNG written by the `png` crate reads back through OpenImageIO (the texture reader) as the
/// tone mapper's codes, byte for byte, and says it is sRGB; with exposure, as the tone mapper
/// applies it.
#[test]
fn png_reads_back_through_openimageio_as_the_tone_mappers_codes() {
    let tmp = scratch_dir("png");
    let path = tmp.path().join("image.png");
    let mut img = Image::new(9, 7);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        let v = i as f32 / 20.0;
        *p = Rgb::new(v, 1.0 - v * 0.5, (v * 7.0).sin().abs() * 3.0);
    }
    for exposure in [0.0, -1.5] {
        write_image(&path, &img, &WriteOptions { exposure, ..WriteOptions::default() }).unwrap();
        let read = plexus::film::oiio::read_image(&path).unwrap();
        assert_eq!((read.width, read.height, read.channels), (9, 7, 3));
        assert_eq!(read.srgb, Some(true), "the file says it is sRGB");
        let plexus::film::oiio::ReadPixels::Rgb8 { texels, .. } = read.data else { panic!("a PNG is read as codes") };
        let codes: Vec<u8> = texels.iter().flatten().copied().collect();
        assert_eq!(codes, plexus::film::tonemap::tonemap_srgb8(&img, exposure), "exposure {exposure}");
    }
    assert_eq!(entries(tmp.path()), ["image.png"]);
}

#[test]
fn half_exr_is_within_half_precision() {
    let tmp = scratch_dir("half-exr");
    let dir = tmp.path().to_path_buf();
    let path = dir.join("image.exr");
    // Values inside half's normal range [2^-14, 65504]: rounding to nearest half changes each by
    // at most half an ulp, a relative 2^-11.
    let mut img = Image::new(16, 4);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        let v = 1.0e-4 * 1.21f32.powi(i as i32);
        *p = Rgb::new(v, -v * 0.77, v + 0.123_456_7);
    }
    write_image(&path, &img, &WriteOptions { half: true, ..WriteOptions::default() }).unwrap();
    let (size, planes, all_half) = read_planes(&path);
    assert_eq!(size, (16, 4));
    assert!(all_half, "half was requested");
    for (i, p) in img.pixels.iter().enumerate() {
        for c in 0..3 {
            let rel = ((planes[c][i] - p[c]) / p[c]).abs();
            assert!(rel <= 2f32.powi(-11), "pixel {i} channel {c}: wrote {}, read {} (rel {rel})", p[c], planes[c][i]);
        }
    }
}

#[test]
fn eight_bit_and_other_float_formats_are_written() {
    let tmp = scratch_dir("formats");
    let dir = tmp.path().to_path_buf();
    let mut img = Image::new(8, 6);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        *p = Rgb::new(i as f32 / 48.0, 0.5, 2.0);
    }
    let magic: [(&str, &[u8]); 4] =
        [("png", b"\x89PNG\r\n\x1a\n"), ("jpg", b"\xff\xd8\xff"), ("hdr", b"#?"), ("tif", b"II*\0")];
    for (ext, signature) in magic {
        let path = dir.join(format!("image.{ext}"));
        write_image(&path, &img, &WriteOptions::default()).unwrap_or_else(|e| panic!("{ext}: {e}"));
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.len() > 64, "{ext}: {} bytes", bytes.len());
        assert!(bytes.starts_with(signature), "{ext}: unexpected signature {:?}", &bytes[..8]);
    }
    assert_eq!(entries(&dir), ["image.hdr", "image.jpg", "image.png", "image.tif"]);

    // The PNG header (IHDR: width, height, bit depth, colour type) says 8×6, 8-bit RGB.
    let png = std::fs::read(dir.join("image.png")).unwrap();
    assert_eq!(&png[12..16], b"IHDR");
    assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 8);
    assert_eq!(u32::from_be_bytes(png[20..24].try_into().unwrap()), 6);
    assert_eq!((png[24], png[25]), (8, 2), "bit depth 8, colour type 2 (RGB)");
}

#[test]
fn bad_output_paths_are_refused_with_their_reason() {
    let tmp = scratch_dir("bad-paths");
    let dir = tmp.path().to_path_buf();
    let img = test_image();

    let missing = dir.join("no-such-dir").join("out.exr");
    let err = write_image(&missing, &img, &WriteOptions::default()).unwrap_err();
    assert!(matches!(err, ImageWriteError::MissingDirectory { .. }), "{err}");
    let text = err.to_string();
    assert!(
        text.contains(&format!("output directory '{}' does not exist", dir.join("no-such-dir").display())),
        "{text}"
    );
    assert_eq!(check_output_path(&missing).unwrap_err().to_string(), text);

    let unknown = dir.join("out.xyz");
    let err = write_image(&unknown, &img, &WriteOptions::default()).unwrap_err();
    assert!(matches!(err, ImageWriteError::UnsupportedFormat { .. }), "{err}");
    assert!(err.to_string().contains("OpenImageIO cannot write '.xyz' files"), "{err}");
    assert!(err.to_string().contains(&unknown.display().to_string()), "{err}");

    // A regular file where the directory should be.
    std::fs::write(dir.join("file"), b"x").unwrap();
    let err = check_output_path(&dir.join("file").join("out.png")).unwrap_err();
    assert!(matches!(err, ImageWriteError::NotADirectory { .. }), "{err}");

    assert_eq!(entries(&dir), ["file"], "nothing was created by the refused writes");
}

#[test]
fn no_temporary_file_is_left_behind() {
    let tmp = scratch_dir("temp-files");
    let dir = tmp.path().to_path_buf();
    let img = test_image();

    // Success: only the requested file, and writing again replaces it.
    let path = dir.join("out.exr");
    write_image(&path, &img, &WriteOptions::default()).unwrap();
    let mut brighter = img.clone();
    brighter.pixels[3] = Rgb::splat(42.0);
    write_image(&path, &brighter, &WriteOptions::default()).unwrap();
    assert_eq!(read_exr(&path).unwrap().pixels[3], Rgb::splat(42.0));
    assert_eq!(entries(&dir), ["out.exr"]);

    // An image larger than the format allows is refused before any file is created (libwebp would
    // only refuse it at close; that failure's clean-up is tested beside the writer, in film::oiio).
    let wide = Image::new(20_000, 1);
    let err = write_image(&dir.join("wide.webp"), &wide, &WriteOptions::default()).unwrap_err();
    assert!(matches!(err, ImageWriteError::TooLarge { .. }), "{err}");
    assert!(err.to_string().contains("wide.webp"), "{err}");
    assert_eq!(entries(&dir), ["out.exr"]);

    // libjpeg would exit() the process on an image above its size limit: refused before writing.
    let err = write_image(&dir.join("wide.jpg"), &Image::new(70_000, 1), &WriteOptions::default()).unwrap_err();
    assert!(matches!(err, ImageWriteError::TooLarge { max: 65500, .. }), "{err}");
    assert_eq!(entries(&dir), ["out.exr"]);

    // An existing directory under the requested name is refused before rendering.
    std::fs::create_dir(dir.join("taken.png")).unwrap();
    let err = check_output_path(&dir.join("taken.png")).unwrap_err();
    assert!(matches!(err, ImageWriteError::IsADirectory { .. }), "{err}");
    assert_eq!(entries(&dir), ["out.exr", "taken.png"]);

    // A malformed image is refused before anything touches the file system.
    let empty = Image { width: 0, height: 0, pixels: vec![] };
    assert!(matches!(
        write_image(&dir.join("e.exr"), &empty, &WriteOptions::default()),
        Err(ImageWriteError::BadImage { .. })
    ));
    assert_eq!(entries(&dir), ["out.exr", "taken.png"]);
}

fn quad() -> Arc<TriangleMesh> {
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    Arc::new(TriangleMesh::new(p, vec![[0, 1, 2], [0, 2, 3]], None, None).unwrap())
}

#[test]
fn embree_errors_are_results_and_queries_work_through_the_trait() {
    let err = EmbreeAccel::build_with_config(&[quad()], "threads=notanumber").err().expect("invalid configuration");
    assert!(matches!(err, AccelError::Embree(_)));
    assert!(err.to_string().starts_with("Embree: ") && err.to_string().contains("threads=notanumber"), "{err}");

    let accel = accel::build(AccelKind::Embree, &[quad()]).unwrap();
    assert_eq!(accel.kind(), AccelKind::Embree);
    let hit = accel.intersect(&Ray::new(Vec3::new(0.5, -0.5, 3.0), -Vec3::Z)).unwrap();
    assert!((hit.t - 3.0).abs() < 1e-6 && hit.geom_id == 0);
    assert!(accel.occluded(&Ray::new(Vec3::new(0.5, -0.5, 3.0), -Vec3::Z)));
    assert!(!accel.occluded(&Ray::new(Vec3::new(1.5, -0.5, 3.0), -Vec3::Z)));
}
