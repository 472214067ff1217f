//! The scene's identity in a state file: a SHA-256 over the bytes of every file the scene was
//! made of, as the loader opened them (`input_file::recording_reads`: the scene file, files it
//! includes, meshes, textures, environment maps), so that a checkpoint is refused when any of them
//! has changed — including files named through an include or a `$name` default, which no reading
//! of the top file's text would find.

use std::path::Path;

use sha2::{Digest, Sha256};

use super::StateError;

/// Hex SHA-256 of the files a scene was loaded from, in the order the loader opened them. Only the
/// bytes count, not where the files were: a scene moved with its files keeps its identity, and an
/// imported scene's meshes converted to a temporary directory hash the same every time.
pub fn scene_hash(files: &[impl AsRef<Path>]) -> Result<String, StateError> {
    let mut hasher = Sha256::new();
    hasher.update(b"scene files\0");
    for file in files {
        let file = file.as_ref();
        let bytes = crate::input_file::read_regular(file, u64::MAX)
            .map_err(|e| StateError::Read { path: file.to_path_buf(), source: std::io::Error::other(e) })?;
        hasher.update(b"file\0");
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

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hash changes with the bytes of any file the scene was made of, and not with their
    /// places.
    #[test]
    fn hash_covers_every_file_read() {
        let dir = tempfile::tempdir().expect("temp dir");
        let (scene, mesh) = (dir.path().join("s.toml"), dir.path().join("m.obj"));
        std::fs::write(&scene, "[[shapes]]\nfile = \"m.obj\"\n").expect("write");
        std::fs::write(&mesh, "v 0 0 0\n").expect("write");
        let a = scene_hash(&[&scene, &mesh]).expect("hash");
        std::fs::write(&mesh, "v 0 0 1\n").expect("write");
        let b = scene_hash(&[&scene, &mesh]).expect("hash");
        assert_ne!(a, b);
        let moved = dir.path().join("elsewhere.obj");
        std::fs::rename(&mesh, &moved).expect("rename");
        assert_eq!(scene_hash(&[&scene, &moved]).expect("hash"), b);
        assert_ne!(scene_hash(&[&scene]).expect("hash"), b);
    }
}
