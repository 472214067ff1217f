//! Imports run one way: no module of `src/` reaches, through the paths it names, back to itself.
//!
//! The graph is read from the source text, not from the compiler: every path that starts with
//! `crate::`, `super::` or `self::` (in `use` trees and in code, `#[cfg(test)]` modules included)
//! is resolved to the deepest module it names, a module being a file (`a/b.rs`) or a directory
//! module (`a/b/mod.rs`, `a/b.rs` with `a/b/`). Comments, doc links and strings are not paths;
//! visibility paths (`pub(in crate::scene)`) are not uses. The library (`src/lib.rs`) and the binary
//! (`src/main.rs` with `src/cli/`) are separate crates, so `crate::` means each its own root.
//!
//! The check runs at every level of the module tree: under each module, its children's subtrees
//! are the nodes (child `a` uses child `b` when any file in `a`'s subtree names anything in `b`'s),
//! and they must form no cycle. That is stricter than a file-level graph: `state` naming
//! `integrator::driver` while `integrator::pt` names `state` is a cycle between `state` and
//! `integrator` even though no single pair of files names each other. A module and its own
//! descendants may name each other (a parent re-exporting its child, a child using its parent's
//! types): that is one module's inside, not an import between layers.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path below a crate root (`["integrator", "pt"]`; empty for the root).
type ModPath = Vec<String>;

/// One use: a file (as a module) names something in another module.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Edge {
    pub from: ModPath,
    pub to: ModPath,
}

/// Source text without comments, string and character literals (replaced by a space), so that
/// neither a doc link nor a message that mentions `crate::x` counts as a use.
fn strip(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            // Block comments nest in Rust.
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push(' ');
        } else if c == b'r' && matches!(b.get(i + 1), Some(b'"') | Some(b'#')) && !ident_byte_before(b, i) {
            // A raw string r"…" or r#"…"#: ends at the quote followed by as many hashes.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&b'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&b'"') {
                out.push(c as char);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == b'"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&b'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            i = j;
            out.push(' ');
        } else if c == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push(' ');
        } else if c == b'\'' {
            // A character literal ('a', '\n', '\u{1F600}', '"') or a lifetime ('a): a literal
            // closes within a few bytes, a lifetime does not close.
            let close = if b.get(i + 1) == Some(&b'\\') {
                (i + 3..b.len().min(i + 12)).find(|&j| b[j] == b'\'')
            } else {
                let len = src[i + 1..].chars().next().map_or(1, char::len_utf8);
                (b.get(i + 1 + len) == Some(&b'\'')).then_some(i + 1 + len)
            };
            match close {
                Some(j) => {
                    i = j + 1;
                    out.push(' ');
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            let ch = src[i..].chars().next().expect("a char at a char boundary");
            out.push(ch);
            i += ch.len_utf8();
        }
    }
    out
}

fn ident_byte_before(b: &[u8], i: usize) -> bool {
    i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// The tokens that matter for paths: identifiers, `::` and single punctuation characters.
fn tokens(src: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut chars = src.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        if c.is_whitespace() {
            continue;
        }
        if c.is_alphanumeric() || c == '_' {
            let mut end = i + c.len_utf8();
            while let Some(&(j, d)) = chars.peek() {
                if d.is_alphanumeric() || d == '_' {
                    end = j + d.len_utf8();
                    chars.next();
                } else {
                    break;
                }
            }
            out.push(src[i..end].to_string());
        } else if c == ':' && chars.peek().map(|&(_, d)| d) == Some(':') {
            chars.next();
            out.push("::".to_string());
        } else {
            out.push(c.to_string());
        }
    }
    out
}

fn is_ident(t: &str) -> bool {
    t.chars().next().is_some_and(|c| c.is_alphabetic() || c == '_')
}

/// The paths of a `use` tree starting at `toks[j]` (after the prefix `prefix`), each as far as it
/// goes; returns them and the index after the tree.
fn use_tree(toks: &[String], mut j: usize, prefix: &[String], out: &mut Vec<Vec<String>>) -> usize {
    let mut path = prefix.to_vec();
    while j < toks.len() && is_ident(&toks[j]) {
        if toks[j] != "self" {
            path.push(toks[j].clone());
        }
        j += 1;
        if toks.get(j).map(String::as_str) == Some("::") {
            j += 1;
        } else {
            break;
        }
    }
    match toks.get(j).map(String::as_str) {
        Some("{") => {
            j += 1;
            while j < toks.len() && toks[j] != "}" {
                j = use_tree(toks, j, &path, out);
                // Skip an `as name` and the separator.
                while j < toks.len() && toks[j] != "," && toks[j] != "}" {
                    j += 1;
                }
                if toks.get(j).map(String::as_str) == Some(",") {
                    j += 1;
                }
            }
            j + 1
        }
        Some("*") => {
            out.push(path);
            j + 1
        }
        _ => {
            out.push(path);
            j
        }
    }
}

/// The deepest module of `modules` that `path` names (a path's tail is an item, or a module).
fn resolve(path: &[String], modules: &BTreeSet<ModPath>) -> Option<ModPath> {
    (0..=path.len()).rev().map(|n| path[..n].to_vec()).find(|p| modules.contains(p))
}

/// The uses in one file, the module `module` of a crate with the given modules.
pub fn uses(module: &ModPath, src: &str, modules: &BTreeSet<ModPath>) -> BTreeSet<Edge> {
    let toks = tokens(&strip(src));
    let mut edges = BTreeSet::new();
    // Inline modules (`mod tests { … }`): their names and the brace depth their body opens at,
    // so that `super::` inside one means the file's module.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < toks.len() {
        let t = toks[i].as_str();
        match t {
            "{" => depth += 1,
            "}" => {
                if inline.last().is_some_and(|&(_, d)| d == depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
            }
            "mod" if toks.get(i + 2).map(String::as_str) == Some("{") => {
                inline.push((toks[i + 1].clone(), depth + 1));
            }
            // `pub(in crate::scene)`: a visibility, not a use.
            "in" if i >= 2 && toks[i - 1] == "(" && toks[i - 2] == "pub" => {
                while i < toks.len() && toks[i] != ")" {
                    i += 1;
                }
            }
            "crate" | "super" | "self"
                if toks.get(i + 1).map(String::as_str) == Some("::") && (i == 0 || toks[i - 1] != "::") =>
            {
                let mut here: Vec<String> = module.clone();
                here.extend(inline.iter().map(|(name, _)| name.clone()));
                let mut j = i;
                let mut base = if t == "crate" {
                    j += 2;
                    Vec::new()
                } else {
                    here
                };
                if t != "crate" {
                    while j + 1 < toks.len() && (toks[j] == "super" || toks[j] == "self") && toks[j + 1] == "::" {
                        if toks[j] == "super" {
                            base.pop();
                        }
                        j += 2;
                    }
                }
                let mut paths = Vec::new();
                let end = use_tree(&toks, j, &base, &mut paths);
                for p in paths {
                    if let Some(to) = resolve(&p, modules) {
                        edges.insert(Edge { from: module.clone(), to });
                    }
                }
                i = end.max(i + 1);
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    edges
}

/// A circle among the children of one module: every child in it (a strongly connected component
/// of the children's graph), and one cycle through them, the first repeated at the end, with for
/// each step a file-level use that makes it.
#[derive(Debug)]
pub struct Cycle {
    pub under: ModPath,
    pub members: Vec<String>,
    pub children: Vec<String>,
    pub witnesses: Vec<Edge>,
}

fn show(path: &ModPath) -> String {
    if path.is_empty() {
        "crate".to_string()
    } else {
        path.join("::")
    }
}

impl std::fmt::Display for Cycle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<String> = self
            .children
            .iter()
            .map(|c| {
                let mut p = self.under.clone();
                p.push(c.clone());
                show(&p)
            })
            .collect();
        write!(f, "cycle under {} (circle of {}): {}", show(&self.under), self.members.join(", "), names.join(" -> "))?;
        for e in &self.witnesses {
            write!(f, "\n    {} uses {}", show(&e.from), show(&e.to))?;
        }
        Ok(())
    }
}

/// One cycle for every level of the tree whose children's subtrees are not acyclic.
pub fn cycles(modules: &BTreeSet<ModPath>, edges: &BTreeSet<Edge>) -> Vec<Cycle> {
    let mut found = Vec::new();
    for parent in modules {
        let n = parent.len();
        // child -> child -> one witnessing file-level edge
        let mut graph: BTreeMap<String, BTreeMap<String, Edge>> = BTreeMap::new();
        for e in edges {
            if e.from.len() > n && e.to.len() > n && e.from[..n] == parent[..] && e.to[..n] == parent[..] {
                let (a, b) = (&e.from[n], &e.to[n]);
                if a != b {
                    graph.entry(a.clone()).or_default().entry(b.clone()).or_insert_with(|| e.clone());
                }
            }
        }
        // The circles: children that reach each other (the graphs are a few dozen nodes).
        let reach = |from: &String| -> BTreeSet<String> {
            let mut seen = BTreeSet::new();
            let mut todo = vec![from.clone()];
            while let Some(n) = todo.pop() {
                for next in graph.get(&n).into_iter().flat_map(|m| m.keys()) {
                    if seen.insert(next.clone()) {
                        todo.push(next.clone());
                    }
                }
            }
            seen
        };
        let reaches: BTreeMap<String, BTreeSet<String>> = graph.keys().map(|k| (k.clone(), reach(k))).collect();
        let mut placed = BTreeSet::new();
        for node in graph.keys() {
            if placed.contains(node) || !reaches[node].contains(node) {
                continue;
            }
            let members: Vec<String> =
                reaches[node].iter().filter(|m| reaches.get(*m).is_some_and(|r| r.contains(node))).cloned().collect();
            placed.extend(members.iter().cloned());
            let inside: BTreeMap<String, BTreeMap<String, Edge>> = members
                .iter()
                .map(|m| {
                    let out = graph[m].iter().filter(|(to, _)| members.contains(to));
                    (m.clone(), out.map(|(to, e)| (to.clone(), e.clone())).collect())
                })
                .collect();
            let cycle = find_cycle(&inside).expect("a strongly connected component has a cycle");
            let witnesses = cycle.windows(2).map(|w| graph[&w[0]][&w[1]].clone()).collect();
            found.push(Cycle { under: parent.clone(), members, children: cycle, witnesses });
        }
    }
    found
}

/// A cycle of a directed graph (depth-first search; the first back edge found), as its nodes with
/// the first repeated at the end.
fn find_cycle<V>(graph: &BTreeMap<String, BTreeMap<String, V>>) -> Option<Vec<String>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        Open,
        Done,
    }
    fn visit<V>(
        node: &str,
        graph: &BTreeMap<String, BTreeMap<String, V>>,
        marks: &mut BTreeMap<String, Mark>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        marks.insert(node.to_string(), Mark::Open);
        stack.push(node.to_string());
        for next in graph.get(node).into_iter().flat_map(|m| m.keys()) {
            match marks.get(next) {
                Some(Mark::Open) => {
                    let from = stack.iter().position(|s| s == next).expect("an open node is on the stack");
                    let mut cycle = stack[from..].to_vec();
                    cycle.push(next.clone());
                    return Some(cycle);
                }
                Some(Mark::Done) => {}
                None => {
                    if let Some(c) = visit(next, graph, marks, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        marks.insert(node.to_string(), Mark::Done);
        None
    }
    let mut marks = BTreeMap::new();
    for node in graph.keys() {
        if !marks.contains_key(node) {
            if let Some(c) = visit(node, graph, &mut marks, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

/// The module a file below a crate's directory is (`integrator/pt.rs` → `integrator::pt`,
/// `scene/mod.rs` → `scene`, the root file → the root).
fn module_of(rel: &Path) -> ModPath {
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    let last = parts.pop().expect("a file name");
    let stem = last.strip_suffix(".rs").expect("a .rs file");
    if !matches!(stem, "mod" | "lib" | "main") {
        parts.push(stem.to_string());
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> =
        std::fs::read_dir(dir).expect("a source directory").flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The cycles of one crate: its files as (module, source).
pub fn crate_cycles(files: &[(ModPath, String)]) -> Vec<Cycle> {
    let modules: BTreeSet<ModPath> = files.iter().map(|(m, _)| m.clone()).collect();
    let edges: BTreeSet<Edge> = files.iter().flat_map(|(m, src)| uses(m, src, &modules)).collect();
    cycles(&modules, &edges)
}

/// The library's and the binary's files under `src`: the binary is `main.rs` and `cli/`.
pub fn crates_of(src: &Path) -> [Vec<(ModPath, String)>; 2] {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let (mut lib, mut bin) = (Vec::new(), Vec::new());
    for f in files {
        let rel = f.strip_prefix(src).expect("below src");
        let text = std::fs::read_to_string(&f).expect("a source file");
        let module = module_of(rel);
        if module.first().is_some_and(|m| m == "cli") || rel == Path::new("main.rs") {
            bin.push((module, text));
        } else {
            lib.push((module, text));
        }
    }
    [lib, bin]
}

fn m(path: &str) -> ModPath {
    if path.is_empty() {
        Vec::new()
    } else {
        path.split("::").map(str::to_string).collect()
    }
}

#[test]
fn no_module_cycle_in_src() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let [lib, bin] = crates_of(&src);
    assert!(lib.len() > 100 && !bin.is_empty(), "the source tree was read");
    let mut failures: Vec<String> = crate_cycles(&lib).iter().map(|c| format!("library: {c}")).collect();
    failures.extend(crate_cycles(&bin).iter().map(|c| format!("binary: {c}")));
    assert!(failures.is_empty(), "module cycles (imports must run one way):\n{}", failures.join("\n"));
}

/// The reader on the forms the crate uses, and the check rejecting cycles it must see: between
/// top-level modules through different files, between siblings deeper down, through `super::` and
/// `use` trees; and not counting comments, strings, visibility paths or a parent's own children.
#[test]
fn the_cycle_check_finds_cycles_and_only_cycles() {
    let files =
        |list: &[(&str, &str)]| -> Vec<(ModPath, String)> { list.iter().map(|(p, s)| (m(p), s.to_string())).collect() };
    // A layered crate: job at the bottom, state over it, integrator over both; a parent using its
    // children and a child its parent; paths in comments, strings and visibilities that would be
    // cycles if they counted.
    let layered = [
        ("", "pub mod job; pub mod state; pub mod integrator;"),
        ("job", "pub struct Budget; // crate::integrator::Budget once lived here\n"),
        ("job::memory", "use super::Budget; pub(in crate::integrator) fn f() {}"),
        ("state", "use crate::job::{Budget, memory::{self}};\nconst S: &str = \"crate::integrator::x\";"),
        ("integrator", "pub mod pt; use self::pt::Pt; use crate::state; fn c() -> char { '{' }"),
        (
            "integrator::pt",
            "use super::super::job::Budget; use crate::state::*; /* crate::integrator */ pub struct Pt;",
        ),
    ];
    let found = crate_cycles(&files(&layered));
    assert!(found.is_empty(), "{}", found.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n"));

    // state names a grandchild of integrator while integrator's child names state: a cycle
    // between the top-level modules, though no two files name each other.
    let mut circle = layered.to_vec();
    circle[3] = ("state", "use crate::{job::Budget, integrator::pt::{Pt as P}};");
    let found = crate_cycles(&files(&circle));
    assert_eq!(found.len(), 1, "{found:?}");
    let text = found[0].to_string();
    assert!(
        text.contains("cycle under crate (circle of integrator, state): integrator -> state -> integrator"),
        "{text}"
    );
    assert!(text.contains("state uses integrator::pt") && text.contains("integrator uses state"), "{text}");

    // Siblings deep in the tree through `super::`, and a cycle inside an inline test module.
    let mut deep = layered.to_vec();
    deep.push(("job::limits", "use super::memory::f;"));
    deep[2] = ("job::memory", "#[cfg(test)] mod tests { use super::super::limits; }");
    let found = crate_cycles(&files(&deep));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0]
            .to_string()
            .contains("under job (circle of limits, memory): job::limits -> job::memory -> job::limits"),
        "{}",
        found[0]
    );

    // A path inside a string or a comment and a lifetime next to a quote do not hide real paths.
    assert_eq!(strip("a /* b /* c */ d */ e \"f\\\"g\" 'h' &'a x r#\"y\"# z"), "a   e     &'a x   z");
    let uses_of = uses(&m("a"), "fn f<'a>(x: &'a str) { crate::b::g(); }", &[m("a"), m("b")].into());
    assert_eq!(uses_of.into_iter().map(|e| e.to).collect::<Vec<_>>(), vec![m("b")]);
}
