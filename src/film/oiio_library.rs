//! The OpenImageIO shim (ffi/oiio_shim.cpp), opened on first use.
//!
//! build.rs compiles the shim into a shared library linked to OpenImageIO, and plexus carries its
//! bytes. Linking OpenImageIO into plexus itself would make every process load Debian's
//! `libOpenImageIO` and the ~260 libraries it pulls in (codecs, gdcm, ffmpeg, ...) before `main`:
//! 0.22 s and 130 MB resident, measured on an empty C program (docs/lab/performance.md), for a
//! `--version` or a render that writes only EXR as much as for one that reads JPEG textures. Now
//! only a process that reads a bitmap or writes another format than EXR pays it, once.
//!
//! The library is handed to the dynamic loader from an anonymous in-memory file (`memfd_create`,
//! opened as `/proc/self/fd/N`), so nothing is written to disk and a copied or installed plexus
//! binary needs no file beside it; where that is refused (no /proc, or a kernel that forbids
//! executable memfds), from a temporary file that is removed once loaded.

use std::ffi::{c_char, c_int, c_void};
use std::io::Write;
use std::sync::OnceLock;

/// The shim's bytes, as build.rs linked them.
static SHIM_LIBRARY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/libplexus_oiio.so"));

/// `struct plx_image_info` of ffi/oiio_shim.h.
#[repr(C)]
#[derive(Default)]
pub(crate) struct PlxImageInfo {
    pub width: c_int,
    pub height: c_int,
    pub channels: c_int,
    pub is_float: c_int,
    pub color_space: c_int,
    pub is_uint8: c_int,
}

// Constants and signatures matching ffi/oiio_shim.h (kept by hand: five functions).
pub(crate) const PLX_DATA_FLOAT: c_int = 0;
pub(crate) const PLX_DATA_UINT8: c_int = 1;
pub(crate) const PLX_PIXEL_FLOAT: c_int = 0;
pub(crate) const PLX_PIXEL_HALF: c_int = 1;
pub(crate) const PLX_PIXEL_UINT8: c_int = 2;
pub(crate) const PLX_OK: c_int = 0;

type WriteImage = unsafe extern "C" fn(
    path: *const c_char,
    width: c_int,
    height: c_int,
    channels: c_int,
    data_type: c_int,
    data: *const c_void,
    pixel_type: c_int,
    msg: *mut c_char,
    msg_len: usize,
) -> c_int;
type CanWrite = unsafe extern "C" fn(filename: *const c_char, msg: *mut c_char, msg_len: usize) -> c_int;
type ReadInfo =
    unsafe extern "C" fn(path: *const c_char, info: *mut PlxImageInfo, msg: *mut c_char, msg_len: usize) -> c_int;
type ReadImage = unsafe extern "C" fn(
    path: *const c_char,
    width: c_int,
    height: c_int,
    channels: c_int,
    data: *mut f32,
    msg: *mut c_char,
    msg_len: usize,
) -> c_int;
type ReadImageUint8 = unsafe extern "C" fn(
    path: *const c_char,
    width: c_int,
    height: c_int,
    channels: c_int,
    read_channels: c_int,
    data: *mut u8,
    levels: *mut f32,
    msg: *mut c_char,
    msg_len: usize,
) -> c_int;

/// The shim's entry points. The library stays loaded for the rest of the process (it is in a
/// `static`), so the pointers stay valid.
pub(crate) struct Shim {
    _library: libloading::Library,
    pub write_image: WriteImage,
    pub can_write: CanWrite,
    pub read_info: ReadInfo,
    pub read_image: ReadImage,
    pub read_image_uint8: ReadImageUint8,
}

static SHIM: OnceLock<Result<Shim, String>> = OnceLock::new();

/// The shim, loaded on the first call; Err says why OpenImageIO could not be loaded (its
/// libraries missing, say: `apt-get install libopenimageio2.4`).
pub(crate) fn shim() -> Result<&'static Shim, String> {
    SHIM.get_or_init(load).as_ref().map_err(|e| format!("OpenImageIO could not be loaded: {e}"))
}

/// Whether this process has loaded OpenImageIO (for tests of the loading rule).
pub fn is_loaded() -> bool {
    SHIM.get().is_some_and(|s| s.is_ok())
}

fn load() -> Result<Shim, String> {
    let library = open_from_memory().or_else(|memfd_error| {
        // A missing or broken OpenImageIO fails both ways with the same message: say it once.
        open_from_temporary_file().map_err(|e| {
            if e == memfd_error {
                e
            } else {
                format!("{e} (from an in-memory file: {memfd_error})")
            }
        })
    })?;
    // SAFETY: each symbol is the shim's function of that name, whose C signature in
    // ffi/oiio_shim.h the type above matches.
    unsafe {
        let write_image = *library.get::<WriteImage>(b"plx_oiio_write_image\0").map_err(|e| e.to_string())?;
        let can_write = *library.get::<CanWrite>(b"plx_oiio_can_write\0").map_err(|e| e.to_string())?;
        let read_info = *library.get::<ReadInfo>(b"plx_oiio_read_info\0").map_err(|e| e.to_string())?;
        let read_image = *library.get::<ReadImage>(b"plx_oiio_read_image\0").map_err(|e| e.to_string())?;
        let read_image_uint8 =
            *library.get::<ReadImageUint8>(b"plx_oiio_read_image_uint8\0").map_err(|e| e.to_string())?;
        Ok(Shim { _library: library, write_image, can_write, read_info, read_image, read_image_uint8 })
    }
}

/// Loads the shim from an anonymous memory file.
fn open_from_memory() -> Result<libloading::Library, String> {
    use std::os::fd::FromRawFd;
    // SAFETY: the name is NUL-terminated; a returned descriptor is new and owned by `file` below.
    let fd = unsafe { libc::memfd_create(c"plexus-oiio-shim".as_ptr(), libc::MFD_CLOEXEC) };
    if fd < 0 {
        return Err(format!("memfd_create: {}", std::io::Error::last_os_error()));
    }
    // SAFETY: `fd` was just created and nothing else owns it.
    let mut file = unsafe { std::fs::File::from_raw_fd(fd) };
    file.write_all(SHIM_LIBRARY).map_err(|e| format!("writing the in-memory file: {e}"))?;
    // The loader opens the path itself; the descriptor (closed when `file` drops) must live until then.
    open(&format!("/proc/self/fd/{fd}"))
}

/// Loads the shim from a temporary file, removed once loaded (the mapping keeps its pages).
fn open_from_temporary_file() -> Result<libloading::Library, String> {
    let mut file = tempfile::Builder::new()
        .prefix("plexus-oiio-shim-")
        .suffix(".so")
        .tempfile()
        .map_err(|e| format!("creating a temporary file in {}: {e}", std::env::temp_dir().display()))?;
    file.write_all(SHIM_LIBRARY).map_err(|e| format!("writing {}: {e}", file.path().display()))?;
    file.flush().map_err(|e| format!("writing {}: {e}", file.path().display()))?;
    open(&file.path().to_string_lossy())
}

fn open(path: &str) -> Result<libloading::Library, String> {
    // SAFETY: the shim's initialisers are OpenImageIO's and the C++ runtime's, which are safe to
    // run on any thread; the shim itself defines no static constructors.
    unsafe { libloading::Library::new(path) }.map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both ways of handing the shim to the loader give a library with the shim's entry points
    /// (the temporary file is only the fallback, so nothing else runs it), and the fallback leaves
    /// no file behind.
    #[test]
    fn the_shim_loads_from_memory_and_from_a_temporary_file() {
        for library in [open_from_memory(), open_from_temporary_file()] {
            let library = library.unwrap();
            // SAFETY: only the symbol's presence is checked; it is not called.
            let symbol = unsafe { library.get::<CanWrite>(b"plx_oiio_can_write\0") };
            assert!(symbol.is_ok());
        }
        let left = std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with("plexus-oiio-shim-"))
            .count();
        assert_eq!(left, 0, "the temporary copy of the shim was left in {}", std::env::temp_dir().display());
    }
}
