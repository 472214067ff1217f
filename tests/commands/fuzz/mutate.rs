//! The mutators: random TOML values and trees, scene trees changed in place, bytes and text
//! truncated, flipped, dropped or repeated — all driven by the suite's seeded [`Rng`].

use toml::Value;

use super::Rng;

pub(crate) const INTS: &[i64] = &[-1, 0, 1, 2, 3, 7, 64, 1 << 31, 1 << 32, 1 << 53, i64::MAX, i64::MIN, 65537];
pub(crate) const FLOATS: &[f64] = &[
    0.0,
    -0.0,
    -1.0,
    0.5,
    1.0,
    1.5,
    90.0,
    180.0,
    1e-45,
    1e-30,
    1e-12,
    1e12,
    1e30,
    3.4e38,
    1e300,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
];
pub(crate) const STRINGS: &[&str] = &[
    "",
    "x",
    "pt",
    "bdpt",
    "light",
    "mmlt",
    "pssmlt",
    "rjmlt",
    "diffuse",
    "mirror",
    "dielectric",
    "conductor",
    "plastic",
    "quad",
    "box",
    "sphere",
    "disk",
    "obj",
    "ply",
    "constant",
    "image",
    "embree",
    "bvh",
    "balance",
    "/dev/zero",
    "/",
    "missing.obj",
    "s.toml",
    "ünïcödé",
];
pub(crate) const KEYS: &[&str] = &[
    "type",
    "scale",
    "radiance",
    "resolution",
    "fov",
    "file",
    "material",
    "emission",
    "transform",
    "spp",
    "time",
    "threads",
    "seed",
    "max_depth",
    "bootstrap",
    "chains",
    "two_sided",
    "subdivisions",
    "roughness",
    "ior",
    "bogus",
];

pub(crate) fn random_value(rng: &mut Rng, depth: u32) -> Value {
    match rng.below(if depth > 1 { 4 } else { 6 }) {
        0 => Value::Integer(*rng.pick(INTS)),
        1 => Value::Float(*rng.pick(FLOATS)),
        2 => Value::String(rng.pick(STRINGS).to_string()),
        3 => Value::Boolean(rng.chance(0.5)),
        4 => {
            let n = rng.below(5);
            // Mostly homogeneous numeric arrays: the shape of vectors, colours and resolutions.
            let float = rng.chance(0.5);
            Value::Array(
                (0..n)
                    .map(|_| {
                        if rng.chance(0.8) {
                            if float {
                                Value::Float(*rng.pick(FLOATS))
                            } else {
                                Value::Integer(*rng.pick(INTS))
                            }
                        } else {
                            random_value(rng, depth + 1)
                        }
                    })
                    .collect(),
            )
        }
        _ => {
            let mut t = toml::Table::new();
            for _ in 0..rng.below(3) {
                t.insert(rng.pick(KEYS).to_string(), random_value(rng, depth + 1));
            }
            Value::Table(t)
        }
    }
}

#[derive(Clone, Debug)]
pub(crate) enum Seg {
    Key(String),
    Index(usize),
}

pub(crate) fn paths(v: &Value, prefix: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    match v {
        Value::Table(t) => {
            for (k, child) in t {
                prefix.push(Seg::Key(k.clone()));
                out.push(prefix.clone());
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(a) => {
            for (i, child) in a.iter().enumerate() {
                prefix.push(Seg::Index(i));
                out.push(prefix.clone());
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

pub(crate) fn get_mut<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    let mut cur = v;
    for s in path {
        cur = match (s, cur) {
            (Seg::Key(k), Value::Table(t)) => t.get_mut(k)?,
            (Seg::Index(i), Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// One structural mutation of the scene: replace a value, delete a key or element, or add a key.
pub(crate) fn mutate_value(rng: &mut Rng, root: &mut Value) {
    let mut all = Vec::new();
    paths(root, &mut Vec::new(), &mut all);
    if all.is_empty() {
        return;
    }
    let path = rng.pick(&all).clone();
    let (parent_path, last) = path.split_at(path.len() - 1);
    let op = rng.below(4);
    let new = random_value(rng, 0);
    let Some(parent) = get_mut(root, parent_path) else { return };
    match (op, &last[0], parent) {
        (0, Seg::Key(k), Value::Table(t)) => {
            t.remove(k);
        }
        (0, Seg::Index(i), Value::Array(a)) => {
            a.remove(*i);
        }
        (1, _, Value::Table(t)) => {
            t.insert(rng.pick(KEYS).to_string(), new);
        }
        (_, Seg::Key(k), Value::Table(t)) => {
            t.insert(k.clone(), new);
        }
        (_, Seg::Index(i), Value::Array(a)) => a[*i] = new,
        _ => {}
    }
}

/// One textual mutation: truncate, flip a byte, drop or repeat a line.
pub(crate) fn mutate_text(rng: &mut Rng, text: &mut Vec<u8>) {
    if text.is_empty() {
        return;
    }
    match rng.below(4) {
        0 => text.truncate(rng.below(text.len())),
        1 => {
            let i = rng.below(text.len());
            text[i] ^= 1 << rng.below(8);
        }
        _ => {
            let lines: Vec<&[u8]> = text.split(|&b| b == b'\n').collect();
            let k = rng.below(lines.len());
            let repeat = rng.chance(0.5);
            let mut out = Vec::with_capacity(text.len() + 64);
            for (i, l) in lines.iter().enumerate() {
                if i == k && !repeat {
                    continue;
                }
                out.extend_from_slice(l);
                out.push(b'\n');
                if i == k {
                    out.extend_from_slice(l);
                    out.push(b'\n');
                }
            }
            *text = out;
        }
    }
}

/// A shipped scene mutated 1–3 times (structurally, then sometimes as text).
pub(crate) fn mutated_scene(rng: &mut Rng, scenes: &[(String, Value)]) -> (String, Vec<u8>) {
    let (name, scene) = rng.pick(scenes);
    let mut value = scene.clone();
    for _ in 0..1 + rng.below(3) {
        mutate_value(rng, &mut value);
    }
    let mut text = toml::to_string(&value).unwrap_or_default().into_bytes();
    if rng.chance(0.25) {
        mutate_text(rng, &mut text);
    }
    (name.clone(), text)
}

/// Corrupts a file: truncate, flip bytes, overwrite a run with 0xff or with digits (huge counts),
/// or repeat a slice.
pub(crate) fn corrupt(rng: &mut Rng, bytes: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(3) {
        if bytes.is_empty() {
            return;
        }
        let i = rng.below(bytes.len());
        match rng.below(5) {
            0 => bytes.truncate(i),
            1 => bytes[i] ^= 1 << rng.below(8),
            2 => {
                for b in bytes.iter_mut().skip(i).take(1 + rng.below(8)) {
                    *b = 0xff;
                }
            }
            3 => {
                for b in bytes.iter_mut().skip(i).take(1 + rng.below(10)) {
                    *b = b'9';
                }
            }
            _ => {
                let end = (i + 1 + rng.below(64)).min(bytes.len());
                let slice = bytes[i..end].to_vec();
                bytes.splice(i..i, slice);
            }
        }
    }
}
