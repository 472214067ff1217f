//! Opening files a scene refers to (meshes, environment maps) as untrusted input: only regular
//! files are read (a mesh path that is `/dev/zero` once aborted on an endless allocation, a FIFO
//! would block for ever), and their size bounds what a reader may allocate from the counts in
//! their headers.

use std::fs::File;
use std::path::Path;

/// Opens `path` for reading if it is a regular file (symbolic links followed), with its size in
/// bytes. The error is one line naming what the path is instead.
pub fn open_regular(path: &Path) -> Result<(File, u64), String> {
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if !meta.is_file() {
        let what = if meta.is_dir() { "a directory" } else { "not a regular file (a device, FIFO or socket)" };
        return Err(format!("expected a regular file, but it is {what}"));
    }
    let file = File::open(path).map_err(|e| e.to_string())?;
    Ok((file, meta.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

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
