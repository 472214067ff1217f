//! OpenEXR through the `exr` crate: every EXR plexus writes ([`write_exr`]: renders, previews,
//! states), and reading (reference images for `compare`, image environment maps). The first valid layer is read at its largest resolution; its R, G, B channels become the
//! image (A is ignored), or a single Y channel is broadcast to grey. Any sample type (half, float,
//! uint) is converted to f32.

use std::path::{Path, PathBuf};

use exr::prelude::{AnyChannel, FlatSamples};
use thiserror::Error;

use super::Image;
use crate::spectrum::Rgb;

/// Why an EXR file could not be read as an RGB image.
#[derive(Debug, Error)]
pub enum ExrReadError {
    #[error("cannot read EXR file '{path}': {source}")]
    Exr { path: PathBuf, source: exr::error::Error },
    #[error("EXR file '{path}' has neither R, G and B channels nor a Y channel (it has: {channels})")]
    NoColourChannels { path: PathBuf, channels: String },
    #[error(
        "EXR file '{path}': channel '{channel}' is subsampled ({x}x{y}); only full-resolution channels are supported"
    )]
    Subsampled { path: PathBuf, channel: String, x: usize, y: usize },
    #[error("cannot read EXR file '{path}': {reason}")]
    Unreadable { path: PathBuf, reason: String },
    #[error(
        "EXR file '{path}' declares a {width}x{height} image of {bytes} bytes, more than its {size} bytes can hold \
         (truncated or corrupt)"
    )]
    Truncated { path: PathBuf, width: u64, height: u64, bytes: u64, size: u64 },
    #[error("EXR file '{path}' has an empty data window ({width}x{height})")]
    Empty { path: PathBuf, width: usize, height: usize },
}

/// The most uncompressed bytes one byte of an EXR file can stand for: deflate (ZIP, ZIPS) expands
/// at most 1032:1, and RLE, PIZ, PXR24 and the B44 formats less.
const MAX_EXPANSION: u64 = 1032;

/// Reads only the headers and refuses a file whose layers declare more pixel bytes than its size
/// could hold even at the best compression: the `exr` crate would allocate by the header (a
/// 16-byte file declaring a 2^31-pixel window) before finding the data missing.
fn check_declared_size(path: &Path, size: u64) -> Result<(), ExrReadError> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|source| ExrReadError::Exr { path: path.to_path_buf(), source })?;
    for header in meta.headers.iter() {
        let (w, h) = (header.layer_size.width() as u64, header.layer_size.height() as u64);
        let bytes = w.saturating_mul(h).saturating_mul(header.channels.bytes_per_pixel as u64);
        let expansion =
            if header.compression == exr::compression::Compression::Uncompressed { 1 } else { MAX_EXPANSION };
        if bytes > size.saturating_mul(expansion) {
            return Err(ExrReadError::Truncated { path: path.to_path_buf(), width: w, height: h, bytes, size });
        }
    }
    Ok(())
}

/// Finds the channel called `name`, or failing that one whose name ends in `.name` (a layer
/// prefix such as `beauty.R`).
fn find<'a>(channels: &'a [AnyChannel<FlatSamples>], name: &str) -> Option<&'a AnyChannel<FlatSamples>> {
    let suffix = format!(".{name}");
    channels
        .iter()
        .find(|c| c.name.to_string() == name)
        .or_else(|| channels.iter().find(|c| c.name.to_string().ends_with(&suffix)))
}

/// Reads `path` as a linear RGB image (row 0 at the top).
pub fn read_exr(path: &Path) -> Result<Image, ExrReadError> {
    let (_, size) = crate::input_file::open_regular(path)
        .map_err(|reason| ExrReadError::Unreadable { path: path.to_path_buf(), reason })?;
    check_declared_size(path, size)?;
    let image = exr::prelude::read_first_flat_layer_from_file(path)
        .map_err(|source| ExrReadError::Exr { path: path.to_path_buf(), source })?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    if width == 0 || height == 0 {
        return Err(ExrReadError::Empty { path: path.to_path_buf(), width, height });
    }
    let channels = &layer.channel_data.list[..];
    let selected: Vec<&AnyChannel<FlatSamples>> = match (find(channels, "R"), find(channels, "G"), find(channels, "B"))
    {
        (Some(r), Some(g), Some(b)) => vec![r, g, b],
        _ => match find(channels, "Y") {
            Some(y) => vec![y],
            None => {
                let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
                return Err(ExrReadError::NoColourChannels {
                    path: path.to_path_buf(),
                    channels: if names.is_empty() { "no channels".into() } else { names.join(", ") },
                });
            }
        },
    };
    for c in &selected {
        if c.sampling.x() != 1 || c.sampling.y() != 1 || c.sample_data.len() != width * height {
            return Err(ExrReadError::Subsampled {
                path: path.to_path_buf(),
                channel: c.name.to_string(),
                x: c.sampling.x(),
                y: c.sampling.y(),
            });
        }
    }
    let planes: Vec<Vec<f32>> = selected.iter().map(|c| c.sample_data.values_as_f32().collect()).collect();
    let pixels = match planes.as_slice() {
        [r, g, b] => r.iter().zip(g).zip(b).map(|((&r, &g), &b)| Rgb::new(r, g, b)).collect(),
        [y] => y.iter().map(|&y| Rgb::splat(y)).collect(),
        _ => unreachable!("one or three channels were selected above"),
    };
    Ok(Image { width, height, pixels })
}

/// Writes `image` as one layer of R, G and B channels, 32-bit float or (`half`) 16-bit half
/// (rounded to nearest even), ZIP-compressed in blocks of 16 scan lines, row 0 at the top: what
/// OpenImageIO's EXR writer, which plexus used before, writes by default. The caller gives the
/// file (a temporary one, see `interrupt::write_atomically`).
pub fn write_exr(file: &mut std::fs::File, image: &Image, half: bool) -> Result<(), exr::error::Error> {
    use exr::prelude::{f16, Encoding, Layer, LayerAttributes, SpecificChannels, Text, Vec2, WritableImage};
    let attributes = LayerAttributes { software_name: Some(Text::from("plexus")), ..LayerAttributes::default() };
    let encoding = Encoding {
        compression: exr::compression::Compression::ZIP16,
        blocks: exr::prelude::Blocks::ScanLines,
        line_order: exr::prelude::LineOrder::Increasing,
    };
    let size = (image.width, image.height);
    let pixel = |p: Vec2<usize>| image.pixels[p.y() * image.width + p.x()];
    let writer = std::io::BufWriter::new(file);
    if half {
        let channels = SpecificChannels::rgb(|p| {
            let c = pixel(p);
            (f16::from_f32(c.x), f16::from_f32(c.y), f16::from_f32(c.z))
        });
        exr::prelude::Image::from_layer(Layer::new(size, attributes, encoding, channels)).write().to_buffered(writer)
    } else {
        let channels = SpecificChannels::rgb(|p| {
            let c = pixel(p);
            (c.x, c.y, c.z)
        });
        exr::prelude::Image::from_layer(Layer::new(size, attributes, encoding, channels)).write().to_buffered(writer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::{f16, write_rgba_file, AnyChannels, SmallVec, WritableImage};

    /// A path `name` in a fresh directory that is removed with the returned guard.
    fn temp(name: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::Builder::new().prefix("plexus-exr-io-").tempdir().expect("temp dir");
        let path = dir.path().join(name);
        (dir, path)
    }

    #[test]
    fn reads_rgba_half_ignoring_alpha() {
        let (_dir_path, path) = temp("rgba.exr");
        write_rgba_file(&path, 3, 2, |x, y| {
            (f16::from_f32(x as f32), f16::from_f32(y as f32), f16::from_f32(-0.5), f16::from_f32(0.25))
        })
        .unwrap();
        let img = read_exr(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.get(2, 1), Rgb::new(2.0, 1.0, -0.5));
        assert_eq!(img.get(0, 1), Rgb::new(0.0, 1.0, -0.5));
    }

    #[test]
    fn broadcasts_luminance_only_files() {
        let (_dir_path, path) = temp("y.exr");
        let values: Vec<f32> = (0..6).map(|i| i as f32 * 1.5).collect();
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Y", FlatSamples::F32(values))]));
        exr::prelude::Image::from_channels((2, 3), channels).write().to_file(&path).unwrap();
        let img = read_exr(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!((img.width, img.height), (2, 3));
        assert_eq!(img.get(1, 2), Rgb::splat(7.5));
    }

    #[test]
    fn errors_name_the_file() {
        let (_dir_missing, missing) = temp("missing.exr");
        let e = read_exr(&missing).unwrap_err().to_string();
        assert!(e.contains(&missing.display().to_string()), "{e}");

        let (_dir_path, path) = temp("z.exr");
        let channels =
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("Z", FlatSamples::F32(vec![1.0; 4]))]));
        exr::prelude::Image::from_channels((2, 2), channels).write().to_file(&path).unwrap();
        let e = read_exr(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(e, ExrReadError::NoColourChannels { .. }), "{e}");
        assert!(e.to_string().contains("(it has: Z)"), "{e}");

        let (_dir_garbage, garbage) = temp("garbage.exr");
        std::fs::write(&garbage, b"not an exr file").unwrap();
        let e = read_exr(&garbage).unwrap_err().to_string();
        std::fs::remove_file(&garbage).unwrap();
        assert!(e.contains("garbage.exr"), "{e}");
    }
}
