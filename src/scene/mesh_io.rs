//! Reading triangle meshes from OBJ (tobj) and PLY (ply-rs) files into plain arrays. Validation
//! (finite vertices, indices in range) is `TriangleMesh::new`'s job; this module reports only what
//! the file formats themselves get wrong.

use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;

use glam::{Vec2, Vec3};
use ply_rs::parser::Parser;
use ply_rs::ply::{DefaultElement, Property};

use super::ply;
use crate::input_file::open_regular;

pub use super::raw_mesh::RawMesh;

/// Reads every object of an OBJ file into one mesh (polygons triangulated as fans). Normals and
/// texture coordinates are kept only when every object has them for every vertex.
pub fn load_obj(path: &Path) -> Result<RawMesh, String> {
    // Only a regular file is read (tobj would read `/dev/zero` into one endless line), and only
    // it: materials are plexus's own, so an `mtllib` line opens nothing (it could name a device
    // or a FIFO).
    let (file, _) = open_regular(path)?;
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, _materials) =
        tobj::load_obj_buf(&mut std::io::BufReader::new(file), &options, |_| Err(tobj::LoadError::OpenFileFailed))
            .map_err(|e| format!("invalid OBJ: {e}"))?;
    let mut out = RawMesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut all_normals = true;
    let mut all_uvs = true;
    for model in &models {
        let m = &model.mesh;
        let base = out.positions.len();
        let n = m.positions.len() / 3;
        out.positions.extend(m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        if m.indices.len() % 3 != 0 {
            return Err(format!("object '{}' has a face that is not a triangle after triangulation", model.name));
        }
        for t in m.indices.chunks_exact(3) {
            let tri = [t[0], t[1], t[2]].map(|i| (base + i as usize).min(u32::MAX as usize) as u32);
            out.indices.push(tri);
        }
        all_normals &= m.normals.len() == 3 * n;
        all_uvs &= m.texcoords.len() == 2 * n;
        if all_normals {
            normals.extend(m.normals.chunks_exact(3).map(|v| Vec3::new(v[0], v[1], v[2])));
        }
        if all_uvs {
            uvs.extend(m.texcoords.chunks_exact(2).map(|v| Vec2::new(v[0], v[1])));
        }
    }
    if all_normals && !out.positions.is_empty() {
        out.normals = Some(normals);
    }
    if all_uvs && !out.positions.is_empty() {
        out.uvs = Some(uvs);
    }
    Ok(out)
}

/// Reads a PLY file (ASCII or binary): `vertex` with x, y, z and optionally nx, ny, nz and u, v
/// (or s, t); `face` with a `vertex_indices` (or `vertex_index`) list, polygons split into fans.
/// The header's counts are checked against the file's size first (`ply::parse_header`); binary
/// bodies are streamed into the arrays (`ply::read_binary`), ASCII ones parsed by ply-rs.
pub fn load_ply(path: &Path) -> Result<RawMesh, String> {
    let (file, size) = open_regular(path)?;
    let mut reader = BufReader::new(file);
    let header = ply::parse_header(&mut reader, size)?;
    if header.format != ply::Format::Ascii {
        return ply::read_binary(&header, reader);
    }
    reader.seek(SeekFrom::Start(0)).map_err(|e| e.to_string())?;
    let parser = Parser::<DefaultElement>::new();
    let ply = parser.read_ply(&mut reader).map_err(|e| format!("invalid PLY: {}", ply_reason(&e.to_string())))?;
    let vertices = ply.payload.get("vertex").ok_or("invalid PLY: no 'vertex' element")?;
    let faces = ply.payload.get("face").ok_or("invalid PLY: no 'face' element")?;

    let mut out = RawMesh::default();
    let has = |k: &str| vertices.first().is_some_and(|v| v.contains_key(k));
    let (has_n, has_uv, has_st) = (has("nx") && has("ny") && has("nz"), has("u") && has("v"), has("s") && has("t"));
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    for (i, v) in vertices.iter().enumerate() {
        let get = |k: &str| -> Result<f32, String> {
            match v.get(k) {
                Some(p) => scalar(p).ok_or_else(|| format!("vertex {i}: property '{k}' is not a number")),
                None => Err(format!("vertex {i}: missing property '{k}'")),
            }
        };
        out.positions.push(Vec3::new(get("x")?, get("y")?, get("z")?));
        if has_n {
            normals.push(Vec3::new(get("nx")?, get("ny")?, get("nz")?));
        }
        if has_uv {
            uvs.push(Vec2::new(get("u")?, get("v")?));
        } else if has_st {
            uvs.push(Vec2::new(get("s")?, get("t")?));
        }
    }
    for (f, face) in faces.iter().enumerate() {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .ok_or_else(|| format!("face {f}: no 'vertex_indices' list"))?;
        let idx = index_list(list).ok_or_else(|| format!("face {f}: 'vertex_indices' is not an integer list"))?;
        if idx.len() < 3 {
            return Err(format!("face {f}: expected at least 3 vertices, got {}", idx.len()));
        }
        let idx: Vec<u32> = idx
            .into_iter()
            .map(|i| u32::try_from(i).map_err(|_| format!("face {f}: vertex index {i} is negative")))
            .collect::<Result<_, _>>()?;
        for k in 1..idx.len() - 1 {
            out.indices.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    if has_n {
        out.normals = Some(normals);
    }
    if has_uv || has_st {
        out.uvs = Some(uvs);
    }
    Ok(out)
}

/// ply-rs's parse errors span several lines and nest `Debug` output of inner `io::Error`s
/// ("Line 8: Couln't read element line.\n\tString: 'zz\n'\n\tError: Custom { kind: ..., error:
/// \"...\" }"). This keeps what names the culprit: the line number, the offending text and the
/// innermost reason's first sentence, on one line.
fn ply_reason(raw: &str) -> String {
    let Some((line, rest)) = raw.strip_prefix("Line ").and_then(|r| r.split_once(':')) else {
        return raw.split_whitespace().collect::<Vec<_>>().join(" ");
    };
    let text = rest.split_once("String: '").and_then(|(_, t)| t.split_once('\'')).map(|(t, _)| t.trim());
    // The innermost `error: "..."` holds the reader's own words, `Debug`-escaped.
    let reason = rest
        .rsplit_once("error: \"")
        .map(|(_, r)| r.split(['"']).next().unwrap_or_default())
        .map(|r| r.split("\\n").next().unwrap_or_default().replace("\\'", "'"))
        .unwrap_or_else(|| rest.lines().next().unwrap_or_default().to_string());
    let reason = reason.trim().trim_end_matches('.');
    match text {
        Some(t) => format!("line {line}: cannot read '{t}': {reason}"),
        None => format!("line {line}: {reason}"),
    }
}

fn scalar(p: &Property) -> Option<f32> {
    Some(match *p {
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        Property::Char(v) => v as f32,
        Property::UChar(v) => v as f32,
        Property::Short(v) => v as f32,
        Property::UShort(v) => v as f32,
        Property::Int(v) => v as f32,
        Property::UInt(v) => v as f32,
        _ => return None,
    })
}

fn index_list(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&i| i as i64).collect(),
        _ => return None,
    })
}
