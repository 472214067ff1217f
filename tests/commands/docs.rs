//! The documentation stays true to the code. Cheap: no rendering, only reading the pages, the
//! source tree and the built binary's `--help`.
//!
//! For the reference pages (README.md, docs/architecture.md and the other pages of docs/ that
//! describe the code) and the lab notebook's index:
//! - every **source path** a page names in backticks (`src/integrator/pt/mod.rs`, `pss/inverse.rs`,
//!   `scripts/fuzz.sh`, `tests/common/agreement.rs::assert_shares_agree`) exists in the repository:
//!   a path under one of the repository's top-level directories exactly, a bare `*.rs` path as the
//!   tail of a file under `src/`, `tests/` or `examples/`;
//! - every **module path** (`integrator::path_space::retrace`, `plexus::bench::run`,
//!   `driver::bootstrap::BATCH`) names modules that exist under `src/` and items that appear in them;
//! - every **command-line flag** a page gives a `plexus` verb (`plexus render ... --spp 16`, or
//!   `--spp N` under a heading that names the verb) is one that verb's `--help` lists.
//!
//! For every page of docs/ and docs/lab/ and the README, every **relative link** resolves: the file
//! exists, and a `#fragment` is the anchor of a heading in it (GitHub's slugs).
//!
//! And the source tree's imports run one way: no module cycle at any level (`module_cycles`).
//!
//! The checker is plain functions over strings, so the unit tests at the end show it rejecting a
//! copy of a page with a bogus path, module, flag or link inserted: a check that cannot fail is not
//! evidence.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

// The module-cycle check reads the source tree too; it lives beside this file so that it shares
// this binary (each test binary links the whole library).
mod module_cycles;

/// The pages that describe the code as it is now (the lab notebook's entries are dated records and
/// are held only to their links).
const REFERENCE_PAGES: &[&str] = &[
    "README.md",
    "docs/architecture.md",
    "docs/bibliography.md",
    "docs/bench.md",
    "docs/batch.md",
    "docs/mlt.md",
    "docs/reference-images.md",
    "docs/sampling.md",
    "docs/scene-format.md",
    "docs/lab/README.md",
];

/// Top-level directories whose paths a page may name from the repository root.
const ROOTS: &[&str] = &["src", "tests", "scripts", "scenes", "references", "python", "docs", "ffi", "examples"];

/// The verbs of `plexus` (its `--help` lists them; `verbs_are_the_binarys` checks this list).
const VERBS: &[&str] = &["render", "info", "compare", "converge", "resume", "merge", "reference", "bench", "import"];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

// ---------------------------------------------------------------------------------------------
// Reading Markdown.

/// One piece of code on a page: an inline code span, or one line of a fenced block, with the
/// 1-based line it is on and the verb context of the section it is in.
#[derive(Debug, Clone, PartialEq)]
struct Code {
    line: usize,
    text: String,
    /// The `plexus` verb (or `Some("")` for another program) the nearest heading above names.
    context: Option<String>,
}

/// Lines of a page with their 1-based numbers.
type NumberedLines<'a> = Vec<(usize, &'a str)>;

/// The lines of `md` outside fenced code blocks, with their 1-based numbers, and the fenced lines.
fn split_fences(md: &str) -> (NumberedLines<'_>, NumberedLines<'_>) {
    let (mut prose, mut fenced) = (Vec::new(), Vec::new());
    let mut in_fence = false;
    for (i, line) in md.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence {
            fenced.push((i + 1, line));
        } else {
            prose.push((i + 1, line));
        }
    }
    (prose, fenced)
}

/// The inline code spans of one prose line (single backticks; a double-backtick span is read as
/// its contents).
fn inline_spans(line: &str) -> Vec<String> {
    let mut spans = Vec::new();
    let mut rest = line;
    while let Some(start) = rest.find('`') {
        let ticks = rest[start..].chars().take_while(|&c| c == '`').count();
        let after = &rest[start + ticks..];
        let fence = "`".repeat(ticks);
        match after.find(&fence) {
            Some(end) => {
                spans.push(after[..end].trim().to_string());
                rest = &after[end + ticks..];
            }
            None => break,
        }
    }
    spans
}

/// The prose of a line with its code spans removed (where links are looked for).
fn without_spans(line: &str) -> String {
    let mut out = String::new();
    let mut inside = false;
    for c in line.chars() {
        if c == '`' {
            inside = !inside;
        } else if !inside {
            out.push(c);
        }
    }
    out
}

/// The verb context a heading sets: `plexus VERB` or a lone `` `VERB` `` names a verb;
/// `plexus-batch` another program (`Some("")`); anything else leaves no context.
fn heading_context(heading: &str) -> Option<String> {
    if heading.contains("plexus-batch") {
        return Some(String::new());
    }
    let words: Vec<String> = heading
        .split(|c: char| c.is_whitespace() || c == '`' || c == ':' || c == ',' || c == '(' || c == ')')
        .filter(|w| !w.is_empty())
        .map(str::to_string)
        .collect();
    for (i, w) in words.iter().enumerate() {
        if w == "plexus" {
            if let Some(v) = words.get(i + 1).filter(|v| VERBS.contains(&v.as_str())) {
                return Some(v.clone());
            }
        }
    }
    inline_spans(heading).into_iter().find(|span| VERBS.contains(&span.as_str()))
}

/// Every piece of code on the page, in order, with its section's verb context: a heading's own, or
/// else the nearest enclosing (higher-level) heading's.
fn code_of(md: &str) -> Vec<Code> {
    let mut heading_at: BTreeMap<usize, Option<String>> = BTreeMap::new();
    let (prose, fenced) = split_fences(md);
    let mut code = Vec::new();
    let mut open: Vec<(usize, Option<String>)> = Vec::new();
    for &(n, line) in &prose {
        if line.starts_with('#') {
            let level = line.chars().take_while(|&c| c == '#').count();
            open.retain(|(l, _)| *l < level);
            let context = heading_context(line).or_else(|| open.iter().rev().find_map(|(_, c)| c.clone()));
            open.push((level, context.clone()));
            heading_at.insert(n, context);
        }
    }
    let context_at = |n: usize| heading_at.range(..=n).next_back().and_then(|(_, c)| c.clone());
    for &(n, line) in &prose {
        for text in inline_spans(line) {
            code.push(Code { line: n, text, context: context_at(n) });
        }
    }
    for &(n, line) in &fenced {
        code.push(Code { line: n, text: line.to_string(), context: context_at(n) });
    }
    code.sort_by_key(|c| c.line);
    code
}

/// GitHub's anchor of a heading: lower case; letters, digits, `-` and `_` kept, spaces to `-`,
/// everything else dropped.
fn slug(heading: &str) -> String {
    let text = heading.trim_start_matches('#').trim();
    let mut s = String::new();
    for c in text.chars() {
        if c.is_alphanumeric() || c == '-' || c == '_' {
            s.extend(c.to_lowercase());
        } else if c == ' ' {
            s.push('-');
        }
    }
    s
}

/// The anchors of a page's headings (outside code blocks), duplicates numbered as GitHub does.
fn anchors(md: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    for (_, line) in split_fences(md).0 {
        if line.starts_with('#') {
            let s = slug(line);
            let k = seen.entry(s.clone()).or_insert(0);
            out.insert(if *k == 0 { s.clone() } else { format!("{s}-{k}") });
            *k += 1;
        }
    }
    out
}

/// The targets of a page's Markdown links and images (`[text](target)`), outside code.
fn links(md: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (n, line) in split_fences(md).0 {
        let prose = without_spans(line);
        let mut rest = prose.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let Some(end) = after.find(')') else { break };
            let target = after[..end].split_whitespace().next().unwrap_or("").to_string();
            out.push((n, target));
            rest = &after[end..];
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The repository as the checks see it.

/// What the checks compare pages against: the repository's files, its source modules and the
/// flags each verb accepts.
struct Repo {
    root: PathBuf,
    /// Every file under src/, tests/ and examples/, relative to the root, with `/` separators.
    rust_files: Vec<String>,
    /// `src/`-relative module paths (`integrator/path_space/retrace`) to the files that hold them.
    modules: BTreeMap<String, Vec<PathBuf>>,
    /// Crate names a module path may start with that are not plexus's (dependencies, std).
    external: BTreeSet<String>,
    /// Each verb's flags (`--spp`, `-o`).
    flags: BTreeMap<String, BTreeSet<String>>,
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

impl Repo {
    fn new(root: &Path, flags: BTreeMap<String, BTreeSet<String>>) -> Repo {
        let mut files = Vec::new();
        for dir in ["src", "tests", "examples"] {
            walk(&root.join(dir), &mut files);
        }
        let rel = |p: &Path| p.strip_prefix(root).expect("under root").to_string_lossy().replace('\\', "/");
        let rust_files: Vec<String> =
            files.iter().filter(|p| p.extension().is_some_and(|e| e == "rs")).map(|p| rel(p)).collect();
        let mut modules: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
        for f in rust_files.iter().filter(|f| f.starts_with("src/")) {
            let m = f.trim_start_matches("src/").trim_end_matches(".rs");
            let m = m.strip_suffix("/mod").unwrap_or(m);
            modules.entry(m.to_string()).or_default().push(root.join(f));
        }
        // A directory module's own files answer for it too (`pub use` of a submodule's items).
        let keys: Vec<String> = modules.keys().cloned().collect();
        for k in &keys {
            if let Some((parent, _)) = k.rsplit_once('/') {
                let child = modules[k].clone();
                if modules.contains_key(parent) {
                    modules.get_mut(parent).expect("parent").extend(child);
                }
            }
        }
        let mut external: BTreeSet<String> =
            ["std", "core", "alloc", "f32", "f64", "u8", "u16", "u32", "u64", "usize", "i32", "i64", "bool", "str"]
                .iter()
                .map(|s| s.to_string())
                .collect();
        let manifest = std::fs::read_to_string(root.join("Cargo.toml")).expect("Cargo.toml");
        let mut in_deps = false;
        for line in manifest.lines() {
            let t = line.trim();
            if t.starts_with('[') {
                in_deps = t.contains("dependencies");
            } else if in_deps {
                if let Some((name, _)) = t.split_once('=') {
                    external.insert(name.trim().replace('-', "_"));
                }
            }
        }
        Repo { root: root.to_path_buf(), rust_files, modules, external, flags }
    }

    /// Whether `path` (a repository-relative path, a file or a directory) exists.
    fn exists(&self, path: &str) -> bool {
        self.root.join(path.trim_end_matches('/')).exists()
    }

    /// The files of the module `segments` names, looked for from `src/` and then as the tail of
    /// any module path (so `driver::bootstrap` finds `src/integrator/driver/bootstrap.rs`).
    fn module(&self, segments: &[&str]) -> Option<&Vec<PathBuf>> {
        let path = segments.join("/");
        self.modules
            .get(&path)
            .or_else(|| self.modules.iter().find(|(k, _)| k.ends_with(&format!("/{path}"))).map(|(_, v)| v))
    }
}

/// Whether `word` occurs in `text` as a whole identifier.
fn has_word(text: &str, word: &str) -> bool {
    text.match_indices(word).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let after = text[i + word.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
        !ident(before) && !ident(after)
    })
}

// ---------------------------------------------------------------------------------------------
// The checks. Each returns its findings as "line N: ..." strings; none means the page is true.

/// A token of code with surrounding punctuation removed.
fn clean(token: &str) -> &str {
    token.trim_matches(|c: char| matches!(c, ',' | ';' | '.' | ':' | '(' | ')' | '"' | '\'' | '[' | ']'))
}

/// Whether a path component is a placeholder (`NAME.toml`, `S`, `<scene>`, `*-converge.png`).
fn is_placeholder(path: &str) -> bool {
    path.contains(['*', '<', '>', '{', '}', '$', '…', '|']) || path.contains("...") || {
        path.split('/').any(|c| {
            let stem = c.split('.').next().unwrap_or(c);
            !stem.is_empty()
                && stem.chars().any(|ch| ch.is_ascii_uppercase())
                && stem.chars().all(|ch| ch.is_ascii_uppercase() || ch.is_ascii_digit() || ch == '_' || ch == '-')
        })
    }
}

/// Source paths named in code that do not exist.
fn check_paths(code: &[Code], repo: &Repo) -> Vec<String> {
    let mut bad = Vec::new();
    for c in code {
        for raw in c.text.split_whitespace() {
            let token = clean(raw);
            // `file.rs::item`: the file, and the item in it.
            let (path, item) = match token.find(".rs::") {
                Some(i) => (&token[..i + 3], Some(&token[i + 5..])),
                None => (token, None),
            };
            if path.contains("://") || is_placeholder(path) {
                continue;
            }
            let rooted = ROOTS.iter().any(|r| path.starts_with(&format!("{r}/")));
            let file = if rooted {
                if !repo.exists(path) {
                    bad.push(format!("line {}: `{path}` does not exist", c.line));
                    continue;
                }
                Some(path.to_string())
            } else if path.ends_with(".rs") && path.chars().all(|ch| ch.is_alphanumeric() || "_-/.".contains(ch)) {
                match repo.rust_files.iter().find(|f| *f == path || f.ends_with(&format!("/{path}"))) {
                    Some(f) => Some(f.clone()),
                    None => {
                        bad.push(format!("line {}: no file `{path}` in src/, tests/ or examples/", c.line));
                        continue;
                    }
                }
            } else {
                None
            };
            if let (Some(file), Some(item)) = (file, item) {
                let text = std::fs::read_to_string(repo.root.join(&file)).unwrap_or_default();
                for name in item.split("::").map(clean).filter(|n| !n.is_empty()) {
                    if !has_word(&text, name) {
                        bad.push(format!("line {}: `{name}` does not appear in {file}", c.line));
                    }
                }
            }
        }
    }
    bad
}

/// Module paths named in code whose modules or items do not exist.
fn check_modules(code: &[Code], repo: &Repo) -> Vec<String> {
    let mut bad = Vec::new();
    for c in code {
        for raw in c.text.split_whitespace() {
            let token = clean(raw);
            if !token.contains("::") || token.contains(".rs::") || token.contains('/') {
                continue;
            }
            let mut segments: Vec<&str> = token.split("::").collect();
            // `Type::method(args)`, `module::f(x)`: the path ends where the call begins.
            if let Some(last) = segments.last_mut() {
                *last = last.split(['(', '<', '{', '[', '!']).next().unwrap_or(last);
            }
            let ident = |s: &&str| !s.is_empty() && s.chars().all(|ch| ch.is_alphanumeric() || ch == '_');
            if !segments.iter().all(ident) {
                continue;
            }
            if matches!(segments[0], "plexus" | "crate") {
                segments.remove(0);
            }
            let Some(first) = segments.first() else { continue };
            // A type's associated item (`Mlt::propose_jump`) or another crate's path.
            if first.chars().next().is_some_and(|ch| ch.is_uppercase()) || repo.external.contains(*first) {
                continue;
            }
            // The longest prefix of lower-case segments that is a module; the rest are items in it.
            let mut found = None;
            for k in (1..=segments.len()).rev() {
                if let Some(files) = repo.module(&segments[..k]) {
                    found = Some((k, files));
                    break;
                }
            }
            let Some((k, files)) = found else {
                bad.push(format!("line {}: no module `{}` under src/", c.line, segments.join("::")));
                continue;
            };
            let text: String = files.iter().filter_map(|f| std::fs::read_to_string(f).ok()).collect();
            // A lower-case segment with more after it is a module: an inline one (`mod tests`) in
            // these files, or one that does not exist.
            let inner = segments[k..].split_last().map_or(&[][..], |(_, rest)| rest);
            if let Some(missing) =
                inner.iter().position(|s| s.starts_with(char::is_lowercase) && !text.contains(&format!("mod {s}")))
            {
                bad.push(format!("line {}: no module `{}` under src/", c.line, segments[..=k + missing].join("::")));
                continue;
            }
            for name in &segments[k..] {
                if !has_word(&text, name) {
                    bad.push(format!("line {}: `{name}` is not in module `{}`", c.line, segments[..k].join("::")));
                }
            }
        }
    }
    bad
}

/// Whether a token starts a command: `plexus`, a path to it, or `$PLEXUS`.
fn is_plexus(token: &str) -> bool {
    let t = token.trim_matches('"');
    t == "plexus" || t.ends_with("/plexus") || t == "$PLEXUS" || t == "${PLEXUS}" || t == "$plexus"
}

/// Flags given to a verb that its `--help` does not list.
fn check_flags(code: &[Code], repo: &Repo) -> Vec<String> {
    let mut bad = Vec::new();
    for c in code {
        let tokens: Vec<&str> = c.text.split_whitespace().collect();
        // The verb the flags belong to: a command in the span, else the section's context.
        let mut verb: Option<String> = match &c.context {
            Some(v) if v.is_empty() => None,
            Some(v) => Some(v.clone()),
            None => None,
        };
        let mut foreign = c.context.as_deref() == Some("");
        let mut standalone = true;
        let mut i = 0;
        while i < tokens.len() {
            let t = tokens[i];
            if matches!(t, "|" | "||" | "&&" | ";" | ">" | "2>" | "&") || t.ends_with(';') {
                verb = None;
                foreign = true;
                standalone = false;
            } else if is_plexus(t) || (t == "./dev" && tokens.get(i + 1) == Some(&"render")) {
                standalone = false;
                foreign = false;
                verb = tokens.get(i + 1).map(|v| v.to_string()).filter(|v| VERBS.contains(&v.as_str()));
                if verb.is_none() {
                    // `plexus --help`, `plexus --version`: the top-level flags.
                    verb = Some(String::new());
                }
                i += 1;
            } else if t.starts_with('-')
                && t.len() > 1
                && t.chars().nth(1).is_some_and(|ch| ch == '-' || ch.is_ascii_alphabetic())
            {
                let flag = t.split('=').next().unwrap_or(t).trim_end_matches([',', '.', ')', ';', ':', ']']);
                let is_long = flag.starts_with("--") && flag.len() > 2;
                let is_short = !flag.starts_with("--") && flag.len() == 2;
                let finding = match (&verb, foreign) {
                    _ if !(is_long || is_short) => None,
                    (Some(v), false) if !v.is_empty() => (!repo.flags.get(v).is_some_and(|f| f.contains(flag)))
                        .then(|| format!("`plexus {v}` has no flag `{flag}`")),
                    (Some(_), false) => (!matches!(flag, "--help" | "-h" | "--version" | "-V"))
                        .then(|| format!("`plexus` has no top-level flag `{flag}`")),
                    (None, false) if standalone => (!repo.flags.values().any(|f| f.contains(flag)))
                        .then(|| format!("no plexus verb has the flag `{flag}`")),
                    _ => None,
                };
                if let Some(finding) = finding {
                    bad.push(format!("line {}: {finding}", c.line));
                }
            } else if i == 0 {
                // Another program's command line (`cargo test --release`, `scripts/x.sh --help`).
                verb = None;
                foreign = true;
                standalone = false;
            }
            i += 1;
        }
    }
    bad
}

/// Relative links of the page at `page` (repository-relative) that do not resolve.
fn check_links(page: &str, md: &str, repo: &Repo) -> Vec<String> {
    let mut bad = Vec::new();
    let dir = Path::new(page).parent().unwrap_or(Path::new(""));
    for (n, target) in links(md) {
        if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (file, fragment) = match target.split_once('#') {
            Some((f, frag)) => (f, Some(frag)),
            None => (target.as_str(), None),
        };
        let resolved = if file.is_empty() { PathBuf::from(page) } else { normalise(&dir.join(file)) };
        let full = repo.root.join(&resolved);
        if !full.exists() {
            bad.push(format!("line {n}: link `{target}`: {} does not exist", resolved.display()));
            continue;
        }
        if let Some(fragment) = fragment {
            let text =
                if file.is_empty() { md.to_string() } else { std::fs::read_to_string(&full).unwrap_or_default() };
            if !anchors(&text).contains(fragment) {
                bad.push(format!("line {n}: link `{target}`: no heading with the anchor #{fragment}"));
            }
        }
    }
    bad
}

/// `a/b/../c` as `a/c` (links may climb out of docs/).
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The binary's verbs and flags.

/// The long and short options `text` (a clap `--help` page) lists.
fn help_flags(text: &str) -> BTreeSet<String> {
    let mut flags = BTreeSet::new();
    for line in text.lines() {
        let t = line.trim_start();
        if !t.starts_with('-') {
            continue;
        }
        for part in t.split(", ") {
            let flag = part.split([' ', '=']).next().unwrap_or("");
            if flag.starts_with('-') && flag.len() >= 2 {
                flags.insert(flag.to_string());
            }
            if !part.starts_with('-') {
                break;
            }
        }
    }
    flags
}

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_plexus")).args(args).env("CI", "true").output().expect("run plexus");
    assert!(out.status.success(), "plexus {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf-8 help")
}

fn binary_flags() -> BTreeMap<String, BTreeSet<String>> {
    VERBS.iter().map(|v| (v.to_string(), help_flags(&help(&[v, "--help"])))).collect()
}

fn repo() -> Repo {
    Repo::new(root(), binary_flags())
}

fn read(page: &str) -> String {
    std::fs::read_to_string(root().join(page)).unwrap_or_else(|e| panic!("{page}: {e}"))
}

/// Every finding of every check on one reference page.
fn findings(page: &str, md: &str, repo: &Repo) -> Vec<String> {
    let code = code_of(md);
    let mut all = check_paths(&code, repo);
    all.extend(check_modules(&code, repo));
    all.extend(check_flags(&code, repo));
    all.extend(check_links(page, md, repo));
    all
}

// ---------------------------------------------------------------------------------------------
// The tests.

#[test]
fn verbs_are_the_binarys() {
    let top = help(&["--help"]);
    let listed: BTreeSet<String> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|w| *w != "help")
        .map(str::to_string)
        .collect();
    let ours: BTreeSet<String> = VERBS.iter().map(|v| v.to_string()).collect();
    assert_eq!(listed, ours, "plexus --help lists other verbs than this test knows");
}

#[test]
fn reference_pages_name_paths_modules_and_flags_that_exist() {
    let repo = repo();
    let mut failures = Vec::new();
    for page in REFERENCE_PAGES {
        for f in findings(page, &read(page), &repo) {
            failures.push(format!("{page}: {f}"));
        }
    }
    assert!(failures.is_empty(), "the reference pages disagree with the code:\n{}", failures.join("\n"));
}

#[test]
fn every_relative_link_between_docs_resolves() {
    let repo = repo();
    let mut pages = vec!["README.md".to_string()];
    for dir in ["docs", "docs/lab"] {
        let mut here: Vec<String> = std::fs::read_dir(root().join(dir))
            .expect(dir)
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .map(|p| format!("{dir}/{}", p.file_name().expect("name").to_string_lossy()))
            .collect();
        here.sort();
        pages.extend(here);
    }
    let mut failures = Vec::new();
    for page in &pages {
        for f in check_links(page, &read(page), &repo) {
            failures.push(format!("{page}: {f}"));
        }
    }
    assert!(failures.is_empty(), "broken links:\n{}", failures.join("\n"));
}

/// A small repository for the checker's own tests: the real tree and a fixed flag table, so the
/// tests of the checker do not depend on the binary.
fn test_repo() -> Repo {
    let flags = [("render", &["--spp", "--out", "-o", "--set"][..]), ("bench", &["--threads"][..])]
        .iter()
        .map(|(v, f)| (v.to_string(), f.iter().map(|s| s.to_string()).collect()))
        .collect();
    Repo::new(root(), flags)
}

/// The checker finds nothing on a true page and names each inserted error: a bogus path, module,
/// item, flag and link each fail, in a copy of a page that passes.
#[test]
fn the_checker_rejects_a_page_with_a_bogus_path_module_flag_or_link() {
    let repo = test_repo();
    let good = "# Title\n\n## `render`\n\nSee `src/integrator/pt/mod.rs`, `pss/inverse.rs`, \
                `tests/common/agreement.rs::assert_shares_agree`, `integrator::path_space::retrace`, \
                `plexus::bench::run`, `driver::bootstrap::BATCH` and `Mlt::propose_jump`; `--spp 16`.\n\n\
                ```\nplexus render scene.toml --spp 4 -o x.exr | cargo test --release\n```\n\n\
                [back](#title), [bench](docs/bench.md#what-it-measures).\n";
    assert!(findings("README.md", good, &repo).is_empty(), "{:?}", findings("README.md", good, &repo));
    for (bogus, expect) in [
        ("`src/integrator/no_such_file.rs`", "does not exist"),
        ("`no_such_module.rs`", "no file"),
        ("`tests/common/agreement.rs::no_such_function`", "does not appear"),
        ("`integrator::no_such_module::retrace`", "no module"),
        ("`integrator::pss::NoSuchType`", "is not in module"),
        ("`--no-such-flag N`", "has no flag"),
        ("`plexus bench --spp 4`", "`plexus bench` has no flag `--spp`"),
        ("[x](docs/no-such-page.md)", "does not exist"),
        ("[x](docs/bench.md#no-such-heading)", "no heading"),
    ] {
        let page = good.replace("; `--spp 16`.", &format!("; `--spp 16`. {bogus}"));
        let found = findings("README.md", &page, &repo);
        assert!(found.iter().any(|f| f.contains(expect)), "{bogus}: expected '{expect}', found {found:?}");
    }
}

/// The Markdown readers on the cases the pages use: code spans, fences, headings in fences, anchors
/// of headings with code and punctuation, duplicate headings.
#[test]
fn markdown_reading_follows_githubs_rules() {
    assert_eq!(inline_spans("a `b` and ``c`d`` e"), vec!["b", "c`d"]);
    assert_eq!(slug("## Path-space MLT (`pmlt`)"), "path-space-mlt-pmlt");
    assert_eq!(slug("### Why the door is 0.55×"), "why-the-door-is-055");
    assert_eq!(slug("## `[camera]` — a pinhole"), "camera--a-pinhole");
    let md = "# A\n```\n# not a heading\n```\n## B\n## B\n";
    let a = anchors(md);
    assert!(a.contains("a") && a.contains("b") && a.contains("b-1") && !a.contains("not-a-heading"), "{a:?}");
    assert_eq!(links("see [x](y.md#z) and `[not](a link)`"), vec![(1, "y.md#z".to_string())]);
    assert_eq!(heading_context("### `render`"), Some("render".to_string()));
    assert_eq!(heading_context("# `plexus bench`: throughput"), Some("bench".to_string()));
    assert_eq!(heading_context("# Batch renders: `plexus-batch` on Dask"), Some(String::new()));
    assert!(help_flags("Options:\n  -o, --out <PATH>  Output\n      --spp <N>  Samples\n").contains("-o"));
}
