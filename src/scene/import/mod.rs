//! Mitsuba scene import: Mitsuba 0.5/0.6 and Mitsuba 3 XML turned into the plexus scene format.
//!
//! The importer writes TOML and the ordinary loader reads it, so that a Mitsuba scene becomes the
//! same `SceneDesc` a hand-written file would (a feature exists once: in the loader). What plexus
//! cannot represent is mapped to the nearest model with a warning naming the file, the line and the
//! choice made; nothing is dropped silently: every parameter the importer did not use is reported
//! by name and line. Missing mesh and texture files are errors naming them.
//!
//! `xml` reads the files (includes, defaults, line numbers), `objects` resolves plugins and refs,
//! `scene` converts sensor, shapes, emitters and integrator, `bsdf` materials and textures,
//! `colour` colour values and spectra, `serialized` Mitsuba's compressed meshes (to PLY).

mod bsdf;
mod colour;
mod numbers;
mod objects;
mod scene;
mod serialized;
mod sun;
mod toml_out;
mod transform;
mod xml;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::accel::AccelKind;
use crate::scene::{load_scene_str, LoadedScene, SceneError};

pub use xml::Loc;

/// Why a Mitsuba file could not be imported: one line naming the file and line.
#[derive(Debug, Error)]
pub enum ImportError {
    #[error("{file}:{line}: {message}")]
    At { file: String, line: u32, message: String },
    #[error("{file}: {message}")]
    File { file: String, message: String },
    /// The converted TOML did not load (a value out of the loader's range, a mesh it refused).
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// As `Scene`, its message rewritten to name what the user gave (a converted mesh's source).
    #[error("{0}")]
    Message(String),
}

/// Errors and warnings quote the file (ids, names, paths): each is kept to one line
/// (`toml_out::one_line`), so a file cannot print a second, made-up line of its own.
impl ImportError {
    pub fn at(loc: &Loc, message: impl Into<String>) -> ImportError {
        let (file, message) = (toml_out::one_line(&loc.file).into_owned(), message.into());
        ImportError::At { file, line: loc.line, message: toml_out::one_line(&message).into_owned() }
    }
    pub fn file(file: &str, message: impl Into<String>) -> ImportError {
        let message = message.into();
        ImportError::File {
            file: toml_out::one_line(file).into_owned(),
            message: toml_out::one_line(&message).into_owned(),
        }
    }
}

/// Warnings, each at the place in the file it concerns. Repeats of one message (the same
/// unsupported parameter on fifty materials) are reported once with their count.
#[derive(Debug, Default)]
pub struct Warnings {
    items: Vec<(Loc, String)>,
}

impl Warnings {
    pub fn warn(&mut self, loc: &Loc, message: impl Into<String>) {
        self.items.push((loc.clone(), message.into()));
    }
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
    /// One line per distinct message: `file:line: message` (+ how many more places and where).
    pub fn lines(&self) -> Vec<String> {
        let mut order: Vec<&str> = Vec::new();
        let mut places: HashMap<&str, Vec<&Loc>> = HashMap::new();
        for (loc, msg) in &self.items {
            let entry = places.entry(msg.as_str()).or_default();
            if entry.is_empty() {
                order.push(msg);
            }
            entry.push(loc);
        }
        order
            .into_iter()
            .map(|msg| {
                let locs = &places[msg];
                let more = match locs.len() {
                    1 => String::new(),
                    n => {
                        let lines: Vec<String> = locs[1..].iter().take(5).map(|l| l.line.to_string()).collect();
                        let etc = if n > 6 { ", ..." } else { "" };
                        format!(" (and {} more: lines {}{etc})", n - 1, lines.join(", "))
                    }
                };
                toml_out::one_line(&format!("{}: {msg}{more}", locs[0])).into_owned()
            })
            .collect()
    }
}

/// Where the TOML goes and where converted meshes are written.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// Directory the TOML will be read from: mesh and texture paths are written relative to it.
    /// Default: the XML file's directory.
    pub toml_dir: Option<PathBuf>,
    /// Directory for meshes converted from `.serialized` (PLY). Default: `toml_dir`.
    pub mesh_dir: Option<PathBuf>,
    /// `$name` values, overriding the file's `<default>`s.
    pub defines: HashMap<String, String>,
    /// Leave out shapes whose mesh file is missing (with a warning) instead of failing.
    pub skip_missing_meshes: bool,
}

/// An imported scene: its TOML text and the warnings.
#[derive(Debug)]
pub struct Imported {
    pub toml: String,
    pub warnings: Warnings,
    /// The PLY files written for `.serialized` meshes, each with what it is ("mesh 2 of
    /// 'a/m.serialized'"), for messages about them.
    pub converted: Vec<(PathBuf, String)>,
}

/// Reads the Mitsuba scene at `path` and converts it to plexus TOML.
pub fn import_mitsuba(path: &Path, options: &ImportOptions) -> Result<Imported, ImportError> {
    let root = xml::read_scene(path, &options.defines)?;
    let objects = objects::Objects::build(&root)?;
    let xml_dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let toml_dir = options.toml_dir.clone().unwrap_or_else(|| xml_dir.clone());
    let mesh_dir = options.mesh_dir.clone().unwrap_or_else(|| toml_dir.clone());
    let version = root.attr("version").unwrap_or("unknown").to_string();
    scene::convert(&objects, &version, path, &toml_dir, &mesh_dir, options.skip_missing_meshes)
}

/// Imports the Mitsuba scene at `path` and loads it as the TOML loader would load the converted
/// file. Converted `.serialized` meshes go to a temporary directory that lives as long as the load.
pub fn load_mitsuba(
    path: &Path,
    options: &ImportOptions,
    accel: Option<AccelKind>,
) -> Result<(LoadedScene, Warnings), ImportError> {
    let tmp = tempfile::tempdir().map_err(|e| {
        ImportError::file(&path.display().to_string(), format!("cannot create a temporary directory: {e}"))
    })?;
    let options = ImportOptions { mesh_dir: Some(tmp.path().to_path_buf()), toml_dir: None, ..options.clone() };
    let imported = import_mitsuba(path, &options)?;
    let base = path.parent().unwrap_or(Path::new(""));
    let name = format!("{} (imported)", path.display());
    // The converted meshes live in a temporary directory the user never sees: a message about one
    // names its `.serialized` file and shape index instead.
    let mut loaded = load_scene_str(&imported.toml, base, &name, accel).map_err(|e| {
        let text = e.to_string();
        let tmp_name = tmp.path().file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let named = name_converted_meshes(&text, &tmp_name, &imported.converted);
        if named == text {
            ImportError::Scene(e)
        } else {
            ImportError::Message(toml_out::one_line(&named).into_owned())
        }
    })?;
    loaded.scene.source = Some(path.to_path_buf());
    Ok((loaded, imported.warnings))
}

/// `message` with every path into the temporary directory `tmp_name` that holds a converted mesh
/// (however the loader spelt the way there) replaced by what the mesh is (`converted`).
fn name_converted_meshes(message: &str, tmp_name: &str, converted: &[(PathBuf, String)]) -> String {
    let mut out = message.to_string();
    for (ply, what) in converted {
        let Some(file) = ply.file_name() else { continue };
        let tail = format!("{tmp_name}/{}", file.to_string_lossy());
        while let Some(i) = out.find(&tail) {
            let start = out[..i].rfind(['\'', '"', ' ']).map_or(0, |j| j + 1);
            let end = i + tail.len();
            let quoted = start > 0 && matches!(out.as_bytes()[start - 1], b'\'' | b'"');
            let (start, end) = if quoted && out.as_bytes().get(end) == Some(&out.as_bytes()[start - 1]) {
                (start - 1, end + 1)
            } else {
                (start, end)
            };
            out.replace_range(start..end, what);
        }
    }
    out
}

/// Whether `path` names a Mitsuba XML file (by its extension).
pub fn is_mitsuba_file(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml"))
}

/// `to` relative to the directory `from` (both made absolute first), with `/` separators.
pub fn relative_path(from: &Path, to: &Path) -> PathBuf {
    let abs = |p: &Path| {
        let p = if p.as_os_str().is_empty() { Path::new(".") } else { p };
        p.canonicalize().unwrap_or_else(|_| std::env::current_dir().unwrap_or_default().join(p))
    };
    let (from, to) = (abs(from), abs(to));
    let a: Vec<_> = from.components().collect();
    let b: Vec<_> = to.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests;
