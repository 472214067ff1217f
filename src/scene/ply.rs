//! PLY headers, and a streaming reader for binary PLY bodies.
//!
//! The header is parsed here once (`parse_header`) and its element counts are checked against the
//! file's size before anything is allocated by them. A binary body is then read straight into the
//! mesh's arrays (`read_binary`): one pass through a fixed-size buffer, with no per-vertex or
//! per-face allocation; fixed-size records (vertices, and faces while their count stays the same)
//! are decoded a buffer at a time on all threads. ply-rs, which builds a map of properties per element, held a 10M-triangle
//! grid (190 MB) in 6.9 GB and took 27 s to read it (issue 20); it still reads ASCII files, which
//! are small in practice.

use std::io::{BufRead, Read};
use std::sync::atomic::{AtomicBool, Ordering};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::mesh_io::RawMesh;

/// The longest PLY header read before giving up (real headers are a few hundred bytes).
const MAX_PLY_HEADER: u64 = 1 << 20;

/// Bytes of the body read from the file at a time.
const CHUNK: usize = 1 << 20;

/// A PLY body's encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes `b` (exactly `self.size()` bytes) as an f32: as `decode(b) as f32`, without the
    /// round trip through f64 for the common float32 property.
    #[inline]
    fn decode_f32(self, b: &[u8], big_endian: bool) -> f32 {
        match self {
            Scalar::F32 => {
                let a = b.try_into().unwrap_or_default();
                if big_endian {
                    f32::from_be_bytes(a)
                } else {
                    f32::from_le_bytes(a)
                }
            }
            _ => self.decode(b, big_endian) as f32,
        }
    }

    /// Decodes `b` (exactly `self.size()` bytes) as an integer that fits a u32 (a count or a
    /// vertex index): `None` for a negative value or a float type.
    #[inline]
    fn decode_index(self, b: &[u8], big_endian: bool) -> Option<u32> {
        macro_rules! int {
            ($t:ty) => {{
                let a = b.try_into().ok()?;
                u32::try_from(if big_endian { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }).ok()
            }};
        }
        match self {
            Scalar::I8 => u32::try_from(b[0] as i8).ok(),
            Scalar::U8 => Some(b[0] as u32),
            Scalar::I16 => int!(i16),
            Scalar::U16 => int!(u16),
            Scalar::I32 => int!(i32),
            Scalar::U32 => int!(u32),
            Scalar::F32 | Scalar::F64 => None,
        }
    }

    /// Decodes `b` (exactly `self.size()` bytes).
    #[inline]
    fn decode(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! num {
            ($t:ty) => {{
                let a = b.try_into().unwrap_or_default();
                (if big_endian { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => num!(i16),
            Scalar::U16 => num!(u16),
            Scalar::I32 => num!(i32),
            Scalar::U32 => num!(u32),
            Scalar::F32 => num!(f32),
            Scalar::F64 => num!(f64),
        }
    }
}

/// A property of an element: a scalar, or a list (a count, then that many items).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
pub(super) struct Property {
    name: String,
    kind: Kind,
}

#[derive(Clone, Debug)]
pub(super) struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    fn find(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

/// A parsed header.
#[derive(Clone, Debug)]
pub(super) struct Header {
    pub format: Format,
    elements: Vec<Element>,
    /// Bytes after the header (the body's size, by the file's size).
    body_bytes: u64,
}

/// Reads the header from `reader` (left at the first byte of the body) and checks its element
/// counts against the file's `size`: each element needs at least a known number of bytes
/// (binary: its scalar properties' sizes and its lists' count fields; ASCII: its line's newline, a
/// loose bound that leaves a short last line to ply-rs, which names its line number), so a header
/// that declares more elements than the file can hold is truncated or lying, and is refused before
/// any reader allocates by its counts.
pub(super) fn parse_header<R: BufRead>(reader: &mut R, size: u64) -> Result<Header, String> {
    let mut header_bytes = 0u64;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut line = Vec::new();
    let mut first = true;
    loop {
        line.clear();
        let n = reader.by_ref().take(MAX_PLY_HEADER - header_bytes).read_until(b'\n', &mut line);
        let n = n.map_err(|e| e.to_string())? as u64;
        header_bytes += n;
        if n == 0 || header_bytes >= MAX_PLY_HEADER {
            return Err(format!(
                "invalid PLY: no 'end_header' in the first {} bytes",
                header_bytes.min(MAX_PLY_HEADER)
            ));
        }
        let text = String::from_utf8_lossy(&line);
        let words: Vec<&str> = text.split_whitespace().collect();
        if std::mem::take(&mut first) {
            if words.as_slice() != ["ply"] {
                return Err("invalid PLY: the file does not start with the line 'ply'".into());
            }
            continue;
        }
        let unknown_type = |t: &str| format!("invalid PLY: unknown property type '{t}'");
        match words.as_slice() {
            ["end_header"] => break,
            ["format", f, ..] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLittleEndian,
                    "binary_big_endian" => Format::BinaryBigEndian,
                    other => return Err(format!("invalid PLY: unknown format '{other}'")),
                })
            }
            ["element", name, count] => {
                let count =
                    count.parse::<u64>().map_err(|_| format!("invalid PLY: element '{name}' count '{count}'"))?;
                elements.push(Element { name: name.to_string(), count, properties: Vec::new() });
            }
            ["property", "list", count, item, name] => {
                let kind = Kind::List {
                    count: Scalar::parse(count).ok_or_else(|| unknown_type(count))?,
                    item: Scalar::parse(item).ok_or_else(|| unknown_type(item))?,
                };
                let e = elements.last_mut().ok_or("invalid PLY: a property before any element")?;
                e.properties.push(Property { name: name.to_string(), kind });
            }
            ["property", ty, name] => {
                let kind = Kind::Scalar(Scalar::parse(ty).ok_or_else(|| unknown_type(ty))?);
                let e = elements.last_mut().ok_or("invalid PLY: a property before any element")?;
                e.properties.push(Property { name: name.to_string(), kind });
            }
            _ => {}
        }
    }
    let format = format.ok_or("invalid PLY: no 'format' line")?;
    let body = size.saturating_sub(header_bytes);
    let mut need = 0u64;
    for e in &elements {
        let per: u64 = match format {
            Format::Ascii => 1,
            _ => e
                .properties
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) | Kind::List { count: s, .. } => s.size() as u64,
                })
                .sum::<u64>()
                .max(1),
        };
        // An ASCII file's last line may lack its newline: one byte of slack per file.
        need = need.saturating_add(e.count.saturating_mul(per));
        if need > body + 1 {
            return Err(format!(
                "invalid PLY: the header declares {} '{}' elements, which need at least {need} bytes, but only {body} \
                 bytes follow the header (truncated file or wrong count)",
                e.count, e.name
            ));
        }
    }
    Ok(Header { format, elements, body_bytes: body })
}

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
pub(super) fn read_binary<R: Read>(header: &Header, reader: R) -> Result<RawMesh, String> {
    read_binary_in_chunks(header, reader, CHUNK)
}

/// `read_binary` with batches of at most `chunk` bytes (small in tests, to cross batch
/// boundaries).
fn read_binary_in_chunks<R: Read>(header: &Header, reader: R, chunk: usize) -> Result<RawMesh, String> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn read(bytes: &[u8]) -> Result<RawMesh, String> {
        let mut r = bytes;
        let header = parse_header(&mut r, bytes.len() as u64)?;
        read_binary(&header, r)
    }

    fn header(format: &str, vertex_props: &str, face_props: &str, nv: usize, nf: usize) -> Vec<u8> {
        format!(
            "ply\nformat {format} 1.0\ncomment test\nelement vertex {nv}\n{vertex_props}element face {nf}\n\
             {face_props}end_header\n"
        )
        .into_bytes()
    }

    #[test]
    fn reads_both_endiannesses_with_normals_uvs_fans_and_extra_properties() {
        for big in [false, true] {
            let format = if big { "binary_big_endian" } else { "binary_little_endian" };
            let vp = "property double x\nproperty float y\nproperty float z\nproperty uchar red\n\
                      property float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n";
            let fp = "property uchar flags\nproperty list uchar uint vertex_indices\nproperty list int float junk\n";
            let mut b = header(format, vp, fp, 4, 1);
            let f32b = |v: f32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
            for k in 0..4 {
                let x = k as f64;
                b.extend(if big { x.to_be_bytes() } else { x.to_le_bytes() });
                b.extend(f32b(k as f32 + 0.5));
                b.extend(f32b(-1.0));
                b.push(7);
                for v in [0.0, 0.0, 1.0, 0.25 * k as f32, 0.5] {
                    b.extend(f32b(v));
                }
            }
            b.push(9);
            b.push(4);
            for i in [0u32, 1, 2, 3] {
                b.extend(if big { i.to_be_bytes() } else { i.to_le_bytes() });
            }
            b.extend(if big { 1i32.to_be_bytes() } else { 1i32.to_le_bytes() });
            b.extend(f32b(3.0));
            let m = read(&b).expect("valid");
            assert_eq!(m.positions.len(), 4);
            assert_eq!(m.positions[2], Vec3::new(2.0, 2.5, -1.0));
            assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
            assert_eq!(m.normals.as_deref().map(|n| n[3]), Some(Vec3::Z));
            assert_eq!(m.uvs.as_deref().map(|u| u[1]), Some(Vec2::new(0.25, 0.5)));
            assert!(m.positions.capacity() > m.positions.len(), "room for the padding vertex");
        }
    }

    /// A little-endian PLY of `nv` vertices (vertex k at (k, 2k, -k)) and `faces`, each face's
    /// record a flag byte, the index list and a float (fixed-size records around the list).
    fn polygons(nv: usize, faces: &[Vec<i32>]) -> Vec<u8> {
        let vp = "property float x\nproperty float y\nproperty float z\n";
        let fp = "property uchar flags\nproperty list uchar int vertex_indices\nproperty float quality\n";
        let mut b = header("binary_little_endian", vp, fp, nv, faces.len());
        for k in 0..nv {
            for v in [k as f32, 2.0 * k as f32, -(k as f32)] {
                b.extend(v.to_le_bytes());
            }
        }
        for f in faces {
            b.push(1);
            b.push(f.len() as u8);
            f.iter().for_each(|i| b.extend(i.to_le_bytes()));
            b.extend(0.5f32.to_le_bytes());
        }
        b
    }

    fn read_in_chunks(bytes: &[u8], chunk: usize) -> Result<RawMesh, String> {
        let mut r = bytes;
        let header = parse_header(&mut r, bytes.len() as u64)?;
        read_binary_in_chunks(&header, r, chunk)
    }

    /// The batched readers (vertex records, and face records while their count stays the same)
    /// against the face-by-face reader's results and errors, across batch boundaries: batches of
    /// 40 bytes hold three vertices or two triangle records (18 bytes each), so every kind of face
    /// meets a boundary somewhere. Wrong variants this catches: a batch with a quad among
    /// triangles kept (its corners read as a triangle), a dropped batch not re-read, an error naming
    /// the batch's first face instead of the culprit.
    #[test]
    fn batched_records_read_like_single_faces_across_batch_boundaries() {
        let tri = |k: i32| vec![k % 9, (k + 1) % 9, (k + 2) % 9];
        let mut faces: Vec<Vec<i32>> = (0..7).map(tri).collect();
        faces.push(vec![0, 1, 2, 3]);
        faces.extend((0..5).map(tri));
        faces.extend([vec![4, 5, 6, 7, 8], vec![1, 2, 3, 4, 5]]);
        faces.extend((0..4).map(tri));
        let expected: Vec<[u32; 3]> = faces
            .iter()
            .flat_map(|f| (1..f.len() - 1).map(move |t| [f[0], f[t], f[t + 1]].map(|i| i as u32)))
            .collect();
        let bytes = polygons(9, &faces);
        for chunk in [1, 20, 40, 64, 1 << 20] {
            let m = read_in_chunks(&bytes, chunk).expect("valid");
            assert_eq!(m.indices, expected, "chunk {chunk}");
            assert_eq!(m.positions.len(), 9);
            assert_eq!(m.positions[7], Vec3::new(7.0, 14.0, -7.0), "chunk {chunk}");
        }
        // All quads: read in batches too, as fans.
        let quads: Vec<Vec<i32>> = (0..6).map(|k| vec![k, k + 1, k + 2, k + 3]).collect();
        let m = read_in_chunks(&polygons(9, &quads), 40).expect("quads");
        assert_eq!(m.indices.len(), 12);
        assert_eq!(m.indices[10..], [[5, 6, 7], [5, 7, 8]]);

        // Errors name the culprit face, wherever it is in its batch.
        for chunk in [40, 64, 1 << 20] {
            let mut bad = faces.clone();
            bad[10][1] = -3;
            let e = read_in_chunks(&polygons(9, &bad), chunk).expect_err("negative");
            assert!(e.contains("face 10: vertex index -3 is negative"), "chunk {chunk}: {e}");
            let mut two = faces.clone();
            two[14] = vec![1, 2];
            let e = read_in_chunks(&polygons(9, &two), chunk).expect_err("two");
            assert!(e.contains("face 14: expected at least 3 vertices"), "chunk {chunk}: {e}");
            // Truncated inside face 16's index list (faces 17 and 18 are 18-byte triangles). A
            // body cut inside the vertices is refused by the header's bound before any batch.
            let ok = polygons(9, &faces);
            let face_16_end = ok.len() - 2 * 18;
            let e = read_in_chunks(&ok[..face_16_end - 5], chunk).expect_err("truncated");
            assert!(e.contains("ends inside face 16 of 19"), "chunk {chunk}: {e}");
        }
    }

    #[test]
    fn malformed_bodies_are_errors_naming_the_element() {
        let vp = "property float x\nproperty float y\nproperty float z\n";
        let fp = "property list uchar int vertex_indices\n";
        let mut ok = header("binary_little_endian", vp, fp, 3, 1);
        ok.extend([0u8; 36]);
        ok.push(3);
        for i in [0i32, 1, 2] {
            ok.extend(i.to_le_bytes());
        }
        assert_eq!(read(&ok).expect("valid").indices, vec![[0, 1, 2]]);
        // Truncated inside the face's list.
        let e = read(&ok[..ok.len() - 2]).expect_err("truncated");
        assert!(e.contains("ends inside face 0 of 1"), "{e}");
        // A negative index.
        let mut neg = ok.clone();
        let n = neg.len();
        neg[n - 4..].copy_from_slice(&(-5i32).to_le_bytes());
        assert!(read(&neg).expect_err("negative").contains("vertex index -5 is negative"));
        // Two vertices in a face.
        let mut two = ok.clone();
        two[n - 13] = 2;
        assert!(read(&two).expect_err("two").contains("at least 3 vertices"));
        // A list count that lies: it meets the end of the file, not an allocation.
        let mut lie = ok.clone();
        lie[n - 13] = 255;
        assert!(read(&lie).expect_err("lie").contains("ends inside face 0"));
        // Missing pieces and unknown types.
        let no_z = header("binary_little_endian", "property float x\nproperty float y\n", fp, 0, 0);
        assert!(read(&no_z).expect_err("no z").contains("no property 'z'"));
        let float_list = header("binary_little_endian", vp, "property list uchar float vertex_indices\n", 0, 0);
        assert!(read(&float_list).expect_err("floats").contains("not an integer list"));
        let odd = header("binary_little_endian", "property quad x\n", fp, 0, 0);
        assert!(read(&odd).expect_err("type").contains("unknown property type 'quad'"));
        assert!(read(b"plx\nformat ascii 1.0\nend_header\n").expect_err("magic").contains("start with"));
    }

    /// A face's other list longer than the read buffer (read item by item) makes no triangles:
    /// before this fix the fan step after it ran for every list, so a long list ahead of the
    /// index list took `fan.len() - 1` of an empty fan (a panic), and one after it repeated the
    /// face's triangles.
    #[test]
    fn long_lists_other_than_the_indices_make_no_triangles() {
        let vp = "property float x\nproperty float y\nproperty float z\n";
        let long = CHUNK / 4 + 10;
        for before in [true, false] {
            let (indices, extra) = ("property list uchar int vertex_indices\n", "property list int float weights\n");
            let fp = if before { format!("{extra}{indices}") } else { format!("{indices}{extra}") };
            let mut b = header("binary_little_endian", vp, &fp, 3, 1);
            b.extend([0u8; 36]);
            let mut weights = (long as i32).to_le_bytes().to_vec();
            weights.extend(std::iter::repeat_n(0u8, 4 * long));
            let mut tri = vec![3u8];
            for i in [0i32, 1, 2] {
                tri.extend(i.to_le_bytes());
            }
            if before {
                b.extend(&weights);
                b.extend(&tri);
            } else {
                b.extend(&tri);
                b.extend(&weights);
            }
            assert_eq!(read(&b).expect("valid").indices, vec![[0, 1, 2]], "long list before the indices: {before}");
        }
    }
}
