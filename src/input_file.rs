//! Opening files a scene refers to (meshes, environment maps) as untrusted input: only regular
//! files are read (a mesh path that is `/dev/zero` once aborted on an endless allocation, a FIFO
//! would block for ever), and their size bounds what a reader may allocate from the counts in
//! their headers.

use std::cell::RefCell;
use std::fs::File;
use std::path::{Path, PathBuf};

thread_local! {
    /// The files opened through this module on this thread while a `recording_reads` runs.
    static OPENED: RefCell<Option<Vec<PathBuf>>> = const { RefCell::new(None) };
}

/// Runs `f` and returns, with its result, every file opened through this module on this thread
/// meanwhile, in the order of their first opening, each once. Scene loading opens every file it
/// reads here (the scene text, included files, meshes, textures, environment maps) on the calling
/// thread, so this is the list of files a scene is made of — what its identity must cover.
pub fn recording_reads<T>(f: impl FnOnce() -> T) -> (T, Vec<PathBuf>) {
    let outer = OPENED.with(|o| o.borrow_mut().replace(Vec::new()));
    let out = f();
    let files = OPENED.with(|o| std::mem::replace(&mut *o.borrow_mut(), outer)).unwrap_or_default();
    for p in &files {
        note_opened(p);
    }
    (out, files)
}

fn note_opened(path: &Path) {
    OPENED.with(|o| {
        if let Some(files) = o.borrow_mut().as_mut() {
            if !files.iter().any(|p| p == path) {
                files.push(path.to_path_buf());
            }
        }
    });
}

/// Opens `path` for reading if it is a regular file (symbolic links followed), with its size in
/// bytes. The error is one line naming what the path is instead.
///
/// The file is opened without blocking and checked on the open handle, so a FIFO put in the
/// file's place between a check and the open cannot block the process either.
pub fn open_regular(path: &Path) -> Result<(File, u64), String> {
    use std::os::unix::fs::OpenOptionsExt;
    let file =
        std::fs::OpenOptions::new().read(true).custom_flags(libc::O_NONBLOCK).open(path).map_err(|e| e.to_string())?;
    let meta = file.metadata().map_err(|e| e.to_string())?;
    if !meta.is_file() {
        let what = if meta.is_dir() { "a directory" } else { "not a regular file (a device, FIFO or socket)" };
        return Err(format!("expected a regular file, but it is {what}"));
    }
    note_opened(path);
    Ok((file, meta.len()))
}

/// The whole of the regular file `path` (see [`open_regular`]), at most `max_bytes` of it: a
/// larger file is an error naming its size, read from no further than its header would be.
pub fn read_regular(path: &Path, max_bytes: u64) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let (file, len) = open_regular(path)?;
    if len > max_bytes {
        return Err(format!("{len} bytes, more than the {max_bytes} a file of this kind may have"));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max_bytes.saturating_add(1)).read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    if bytes.len() as u64 > max_bytes {
        return Err(format!("grew past the {max_bytes} bytes a file of this kind may have while it was read"));
    }
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text.
pub fn read_regular_text(path: &Path, max_bytes: u64) -> Result<String, String> {
    String::from_utf8(read_regular(path, max_bytes)?).map_err(|_| "not UTF-8 text".to_string())
}

/// Scene text (TOML, Mitsuba XML and each file it includes): far above any real scene file,
/// whose geometry lives in mesh files.
pub const MAX_SCENE_TEXT_BYTES: u64 = 1 << 30;

#[cfg(test)]
mod tests {
    use super::*;

    /// A recording lists the files opened inside it, each once, in order; a nested one's files
    /// count for the outer one too.
    #[test]
    fn recordings_list_what_was_opened() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::write(&a, "a").unwrap();
        std::fs::write(&b, "b").unwrap();
        let ((inner, _), outer) = recording_reads(|| {
            read_regular(&b, 10).unwrap();
            let inner = recording_reads(|| read_regular(&a, 10).unwrap()).1;
            read_regular(&b, 10).unwrap();
            (inner, ())
        });
        assert_eq!(inner, std::slice::from_ref(&a));
        assert_eq!(outer, [b, a]);
        assert!(open_regular(Path::new("/dev/null")).is_err());
    }

    /// A FIFO is refused at once rather than blocking the reader (nobody writes to it).
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: `c` is a NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = read_regular(&fifo, 1 << 20).expect_err("FIFO");
        assert!(e.contains("not a regular file"), "{e}");
        let big = dir.path().join("big");
        std::fs::write(&big, [0u8; 100]).unwrap();
        assert!(read_regular(&big, 99).unwrap_err().contains("100 bytes"));
        assert_eq!(read_regular(&big, 100).unwrap().len(), 100);
        assert_eq!(read_regular(&big, u64::MAX).unwrap().len(), 100);
    }

    #[test]
    fn devices_and_directories_are_refused() {
        let e = open_regular(Path::new("/dev/zero")).expect_err("/dev/zero");
        assert!(e.contains("not a regular file"), "{e}");
        let e = open_regular(Path::new("/")).expect_err("/");
        assert!(e.contains("a directory"), "{e}");
        let (_, len) = open_regular(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml").as_path()).expect("file");
        assert!(len > 0);
    }
}
