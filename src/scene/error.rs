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
        let message = if let Some(rest) = raw.strip_prefix("unknown field `") {
            let name = rest.split('`').next().unwrap_or_default();
            let expected = backticked(rest.split_once(", expected").map_or("", |(_, e)| e));
            if expected.is_empty() {
                format!("unknown key '{name}' in {within} (this table takes no keys)")
            } else {
                format!("unknown key '{name}' in {within} (expected one of: {})", expected.join(", "))
            }
        } else if let Some(rest) = raw.strip_prefix("missing field `") {
            let name = rest.split('`').next().unwrap_or_default();
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
