//! PLY headers here, and a streaming reader for binary PLY bodies (`binary`).
//!
//! The header is parsed here once (`parse_header`) and its element counts are checked against the
//! file's size before anything is allocated by them. A binary body is then read straight into the
//! mesh's arrays (`read_binary`): one pass through a fixed-size buffer, with no per-vertex or
//! per-face allocation; fixed-size records (vertices, and faces while their count stays the same)
//! are decoded a buffer at a time on all threads. ply-rs, which builds a map of properties per
//! element, holds a 10M-triangle grid (190 MB) in 6.9 GB and takes 27 s to read it; it reads
//! the ASCII files, which are small in practice.

use std::io::{BufRead, Read};

mod binary;
#[cfg(test)]
mod tests;

pub(super) use binary::read_binary;

/// The longest PLY header read before giving up (real headers are a few hundred bytes).
const MAX_PLY_HEADER: u64 = 1 << 20;

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
