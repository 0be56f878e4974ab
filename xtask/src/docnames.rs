//! The names README.md and docs/*.md cite in backticks checked against the
//! tree: a renamed type, a removed command or option, a moved file leaves
//! the docs pointing at nothing, and nobody notices (issue 25 found
//! `LoopConfig::at_rate`, `response --loop firmware`, `LoopTick` and
//! `COMMON.md`). Run by `cargo xtask figures` (and so by `cargo xtask test`).
//!
//! Conservative by design: it checks only what it can decide.
//!
//! * Rust paths (`Type::item`, `module::Type`): each segment must be a word
//!   of the code (comments excluded), and a leading `CamelCase` segment a
//!   defined type, trait or alias; paths into other crates (`Cargo.lock`'s
//!   packages, `core`, `std`) are skipped.
//! * `CamelCase` words (two humps or more) must be words of the code.
//! * Files: a path under one of the repository's top-level directories must
//!   exist; a bare `name.rs` or `NAME.md` must exist somewhere in the tree.
//! * Commands are `doccmds.rs`'s: parsed by the programs' own parsers.
//!
//! [`ALLOW`] lists the few names cited on purpose that the tree does not
//! hold.

use crate::{root, Result};
use std::collections::HashSet;
use std::fs;
use std::path::{Path, PathBuf};

/// Cited on purpose, not in the tree: names of the 1983 programs, of other
/// projects' items, of files a command writes.
const ALLOW: &[&str] = &[
    // core's iterator whose zip SAFETY.md says the handlers avoid (its
    // size is a division: a panic path).
    "ChunksExact",
];

/// What the tree holds.
#[derive(Default)]
pub struct Tree {
    /// Identifiers of the Rust code outside comments.
    pub words: HashSet<String>,
    /// Names given to `struct`, `enum`, `trait`, `type`, `union`.
    pub types: HashSet<String>,
    /// External crates (Cargo.lock's packages, `-` as `_`) and std's.
    pub external: HashSet<String>,
    /// Repository-relative file paths and directory paths.
    pub paths: HashSet<String>,
    /// File names anywhere in the tree.
    pub names: HashSet<String>,
    /// Top-level directories.
    pub top: HashSet<String>,
}

fn idents(line: &str, out: &mut HashSet<String>) {
    for w in line.split(|c: char| !(c.is_alphanumeric() || c == '_')) {
        if !w.is_empty() && !w.starts_with(|c: char| c.is_ascii_digit()) {
            out.insert(w.to_string());
        }
    }
}

fn walk(dir: &Path, files: &mut Vec<PathBuf>) {
    let Ok(rd) = fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().to_string();
        if name == "target" || name.starts_with('.') {
            continue;
        }
        if p.is_dir() {
            walk(&p, files);
        }
        files.push(p);
    }
}

impl Tree {
    /// Reads the repository at `base`.
    pub fn read(base: &Path) -> Result<Tree> {
        let mut t = Tree::default();
        let mut files = Vec::new();
        walk(base, &mut files);
        for p in &files {
            let rel = p
                .strip_prefix(base)
                .unwrap_or(p)
                .to_string_lossy()
                .to_string();
            if let Some(top) = rel.split('/').next() {
                if p.is_dir() && !rel.contains('/') {
                    t.top.insert(top.to_string());
                }
            }
            t.paths.insert(rel.clone());
            if let Some(n) = p.file_name() {
                t.names.insert(n.to_string_lossy().to_string());
            }
            if p.extension().is_some_and(|x| x == "rs") {
                let text = fs::read_to_string(p).map_err(|e| format!("{rel}: {e}"))?;
                t.add_code(&text);
            }
        }
        let lock = fs::read_to_string(base.join("Cargo.lock")).unwrap_or_default();
        for l in lock.lines() {
            if let Some(n) = l.strip_prefix("name = \"") {
                t.external.insert(n.trim_end_matches('"').replace('-', "_"));
            }
        }
        // The project's own crates are checked, not skipped.
        for own in [
            "zslide",
            "host_sim",
            "zslide_plant",
            "zslide_replay",
            "xtask",
        ] {
            t.external.remove(own);
        }
        for s in ["core", "std", "alloc", "cargo", "rustc", "libc"] {
            t.external.insert(s.into());
        }
        Ok(t)
    }

    /// Adds one Rust source's identifiers and defined types.
    pub fn add_code(&mut self, text: &str) {
        for line in text.lines() {
            let code = line.trim_start();
            if code.starts_with("//") {
                continue;
            }
            let code = match code.find("// ") {
                Some(k) if !code[..k].contains('"') => &code[..k],
                _ => code,
            };
            idents(code, &mut self.words);
            let toks: Vec<&str> = code
                .split(|c: char| !(c.is_alphanumeric() || c == '_'))
                .filter(|w| !w.is_empty())
                .collect();
            for w in toks.windows(2) {
                if matches!(w[0], "struct" | "enum" | "trait" | "type" | "union") {
                    self.types.insert(w[1].to_string());
                }
            }
        }
    }
}

/// `(path, line)` of each backticked span and of each command line of a
/// fenced code block.
pub fn spans(text: &str) -> Vec<(String, usize)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (k, line) in text.lines().enumerate() {
        let n = k + 1;
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            let l = line.trim_start().trim_start_matches("$ ");
            if l.starts_with("cargo ") || l.starts_with("host-sim ") {
                out.push((l.to_string(), n));
            }
            continue;
        }
        let parts: Vec<&str> = line.split('`').collect();
        for (i, p) in parts.iter().enumerate() {
            if i % 2 == 1 && i + 1 < parts.len() && !p.is_empty() {
                out.push((p.to_string(), n));
            }
        }
    }
    out
}

fn is_ident(s: &str) -> bool {
    !s.is_empty()
        && s.chars().all(|c| c.is_alphanumeric() || c == '_')
        && !s.starts_with(|c: char| c.is_ascii_digit())
}

/// `CamelCase` (an upper-case start, lower case in it: not `ALL_CAPS`).
fn camel(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_uppercase())
        && s.chars().any(|c| c.is_ascii_lowercase())
        && s.chars().all(|c| c.is_ascii_alphanumeric())
}

/// A bare word checked on its own: CamelCase with two humps or more
/// (`LoopTick`), not a plain word that starts a sentence.
fn camel_name(s: &str) -> bool {
    camel(s) && s.chars().filter(char::is_ascii_uppercase).count() >= 2
}

/// What is wrong with one span, if anything it can decide.
pub fn check_span(t: &Tree, span: &str) -> Option<String> {
    let s = span.trim();
    if ALLOW.contains(&s) {
        return None;
    }
    // A Rust path, maybe called or a macro.
    let p = s.trim_end_matches("()").trim_end_matches('!');
    if p.contains("::") && p.split("::").all(is_ident) {
        let segs: Vec<&str> = p.split("::").collect();
        if t.external.contains(segs[0]) {
            return None;
        }
        let own = [
            "crate",
            "self",
            "super",
            "zslide",
            "host_sim",
            "zslide_plant",
        ];
        let segs: Vec<&str> = segs.into_iter().filter(|s| !own.contains(s)).collect();
        // A leading CamelCase segment is a type: defined here, or one of
        // another crate's the code uses (`Cell::take`, `Vec::remove`).
        if let Some(first) = segs.first() {
            if camel(first) && !t.types.contains(*first) && !t.words.contains(*first) {
                return Some(format!("`{s}`: no type `{first}` in the code"));
            }
        }
        for seg in segs {
            if !t.words.contains(seg) && !ALLOW.contains(&seg) {
                return Some(format!("`{s}`: `{seg}` is not in the code"));
            }
        }
        return None;
    }
    if camel_name(s) && !t.words.contains(s) {
        return Some(format!("`{s}`: not in the code"));
    }
    check_file(t, s)
}

fn check_file(t: &Tree, s: &str) -> Option<String> {
    if s.contains(['*', '{', '<', ' ', '$']) {
        return None;
    }
    let s = s.trim_end_matches('/');
    let s = s.split(':').next().unwrap_or(s);
    if let Some((top, _)) = s.split_once('/') {
        if t.top.contains(top) && !t.paths.contains(s) {
            return Some(format!("`{s}`: no such file or directory"));
        }
        return None;
    }
    let source = s.ends_with(".rs")
        || (s.ends_with(".md") && s[..s.len() - 3].chars().all(|c| c.is_ascii_uppercase()));
    if source && is_ident(s.trim_end_matches(".rs").trim_end_matches(".md")) && !t.names.contains(s)
    {
        return Some(format!("`{s}`: no such file in the tree"));
    }
    None
}

/// The problems of every document, `doc:line: ...`.
pub fn check() -> Result<Vec<String>> {
    let t = Tree::read(&root())?;
    let mut out = Vec::new();
    for (_, rel, text) in read_docs()? {
        for (span, line) in spans(&text) {
            if let Some(e) = check_span(&t, &span) {
                out.push(format!("{rel}:{line}: {e}"));
            }
        }
    }
    Ok(out)
}

/// Every document: its path, its path from the root, its text.
pub fn read_docs() -> Result<Vec<(PathBuf, String, String)>> {
    let base = root();
    docs()?
        .into_iter()
        .map(|doc| {
            let text = fs::read_to_string(&doc).map_err(|e| format!("{}: {e}", doc.display()))?;
            let rel = doc
                .strip_prefix(&base)
                .unwrap_or(&doc)
                .display()
                .to_string();
            Ok((doc, rel, text))
        })
        .collect()
}

/// The documents that may hold figures.
pub fn docs() -> Result<Vec<PathBuf>> {
    let mut v = vec![root().join("README.md")];
    let mut d: Vec<PathBuf> = fs::read_dir(root().join("docs"))
        .map_err(|e| format!("docs/: {e}"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    d.sort();
    v.extend(d);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree() -> Tree {
        let mut t = Tree::default();
        t.add_code(
            "pub struct ServoConfig;\nimpl ServoConfig { pub fn at_rate() {} }\npub enum Fault { SignCheck }\n// struct LoopConfig; a comment does not define it\n",
        );
        t.external.insert("heapless".into());
        t.top.insert("docs".into());
        t.paths.insert("docs/BOARD.md".into());
        t.names.insert("BOARD.md".into());
        t.names.insert("ahead.rs".into());
        t
    }

    #[test]
    fn a_renamed_type_or_item_is_found_and_a_present_one_passes() {
        let t = tree();
        assert!(check_span(&t, "LoopConfig::at_rate")
            .unwrap()
            .contains("LoopConfig"));
        assert_eq!(check_span(&t, "ServoConfig::at_rate"), None);
        assert!(check_span(&t, "ServoConfig::at_speed").is_some());
        assert_eq!(check_span(&t, "Fault::SignCheck"), None);
        assert_eq!(check_span(&t, "heapless::HistoryBuf::write"), None);
        assert!(check_span(&t, "LoopTick").is_some());
        // A constant of the crate, and another crate's type the code uses.
        t_with(&t);
    }

    fn t_with(t: &Tree) {
        let mut t2 = Tree {
            words: t.words.clone(),
            types: t.types.clone(),
            ..Tree::default()
        };
        t2.add_code("pub const DEFAULT_TABLE: &[u8] = &[];\nlet c = Cell::new(0);\nc.take();\n");
        assert_eq!(check_span(&t2, "zslide::DEFAULT_TABLE"), None);
        assert_eq!(check_span(&t2, "Cell::take"), None);
        assert!(check_span(&t2, "Interp::columns").is_some());
    }

    #[test]
    fn missing_files_are_found() {
        let t = tree();
        assert_eq!(check_span(&t, "docs/BOARD.md"), None);
        assert!(check_span(&t, "docs/COMMON.md").is_some());
        assert!(check_span(&t, "COMMON.md").is_some());
        assert_eq!(check_span(&t, "ahead.rs"), None);
        assert!(check_span(&t, "looptick2.rs").is_some());
        // Output files a command writes are not the tree's.
        assert_eq!(check_span(&t, "loop.svg"), None);
    }

    #[test]
    fn spans_come_from_backticks_and_fenced_command_lines() {
        let s = spans("a `X::y` b `z`\n```\ncargo sim -- --rpm 3\nnot a command\n```\n");
        assert_eq!(
            s,
            vec![
                ("X::y".to_string(), 1),
                ("z".to_string(), 1),
                ("cargo sim -- --rpm 3".to_string(), 3)
            ]
        );
    }
}
