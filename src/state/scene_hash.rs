//! The scene's identity in a state file: a SHA-256 over the scene file and every file it names, so
//! that a checkpoint is refused when the scene or one of its meshes or textures has changed.
//!
//! Which files a scene references is read from the scene text itself, not from the loader: every
//! quoted string (TOML `"..."` / `'...'`, XML attribute values) that names an existing regular
//! file, relative to the scene's directory or absolute, is hashed (its path as written, then its
//! bytes). That covers `file = "bunny.ply"`, texture tables and imported Mitsuba scenes without a
//! list to keep in step with the loaders; a string that merely happens to name a file costs a read.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::StateError;

/// Hex SHA-256 of the scene file at `path` and of the files it references.
pub fn scene_hash(path: &Path) -> Result<String, StateError> {
    let read = |p: &Path| std::fs::read(p).map_err(|source| StateError::Read { path: p.to_path_buf(), source });
    let text = read(path)?;
    let mut hasher = Sha256::new();
    hasher.update(b"scene\0");
    hasher.update((text.len() as u64).to_le_bytes());
    hasher.update(&text);
    let base = path.parent().unwrap_or(Path::new("."));
    for (name, file) in referenced_files(&String::from_utf8_lossy(&text), base) {
        let bytes = read(&file)?;
        hasher.update(b"file\0");
        hasher.update(name.as_bytes());
        hasher.update((bytes.len() as u64).to_le_bytes());
        hasher.update(&bytes);
    }
    Ok(hex(&hasher.finalize()))
}

/// The hash of the built-in scene (its text is compiled in).
pub fn builtin_scene_hash() -> String {
    let mut hasher = Sha256::new();
    hasher.update(b"builtin\0");
    hasher.update(crate::scene::CORNELL_BOX_TOML.as_bytes());
    hex(&hasher.finalize())
}

/// Quoted strings of `text` naming existing regular files (relative to `base` unless absolute),
/// sorted by name and without repeats.
fn referenced_files(text: &str, base: &Path) -> Vec<(String, PathBuf)> {
    let mut found: Vec<(String, PathBuf)> = Vec::new();
    for quote in ['"', '\''] {
        let mut parts = text.split(quote);
        parts.next();
        // Every other piece lies between a pair of quotes.
        while let Some(inside) = parts.next() {
            parts.next();
            if inside.is_empty() || inside.len() > 4096 || inside.contains('\n') {
                continue;
            }
            let candidate = base.join(inside);
            if candidate.is_file() && !found.iter().any(|(n, _)| n == inside) {
                found.push((inside.to_string(), candidate));
            }
        }
    }
    found.sort();
    found
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hash changes with the scene text and with the bytes of a file it references, and not
    /// with a file it does not reference.
    #[test]
    fn hash_covers_the_scene_and_its_files() {
        let dir = tempfile::tempdir().expect("temp dir");
        let scene = dir.path().join("s.toml");
        std::fs::write(&scene, "[[shapes]]\nfile = \"m.obj\"\nx = 'other.txt'\n").expect("write");
        std::fs::write(dir.path().join("m.obj"), "v 0 0 0\n").expect("write");
        let a = scene_hash(&scene).expect("hash");
        std::fs::write(dir.path().join("unrelated.obj"), "v 1 1 1\n").expect("write");
        assert_eq!(scene_hash(&scene).expect("hash"), a);
        std::fs::write(dir.path().join("m.obj"), "v 0 0 1\n").expect("write");
        let b = scene_hash(&scene).expect("hash");
        assert_ne!(a, b);
        std::fs::write(dir.path().join("other.txt"), "x").expect("write");
        assert_ne!(scene_hash(&scene).expect("hash"), b, "single-quoted names count too");
        assert_eq!(referenced_files("a = \"m.obj\" b = \"m.obj\"", dir.path()).len(), 1);
    }
}
