//! Mitsuba's `.serialized` meshes, converted to PLY for the scene loader.
//!
//! The format (Mitsuba 0.6 `TriMesh::loadCompressed`, also read by Mitsuba 3): a file holds
//! several meshes, each `u16 0x041C` (format), `u16` version (3 or 4), then one zlib stream with
//! `u32` flags, (version 4) the mesh's name as a NUL-terminated string, `u64` vertex and triangle
//! counts, the positions, optional normals, uvs and colours (f32, or f64 with flag 0x2000) and
//! the indices (u32, or u64 past 2^32 vertices). The file ends with a table of the meshes' byte
//! offsets (`u64` in version 4, `u32` in version 3) and a `u32` count. All little-endian.

use std::io::{Read, Write};
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::scene::mesh_io::RawMesh;

const FORMAT: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_UVS: u32 = 0x0002;
const HAS_COLOURS: u32 = 0x0008;
const DOUBLE: u32 = 0x2000;

/// Reads mesh `index` of the `.serialized` file at `path`.
pub fn read(path: &Path, index: usize) -> Result<RawMesh, String> {
    let data = std::fs::read(path).map_err(|e| e.to_string())?;
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
    let mut indices = Vec::with_capacity(nt);
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

/// Writes `mesh` as a binary little-endian PLY (positions, normals and uvs when present).
pub fn write_ply(path: &Path, mesh: &RawMesh) -> Result<(), String> {
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
    let mut f = std::fs::File::create(path).map_err(|e| format!("cannot create '{}': {e}", path.display()))?;
    f.write_all(&out).map_err(|e| format!("cannot write '{}': {e}", path.display()))
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
            write_ply(&ply, &got).unwrap();
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
}
