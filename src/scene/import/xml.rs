//! Reading Mitsuba scene XML into an owned element tree: `include` spliced in, `default` values
//! substituted for `$name`, and every element keeping the file and line it came from, so that each
//! warning and error can name them.
//!
//! Mitsuba 0.5/0.6 names parameters in camelCase (`toWorld`, `intIOR`, `fovAxis`), Mitsuba 3 in
//! snake_case (`to_world`, `int_ior`, `fov_axis`). Names are normalised to snake_case here with
//! Mitsuba 3's own upgrade rule (an underscore before an upper-case letter that follows a
//! lower-case one, then lower case), so the rest of the importer reads one dialect.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::ImportError;

/// Where an element was written.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Loc {
    pub file: Arc<str>,
    pub line: u32,
}

impl std::fmt::Display for Loc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.file, self.line)
    }
}

/// One XML element with its attributes (defaults substituted) and children (includes spliced).
#[derive(Clone, Debug)]
pub struct Element {
    /// Tag name, normalised (`lookAt` becomes `lookat`).
    pub tag: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
    pub loc: Loc,
    /// Directory that relative file names in this element resolve against.
    pub dir: Arc<Path>,
}

impl Element {
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == name).map(|(_, v)| v.as_str())
    }
    /// The `name` attribute, normalised to snake_case.
    pub fn name(&self) -> Option<String> {
        self.attr("name").map(snake_case)
    }
}

/// camelCase to snake_case as Mitsuba 3 upgrades 0.x files: `toWorld` → `to_world`,
/// `intIOR` → `int_ior`, `sunRadiusScale` → `sun_radius_scale`; snake_case stays as it is.
pub fn snake_case(name: &str) -> String {
    let mut out = String::with_capacity(name.len() + 4);
    let mut prev_lower = false;
    for c in name.chars() {
        if c.is_ascii_uppercase() && prev_lower {
            out.push('_');
        }
        prev_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
        out.push(c.to_ascii_lowercase());
    }
    out
}

/// Reads `path` (a `<scene>` document) with its includes. `defines` are `$name` values given by the
/// caller; they take precedence over the file's `<default>`s, as Mitsuba's `-D` does.
pub fn read_scene(path: &Path, defines: &HashMap<String, String>) -> Result<Element, ImportError> {
    let mut reader = Reader { defines: defines.clone(), stack: Vec::new(), elements: 0, depth: 0 };
    let root = reader.read_file(path, None)?;
    if root.tag != "scene" {
        return Err(ImportError::at(&root.loc, format!("expected a <scene> root element, got <{}>", root.tag)));
    }
    Ok(root)
}

struct Reader {
    /// `$name` substitutions in force (command line first, then the file's defaults).
    defines: HashMap<String, String>,
    /// Files being read, to refuse include cycles.
    stack: Vec<PathBuf>,
    /// Elements read so far, all files together, against `MAX_ELEMENTS`.
    elements: usize,
    /// Element nesting of the element being converted, includes counted through.
    depth: usize,
}

/// Deeper nesting than any scene has (Mitsuba's nest a few levels: shape, bsdf, texture, ...); a
/// deeper file is refused before the recursive conversion could exhaust the stack.
const MAX_DEPTH: usize = 256;
/// Elements in all, includes counted each time they are included: a scene that includes a file
/// twice that includes another twice, and so on, doubles at every level without a cycle.
const MAX_ELEMENTS: usize = 1 << 22;

impl Reader {
    fn read_file(&mut self, path: &Path, from: Option<&Loc>) -> Result<Element, ImportError> {
        let name: Arc<str> = Arc::from(path.display().to_string());
        let text =
            crate::input_file::read_regular_text(path, crate::input_file::MAX_SCENE_TEXT_BYTES).map_err(|e| {
                let msg = format!("cannot read '{}': {e}", path.display());
                match from {
                    Some(loc) => ImportError::at(loc, msg),
                    None => ImportError::file(&name, msg),
                }
            })?;
        let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        if self.stack.contains(&canonical) {
            let loc = from.cloned().unwrap_or(Loc { file: name.clone(), line: 1 });
            return Err(ImportError::at(&loc, format!("include cycle: '{}' includes itself", path.display())));
        }
        let doc = roxmltree::Document::parse(&text).map_err(|e| {
            let pos = e.pos();
            ImportError::at(&Loc { file: name.clone(), line: pos.row }, format!("invalid XML: {e}"))
        })?;
        let dir: Arc<Path> = Arc::from(path.parent().unwrap_or(Path::new("")));
        self.stack.push(canonical);
        let root = doc.root_element();
        // `<default>`s apply to the whole file; a define from the caller wins.
        let mut added = Vec::new();
        for child in root.children().filter(|c| c.is_element() && c.tag_name().name() == "default") {
            let loc = loc_of(&doc, &child, &name);
            let (Some(n), Some(v)) = (child.attribute("name"), child.attribute("value")) else {
                return Err(ImportError::at(&loc, "<default> needs 'name' and 'value' attributes"));
            };
            if !self.defines.contains_key(n) {
                self.defines.insert(n.to_string(), v.to_string());
                added.push(n.to_string());
            }
        }
        let out = self.convert(&doc, root, &name, &dir);
        for n in added {
            self.defines.remove(&n);
        }
        self.stack.pop();
        out
    }

    fn convert(
        &mut self,
        doc: &roxmltree::Document,
        node: roxmltree::Node,
        file: &Arc<str>,
        dir: &Arc<Path>,
    ) -> Result<Element, ImportError> {
        let loc = loc_of(doc, &node, file);
        self.elements += 1;
        if self.elements > MAX_ELEMENTS {
            return Err(ImportError::at(
                &loc,
                format!("more than {MAX_ELEMENTS} elements (includes counted each time): refused as unbounded"),
            ));
        }
        if self.depth >= MAX_DEPTH {
            return Err(ImportError::at(&loc, format!("elements nested more than {MAX_DEPTH} deep")));
        }
        self.depth += 1;
        let converted = self.convert_children(doc, node, file, dir, loc);
        self.depth -= 1;
        converted
    }

    fn convert_children(
        &mut self,
        doc: &roxmltree::Document,
        node: roxmltree::Node,
        file: &Arc<str>,
        dir: &Arc<Path>,
        loc: Loc,
    ) -> Result<Element, ImportError> {
        let mut attrs = Vec::new();
        for a in node.attributes() {
            attrs.push((a.name().to_string(), self.substitute(a.value(), &loc)?));
        }
        let tag = match node.tag_name().name() {
            "lookAt" => "lookat".to_string(),
            t => t.to_string(),
        };
        let mut children = Vec::new();
        for child in node.children().filter(|c| c.is_element()) {
            match child.tag_name().name() {
                "default" => {}
                "include" => {
                    let cloc = loc_of(doc, &child, file);
                    let Some(f) = child.attribute("filename") else {
                        return Err(ImportError::at(&cloc, "<include> needs a 'filename' attribute"));
                    };
                    let f = self.substitute(f, &cloc)?;
                    let included = self.read_file(&dir.join(&f), Some(&cloc))?;
                    if included.tag != "scene" {
                        return Err(ImportError::at(
                            &cloc,
                            format!("included file '{f}' must have a <scene> root, got <{}>", included.tag),
                        ));
                    }
                    children.extend(included.children);
                }
                _ => children.push(self.convert(doc, child, file, dir)?),
            }
        }
        Ok(Element { tag, attrs, children, loc, dir: dir.clone() })
    }

    /// Replaces every `$name` by its default or define; an unknown name is an error.
    fn substitute(&self, value: &str, loc: &Loc) -> Result<String, ImportError> {
        if !value.contains('$') {
            return Ok(value.to_string());
        }
        let mut out = String::new();
        let mut rest = value;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let end = after.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(after.len());
            let name = &after[..end];
            match self.defines.get(name) {
                Some(v) if !name.is_empty() => out.push_str(v),
                _ => {
                    return Err(ImportError::at(
                        loc,
                        format!("'${name}' has no value (no <default name=\"{name}\"> and no define)"),
                    ))
                }
            }
            rest = &after[end..];
        }
        out.push_str(rest);
        Ok(out)
    }
}

fn loc_of(doc: &roxmltree::Document, node: &roxmltree::Node, file: &Arc<str>) -> Loc {
    Loc { file: file.clone(), line: doc.text_pos_at(node.range().start).row }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snake_case_follows_mitsuba_3() {
        for (from, to) in [
            ("toWorld", "to_world"),
            ("intIOR", "int_ior"),
            ("fovAxis", "fov_axis"),
            ("sunRadiusScale", "sun_radius_scale"),
            ("diffuseReflectance", "diffuse_reflectance"),
            ("to_world", "to_world"),
            ("uscale", "uscale"),
            ("color0", "color0"),
        ] {
            assert_eq!(snake_case(from), to);
        }
    }

    #[test]
    fn includes_defaults_and_lines() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("part.xml"),
            "<scene version=\"0.6.0\">\n  <bsdf type=\"diffuse\" id=\"$mat\"/>\n</scene>\n",
        )
        .unwrap();
        let main = dir.path().join("main.xml");
        std::fs::write(
            &main,
            "<scene version=\"0.6.0\">\n<default name=\"mat\" value=\"white\"/>\n<include filename=\"part.xml\"/>\n\
             <integer name=\"x\" value=\"$n\"/>\n</scene>\n",
        )
        .unwrap();
        let mut defines = HashMap::new();
        defines.insert("n".to_string(), "7".to_string());
        let root = read_scene(&main, &defines).unwrap();
        assert_eq!(root.children.len(), 2);
        let bsdf = &root.children[0];
        // The include's own file and line; its `$mat` filled from the includer's default.
        assert_eq!((bsdf.tag.as_str(), bsdf.attr("id")), ("bsdf", Some("white")));
        assert!(bsdf.loc.file.ends_with("part.xml") && bsdf.loc.line == 2, "{}", bsdf.loc);
        assert_eq!(root.children[1].attr("value"), Some("7"));
        assert_eq!(root.children[1].loc.line, 4);

        // Without the define, `$n` is an error naming the line.
        let err = read_scene(&main, &HashMap::new()).unwrap_err().to_string();
        assert!(err.contains("main.xml:4") && err.contains("$n"), "{err}");
    }

    #[test]
    fn include_cycles_and_missing_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.xml");
        std::fs::write(&a, "<scene>\n<include filename=\"a.xml\"/>\n</scene>").unwrap();
        let err = read_scene(&a, &HashMap::new()).unwrap_err().to_string();
        assert!(err.contains("a.xml:2") && err.contains("cycle"), "{err}");
        let b = dir.path().join("b.xml");
        std::fs::write(&b, "<scene>\n\n<include filename=\"gone.xml\"/>\n</scene>").unwrap();
        let err = read_scene(&b, &HashMap::new()).unwrap_err().to_string();
        assert!(err.contains("b.xml:3") && err.contains("gone.xml"), "{err}");
        std::fs::write(&b, "<scene>\n<shape type=\"obj\">\n</scene>").unwrap();
        let err = read_scene(&b, &HashMap::new()).unwrap_err().to_string();
        assert!(err.contains("invalid XML"), "{err}");
    }
}
