//! Mitsuba's `.serialized` meshes, converted to PLY for the scene loader.
//!
//! The format (Mitsuba 0.6 `TriMesh::loadCompressed`, also read by Mitsuba 3): a file holds
//! several meshes, each `u16 0x041C` (format), `u16` version (3 or 4), then one zlib stream with
//! `u32` flags, (version 4) the mesh's name as a NUL-terminated string, `u64` vertex and triangle
//! counts, the positions, optional normals, uvs and colours (f32, or f64 with flag 0x2000) and
//! the indices (u32, or u64 past 2^32 vertices). The file ends with a table of the meshes' byte
//! offsets (`u64` in version 4, `u32` in version 3) and a `u32` count. All little-endian.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use crate::scene::raw_mesh::RawMesh;

const FORMAT: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_UVS: u32 = 0x0002;
const HAS_COLOURS: u32 = 0x0008;
const DOUBLE: u32 = 0x2000;

/// Reads mesh `index` of the `.serialized` file at `path`.
pub fn read(path: &Path, index: usize) -> Result<RawMesh, String> {
    let data = crate::input_file::read_regular(path, u64::MAX)?;
    if data.len() < 8 {
        return Err("too short for a serialized mesh file".into());
    }
    let count = u32::from_le_bytes(data[data.len() - 4..].try_into().unwrap_or_default()) as usize;
    if index >= count {
        return Err(format!("has {count} meshes, no shape_index {index}"));
    }
    let version = u16::from_le_bytes([data[2], data[3]]);
    let offset = if version >= 4 {
        let table = data.len().checked_sub(4 + 8 * count).ok_or("truncated offset table")?;
        let at = table + 8 * index;
        u64::from_le_bytes(data[at..at + 8].try_into().unwrap_or_default()) as usize
    } else {
        let table = data.len().checked_sub(4 + 4 * count).ok_or("truncated offset table")?;
        let at = table + 4 * index;
        u32::from_le_bytes(data[at..at + 4].try_into().unwrap_or_default()) as usize
    };
    let header = data.get(offset..offset + 4).ok_or("mesh offset past the end of the file")?;
    let (format, version) = (u16::from_le_bytes([header[0], header[1]]), u16::from_le_bytes([header[2], header[3]]));
    if format != FORMAT || !(3..=4).contains(&version) {
        return Err(format!("mesh {index}: not a serialized mesh (format {format:#x}, version {version})"));
    }
    let mut z = flate2::read::ZlibDecoder::new(&data[offset + 4..]);
    let mut r = Stream { inner: &mut z };
    let flags = r.u32()?;
    if version >= 4 {
        // The mesh's name, NUL-terminated.
        while r.u8()? != 0 {}
    }
    let (nv, nt) = (r.u64()? as usize, r.u64()? as usize);
    if nv > 1 << 31 || nt > 1 << 31 {
        return Err(format!("mesh {index}: implausible sizes ({nv} vertices, {nt} triangles)"));
    }
    let double = flags & DOUBLE != 0;
    let mut floats = |n: usize| -> Result<Vec<f32>, String> {
        (0..n).map(|_| if double { r.f64().map(|v| v as f32) } else { r.f32() }).collect()
    };
    let p = floats(3 * nv)?;
    let positions = p.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    let normals = if flags & HAS_NORMALS != 0 {
        let n = floats(3 * nv)?;
        Some(n.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
    } else {
        None
    };
    let uvs = if flags & HAS_UVS != 0 {
        let t = floats(2 * nv)?;
        Some(t.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect())
    } else {
        None
    };
    if flags & HAS_COLOURS != 0 {
        floats(3 * nv)?;
    }
    let wide = nv > u32::MAX as usize;
    // The counts are the file's word: reserve no more than its compressed bytes could be (a
    // truncated stream then ends the read with an error long before memory runs out).
    let mut indices = Vec::with_capacity(nt.min(data.len()));
    for _ in 0..nt {
        let mut tri = [0u32; 3];
        for slot in &mut tri {
            *slot = if wide { r.u64()? as u32 } else { r.u32()? };
        }
        indices.push(tri);
    }
    Ok(RawMesh { positions, indices, normals, uvs })
}

struct Stream<'a, R: Read> {
    inner: &'a mut R,
}

impl<R: Read> Stream<'_, R> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut b = [0u8; N];
        self.inner.read_exact(&mut b).map_err(|e| format!("truncated or corrupt mesh data: {e}"))?;
        Ok(b)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.bytes::<1>()?[0])
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.bytes()?))
    }
    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.bytes()?))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.bytes()?))
    }
}

/// Where an import writes the PLY files of the `.serialized` meshes it converts, and what it
/// wrote. Invariants: it never writes through a symbolic link and never replaces a file it did not
/// create in this import; each (file, shape index) gets its own PLY, so two `.serialized` files of
/// the same name in different directories cannot share one. A name already taken on disk is kept
/// as it is: reused when it holds exactly the bytes this conversion makes (a second import of the
/// same scene), otherwise the mesh goes to the next free name `<stem>_<index>-<k>.ply`, with a
/// warning. Each file is written to a temporary file and linked into place only if the name is
/// still free, so a file that appears meanwhile is not replaced either.
#[derive(Debug)]
pub struct ConvertedMeshes {
    dir: PathBuf,
    /// (source file, shape index) → the PLY written or reused for it.
    written: HashMap<(PathBuf, i64), PathBuf>,
}

/// How many other names a conversion tries before giving up.
const MAX_NAME_TRIES: usize = 1000;

impl ConvertedMeshes {
    pub fn new(dir: &Path) -> ConvertedMeshes {
        ConvertedMeshes { dir: dir.to_path_buf(), written: HashMap::new() }
    }

    /// Each PLY written or reused, with the mesh it holds in words ("mesh 2 of 'a/m.serialized'").
    pub fn descriptions(&self) -> Vec<(PathBuf, String)> {
        let mut d: Vec<(PathBuf, String)> = self
            .written
            .iter()
            .map(|((source, index), ply)| (ply.clone(), format!("mesh {index} of '{}'", source.display())))
            .collect();
        d.sort();
        d
    }

    /// The PLY holding mesh `index` of `source` (already read as `mesh`), written if needed, and
    /// a note when it could not take its first-choice name.
    pub fn convert(&mut self, source: &Path, index: i64, mesh: &RawMesh) -> Result<(PathBuf, Option<String>), String> {
        let key = (source.to_path_buf(), index);
        if let Some(path) = self.written.get(&key) {
            return Ok((path.clone(), None));
        }
        let bytes = ply_bytes(mesh);
        let stem = source.file_stem().map(|x| x.to_string_lossy().into_owned()).unwrap_or_default();
        let first = self.dir.join(format!("{stem}_{index}.ply"));
        for k in 0..MAX_NAME_TRIES {
            let path = if k == 0 { first.clone() } else { self.dir.join(format!("{stem}_{index}-{}.ply", k + 1)) };
            if self.written.values().any(|p| *p == path) {
                continue;
            }
            let placed = match std::fs::symlink_metadata(&path) {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => write_new(&path, &bytes)?,
                Err(e) => return Err(format!("cannot check '{}': {e}", path.display())),
                // Only a regular file (not a link, FIFO or device) is read, and only to compare.
                Ok(meta) => {
                    meta.file_type().is_file()
                        && meta.len() == bytes.len() as u64
                        && std::fs::read(&path).is_ok_and(|existing| existing == bytes)
                }
            };
            if placed {
                let note = (k > 0).then(|| {
                    format!(
                        "'{}' exists and holds something else: mesh {index} of '{}' was written to '{}'",
                        first.display(),
                        source.display(),
                        path.display()
                    )
                });
                self.written.insert(key, path.clone());
                return Ok((path, note));
            }
        }
        Err(format!(
            "cannot convert mesh {index} of '{}': '{}' and {} other names beside it are taken",
            source.display(),
            first.display(),
            MAX_NAME_TRIES - 1
        ))
    }
}

/// Writes `bytes` to the new file `path` through a temporary file that is linked into place only
/// if `path` still does not exist. False when it has appeared meanwhile (left as it is).
fn write_new(path: &Path, bytes: &[u8]) -> Result<bool, String> {
    let dir = crate::interrupt::directory_of(path);
    let mut tmp = tempfile::Builder::new()
        .prefix(".plexus-import-")
        .suffix(".ply")
        .tempfile_in(dir)
        .map_err(|e| format!("cannot write in '{}': {e}", dir.display()))?;
    tmp.write_all(bytes).map_err(|e| format!("cannot write '{}': {e}", path.display()))?;
    match tmp.persist_noclobber(path) {
        Ok(_) => Ok(true),
        Err(e) if e.error.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e) => Err(format!("cannot write '{}': {}", path.display(), e.error)),
    }
}

/// `mesh` as a binary little-endian PLY (positions, normals and uvs when present).
pub fn ply_bytes(mesh: &RawMesh) -> Vec<u8> {
    let mut out = Vec::new();
    let mut header = format!("ply\nformat binary_little_endian 1.0\ncomment converted by plexus import\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n", mesh.positions.len());
    if mesh.normals.is_some() {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if mesh.uvs.is_some() {
        header.push_str("property float u\nproperty float v\n");
    }
    header.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.indices.len()
    ));
    out.extend_from_slice(header.as_bytes());
    for (i, p) in mesh.positions.iter().enumerate() {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(n) = &mesh.normals {
            for c in n[i].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        if let Some(t) = &mesh.uvs {
            for c in t[i].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for tri in &mesh.indices {
        out.push(3);
        for i in tri {
            out.extend_from_slice(&(*i as i32).to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Writes meshes in the serialized format (version 4, f32, with normals on the first), as
    /// Mitsuba's `TriMesh::serialize` lays them out.
    pub fn write_serialized(path: &Path, meshes: &[RawMesh]) {
        let mut data = Vec::new();
        let mut offsets = Vec::new();
        for (k, m) in meshes.iter().enumerate() {
            offsets.push(data.len() as u64);
            data.extend_from_slice(&FORMAT.to_le_bytes());
            data.extend_from_slice(&4u16.to_le_bytes());
            let mut body = Vec::new();
            let flags = if m.normals.is_some() { HAS_NORMALS } else { 0 } | 0x1000;
            body.extend_from_slice(&flags.to_le_bytes());
            body.extend_from_slice(format!("mesh{k}\0").as_bytes());
            body.extend_from_slice(&(m.positions.len() as u64).to_le_bytes());
            body.extend_from_slice(&(m.indices.len() as u64).to_le_bytes());
            for p in &m.positions {
                p.to_array().iter().for_each(|c| body.extend_from_slice(&c.to_le_bytes()));
            }
            if let Some(n) = &m.normals {
                n.iter().flat_map(|v| v.to_array()).for_each(|c| body.extend_from_slice(&c.to_le_bytes()));
            }
            m.indices.iter().flatten().for_each(|i| body.extend_from_slice(&i.to_le_bytes()));
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&body).unwrap();
            data.extend(z.finish().unwrap());
        }
        for o in &offsets {
            data.extend_from_slice(&o.to_le_bytes());
        }
        data.extend_from_slice(&(meshes.len() as u32).to_le_bytes());
        std::fs::write(path, data).unwrap();
    }

    pub fn two_meshes() -> Vec<RawMesh> {
        vec![
            RawMesh {
                positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
                indices: vec![[0, 1, 2]],
                normals: Some(vec![Vec3::Z; 3]),
                uvs: None,
            },
            RawMesh {
                positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE],
                indices: vec![[0, 1, 2], [1, 3, 2]],
                normals: None,
                uvs: None,
            },
        ]
    }

    #[test]
    fn reads_each_mesh_and_converts_to_ply() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.serialized");
        let meshes = two_meshes();
        write_serialized(&path, &meshes);
        for (k, want) in meshes.iter().enumerate() {
            let got = read(&path, k).unwrap();
            assert_eq!(got.positions, want.positions);
            assert_eq!(got.indices, want.indices);
            assert_eq!(got.normals, want.normals);
            let ply = dir.path().join(format!("m_{k}.ply"));
            std::fs::write(&ply, ply_bytes(&got)).unwrap();
            let back = crate::scene::mesh_io::load_ply(&ply).unwrap();
            assert_eq!(back.positions, want.positions);
            assert_eq!(back.indices, want.indices);
        }
        assert!(read(&path, 2).unwrap_err().contains("has 2 meshes"));
        // A corrupt stream is an error, not a panic.
        let mut bytes = std::fs::read(&path).unwrap();
        for b in &mut bytes[10..30] {
            *b ^= 0x5a;
        }
        std::fs::write(&path, bytes).unwrap();
        assert!(read(&path, 0).is_err());
    }

    /// A conversion never writes through a link, never replaces a file it did not write (reusing
    /// one only when it holds the same bytes), and gives same-named sources their own files.
    #[test]
    fn conversions_never_replace_or_write_through_links() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let meshes = two_meshes();
        let victim = d.join("victim.txt");
        std::fs::write(&victim, "keep me").unwrap();
        std::os::unix::fs::symlink(&victim, d.join("m_0.ply")).unwrap();
        std::fs::write(d.join("m_1.ply"), "the user's own mesh").unwrap();
        let mut out = ConvertedMeshes::new(d);
        let (a, note) = out.convert(Path::new("a/m.serialized"), 0, &meshes[0]).unwrap();
        assert_eq!(a, d.join("m_0-2.ply"));
        assert!(note.unwrap().contains("m_0.ply' exists"));
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
        let (b, _) = out.convert(Path::new("a/m.serialized"), 1, &meshes[1]).unwrap();
        assert_eq!(b, d.join("m_1-2.ply"));
        assert_eq!(std::fs::read_to_string(d.join("m_1.ply")).unwrap(), "the user's own mesh");
        // Another directory's m.serialized, mesh 0: its own file, not a replacement of a's.
        let (c, _) = out.convert(Path::new("b/m.serialized"), 0, &meshes[1]).unwrap();
        assert_eq!(c, d.join("m_0-3.ply"));
        assert_eq!(std::fs::read(&a).unwrap(), ply_bytes(&meshes[0]));
        assert_eq!(std::fs::read(&c).unwrap(), ply_bytes(&meshes[1]));
        // The same mesh again: the same file.
        assert_eq!(out.convert(Path::new("a/m.serialized"), 0, &meshes[0]).unwrap().0, a);
        // A second import of the same scene reuses the identical files it finds (still saying
        // why the first-choice name was not taken).
        let mut again = ConvertedMeshes::new(d);
        assert_eq!(again.convert(Path::new("a/m.serialized"), 0, &meshes[0]).unwrap().0, a);
        let (b_again, note) = again.convert(Path::new("a/m.serialized"), 1, &meshes[1]).unwrap();
        assert_eq!((b_again, note.is_some()), (b, true));
        let leftovers = std::fs::read_dir(d)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with(".plexus-import-"));
        assert_eq!(leftovers.count(), 0);
    }
}
