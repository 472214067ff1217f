//! Writing the imported scene as TOML: sections in the scene format's order (`[camera]`,
//! `[materials.*]`, `[[shapes]]`, `[environment]`, `[integrator]`, `[render]`), with comments
//! saying where each came from and what the import changed. Values are written inline.

use std::fmt::Write;

/// A TOML value.
#[derive(Clone, Debug, PartialEq)]
pub enum TVal {
    Num(f64),
    Int(i64),
    Bool(bool),
    Str(String),
    Arr(Vec<TVal>),
    /// An inline table, keys in order.
    Tab(Vec<(String, TVal)>),
}

impl TVal {
    pub fn colour(c: [f64; 3]) -> TVal {
        if c[0] == c[1] && c[1] == c[2] {
            TVal::Num(c[0])
        } else {
            TVal::Arr(c.iter().map(|&v| TVal::Num(v)).collect())
        }
    }
    pub fn vec3(v: [f64; 3]) -> TVal {
        TVal::Arr(v.iter().map(|&x| TVal::Num(x)).collect())
    }
    pub fn str(s: impl Into<String>) -> TVal {
        TVal::Str(s.into())
    }
}

/// Numbers as f32 would print them: the loader reads f32, and shorter is more readable.
fn number(v: f64) -> String {
    let f = v as f32;
    if f == f.trunc() && f.abs() < 1e15 {
        format!("{f:.1}")
    } else {
        format!("{f:?}")
    }
}

/// `text` with every control character (line breaks included) written as a `\u{..}` escape, so it
/// stays on one line of a comment or a message whatever the file it came from contains. TOML
/// allows no control character but tab in a comment; tab is escaped too, for messages.
pub fn one_line(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.chars().any(is_line_unsafe) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if is_line_unsafe(c) {
            let _ = write!(out, "\\u{{{:x}}}", c as u32);
        } else {
            out.push(c);
        }
    }
    std::borrow::Cow::Owned(out)
}

/// Control characters (C0, DEL, C1) and the Unicode line and paragraph separators.
fn is_line_unsafe(c: char) -> bool {
    c.is_control() || c == '\u{2028}' || c == '\u{2029}'
}

/// A bare key when TOML allows one, else a quoted one.
pub fn key(k: &str) -> String {
    if !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        k.to_string()
    } else {
        toml::Value::String(k.to_string()).to_string()
    }
}

impl std::fmt::Display for TVal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TVal::Num(v) => f.write_str(&number(*v)),
            TVal::Int(v) => write!(f, "{v}"),
            TVal::Bool(v) => write!(f, "{v}"),
            TVal::Str(s) => write!(f, "{}", toml::Value::String(s.clone())),
            TVal::Arr(items) => {
                f.write_str("[")?;
                for (i, v) in items.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{v}")?;
                }
                f.write_str("]")
            }
            TVal::Tab(entries) => {
                f.write_str("{ ")?;
                for (i, (k, v)) in entries.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{} = {v}", key(k))?;
                }
                f.write_str(" }")
            }
        }
    }
}

/// One `[header]` or `[[header]]` section.
#[derive(Clone, Debug, Default)]
pub struct Section {
    /// `camera`, `materials.white`, `shapes` (an array of tables when `array`).
    pub header: String,
    pub array: bool,
    pub comments: Vec<String>,
    pub entries: Vec<(String, TVal)>,
}

impl Section {
    pub fn new(header: impl Into<String>) -> Section {
        Section { header: header.into(), ..Default::default() }
    }
    /// Removes `k`, returning whether it was there.
    pub fn remove(&mut self, k: &str) -> bool {
        let before = self.entries.len();
        self.entries.retain(|(key, _)| key != k);
        self.entries.len() != before
    }
    pub fn set(&mut self, k: &str, v: TVal) {
        match self.entries.iter_mut().find(|(key, _)| key == k) {
            Some(slot) => slot.1 = v,
            None => self.entries.push((k.to_string(), v)),
        }
    }
}

/// Writes `sections` after the `preamble` comment lines. Comments carry text copied from the
/// Mitsuba file (ids, file names), so each is made one line first ([`one_line`]): a line break in
/// an id would otherwise end the comment and let the rest of the id be read as TOML.
pub fn write(preamble: &[String], sections: &[Section]) -> String {
    let mut out = String::new();
    for line in preamble {
        let _ = writeln!(out, "# {}", one_line(line));
    }
    for s in sections {
        out.push('\n');
        for c in &s.comments {
            let _ = writeln!(out, "# {}", one_line(c));
        }
        if s.array {
            let _ = writeln!(out, "[[{}]]", s.header);
        } else {
            let _ = writeln!(out, "[{}]", s.header);
        }
        for (k, v) in &s.entries {
            let _ = writeln!(out, "{} = {v}", key(k));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_through_toml() {
        let mut s = Section::new("materials.\"odd name\"");
        s.set("reflectance", TVal::colour([0.5, 0.25, 1.0]));
        s.set("ior", TVal::Num(1.5));
        s.set("flag", TVal::Bool(true));
        s.set(
            "transform",
            TVal::Tab(vec![("matrix".into(), TVal::Arr(vec![TVal::vec3([1.0, 2e-9, 3.0]), TVal::vec3([0.0; 3])]))]),
        );
        s.set("file", TVal::str("a \"b\"\\c.obj"));
        let text = write(&["imported".to_string()], &[s]);
        let t: toml::Table = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        let m = &t["materials"]["odd name"];
        assert_eq!(m["file"].as_str(), Some("a \"b\"\\c.obj"));
        assert_eq!(m["ior"].as_float(), Some(1.5));
        assert_eq!(m["transform"]["matrix"][0][1].as_float(), Some(2e-9));
        assert_eq!(key("a b"), "\"a b\"");
    }

    /// Text copied into comments cannot add TOML: a line break (or any control character) in an
    /// id is escaped, so the comment stays one line and the file parses to the same tables.
    #[test]
    fn comments_cannot_inject_toml() {
        let injected = "cam\n[render]\noutput = [\"/elsewhere/x.png\"]\r\u{2028}\u{85}";
        let mut s = Section::new("camera");
        s.comments.push(format!("<sensor id=\"{injected}\">"));
        s.set("fov", TVal::Num(40.0));
        let text = write(&[format!("from {injected}")], &[s]);
        let t: toml::Table = toml::from_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(t.keys().collect::<Vec<_>>(), ["camera"], "{text}");
        assert_eq!(text.lines().filter(|l| l.starts_with('#')).count(), 2, "{text}");
        assert!(text.contains("cam\\u{a}[render]\\u{a}output"), "{text}");
        assert_eq!(one_line("plain text"), "plain text");
    }
}
