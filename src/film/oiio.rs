//! Writing images, and reading them for textures: EXR is written by the `exr` crate
//! ([`super::exr_io`]), PNG by the `png` crate ([`super::png_io`]), every other format through
//! OpenImageIO (the C shim in ffi/oiio_shim.cpp, loaded on first use by
//! [`super::oiio_library`]), which also reads every bitmap.
//!
//! The format follows the file extension. Floating-point formats (`.exr`, `.hdr`, `.tif`/`.tiff`,
//! `.pfm`) receive the linear image unchanged: `.exr` as 32-bit float, or half with
//! [`WriteOptions::half`]. Every other format OpenImageIO can write (`.png`, `.jpg`, `.bmp`, ...)
//! receives 8-bit sRGB from the display transform in [`super::tonemap`].
//!
//! Images are written to a hidden temporary file in the target directory and renamed over the
//! requested name only once complete, so a crash never leaves a truncated image under that name.

use std::ffi::{c_char, c_int, c_void, CString};
use std::path::{Path, PathBuf};

use thiserror::Error;

use super::{tonemap, Image};

use super::oiio_library::{
    shim, PlxImageInfo, PLX_DATA_FLOAT, PLX_DATA_UINT8, PLX_OK, PLX_PIXEL_FLOAT, PLX_PIXEL_HALF, PLX_PIXEL_UINT8,
};

/// Most texels a texture may have (2^28: 3 GiB of RGB floats), so a corrupt or hostile header
/// cannot ask for an absurd allocation.
pub const MAX_READ_TEXELS: usize = 1 << 28;

/// An image read from a file: its channels as stored (integers normalised to [0, 1]), row 0 at
/// the top.
#[derive(Clone, Debug)]
pub struct ReadImage {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    /// The values (see [`ReadPixels`]).
    pub data: ReadPixels,
    /// Whether the file stores floating-point pixels.
    pub is_float: bool,
    /// What the file says about its encoding: Some(true) sRGB, Some(false) linear, None silent.
    pub srgb: Option<bool>,
}

/// The values of a read image.
#[derive(Clone, Debug)]
pub enum ReadPixels {
    /// width·height·channels values as floats, interleaved.
    Float(Vec<f32>),
    /// An 8-bit file's colours as byte codes, one per texel, and the float OpenImageIO makes of
    /// each code: a texel's colour is `levels` of its codes, bit for bit what `Float` holds there.
    /// The colour is the file's first three channels, or its first repeated in a file of one or
    /// two (grey; a second or fourth channel, alpha, is not read): the rule
    /// `TexelImage::from_read` applies to `Float`. Read straight into the array a texture keeps,
    /// on huge pages, in a quarter of the floats' memory and without their conversion (the door's
    /// three photographs: 30 MB instead of 118 MB).
    Rgb8 { texels: Vec<[u8; 3]>, levels: Box<[f32; 256]> },
}

/// Why an image could not be read.
#[derive(Debug, Error)]
pub enum ImageReadError {
    #[error("cannot read image '{path}': the path contains a NUL byte or is not valid text")]
    InvalidPath { path: PathBuf },
    #[error("cannot read image '{path}': OpenImageIO: {message}")]
    Oiio { path: PathBuf, message: String },
    #[error("cannot read image '{path}': {message}")]
    OiioUnavailable { path: PathBuf, message: String },
    #[error("cannot read image '{path}': it is {width}x{height} with {channels} channels; expected a non-empty image of at most 2^28 texels")]
    BadSize { path: PathBuf, width: i64, height: i64, channels: i64 },
}

/// While it lives, what C libraries write to file descriptor 2 is discarded; plexus's own
/// messages are not lost: it holds Rust's stderr lock, so another thread's `eprintln!` waits for
/// it instead of writing into the void. Redirects nothing if any step fails (stderr then shows
/// the library's line, as without the guard).
struct QuietStderr {
    _lock: std::io::StderrLock<'static>,
    saved: Option<std::os::fd::OwnedFd>,
}

impl QuietStderr {
    fn new() -> QuietStderr {
        use std::io::Write;
        use std::os::fd::{AsRawFd, FromRawFd};
        let mut lock = std::io::stderr().lock();
        let _ = lock.flush();
        let saved = (|| {
            let null = std::fs::OpenOptions::new().write(true).open("/dev/null").ok()?;
            // SAFETY: dup of the process's stderr; the new descriptor is owned by `saved`.
            let copy = unsafe { libc::dup(libc::STDERR_FILENO) };
            if copy < 0 {
                return None;
            }
            // SAFETY: `copy` is a fresh descriptor nothing else owns.
            let saved = unsafe { std::os::fd::OwnedFd::from_raw_fd(copy) };
            // SAFETY: both descriptors are open; dup2 replaces descriptor 2 atomically.
            (unsafe { libc::dup2(null.as_raw_fd(), libc::STDERR_FILENO) } >= 0).then_some(saved)
        })();
        QuietStderr { _lock: lock, saved }
    }
}

impl Drop for QuietStderr {
    fn drop(&mut self) {
        use std::os::fd::AsRawFd;
        if let Some(saved) = &self.saved {
            // SAFETY: `saved` is open (owned here); dup2 puts the original stderr back.
            unsafe { libc::dup2(saved.as_raw_fd(), libc::STDERR_FILENO) };
        }
    }
}

/// Reads the first subimage of `path` through OpenImageIO (any format it reads: PNG, JPEG, EXR,
/// TGA, HDR, TIFF, ...).
pub fn read_image(path: &Path) -> Result<ReadImage, ImageReadError> {
    read_image_with(path, true)
}

/// [`read_image`] with every file read as floats (the test oracle of the 8-bit path).
#[cfg(test)]
pub fn read_image_as_float(path: &Path) -> Result<ReadImage, ImageReadError> {
    read_image_with(path, false)
}

/// Reads `path`; an 8-bit file as its codes when `codes_for_8_bit`, else as floats.
fn read_image_with(path: &Path, codes_for_8_bit: bool) -> Result<ReadImage, ImageReadError> {
    // OpenImageIO would block on a FIFO and read a device for ever: only a regular file is
    // handed to it (and the read is recorded with the scene's other files).
    crate::input_file::open_regular(path)
        .map_err(|message| ImageReadError::Oiio { path: path.to_path_buf(), message })?;
    let c = c_path(path).map_err(|_| ImageReadError::InvalidPath { path: path.to_path_buf() })?;
    let shim = shim().map_err(|message| ImageReadError::OiioUnavailable { path: path.to_path_buf(), message })?;
    // libpng reports a broken file on stderr itself before OpenImageIO hands its reader the same
    // text as the error this function returns: its line would precede plexus's one-line error.
    let _quiet = QuietStderr::new();
    let mut msg = [0u8; 1024];
    let mut info = PlxImageInfo::default();
    // SAFETY: `c` is NUL-terminated, `info` and `msg` are valid for writes of their sizes.
    let status = unsafe { (shim.read_info)(c.as_ptr(), &mut info, msg.as_mut_ptr().cast(), msg.len()) };
    if status != PLX_OK {
        return Err(ImageReadError::Oiio { path: path.to_path_buf(), message: message(&msg) });
    }
    let (w, h, ch) = (i64::from(info.width), i64::from(info.height), i64::from(info.channels));
    let bad = || ImageReadError::BadSize { path: path.to_path_buf(), width: w, height: h, channels: ch };
    if w <= 0 || h <= 0 || !(1..=64).contains(&ch) {
        return Err(bad());
    }
    let texels = (w as usize).checked_mul(h as usize).filter(|&n| n <= MAX_READ_TEXELS).ok_or_else(bad)?;
    let (status, data) = if codes_for_8_bit && info.is_uint8 != 0 {
        let mut levels = Box::new([0.0f32; 256]);
        let read_codes = |read_channels: c_int, codes: *mut u8, levels: &mut [f32; 256], msg: &mut [u8]| {
            // SAFETY: `codes` points to width·height·read_channels bytes (its callers below), the
            // size the shim checks against the file; `levels` holds 256 floats, `msg` its length.
            unsafe {
                (shim.read_image_uint8)(
                    c.as_ptr(),
                    info.width,
                    info.height,
                    info.channels,
                    read_channels,
                    codes,
                    levels.as_mut_ptr(),
                    msg.as_mut_ptr().cast(),
                    msg.len(),
                )
            }
        };
        let mut colours = vec![[0u8; 3]; texels];
        crate::process::huge_pages::advise_huge_pages(&colours);
        let status = if info.channels >= 3 {
            read_codes(3, colours.as_mut_ptr().cast(), &mut levels, &mut msg)
        } else {
            let mut grey = vec![0u8; texels];
            let status = read_codes(1, grey.as_mut_ptr(), &mut levels, &mut msg);
            for (colour, &g) in colours.iter_mut().zip(&grey) {
                *colour = [g; 3];
            }
            status
        };
        (status, ReadPixels::Rgb8 { texels: colours, levels })
    } else {
        let mut data = vec![0.0f32; texels * ch as usize];
        // SAFETY: `data` holds width·height·channels floats, the size the shim checks against the file.
        let status = unsafe {
            (shim.read_image)(
                c.as_ptr(),
                info.width,
                info.height,
                info.channels,
                data.as_mut_ptr(),
                msg.as_mut_ptr().cast(),
                msg.len(),
            )
        };
        (status, ReadPixels::Float(data))
    };
    if status != PLX_OK {
        return Err(ImageReadError::Oiio { path: path.to_path_buf(), message: message(&msg) });
    }
    Ok(ReadImage {
        width: w as usize,
        height: h as usize,
        channels: ch as usize,
        data,
        is_float: info.is_float != 0,
        srgb: match info.color_space {
            1 => Some(true),
            2 => Some(false),
            _ => None,
        },
    })
}

/// Why an image could not be written (or an output path was refused up front).
#[derive(Debug, Error)]
pub enum ImageWriteError {
    #[error("cannot write '{path}': output directory '{dir}' does not exist")]
    MissingDirectory { path: PathBuf, dir: PathBuf },
    #[error("cannot write '{path}': '{dir}' is not a directory")]
    NotADirectory { path: PathBuf, dir: PathBuf },
    #[error("cannot write '{path}': it is a directory")]
    IsADirectory { path: PathBuf },
    #[error("cannot write '{path}': the name ends with '/', so it names a directory, not a file")]
    TrailingSlash { path: PathBuf },
    #[error("cannot write '{path}': cannot create a file in '{dir}': {source}")]
    NotWritable { path: PathBuf, dir: PathBuf, source: std::io::Error },
    #[error("cannot write '{path}': a {width}x{height} image is larger than '.{extension}' files allow ({max} pixels per side at most)")]
    TooLarge { path: PathBuf, width: usize, height: usize, extension: String, max: usize },
    #[error("cannot write '{path}': the file name has no extension to choose an image format by")]
    NoExtension { path: PathBuf },
    #[error("cannot write '{path}': OpenImageIO cannot write '.{extension}' files")]
    UnsupportedFormat { path: PathBuf, extension: String },
    #[error("cannot write '{path}': the path contains a NUL byte or is not valid text")]
    InvalidPath { path: PathBuf },
    #[error("cannot write '{path}': the image is {width}x{height} with {pixels} pixels; expected a non-empty image with width*height pixels, each side below 2^31")]
    BadImage { path: PathBuf, width: usize, height: usize, pixels: usize },
    #[error("cannot write '{path}': OpenImageIO: {message}")]
    Oiio { path: PathBuf, message: String },
    #[error("cannot write '{path}': {message} (EXR and PNG files are written without it)")]
    OiioUnavailable { path: PathBuf, message: String },
    /// The `exr` or `png` crate's encoder failed.
    #[error("cannot write '{path}': {message}")]
    Encoder { path: PathBuf, message: String },
    #[error("cannot write '{path}': {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

/// How the image is stored in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Linear, 32-bit float.
    Float,
    /// Linear, 16-bit half float.
    Half,
    /// 8-bit sRGB after the display transform.
    Srgb8,
}

/// Options for [`write_image`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WriteOptions {
    /// Store `.exr` files as half floats instead of 32-bit floats.
    pub half: bool,
    /// Exposure in stops applied before the display transform of 8-bit outputs (float outputs are
    /// never scaled).
    pub exposure: f32,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions { half: false, exposure: 0.0 }
    }
}

/// The lower-case extension of `path`, if any.
fn extension(path: &Path) -> Option<String> {
    path.extension().map(|e| e.to_string_lossy().to_lowercase()).filter(|e| !e.is_empty())
}

/// How an image written to `path` with `opts` will be stored.
pub fn encoding_for(path: &Path, opts: &WriteOptions) -> Encoding {
    match extension(path).as_deref() {
        Some("exr") if opts.half => Encoding::Half,
        Some("exr" | "hdr" | "tif" | "tiff" | "pfm") => Encoding::Float,
        _ => Encoding::Srgb8,
    }
}

fn c_path(path: &Path) -> Result<CString, ImageWriteError> {
    let invalid = || ImageWriteError::InvalidPath { path: path.to_path_buf() };
    #[cfg(unix)]
    let bytes = {
        use std::os::unix::ffi::OsStrExt;
        path.as_os_str().as_bytes().to_vec()
    };
    #[cfg(not(unix))]
    let bytes = path.to_str().ok_or_else(invalid)?.as_bytes().to_vec();
    CString::new(bytes).map_err(|_| invalid())
}

/// The text the shim wrote into `buf` (up to its NUL).
fn message(buf: &[u8]) -> String {
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).trim().to_string()
}

/// The largest width or height a format's writer accepts, where it is below what `c_int` (the
/// shim's type) holds. OpenImageIO has no query for this, so the limits are those of the
/// libraries it writes through:
/// - JPEG: 16-bit frame dimensions (ITU-T T.81, B.2.2), and libjpeg refuses more than
///   `JPEG_MAX_DIMENSION` = 65500 (jmorecfg.h).
/// - WebP: `WEBP_MAX_DIMENSION` = 16383 (libwebp encode.h).
/// - Targa, GIF: 16-bit width and height fields.
/// - ICO: 256 (one byte, 0 meaning 256).
///
/// PNG (the `png` crate) and EXR (the `exr` crate) have no limit of their own below the 2^31 − 1
/// that [`check_output`] applies to every format.
/// Every format takes the three channels plexus writes.
fn max_side(extension: &str) -> Option<usize> {
    Some(match extension {
        "jpg" | "jpeg" | "jpe" | "jfif" => 65_500,
        "webp" => 16_383,
        "tga" | "tpic" | "gif" => 65_535,
        "ico" => 256,
        _ => return None,
    })
}

/// Checks, without rendering, that a `width`×`height` image could be written to `path`: what
/// [`check_output_path`] checks, and that the format can hold that resolution.
pub fn check_output(path: &Path, width: usize, height: usize) -> Result<(), ImageWriteError> {
    check_output_path(path)?;
    // `check_output_path` guaranteed an extension.
    let ext = extension(path).unwrap_or_default();
    let max = max_side(&ext).unwrap_or(c_int::MAX as usize);
    if width > max || height > max {
        return Err(ImageWriteError::TooLarge { path: path.to_path_buf(), width, height, extension: ext, max });
    }
    Ok(())
}

/// Checks, without writing an image, that one could be written to `path`: the name is not a
/// directory, its directory exists and a file can be created there (tried: permissions, a
/// read-only file system or a pseudo file system like /proc only show when one is), and
/// OpenImageIO has a writer for its extension. Call it before a long render.
pub fn check_output_path(path: &Path) -> Result<(), ImageWriteError> {
    // `Path` drops a trailing '/' from its components (`o.exr/` has the extension "exr"), but
    // the file system would refuse to create a file by that name.
    if path.as_os_str().to_string_lossy().ends_with('/') {
        return Err(ImageWriteError::TrailingSlash { path: path.to_path_buf() });
    }
    let dir = crate::interrupt::directory_of(path);
    if !dir.exists() {
        return Err(ImageWriteError::MissingDirectory { path: path.to_path_buf(), dir: dir.to_path_buf() });
    }
    if !dir.is_dir() {
        return Err(ImageWriteError::NotADirectory { path: path.to_path_buf(), dir: dir.to_path_buf() });
    }
    if path.is_dir() {
        return Err(ImageWriteError::IsADirectory { path: path.to_path_buf() });
    }
    let Some(ext) = extension(path) else {
        return Err(ImageWriteError::NoExtension { path: path.to_path_buf() });
    };
    // EXR and PNG are written by the `exr` and `png` crates; every other format needs OpenImageIO
    // to have a writer for it. Only the extension matters to that lookup; passing a synthetic name
    // keeps odd characters elsewhere in the path out of the question.
    if !matches!(ext.as_str(), "exr" | "png") {
        let shim = shim().map_err(|message| ImageWriteError::OiioUnavailable { path: path.to_path_buf(), message })?;
        let probe = CString::new(format!("probe.{ext}"))
            .map_err(|_| ImageWriteError::InvalidPath { path: path.to_path_buf() })?;
        let mut buf = [0u8; 512];
        // SAFETY: `probe` is NUL-terminated; `buf` is writable for `buf.len()` bytes; the shim never
        // throws across the boundary.
        let status = unsafe { (shim.can_write)(probe.as_ptr(), buf.as_mut_ptr() as *mut c_char, buf.len()) };
        if status != PLX_OK {
            return Err(ImageWriteError::UnsupportedFormat { path: path.to_path_buf(), extension: ext });
        }
    }
    // Dropping the probe removes it; a second Ctrl-C meanwhile waits for that.
    let _writing = crate::interrupt::FileWriting::enter();
    tempfile::Builder::new()
        .prefix(".plexus-write-check-")
        .tempfile_in(dir)
        .map_err(|source| ImageWriteError::NotWritable { path: path.to_path_buf(), dir: dir.to_path_buf(), source })?;
    Ok(())
}

/// Writes `image` to `path` in the format its extension names (see the module documentation).
pub fn write_image(path: &Path, image: &Image, opts: &WriteOptions) -> Result<(), ImageWriteError> {
    check_output(path, image.width, image.height)?;
    encode_through_temp_file(path, image, opts)
}

/// The writing half of [`write_image`], after its checks: encodes (EXR and PNG with their crates,
/// other formats through OpenImageIO) into a temporary file beside `path` and renames it into place; on
/// any failure the temporary is removed.
fn encode_through_temp_file(path: &Path, image: &Image, opts: &WriteOptions) -> Result<(), ImageWriteError> {
    let bad_image = || ImageWriteError::BadImage {
        path: path.to_path_buf(),
        width: image.width,
        height: image.height,
        pixels: image.pixels.len(),
    };
    let (Ok(width), Ok(height)) = (c_int::try_from(image.width), c_int::try_from(image.height)) else {
        return Err(bad_image());
    };
    if width == 0 || height == 0 || image.pixels.len() != image.width * image.height {
        return Err(bad_image());
    }

    let encoding = encoding_for(path, opts);
    let io_error = |source| ImageWriteError::Io { path: path.to_path_buf(), source };
    let encoder_error = |message: String| ImageWriteError::Encoder { path: path.to_path_buf(), message };
    match extension(path).as_deref() {
        Some("exr") => {
            return crate::interrupt::write_atomically(path, true, io_error, |_, file| {
                super::exr_io::write_exr(file, image, encoding == Encoding::Half)
                    .map_err(|e| encoder_error(e.to_string()))
            });
        }
        Some("png") => {
            let codes = tonemap::tonemap_srgb8(image, opts.exposure);
            return crate::interrupt::write_atomically(path, true, io_error, |_, file| {
                super::png_io::write_png(file, width as u32, height as u32, &codes)
                    .map_err(|e| encoder_error(e.to_string()))
            });
        }
        _ => {}
    }
    let shim = shim().map_err(|message| ImageWriteError::OiioUnavailable { path: path.to_path_buf(), message })?;
    let floats: Vec<f32>;
    let bytes: Vec<u8>;
    let (data_type, data, pixel_type): (c_int, *const c_void, c_int) = match encoding {
        Encoding::Float | Encoding::Half => {
            floats = image.pixels.iter().flat_map(|p| p.to_array()).collect();
            let pixel = if encoding == Encoding::Half { PLX_PIXEL_HALF } else { PLX_PIXEL_FLOAT };
            (PLX_DATA_FLOAT, floats.as_ptr() as *const c_void, pixel)
        }
        Encoding::Srgb8 => {
            bytes = tonemap::tonemap_srgb8(image, opts.exposure);
            (PLX_DATA_UINT8, bytes.as_ptr() as *const c_void, PLX_PIXEL_UINT8)
        }
    };

    crate::interrupt::write_atomically(path, true, io_error, |temp, _| {
        let c_temp = c_path(temp)?;
        let mut buf = [0u8; 1024];
        // SAFETY: `c_temp` is NUL-terminated; `data` points to width*height*3 values of `data_type`
        // (`floats` or `bytes`, alive until the end of this function); `buf` is writable for its
        // length; the shim catches every C++ exception.
        let status = unsafe {
            (shim.write_image)(
                c_temp.as_ptr(),
                width,
                height,
                3,
                data_type,
                data,
                pixel_type,
                buf.as_mut_ptr() as *mut c_char,
                buf.len(),
            )
        };
        if status != PLX_OK {
            // Messages may name the temporary file; the user only knows the name they asked for.
            let text = message(&buf).replace(&temp.display().to_string(), &path.display().to_string());
            return Err(ImageWriteError::Oiio { path: path.to_path_buf(), message: text });
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A failure after OpenImageIO has created the temporary file removes it, and the message names
    /// the requested file, not the temporary. libwebp refuses images wider than 16383 pixels only
    /// when it encodes them, at close; `write_image` refuses such an image before (`check_output`),
    /// so the writing half is called directly here.
    #[test]
    fn a_failure_at_close_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("wide.webp");
        let err = encode_through_temp_file(&path, &Image::new(20_000, 1), &WriteOptions::default()).unwrap_err();
        assert!(matches!(err, ImageWriteError::Oiio { .. }), "{err}");
        assert!(err.to_string().contains("wide.webp") && !err.to_string().contains("plexus-tmp"), "{err}");
        // libjpeg would exit() the process on an image above its size limit; the shim refuses it
        // too, behind `check_output`.
        let jpg = dir.path().join("wide.jpg");
        let err = encode_through_temp_file(&jpg, &Image::new(70_000, 1), &WriteOptions::default()).unwrap_err();
        assert!(err.to_string().contains("at most 65500 pixels"), "{err}");
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("read dir").collect();
        assert!(left.is_empty(), "left behind: {left:?}");
    }

    /// EXR is written by the `exr` crate since OpenImageIO is loaded only on demand: its half
    /// rounding must be what OpenImageIO's (Imath's) was, bit for bit, for normals, ties (both
    /// round to even), half subnormals, overflow to infinity and infinities; NaN stays NaN. The
    /// same image written through the shim as half EXR is the oracle. Rounding ties away from
    /// zero (`f16::from_f32(x + x * 2^-12)`, say) fails it.
    #[test]
    fn half_exr_rounds_as_openimageio_did() {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut values =
            vec![0.0f32, -0.0, 1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 65504.0, 65519.99, 65520.0];
        // Ties and near-ties at several exponents: 1 + k·2^-11 is halfway between halves for odd k.
        for e in [-20, -14, -3, 0, 7, 15] {
            for k in 0..24 {
                let v = 2f32.powi(e) * (1.0 + k as f32 * 2f32.powi(-11));
                values.extend([v, -v, f32::from_bits(v.to_bits() + 1), f32::from_bits(v.to_bits() - 1)]);
            }
        }
        // Half subnormals (below 2^-14), and f32s far below half's smallest subnormal.
        values.extend((1..40).map(|i| i as f32 * 1.37e-8));
        values.extend([1e-30, -1e-30, f32::MIN_POSITIVE]);
        values.resize(values.len().next_multiple_of(3), 0.5);
        let mut img = Image::new(values.len() / 3, 1);
        for (p, c) in img.pixels.iter_mut().zip(values.chunks(3)) {
            *p = glam::Vec3::new(c[0], c[1], c[2]);
        }
        let half = WriteOptions { half: true, ..WriteOptions::default() };
        let ours = dir.path().join("exr-crate.exr");
        write_image(&ours, &img, &half).unwrap();
        let theirs = dir.path().join("oiio.exr");
        let c = c_path(&theirs).unwrap();
        let mut msg = [0u8; 512];
        let floats: Vec<f32> = img.pixels.iter().flat_map(|p| p.to_array()).collect();
        let shim = shim().unwrap();
        // SAFETY: `c` is NUL-terminated, `floats` holds width·1·3 floats, `msg` its length.
        let status = unsafe {
            (shim.write_image)(
                c.as_ptr(),
                img.width as c_int,
                1,
                3,
                PLX_DATA_FLOAT,
                floats.as_ptr().cast(),
                PLX_PIXEL_HALF,
                msg.as_mut_ptr().cast(),
                msg.len(),
            )
        };
        assert_eq!(status, PLX_OK, "{}", message(&msg));
        let halves = |path: &Path| {
            let layer = exr::prelude::read_first_flat_layer_from_file(path).unwrap().layer_data;
            ["R", "G", "B"].map(|name| {
                let channel = layer.channel_data.list.iter().find(|c| c.name.to_string() == name).unwrap();
                let exr::prelude::FlatSamples::F16(v) = &channel.sample_data else { panic!("{name} is not half") };
                v.clone()
            })
        };
        let (a, b) = (halves(&ours), halves(&theirs));
        for (i, &v) in values.iter().enumerate() {
            let (x, y) = (a[i % 3][i / 3], b[i % 3][i / 3]);
            assert!(x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()), "{v:e}: exr {x} vs OpenImageIO {y}");
        }
    }

    #[test]
    fn encodings_follow_the_extension() {
        let o = WriteOptions::default();
        let h = WriteOptions { half: true, ..o };
        assert_eq!(encoding_for(Path::new("a/b.exr"), &o), Encoding::Float);
        assert_eq!(encoding_for(Path::new("a/b.EXR"), &h), Encoding::Half);
        assert_eq!(encoding_for(Path::new("b.hdr"), &h), Encoding::Float);
        assert_eq!(encoding_for(Path::new("b.tif"), &o), Encoding::Float);
        assert_eq!(encoding_for(Path::new("b.png"), &h), Encoding::Srgb8);
        assert_eq!(encoding_for(Path::new("b.jpg"), &o), Encoding::Srgb8);
    }

    #[test]
    fn output_paths_are_checked_before_rendering() {
        assert!(check_output_path(Path::new("render.exr")).is_ok());
        assert!(check_output_path(Path::new("render.png")).is_ok());
        let e = check_output_path(Path::new("no/such/dir/render.exr")).unwrap_err().to_string();
        assert!(e.contains("output directory 'no/such/dir' does not exist"), "{e}");
        let e = check_output_path(Path::new("render.xyz")).unwrap_err().to_string();
        assert!(e.contains("OpenImageIO cannot write '.xyz' files") && e.contains("render.xyz"), "{e}");
        assert!(matches!(check_output_path(Path::new("render")), Err(ImageWriteError::NoExtension { .. })));
    }

    #[test]
    fn malformed_images_are_refused() {
        let dir = std::env::temp_dir();
        let img = Image { width: 2, height: 2, pixels: vec![] };
        let err = write_image(&dir.join("plexus-bad-image.exr"), &img, &WriteOptions::default()).unwrap_err();
        assert!(matches!(err, ImageWriteError::BadImage { .. }), "{err}");
        assert!(!dir.join("plexus-bad-image.exr").exists());
    }
}
