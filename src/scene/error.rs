//! Scene errors: one line each, naming the file, the line or key path, the offending value and
//! what was expected.

use std::ops::Range;

use thiserror::Error;

/// Why a scene could not be loaded.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The scene file itself could not be read.
    #[error("{file}: cannot read the scene file: {reason}")]
    Read { file: String, reason: String },
    /// Malformed TOML or a schema violation (unknown key, wrong type, missing key), located by line.
    #[error("{file}: {location}: {message}")]
    Syntax { file: String, location: String, message: String },
    /// A value out of range, a missing or unreadable referenced file, or an inconsistent
    /// combination, located by its key path (e.g. `materials.glass.ior`, `shapes[2].file`).
    #[error("{file}: {key}: {message}")]
    Invalid { file: String, key: String, message: String },
    /// The accelerator could not be built.
    #[error("{file}: building the {accel} accelerator failed: {message}")]
    Accel { file: String, accel: String, message: String },
}

impl SceneError {
    /// Turns a toml/serde error into a one-line message with the line number, the enclosing table
    /// and, for unknown keys, the keys that table accepts.
    pub fn from_toml(file: &str, text: &str, e: &toml::de::Error) -> SceneError {
        let raw = e.message().trim().replace('\n', " ");
        let Some(span) = e.span() else {
            return SceneError::Syntax { file: file.to_string(), location: "TOML".to_string(), message: raw };
        };
        let location = format!("line {}", line_of(text, span.start));
        let table = enclosing_table(text, span.start);
        let inline_key = inline_key(text, &span);
        let within = match &inline_key {
            Some(k) => format!("'{k}' of {table}"),
            None => table.clone(),
        };
        // toml reports an error of the root table with the empty span 0..0 (a table's own errors
        // span the table); the enclosing "table" is then whatever header comes first, which would
        // misattribute it.
        let root_table = span == (0..0);
        let message = if let Some(rest) = raw.strip_prefix("unknown field `") {
            let name = rest.split('`').next().unwrap_or_default();
            let expected = backticked(rest.split_once(", expected").map_or("", |(_, e)| e));
            if table == "the top level" || header_names_table(text, span.start, name) {
                let tables: Vec<String> = expected.iter().map(|t| format!("[{t}]")).collect();
                format!("unknown top-level table [{name}] (expected one of: {})", tables.join(", "))
            } else if expected.is_empty() {
                format!("unknown key '{name}' in {within} (this table takes no keys)")
            } else {
                format!("unknown key '{name}' in {within} (expected one of: {})", expected.join(", "))
            }
        } else if let Some(rest) = raw.strip_prefix("missing field `") {
            let name = rest.split('`').next().unwrap_or_default();
            if root_table || table == "the top level" {
                // Every required top-level entry (today only `camera`) is a table.
                return SceneError::Syntax {
                    file: file.to_string(),
                    location: "top level".to_string(),
                    message: format!("missing [{name}] table (every scene needs one)"),
                };
            }
            format!("missing key '{name}' in {within}")
        } else if let Some(rest) = raw.strip_prefix("unknown variant `") {
            let name = rest.split('`').next().unwrap_or_default();
            let expected = backticked(rest.split_once(", expected").map_or("", |(_, e)| e));
            let key = inline_key.or_else(|| line_key(text, span.start)).unwrap_or_default();
            format!("key '{key}' in {table}: expected one of: {}, got '{name}'", expected.join(", "))
        } else {
            let raw = raw.replace('`', "'");
            match line_key(text, span.start) {
                Some(k) => format!("key '{k}' in {table}: {raw}"),
                None => format!("{raw} (in {table})"),
            }
        };
        SceneError::Syntax { file: file.to_string(), location, message }
    }
}

/// 1-based line number of byte offset `at`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// The header (`[camera]`, `[[shapes]]`, …) of the table that contains byte offset `at`, or
/// "the top level".
fn enclosing_table(text: &str, at: usize) -> String {
    let before = &text[..at.min(text.len())];
    // The header line itself counts: a span may start at the header of the table it is about.
    let line_end = text[before.len()..].find('\n').map_or(text.len(), |i| before.len() + i);
    for line in text[..line_end].lines().rev() {
        let t = line.trim_start();
        if t.starts_with('[') {
            let close = if t.starts_with("[[") { "]]" } else { "]" };
            if let Some(end) = t.find(close) {
                return t[..end + close.len()].to_string();
            }
        }
    }
    "the top level".to_string()
}

/// Whether the line of byte offset `at` is a table header (`[name]`, `[name.sub]`, `[[name]]`)
/// whose first key is `name`: the unknown key is then a top-level table.
fn header_names_table(text: &str, at: usize, name: &str) -> bool {
    let at = at.min(text.len());
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or_default().trim();
    let Some(inner) = line.strip_prefix('[') else { return false };
    let inner = inner.trim_start_matches('[');
    let first = inner.split([']', '.']).next().unwrap_or_default().trim().trim_matches(['"', '\'']);
    first == name
}

/// The key on the line of `at`, when `at` lies after its `=` (the key whose value is wrong).
fn line_key(text: &str, at: usize) -> Option<String> {
    let at = at.min(text.len());
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = &text[start..];
    let eq = line.find('=')?;
    if start + eq > at {
        return None;
    }
    let key = line[..eq].trim();
    is_key(key).then(|| key.to_string())
}

/// For a span inside an inline table (`emission = { colour = 1 }`), the key of that table.
fn inline_key(text: &str, span: &Range<usize>) -> Option<String> {
    let at = span.start.min(text.len());
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let prefix = &text[start..at];
    let brace = prefix.rfind('{')?;
    let eq = prefix[..brace].rfind('=')?;
    let key = prefix[..eq].trim().rsplit([',', '{']).next().unwrap_or_default().trim();
    is_key(key).then(|| key.to_string())
}

fn is_key(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '"'))
}

/// The words between backticks in serde's "expected one of `a`, `b`" lists.
fn backticked(s: &str) -> Vec<&str> {
    s.split('`').skip(1).step_by(2).collect()
}

/// `[a, b, c]` with each number in its shortest form, as scene files write them.
pub(crate) fn fmt3(v: [f32; 3]) -> String {
    format!("[{}, {}, {}]", v[0], v[1], v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// serde's span for a field missing from the root table does not start at the top of the
    /// document when it begins with a header; the message must still name the root.
    #[test]
    fn missing_camera_is_a_missing_table_wherever_the_file_starts() {
        for text in ["[render]\nspp = 4\n", "\n\n[materials.floor]\ntype = \"diffuse\"\n", ""] {
            let e = toml::from_str::<crate::scene::desc::SceneDesc>(text).unwrap_err();
            let msg = SceneError::from_toml("s.toml", text, &e).to_string();
            assert!(msg.contains("missing [camera] table"), "{msg}");
        }
        // A key missing from a table at the top of the file is still that table's.
        let text = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\nresolution = [8, 6]\n";
        let e = toml::from_str::<crate::scene::desc::SceneDesc>(text).unwrap_err();
        let msg = SceneError::from_toml("s.toml", text, &e).to_string();
        assert!(msg.contains("missing key 'fov' in [camera]"), "{msg}");
    }
}
