//! The binary PLY body: a streaming reader straight into the mesh's arrays (`read_binary`), fixed-size
//! records decoded a buffer at a time on all threads, anything else read record by record with errors
//! that name the element (the module above parses and bounds the header).

use std::io::Read;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{Element, Format, Header, Kind, Scalar};
use crate::scene::raw_mesh::RawMesh;

/// Bytes of the body read from the file at a time.
pub(super) const CHUNK: usize = 1 << 20;

/// The body, read through one reusable buffer.
struct Body<R> {
    inner: R,
    buf: Vec<u8>,
    pos: usize,
    end: usize,
    /// The most bytes a batch of fixed-size records takes at once (the buffer's usual size).
    chunk: usize,
}

impl<R: Read> Body<R> {
    fn new(inner: R, chunk: usize) -> Body<R> {
        Body { inner, buf: vec![0; chunk], pos: 0, end: 0, chunk }
    }

    /// The next `n` bytes, or `None` at the end of the file.
    #[inline]
    fn take(&mut self, n: usize) -> Result<Option<&[u8]>, String> {
        if self.end - self.pos < n && !self.refill(n)? {
            return Ok(None);
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(Some(s))
    }

    /// The next `n` bytes without taking them (fewer only at the end of the file); `consume`
    /// takes what was used.
    fn peek(&mut self, n: usize) -> Result<&[u8], String> {
        if self.end - self.pos < n {
            self.refill(n)?;
        }
        Ok(&self.buf[self.pos..self.end.min(self.pos + n)])
    }

    fn consume(&mut self, n: usize) {
        debug_assert!(n <= self.end - self.pos, "consume past what was peeked");
        self.pos += n;
    }

    /// Makes at least `n` bytes available; false at the end of the file (what is left is then
    /// available).
    #[cold]
    fn refill(&mut self, n: usize) -> Result<bool, String> {
        self.buf.copy_within(self.pos..self.end, 0);
        self.end -= self.pos;
        self.pos = 0;
        if self.buf.len() < n {
            self.buf.resize(n, 0);
        }
        while self.end < n {
            match self.inner.read(&mut self.buf[self.end..]) {
                Ok(0) => return Ok(false),
                Ok(k) => self.end += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.to_string()),
            }
        }
        Ok(true)
    }
}

/// Where the mesh's attributes are among the vertex element's properties.
struct VertexLayout {
    position: [usize; 3],
    normal: Option<[usize; 3]>,
    uv: Option<[usize; 2]>,
}

impl VertexLayout {
    fn new(e: &Element) -> Result<VertexLayout, String> {
        let scalar = |k: &str| -> Result<Option<usize>, String> {
            match e.find(k) {
                Some(i) if matches!(e.properties[i].kind, Kind::List { .. }) => {
                    Err(format!("invalid PLY: vertex property '{k}' is a list, not a number"))
                }
                found => Ok(found),
            }
        };
        let need = |k: &str| scalar(k)?.ok_or_else(|| format!("invalid PLY: the vertex element has no property '{k}'"));
        let all3 = |a: &str, b: &str, c: &str| -> Result<Option<[usize; 3]>, String> {
            Ok(match (scalar(a)?, scalar(b)?, scalar(c)?) {
                (Some(x), Some(y), Some(z)) => Some([x, y, z]),
                _ => None,
            })
        };
        let both = |a: &str, b: &str| -> Result<Option<[usize; 2]>, String> {
            Ok(match (scalar(a)?, scalar(b)?) {
                (Some(x), Some(y)) => Some([x, y]),
                _ => None,
            })
        };
        Ok(VertexLayout {
            position: [need("x")?, need("y")?, need("z")?],
            normal: all3("nx", "ny", "nz")?,
            uv: match both("u", "v")? {
                Some(uv) => Some(uv),
                None => both("s", "t")?,
            },
        })
    }
}

/// Reads a binary body (`header.format` is binary) after `parse_header` has read the header:
/// `vertex` with x, y, z and optionally nx, ny, nz and u, v (or s, t); `face` with a
/// `vertex_indices` (or `vertex_index`) list, polygons split into fans; other elements are
/// skipped. The arrays are allocated once by the header's counts, which `parse_header` has bounded
/// by the file's size.
pub(in crate::scene) fn read_binary<R: Read>(header: &Header, reader: R) -> Result<RawMesh, String> {
    read_binary_in_chunks(header, reader, CHUNK)
}

/// `read_binary` with batches of at most `chunk` bytes (small in tests, to cross batch
/// boundaries).
pub(super) fn read_binary_in_chunks<R: Read>(header: &Header, reader: R, chunk: usize) -> Result<RawMesh, String> {
    let big_endian = header.format == Format::BinaryBigEndian;
    let vertex = header.elements.iter().position(|e| e.name == "vertex").ok_or("invalid PLY: no 'vertex' element")?;
    let face = header.elements.iter().position(|e| e.name == "face").ok_or("invalid PLY: no 'face' element")?;
    let layout = VertexLayout::new(&header.elements[vertex])?;
    let fe = &header.elements[face];
    let list = fe
        .find("vertex_indices")
        .or_else(|| fe.find("vertex_index"))
        .ok_or("invalid PLY: the face element has no 'vertex_indices' list")?;
    match fe.properties[list].kind {
        Kind::List { item, .. } if item.is_integer() => {}
        _ => return Err("invalid PLY: 'vertex_indices' is not an integer list".into()),
    }

    let mut body = Body::new(reader, chunk);
    let mut out = RawMesh::default();
    let last = vertex.max(face);
    for (k, e) in header.elements.iter().enumerate().take(last + 1) {
        if k == vertex {
            read_vertices(&mut body, e, &layout, big_endian, &mut out)?;
        } else if k == face {
            read_faces(&mut body, e, list, big_endian, header.body_bytes, &mut out.indices)?;
        } else {
            for i in 0..e.count {
                skip_element(&mut body, e, big_endian)?.ok_or_else(|| ends_inside(e, i))?;
            }
        }
    }
    Ok(out)
}

fn ends_inside(e: &Element, i: u64) -> String {
    format!("invalid PLY: the file ends inside {} {i} of {}", e.name, e.count)
}

/// Byte offset of each property in the element's record and the record's size, when every
/// property is a scalar (the record has a fixed size); `None` when it has a list.
fn fixed_record(e: &Element) -> Option<(Vec<usize>, usize)> {
    let mut offsets = Vec::with_capacity(e.properties.len());
    let mut size = 0;
    for p in &e.properties {
        let Kind::Scalar(s) = p.kind else { return None };
        offsets.push(size);
        size += s.size();
    }
    Some((offsets, size))
}

/// Reads the vertex element into `out`'s positions, normals and uvs.
fn read_vertices<R: Read>(
    body: &mut Body<R>,
    e: &Element,
    layout: &VertexLayout,
    big_endian: bool,
    out: &mut RawMesh,
) -> Result<(), String> {
    // `count` fits in usize: parse_header bounded it by the file's size.
    let n = e.count as usize;
    // One spare slot: `TriangleMesh::new` appends its padding vertex without reallocating.
    out.positions = Vec::with_capacity(n + 1);
    let mut normals = layout.normal.map(|_| Vec::with_capacity(n));
    let mut uvs = layout.uv.map(|_| Vec::with_capacity(n));
    if let Some((offsets, stride)) = fixed_record(e).filter(|(_, stride)| *stride > 0) {
        // Fixed-size records (the usual case): decoded a buffer's worth at a time, each attribute
        // at its offset, without a per-property read.
        let field = |j: usize| {
            let Kind::Scalar(s) = e.properties[j].kind else { unreachable!("fixed_record has only scalars") };
            (offsets[j], s)
        };
        let vec3 = |[a, b, c]: [usize; 3]| [field(a), field(b), field(c)];
        let position = vec3(layout.position);
        let normal = layout.normal.map(vec3);
        let uv = layout.uv.map(|[a, b]| [field(a), field(b)]);
        let get = |record: &[u8], (at, s): (usize, Scalar)| s.decode_f32(&record[at..at + s.size()], big_endian);
        let per_batch = (body.chunk / stride).max(1);
        let mut done = 0;
        while done < n {
            // A batch of records, decoded on all threads straight into the arrays (rayon's
            // indexed `par_extend` writes into the reserved capacity, in order).
            let k = (n - done).min(per_batch);
            let bytes = body.peek(k * stride)?;
            if bytes.len() < k * stride {
                return Err(ends_inside(e, (done + bytes.len() / stride) as u64));
            }
            let records = || bytes.par_chunks_exact(stride);
            out.positions.par_extend(records().map(|r| Vec3::from_array(position.map(|f| get(r, f)))));
            if let (Some(ns), Some(f)) = (normals.as_mut(), normal) {
                ns.par_extend(records().map(|r| Vec3::from_array(f.map(|f| get(r, f)))));
            }
            if let (Some(us), Some(f)) = (uvs.as_mut(), uv) {
                us.par_extend(records().map(|r| Vec2::from_array(f.map(|f| get(r, f)))));
            }
            body.consume(k * stride);
            done += k;
        }
    } else {
        let mut values = Vec::new();
        for i in 0..e.count {
            read_scalars(body, e, big_endian, &mut values)?.ok_or_else(|| ends_inside(e, i))?;
            let v = |j: usize| values[j] as f32;
            let [x, y, z] = layout.position;
            out.positions.push(Vec3::new(v(x), v(y), v(z)));
            if let (Some(ns), Some([a, b, c])) = (normals.as_mut(), layout.normal) {
                ns.push(Vec3::new(v(a), v(b), v(c)));
            }
            if let (Some(uv), Some([a, b])) = (uvs.as_mut(), layout.uv) {
                uv.push(Vec2::new(v(a), v(b)));
            }
        }
    }
    out.normals = normals;
    out.uvs = uvs;
    Ok(())
}

/// A face record of fixed size: every property a scalar but the index list, whose count is
/// `corners` (the first face's). Faces of a file usually all have the same count, so their
/// records can be read in batches like the vertices'.
struct FixedFaces {
    stride: usize,
    /// Byte offset and type of the list's count, then of its first item.
    count_at: usize,
    count: Scalar,
    items_at: usize,
    item: Scalar,
    corners: usize,
}

impl FixedFaces {
    /// The layout of `e`'s records if every face has the first face's count, which `first`
    /// (the body's next bytes) holds; `None` when `e` has another list, or that count is not a
    /// small polygon's.
    fn new(e: &Element, list: usize, first: &[u8], big_endian: bool) -> Option<FixedFaces> {
        let mut at = 0;
        for (j, p) in e.properties.iter().enumerate() {
            match p.kind {
                Kind::Scalar(s) => at += s.size(),
                Kind::List { .. } if j != list => return None,
                Kind::List { .. } => {}
            }
        }
        let Kind::List { count, item } = e.properties[list].kind else { return None };
        let count_at: usize = e.properties[..list]
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) | Kind::List { count: s, .. } => s.size(),
            })
            .sum();
        let corners = count.decode_index(first.get(count_at..count_at + count.size())?, big_endian)?;
        if !(3..=64).contains(&corners) {
            return None;
        }
        let corners = corners as usize;
        let items_at = count_at + count.size();
        Some(FixedFaces { stride: at + count.size() + corners * item.size(), count_at, count, items_at, item, corners })
    }

    /// The record's corners as vertex indices, or `None` when the record is not of this layout
    /// (another count) or an index is negative: the general reader then names the culprit.
    #[inline]
    fn corner(&self, record: &[u8], k: usize, big_endian: bool) -> Option<u32> {
        let at = self.items_at + k * self.item.size();
        self.item.decode_index(&record[at..at + self.item.size()], big_endian)
    }

    #[inline]
    fn fits(&self, record: &[u8], big_endian: bool) -> bool {
        let c = &record[self.count_at..self.count_at + self.count.size()];
        self.count.decode_index(c, big_endian) == Some(self.corners as u32)
    }
}

/// Reads the face element, the `list`-th property being the vertex indices, into triangles
/// (polygons split into fans). `body_bytes` (the body's size) bounds the triangles reserved up
/// front, whatever the header's count says.
///
/// Faces are read in batches of fixed-size records (`FixedFaces`, the count of the batch's first
/// face), decoded on all threads, while every record of a batch has that layout; a batch with
/// another count, a negative index or the end of the file in it is read again face by face by
/// `read_face`, which names the culprit, and the batches resume after it.
fn read_faces<R: Read>(
    body: &mut Body<R>,
    e: &Element,
    list: usize,
    big_endian: bool,
    body_bytes: u64,
    indices: &mut Vec<[u32; 3]>,
) -> Result<(), String> {
    let Kind::List { count, item } = e.properties[list].kind else { unreachable!("read_binary checked the list") };
    let smallest_triangle = count.size() + 3 * item.size();
    *indices = Vec::with_capacity(e.count.min(body_bytes / smallest_triangle as u64) as usize);
    let per_general_batch = (body.chunk / smallest_triangle).max(1) as u64;
    let mut fan: Vec<u32> = Vec::new();
    let mut f = 0;
    while f < e.count {
        let next = body.peek(body.chunk)?;
        if let Some(fixed) = FixedFaces::new(e, list, next, big_endian) {
            f += read_fixed_faces(body, e.count - f, &fixed, big_endian, indices)?;
        }
        let end = (f + per_general_batch).min(e.count);
        while f < end {
            read_face(body, e, f, list, big_endian, &mut fan, indices)?;
            f += 1;
        }
    }
    Ok(())
}

/// Reads up to `left` faces of `fixed`'s layout in batches, decoded on all threads straight into
/// `indices`, while every record of a batch has that layout; returns how many it read.
fn read_fixed_faces<R: Read>(
    body: &mut Body<R>,
    left: u64,
    fixed: &FixedFaces,
    big_endian: bool,
    indices: &mut Vec<[u32; 3]>,
) -> Result<u64, String> {
    let per_batch = (body.chunk / fixed.stride).max(1) as u64;
    let mut done = 0;
    while done < left {
        let k = (left - done).min(per_batch) as usize;
        let bytes = body.peek(k * fixed.stride)?;
        if bytes.len() < k * fixed.stride {
            break;
        }
        let start = indices.len();
        let odd = AtomicBool::new(false);
        let records = bytes.par_chunks_exact(fixed.stride);
        // A record of another layout is noted in `odd` and read as zeros; the batch is dropped.
        let corner = |r: &[u8], k: usize| {
            let v = fixed.corner(r, k, big_endian).filter(|_| k > 0 || fixed.fits(r, big_endian));
            v.unwrap_or_else(|| {
                odd.store(true, Ordering::Relaxed);
                0
            })
        };
        if fixed.corners == 3 {
            indices.par_extend(records.map(|r| [corner(r, 0), corner(r, 1), corner(r, 2)]));
        } else {
            indices.par_extend(records.flat_map_iter(|r| {
                let first = corner(r, 0);
                (1..fixed.corners - 1).map(move |t| [first, corner(r, t), corner(r, t + 1)])
            }));
        }
        if odd.load(Ordering::Relaxed) {
            indices.truncate(start);
            break;
        }
        body.consume(k * fixed.stride);
        done += k as u64;
    }
    Ok(done)
}

/// Reads face `f` (any layout) into `indices`, naming the face in any error.
fn read_face<R: Read>(
    body: &mut Body<R>,
    e: &Element,
    f: u64,
    list: usize,
    big_endian: bool,
    fan: &mut Vec<u32>,
    indices: &mut Vec<[u32; 3]>,
) -> Result<(), String> {
    let ends = || ends_inside(e, f);
    for (j, p) in e.properties.iter().enumerate() {
        match p.kind {
            Kind::Scalar(s) => {
                body.take(s.size())?.ok_or_else(ends)?;
            }
            Kind::List { count, item } => {
                let c = count.decode(body.take(count.size())?.ok_or_else(ends)?, big_endian);
                if !(c >= 0.0) {
                    return Err(format!("face {f}: list '{}' has a negative length {c}", p.name));
                }
                if j == list && c < 3.0 {
                    return Err(format!("face {f}: expected at least 3 vertices, got {c}"));
                }
                let size = item.size();
                if c * size as f64 > CHUNK as f64 {
                    // A list longer than the buffer (real faces have a handful of vertices):
                    // read item by item, so that a lying count meets the end of the file
                    // rather than an allocation.
                    if j == list {
                        fan.clear();
                    }
                    for _ in 0..c as u64 {
                        let b = body.take(size)?.ok_or_else(ends)?;
                        if j == list {
                            fan.push(vertex_index(f, item.decode(b, big_endian))?);
                        }
                    }
                } else {
                    let items = body.take(c as usize * size)?.ok_or_else(ends)?;
                    if j != list {
                        continue;
                    }
                    fan.clear();
                    for b in items.chunks_exact(size) {
                        fan.push(vertex_index(f, item.decode(b, big_endian))?);
                    }
                }
                // Only the index list makes triangles: another list (read past above) leaves
                // `fan` as it was, perhaps empty or the previous face's.
                if j == list {
                    for t in 1..fan.len() - 1 {
                        indices.push([fan[0], fan[t], fan[t + 1]]);
                    }
                }
            }
        }
    }
    Ok(())
}

/// A decoded integer list item as a vertex index.
#[inline]
fn vertex_index(face: u64, i: f64) -> Result<u32, String> {
    if i < 0.0 {
        return Err(format!("face {face}: vertex index {i} is negative"));
    }
    // Integer items decode exactly into f64; u32 holds every one left.
    Ok(i as u32)
}

/// Reads one element's scalar properties into `values` (lists are read past and leave 0).
/// `None` at the end of the file.
#[inline]
fn read_scalars<R: Read>(
    body: &mut Body<R>,
    e: &Element,
    big_endian: bool,
    values: &mut Vec<f64>,
) -> Result<Option<()>, String> {
    values.clear();
    for p in &e.properties {
        match p.kind {
            Kind::Scalar(s) => match body.take(s.size())? {
                Some(b) => values.push(s.decode(b, big_endian)),
                None => return Ok(None),
            },
            Kind::List { .. } => {
                if skip_list(body, p.kind, big_endian)?.is_none() {
                    return Ok(None);
                }
                values.push(0.0);
            }
        }
    }
    Ok(Some(()))
}

/// Reads past one element. `None` at the end of the file.
fn skip_element<R: Read>(body: &mut Body<R>, e: &Element, big_endian: bool) -> Result<Option<()>, String> {
    for p in &e.properties {
        let done = match p.kind {
            Kind::Scalar(s) => body.take(s.size())?.map(drop),
            Kind::List { .. } => skip_list(body, p.kind, big_endian)?,
        };
        if done.is_none() {
            return Ok(None);
        }
    }
    Ok(Some(()))
}

/// Reads past one list (its count, then its items one at a time, so that a lying count meets the
/// end of the file instead of an allocation). `None` at the end of the file.
fn skip_list<R: Read>(body: &mut Body<R>, kind: Kind, big_endian: bool) -> Result<Option<()>, String> {
    let Kind::List { count, item } = kind else { return Ok(Some(())) };
    let Some(b) = body.take(count.size())? else { return Ok(None) };
    let c = count.decode(b, big_endian);
    if !(c >= 0.0) {
        return Err(format!("invalid PLY: a list has a negative length {c}"));
    }
    for _ in 0..c as u64 {
        if body.take(item.size())?.is_none() {
            return Ok(None);
        }
    }
    Ok(Some(()))
}
