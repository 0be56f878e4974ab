//! No import cycle between the modules of any crate: part of `cargo xtask
//! test`, and `cargo xtask cycles` alone.
//!
//! Each crate of the repository (the workspace's members, `boards/qemu` and
//! `fuzz`) is read from its roots (`[lib]` and `[[bin]]` paths, `src/lib.rs`,
//! `src/main.rs`, `src/bin/*.rs`, `tests/*.rs`, `build.rs`) along its `mod`
//! declarations into a module tree, one node per file (an inline module is
//! part of its file). An arrow runs from a file to the module file a path
//! in it names: `use` trees and paths in code that start at `crate`,
//! `super`, `self` or a child module. A name that a module only imports
//! (`pub use`) is followed to where it is defined, so a folder's `mod.rs`
//! that hands its children's names on ties nobody to itself. Comments and
//! literals are skipped: a doc link is no import. Every strongly connected
//! set of two files or more is a cycle, reported with the arrows inside it
//! and the names each takes.
//!
//! It reads tokens, not types: a name defined inside a function body counts
//! as the module's, and a macro's expansion is not seen.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The crates' directories, from the repository root.
pub const CRATES: &[&str] = &[
    ".",
    "host-sim",
    "plant",
    "replay",
    "xtask",
    "boards/qemu",
    "fuzz",
];

/// `cargo xtask cycles`: prints every cycle and the biggest source file.
pub fn run() -> crate::Result<u8> {
    let root = crate::root();
    let report = check_crates(&root, CRATES)?;
    report.print();
    eprintln!("{}", report.biggest_line());
    Ok(u8::from(!report.cycles.is_empty()))
}

/// What the check found over a set of crates.
#[derive(Debug, Default)]
pub struct Report {
    /// Files read (module files, tests included).
    pub files: usize,
    /// One text per cycle between files: its files and the arrows that
    /// tie them. Any fails the check.
    pub cycles: Vec<String>,
    /// One text per cycle that only appears with each folder taken as one
    /// module (a folder's files use a sibling that uses the folder):
    /// reported, not failed.
    pub folder_cycles: Vec<String>,
    /// The biggest file that is no test (`tests/`, a `#[cfg(test)]` module
    /// file): path from the root, lines.
    pub biggest: Option<(String, usize)>,
}

impl Report {
    /// Every cycle, the folders' marked as not failing, then the summary.
    pub fn print(&self) {
        for c in &self.cycles {
            eprintln!("{c}");
        }
        for c in &self.folder_cycles {
            eprintln!("between folders only (reported, not failed): {c}");
        }
        eprintln!("{}", self.summary());
    }

    pub fn summary(&self) -> String {
        let verdict = if self.cycles.is_empty() {
            "none".to_string()
        } else {
            format!("{} (above)", self.cycles.len())
        };
        format!(
            "import cycles between modules: {verdict} over {} files; between folders only: {}",
            self.files,
            self.folder_cycles.len()
        )
    }

    pub fn biggest_line(&self) -> String {
        match &self.biggest {
            Some((p, n)) => format!("biggest non-test source file: {p}, {n} lines"),
            None => "biggest non-test source file: none read".into(),
        }
    }
}

/// Reads each crate under `root` and finds the cycles of each.
pub fn check_crates(root: &Path, crates: &[&str]) -> crate::Result<Report> {
    let mut report = Report::default();
    for c in crates {
        let dir = root.join(c);
        if !dir.join("Cargo.toml").is_file() {
            return Err(format!("{}: no Cargo.toml", dir.display()));
        }
        for r in crate_roots(&dir)? {
            let tree = Tree::read(&r.path, r.test)?;
            report.files += tree.mods.len();
            for m in &tree.mods {
                if m.test {
                    continue;
                }
                let rel = m.file.strip_prefix(root).unwrap_or(&m.file);
                let rel = rel.to_string_lossy().trim_start_matches("./").to_string();
                if report.biggest.as_ref().is_none_or(|(_, n)| m.lines > *n) {
                    report.biggest = Some((rel, m.lines));
                }
            }
            let between_files = tree.cycles(false);
            // With cycles between files, the folders' repeat them.
            if between_files.is_empty() {
                for cycle in tree.cycles(true) {
                    report.folder_cycles.push(tree.describe(&cycle, root));
                }
            }
            for cycle in between_files {
                report.cycles.push(tree.describe(&cycle, root));
            }
        }
    }
    Ok(report)
}

struct Root {
    path: PathBuf,
    /// An integration test (all of it is test code).
    test: bool,
}

/// The roots of one crate's module trees.
fn crate_roots(dir: &Path) -> crate::Result<Vec<Root>> {
    let toml = fs::read_to_string(dir.join("Cargo.toml")).map_err(|e| e.to_string())?;
    let mut paths = BTreeSet::new();
    let mut in_target = false;
    for line in toml.lines() {
        let l = line.trim();
        if l.starts_with('[') {
            in_target = l == "[lib]" || l == "[[bin]]" || l == "[[test]]" || l == "[[example]]";
        } else if in_target {
            if let Some(v) = l.strip_prefix("path") {
                let v = v
                    .trim_start()
                    .trim_start_matches('=')
                    .trim()
                    .trim_matches('"');
                paths.insert(dir.join(v));
            }
        }
    }
    for default in ["src/lib.rs", "src/main.rs", "build.rs"] {
        paths.insert(dir.join(default));
    }
    let mut roots: Vec<Root> = paths
        .into_iter()
        .filter(|p| p.is_file())
        .map(|path| Root { path, test: false })
        .collect();
    for (sub, test) in [("src/bin", false), ("tests", true)] {
        let Ok(rd) = fs::read_dir(dir.join(sub)) else {
            continue;
        };
        let mut files: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "rs"))
            .collect();
        files.sort();
        for path in files {
            if !roots.iter().any(|r| r.path == path) {
                roots.push(Root { path, test });
            }
        }
    }
    Ok(roots)
}

// ------------------------------------------------------------------ tokens

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    /// `::`
    Path,
    Punct(char),
}

/// The tokens of Rust source that matter to paths: identifiers, `::` and
/// single punctuation; comments, strings, chars and numbers are dropped.
fn tokens(src: &str) -> Vec<Tok> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    let n = c.len();
    while i < n {
        let ch = c[i];
        if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && c.get(i + 1) == Some(&'/') {
            while i < n && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && c.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < n {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if ch == '"' {
            i = skip_string(&c, i + 1);
        } else if (ch == 'r' || ch == 'b')
            && raw_string_start(&c, i).is_some()
            && !prev_is_ident(&c, i)
        {
            let (hashes, body) = raw_string_start(&c, i).unwrap_or((0, i));
            i = skip_raw(&c, body, hashes);
        } else if ch == 'b' && c.get(i + 1) == Some(&'"') && !prev_is_ident(&c, i) {
            i = skip_string(&c, i + 2);
        } else if ch == 'b' && c.get(i + 1) == Some(&'\'') && !prev_is_ident(&c, i) {
            i = skip_char(&c, i + 1);
        } else if ch == '\'' {
            // A char literal ('a', '\n', '\u{..}') or a lifetime ('a).
            if c.get(i + 1) == Some(&'\\') || c.get(i + 2) == Some(&'\'') {
                i = skip_char(&c, i);
            } else {
                i += 1;
                while i < n && (c[i].is_alphanumeric() || c[i] == '_') {
                    i += 1;
                }
            }
        } else if ch.is_ascii_digit() {
            while i < n && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
        } else if ch.is_alphabetic() || ch == '_' {
            let s = i;
            while i < n && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            let w: String = c[s..i].iter().collect();
            out.push(Tok::Ident(w.trim_start_matches("r#").to_string()));
        } else if ch == ':' && c.get(i + 1) == Some(&':') {
            out.push(Tok::Path);
            i += 2;
        } else {
            out.push(Tok::Punct(ch));
            i += 1;
        }
    }
    out
}

fn prev_is_ident(c: &[char], i: usize) -> bool {
    i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_')
}

/// `r"`, `r#"`, `br"`, `br#"` at `i`: (hashes, index after the quote).
fn raw_string_start(c: &[char], i: usize) -> Option<(usize, usize)> {
    let mut j = i;
    if c.get(j) == Some(&'b') {
        j += 1;
    }
    if c.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    let mut hashes = 0;
    while c.get(j) == Some(&'#') {
        hashes += 1;
        j += 1;
    }
    (c.get(j) == Some(&'"')).then_some((hashes, j + 1))
}

fn skip_raw(c: &[char], mut i: usize, hashes: usize) -> usize {
    while i < c.len() {
        if c[i] == '"' && (1..=hashes).all(|k| c.get(i + k) == Some(&'#')) {
            return i + 1 + hashes;
        }
        i += 1;
    }
    i
}

fn skip_string(c: &[char], mut i: usize) -> usize {
    while i < c.len() {
        match c[i] {
            '\\' => i += 2,
            '"' => return i + 1,
            _ => i += 1,
        }
    }
    i
}

fn skip_char(c: &[char], i: usize) -> usize {
    // c[i] is the opening quote.
    let mut j = i + 1;
    if c.get(j) == Some(&'\\') {
        j += 2;
    } else {
        j += 1;
    }
    while j < c.len() && c[j] != '\'' {
        j += 1;
    }
    j + 1
}

// ------------------------------------------------------------ module tree

/// One module: a file, or an inline module of a file.
#[derive(Debug)]
struct Mod {
    /// Index into `Tree::mods`' files of the file it is in.
    file: usize,
    parent: Option<usize>,
    children: BTreeMap<String, usize>,
    /// Names its items define.
    defines: BTreeSet<String>,
    /// Names bound by its `use`s: name → absolute module path of the
    /// source plus the name there (`None`: the module itself).
    imports: BTreeMap<String, (Vec<usize>, Option<String>)>,
    /// Modules whose names it glob-imports.
    globs: Vec<usize>,
    /// Test code (`#[cfg(test)]`, or in a test): its arrows are not drawn.
    test: bool,
}

/// A file of the tree.
#[derive(Debug)]
struct FileNode {
    file: PathBuf,
    /// The file whose module declares this one's.
    parent: Option<usize>,
    lines: usize,
    test: bool,
}

/// An unresolved path met in a module: where, and its segments.
struct RawPath {
    module: usize,
    segs: Vec<String>,
    /// From a `use`: what it binds (alias), or `*`.
    bind: Option<String>,
}

struct Tree {
    mods: Vec<FileNode>,
    modules: Vec<Mod>,
    /// Arrows between files with the names taken.
    arrows: BTreeMap<(usize, usize), BTreeSet<String>>,
}

impl Tree {
    fn read(root: &Path, test: bool) -> crate::Result<Tree> {
        let mut t = Tree {
            mods: Vec::new(),
            modules: Vec::new(),
            arrows: BTreeMap::new(),
        };
        let mut raw = Vec::new();
        let dir = root.parent().unwrap_or(Path::new(".")).to_path_buf();
        t.read_file(root, dir, None, String::new(), test, &mut raw)?;
        // Bind the `use`s first, then resolve every path.
        for r in &raw {
            if let Some(b) = &r.bind {
                if let Some((m, name)) = t.resolve_prefix(r.module, &r.segs) {
                    if b == "*" {
                        if name.is_none() {
                            t.modules[r.module].globs.push(m);
                        }
                    } else {
                        let path = t.abs(m);
                        t.modules[r.module].imports.insert(b.clone(), (path, name));
                    }
                }
            }
        }
        for r in &raw {
            // Test code may reach anywhere: it is not the modules' design.
            if t.modules[r.module].test {
                continue;
            }
            if let Some((m, name)) = t.resolve_prefix(r.module, &r.segs) {
                let (target, name) = t.follow(m, name, 0);
                let from = t.modules[r.module].file;
                let to = t.modules[target].file;
                if from != to {
                    let label = name.unwrap_or_else(|| r.segs.join("::"));
                    t.arrows.entry((from, to)).or_default().insert(label);
                }
            }
        }
        Ok(t)
    }

    /// Reads `file` as module `parent`'s child `name` (the root: `None`).
    fn read_file(
        &mut self,
        file: &Path,
        dir: PathBuf,
        parent: Option<usize>,
        name: String,
        test: bool,
        raw: &mut Vec<RawPath>,
    ) -> crate::Result<usize> {
        let src = fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
        let fi = self.mods.len();
        self.mods.push(FileNode {
            file: file.to_path_buf(),
            parent: parent.map(|p| self.modules[p].file),
            lines: src.lines().count(),
            test,
        });
        let m = self.new_mod(fi, parent, &name);
        self.modules[m].test = test;
        let toks = tokens(&src);
        // Where this file's child files live: a mod.rs-like file's own
        // folder, else the folder named after it.
        let stem = file.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let own = parent.is_none() || stem == "mod";
        let child_dir = if own { dir } else { dir.join(stem) };
        self.read_tokens(&toks, m, fi, child_dir, test, raw)?;
        Ok(m)
    }

    fn new_mod(&mut self, file: usize, parent: Option<usize>, name: &str) -> usize {
        let m = self.modules.len();
        self.modules.push(Mod {
            file,
            parent,
            children: BTreeMap::new(),
            defines: BTreeSet::new(),
            imports: BTreeMap::new(),
            globs: Vec::new(),
            test: false,
        });
        if let Some(p) = parent {
            self.modules[p].children.insert(name.to_string(), m);
        }
        m
    }

    fn read_tokens(
        &mut self,
        toks: &[Tok],
        top: usize,
        fi: usize,
        dir: PathBuf,
        test: bool,
        raw: &mut Vec<RawPath>,
    ) -> crate::Result<()> {
        // The inline modules open at each brace depth.
        let mut stack: Vec<(usize, usize, PathBuf)> = vec![(top, 0, dir)];
        let mut depth = 0usize;
        let mut cfg_test = false;
        let mut i = 0;
        while i < toks.len() {
            let (cur, cur_depth, cur_dir) =
                stack.last().cloned().unwrap_or((top, 0, PathBuf::new()));
            let at_top = depth == cur_depth;
            match &toks[i] {
                Tok::Punct('{') => depth += 1,
                Tok::Punct('}') => {
                    depth = depth.saturating_sub(1);
                    if stack.len() > 1 && depth < cur_depth {
                        stack.pop();
                    }
                }
                Tok::Punct('#') => {
                    // `#[cfg(test)]` before the next item.
                    let attr: Vec<&Tok> = toks[i..].iter().take(6).collect();
                    if let [_, Tok::Punct('['), Tok::Ident(c), Tok::Punct('('), Tok::Ident(t), Tok::Punct(')')] =
                        attr[..]
                    {
                        if c == "cfg" && t == "test" {
                            cfg_test = true;
                        }
                    }
                }
                Tok::Ident(kw) if kw == "mod" => {
                    if let Some(Tok::Ident(name)) = toks.get(i + 1) {
                        let name = name.clone();
                        match toks.get(i + 2) {
                            Some(Tok::Punct(';')) => {
                                let a = cur_dir.join(format!("{name}.rs"));
                                let b = cur_dir.join(&name).join("mod.rs");
                                let (path, sub) = if a.is_file() {
                                    (a, cur_dir.clone())
                                } else if b.is_file() {
                                    (b, cur_dir.join(&name))
                                } else {
                                    return Err(format!(
                                        "{}: `mod {name};` found neither {} nor {}",
                                        self.mods[fi].file.display(),
                                        a.display(),
                                        b.display()
                                    ));
                                };
                                self.read_file(&path, sub, Some(cur), name, test || cfg_test, raw)?;
                                cfg_test = false;
                                i += 3;
                                continue;
                            }
                            Some(Tok::Punct('{')) => {
                                let m = self.new_mod(fi, Some(cur), &name);
                                self.modules[m].test = self.modules[cur].test || cfg_test;
                                depth += 1;
                                stack.push((m, depth, cur_dir.join(&name)));
                                cfg_test = false;
                                i += 3;
                                continue;
                            }
                            _ => {}
                        }
                    }
                }
                Tok::Ident(kw) if kw == "use" => {
                    let end = toks[i..]
                        .iter()
                        .position(|t| *t == Tok::Punct(';'))
                        .map_or(toks.len(), |k| i + k);
                    let mut out = Vec::new();
                    use_tree(&toks[i + 1..end], &mut Vec::new(), &mut out);
                    for (segs, bind) in out {
                        raw.push(RawPath {
                            module: cur,
                            segs,
                            bind: at_top.then_some(bind),
                        });
                    }
                    cfg_test = false;
                    i = end + 1;
                    continue;
                }
                Tok::Ident(kw)
                    if at_top
                        && matches!(
                            kw.as_str(),
                            "fn" | "struct"
                                | "enum"
                                | "trait"
                                | "type"
                                | "const"
                                | "static"
                                | "union"
                        ) =>
                {
                    if let Some(Tok::Ident(name)) = toks.get(i + 1) {
                        self.modules[cur].defines.insert(name.clone());
                    }
                    cfg_test = false;
                }
                Tok::Ident(kw) if kw == "macro_rules" => {
                    if let Some(Tok::Ident(name)) = toks.get(i + 2) {
                        self.modules[cur].defines.insert(name.clone());
                    }
                }
                Tok::Ident(first) if toks.get(i + 1) == Some(&Tok::Path) => {
                    // A path in code: `a::b::c`, not the tail of another.
                    let after_path = i > 0 && toks[i - 1] == Tok::Path;
                    if !after_path {
                        let mut segs = vec![first.clone()];
                        let mut j = i + 1;
                        while toks.get(j) == Some(&Tok::Path) {
                            match toks.get(j + 1) {
                                Some(Tok::Ident(s)) => {
                                    segs.push(s.clone());
                                    j += 2;
                                }
                                _ => break,
                            }
                        }
                        raw.push(RawPath {
                            module: cur,
                            segs,
                            bind: None,
                        });
                        i = j;
                        continue;
                    }
                }
                _ => {}
            }
            i += 1;
        }
        Ok(())
    }

    /// The module path from the root, as module indices.
    fn abs(&self, m: usize) -> Vec<usize> {
        let mut v = vec![m];
        let mut c = m;
        while let Some(p) = self.modules[c].parent {
            v.push(p);
            c = p;
        }
        v.reverse();
        v
    }

    fn root(&self) -> usize {
        0
    }

    /// The deepest module `segs` names from module `at`, and the name after
    /// it (an item, or `None` when the path ends at the module).
    fn resolve_prefix(&self, at: usize, segs: &[String]) -> Option<(usize, Option<String>)> {
        let first = segs.first()?;
        let (mut m, rest) = match first.as_str() {
            "crate" => (self.root(), &segs[1..]),
            "self" => (at, &segs[1..]),
            "super" => {
                let mut m = at;
                let mut k = 0;
                while segs.get(k).map(String::as_str) == Some("super") {
                    m = self.modules[m].parent?;
                    k += 1;
                }
                (m, &segs[k..])
            }
            _ => {
                // A child module of this module or of an enclosing inline
                // one, or a module this module imported by name.
                let mut c = Some(at);
                let mut found = None;
                while let Some(x) = c {
                    if let Some(&ch) = self.modules[x].children.get(first) {
                        found = Some(ch);
                        break;
                    }
                    if let Some((path, None)) = self.modules[x].imports.get(first) {
                        found = path.last().copied();
                        break;
                    }
                    // Only inline modules see their file's children by
                    // name through `super`; stop at the file.
                    if self.modules[x].file != self.modules[at].file {
                        break;
                    }
                    c = self.modules[x]
                        .parent
                        .filter(|p| self.modules[*p].file == self.modules[at].file);
                }
                (found?, &segs[1..])
            }
        };
        let mut k = 0;
        while let Some(s) = rest.get(k) {
            match self.modules[m].children.get(s) {
                Some(&ch) => {
                    m = ch;
                    k += 1;
                }
                None => break,
            }
        }
        Some((m, rest.get(k).cloned()))
    }

    /// Follows a name that module `m` only imports to where it is defined.
    fn follow(&self, m: usize, name: Option<String>, hops: usize) -> (usize, Option<String>) {
        let Some(n) = name.clone() else {
            return (m, name);
        };
        if hops > 16 || self.modules[m].defines.contains(&n) {
            return (m, name);
        }
        if let Some((path, inner)) = self.modules[m].imports.get(&n) {
            if let Some(&src) = path.last() {
                if src != m {
                    return self.follow(src, inner.clone().or(Some(n)), hops + 1);
                }
            }
        }
        for &g in &self.modules[m].globs {
            if g != m
                && (self.modules[g].defines.contains(&n)
                    || self.modules[g].imports.contains_key(&n))
            {
                return self.follow(g, name, hops + 1);
            }
        }
        (m, name)
    }

    /// The files from the root down to `f`.
    fn chain(&self, f: usize) -> Vec<usize> {
        let mut v = vec![f];
        let mut c = f;
        while let Some(p) = self.mods[c].parent {
            v.push(p);
            c = p;
        }
        v.reverse();
        v
    }

    /// The edges of the module graph, each with its file arrows. A module
    /// may use what its ancestors define: that arrow is no edge. Between
    /// files (`folders` false), or each arrow lifted to the level where its
    /// ends part: between two sibling modules (each standing for its
    /// folder), or from a module to one of its children.
    fn edges(&self, folders: bool) -> BTreeMap<(Node, Node), Vec<(usize, usize)>> {
        let mut out: BTreeMap<(Node, Node), Vec<(usize, usize)>> = BTreeMap::new();
        for &(a, b) in self.arrows.keys() {
            let (ca, cb) = (self.chain(a), self.chain(b));
            let k = ca.iter().zip(&cb).take_while(|(x, y)| x == y).count();
            if k == cb.len() {
                continue; // b is a's ancestor
            }
            if !folders {
                let key = (
                    Node {
                        level: FILES,
                        file: a,
                    },
                    Node {
                        level: FILES,
                        file: b,
                    },
                );
                out.entry(key).or_default().push((a, b));
                continue;
            }
            let (level, from) = if k == ca.len() {
                (a, a) // a is b's ancestor: from a itself to its child
            } else {
                (ca[k - 1], ca[k])
            };
            let key = (Node { level, file: from }, Node { level, file: cb[k] });
            out.entry(key).or_default().push((a, b));
        }
        out
    }

    /// Strongly connected sets of two modules or more (Tarjan), each with
    /// the file arrows that tie it. `folders`: among siblings, each folder
    /// one module.
    fn cycles(&self, folders: bool) -> Vec<Cycle> {
        let lifted = self.edges(folders);
        let mut nodes: Vec<Node> = lifted.keys().flat_map(|(a, b)| [*a, *b]).collect();
        nodes.sort();
        nodes.dedup();
        let id = |x: &Node| nodes.binary_search(x).unwrap_or(0);
        let n = nodes.len();
        let mut adj = vec![Vec::new(); n];
        for (a, b) in lifted.keys() {
            adj[id(a)].push(id(b));
        }
        let mut comps = Vec::new();
        let mut index = vec![usize::MAX; n];
        let mut low = vec![0; n];
        let mut on = vec![false; n];
        let mut stack = Vec::new();
        let mut next = 0;
        for s in 0..n {
            if index[s] != usize::MAX {
                continue;
            }
            // Iterative depth-first search: (node, next edge).
            let mut work = vec![(s, 0usize)];
            index[s] = next;
            low[s] = next;
            next += 1;
            stack.push(s);
            on[s] = true;
            while let Some(&(v, e)) = work.last() {
                if let Some(&w) = adj[v].get(e) {
                    if let Some(top) = work.last_mut() {
                        top.1 += 1;
                    }
                    if index[w] == usize::MAX {
                        index[w] = next;
                        low[w] = next;
                        next += 1;
                        stack.push(w);
                        on[w] = true;
                        work.push((w, 0));
                    } else if on[w] {
                        low[v] = low[v].min(index[w]);
                    }
                } else {
                    work.pop();
                    if let Some(&(u, _)) = work.last() {
                        low[u] = low[u].min(low[v]);
                    }
                    if low[v] == index[v] {
                        let mut comp = Vec::new();
                        while let Some(w) = stack.pop() {
                            on[w] = false;
                            comp.push(nodes[w]);
                            if w == v {
                                break;
                            }
                        }
                        if comp.len() > 1 {
                            comp.sort_by(|a, b| {
                                self.mods[a.file].file.cmp(&self.mods[b.file].file)
                            });
                            comps.push(comp);
                        }
                    }
                }
            }
        }
        comps
            .into_iter()
            .map(|comp| {
                let mut arrows: Vec<(usize, usize)> = lifted
                    .iter()
                    .filter(|((a, b), _)| comp.contains(a) && comp.contains(b))
                    .flat_map(|(_, v)| v.iter().copied())
                    .collect();
                arrows.sort_by(|x, y| {
                    (&self.mods[x.0].file, &self.mods[x.1].file)
                        .cmp(&(&self.mods[y.0].file, &self.mods[y.1].file))
                });
                (comp, arrows)
            })
            .collect()
    }

    fn describe(&self, cycle: &Cycle, root: &Path) -> String {
        let name = |f: usize| {
            let p = &self.mods[f].file;
            p.strip_prefix(root)
                .unwrap_or(p)
                .to_string_lossy()
                .trim_start_matches("./")
                .to_string()
        };
        // A member that stands for its folder is named with its files.
        let member = |n: &Node| {
            let has_children = n.level != FILES
                && n.file != n.level
                && self.mods.iter().any(|m| m.parent == Some(n.file));
            if has_children {
                format!("{} (and its modules)", name(n.file))
            } else {
                name(n.file)
            }
        };
        let (comp, arrows) = cycle;
        let members: Vec<String> = comp.iter().map(member).collect();
        let mut s = format!(
            "import cycle of {} modules: {}",
            comp.len(),
            members.join(", ")
        );
        for &(a, b) in arrows {
            let names: Vec<&str> = self.arrows[&(a, b)].iter().map(String::as_str).collect();
            s += &format!("\n  {} -> {}: {}", name(a), name(b), names.join(", "));
        }
        s
    }
}

/// `Node::level` of the graph between files.
const FILES: usize = usize::MAX;

/// The modules of one cycle and the file arrows between them.
type Cycle = (Vec<Node>, Vec<(usize, usize)>);

/// A module in the graph of one level: `file` (a module with its
/// descendants, or `level` itself alone) among the children of `level`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Node {
    level: usize,
    file: usize,
}

/// Flattens a `use` tree (the tokens after `use`) into (path, bound name).
fn use_tree(toks: &[Tok], prefix: &mut Vec<String>, out: &mut Vec<(Vec<String>, String)>) {
    // Split the top level on commas.
    let mut depth = 0;
    let mut start = 0;
    for (k, t) in toks.iter().enumerate() {
        match t {
            Tok::Punct('{') => depth += 1,
            Tok::Punct('}') => depth -= 1,
            Tok::Punct(',') if depth == 0 => {
                use_item(&toks[start..k], prefix, out);
                start = k + 1;
            }
            _ => {}
        }
    }
    use_item(&toks[start..], prefix, out);
}

fn use_item(toks: &[Tok], prefix: &mut Vec<String>, out: &mut Vec<(Vec<String>, String)>) {
    let mut segs = Vec::new();
    let mut k = 0;
    // A leading `::` (extern crate path) is nothing of this crate.
    if toks.first() == Some(&Tok::Path) {
        return;
    }
    while k < toks.len() {
        match &toks[k] {
            Tok::Ident(s) if s == "as" => {
                if let Some(Tok::Ident(alias)) = toks.get(k + 1) {
                    let path: Vec<String> = prefix.iter().chain(&segs).cloned().collect();
                    if alias != "_" {
                        out.push((path, alias.clone()));
                    } else {
                        out.push((path, String::new()));
                    }
                }
                return;
            }
            Tok::Ident(s) => segs.push(s.clone()),
            Tok::Punct('*') => {
                let path: Vec<String> = prefix.iter().chain(&segs).cloned().collect();
                out.push((path, "*".into()));
                return;
            }
            Tok::Punct('{') => {
                let close = toks.len()
                    - 1
                    - toks
                        .iter()
                        .rev()
                        .position(|t| *t == Tok::Punct('}'))
                        .unwrap_or(0);
                let n = segs.len();
                prefix.append(&mut segs);
                use_tree(&toks[k + 1..close.max(k + 1)], prefix, out);
                prefix.truncate(prefix.len() - n);
                return;
            }
            _ => {}
        }
        k += 1;
    }
    let mut path: Vec<String> = prefix.iter().chain(&segs).cloned().collect();
    match path.last().map(String::as_str) {
        // `use a::b::{self}` binds `b`.
        Some("self") => {
            path.pop();
            if let Some(b) = path.last().cloned() {
                out.push((path, b));
            }
        }
        Some(b) => {
            let b = b.to_string();
            out.push((path, b));
        }
        None => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A crate in a temporary folder: (path, text) pairs.
    fn crate_of(name: &str, files: &[(&str, &str)]) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("xtask-cycles-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        for (p, text) in files {
            let f = dir.join(p);
            fs::create_dir_all(f.parent().unwrap()).unwrap();
            fs::write(f, text).unwrap();
        }
        fs::write(dir.join("Cargo.toml"), "[package]\nname = \"t\"\n").unwrap();
        dir
    }

    #[test]
    fn a_cycle_through_a_use_and_a_path_in_code_is_reported_with_its_names() {
        let dir = crate_of(
            "cycle",
            &[
                ("src/lib.rs", "pub mod a;\npub mod b;\npub mod c;\n"),
                ("src/a.rs", "use crate::b::Beta;\npub struct Alpha;\n"),
                // In code, not in a `use`; the doc link is no import.
                (
                    "src/b.rs",
                    "/// [`crate::c::Gamma`]\npub struct Beta;\nfn f() { let _ = crate::a::Alpha; }\n",
                ),
                ("src/c.rs", "pub struct Gamma;\n"),
            ],
        );
        let r = check_crates(&dir, &["."]).unwrap();
        assert_eq!(r.cycles.len(), 1, "{:?}", r.cycles);
        let c = &r.cycles[0];
        assert!(
            c.starts_with("import cycle of 2 modules: src/a.rs, src/b.rs"),
            "{c}"
        );
        assert!(c.contains("src/a.rs -> src/b.rs: Beta"), "{c}");
        assert!(c.contains("src/b.rs -> src/a.rs: Alpha"), "{c}");
        assert!(!c.contains("c.rs"), "{c}");
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_folder_that_hands_its_childrens_names_on_is_no_cycle() {
        // m/mod.rs re-exports x's and y's names; y takes x's name through
        // the face (`super::X`), x takes nothing back; a test module file
        // takes its parent's names, an inline test module takes user's U
        // (test code is no design): no cycle.
        let dir = crate_of(
            "acyclic",
            &[
                ("src/lib.rs", "pub mod m;\npub mod user;\n"),
                (
                    "src/m/mod.rs",
                    "//! crate::user::U in a comment\nmod x;\nmod y;\npub use x::X;\npub use y::Y;\n",
                ),
                (
                    "src/m/x.rs",
                    "pub struct X;\n#[cfg(test)]\nmod tests;\n#[cfg(test)]\nmod more {\n    use crate::user::U;\n}\n",
                ),
                // The longest file, but a test.
                (
                    "src/m/x/tests.rs",
                    "use super::*;\nfn t() -> X {\n    X\n}\n\n\n\n\n\n\n\n\n",
                ),
                ("src/m/y.rs", "use super::X;\npub struct Y(X);\nconst S: &str = \"crate::user::U\";\n"),
                ("src/user.rs", "use crate::m::{X, Y};\npub struct U(X, Y);\n"),
            ],
        );
        let r = check_crates(&dir, &["."]).unwrap();
        assert!(r.cycles.is_empty(), "{:?}", r.cycles);
        assert_eq!(r.files, 6);
        // The test module file is not counted as source.
        assert_eq!(r.biggest.as_ref().unwrap().0, "src/m/x.rs");
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_cycle_through_a_parent_and_its_child_is_found_and_a_child_may_use_its_parent() {
        // faults/mod.rs calls its child by relative path, the child takes
        // cut's Cutter, cut.rs takes faults' Spec: a cycle of three files.
        // The child's `super::Spec` (what its parent defines) is no edge.
        let dir = crate_of(
            "parent",
            &[
                ("src/lib.rs", "pub mod cut;\npub mod faults;\n"),
                (
                    "src/faults/mod.rs",
                    "pub mod link;\npub struct Spec;\nfn r() { link::judge(); }\n",
                ),
                (
                    "src/faults/link.rs",
                    "use super::Spec;\nuse crate::cut::Cutter;\npub fn judge() {}\n",
                ),
                (
                    "src/cut.rs",
                    "pub struct Cutter;\nfn f() { let _ = crate::faults::Spec; }\n",
                ),
            ],
        );
        let r = check_crates(&dir, &["."]).unwrap();
        assert_eq!(r.cycles.len(), 1, "{:?}", r.cycles);
        let c = &r.cycles[0];
        assert!(
            c.starts_with(
                "import cycle of 3 modules: src/cut.rs, src/faults/link.rs, src/faults/mod.rs\n"
            ),
            "{c}"
        );
        assert!(c.contains("src/cut.rs -> src/faults/mod.rs: Spec"), "{c}");
        assert!(
            c.contains("src/faults/link.rs -> src/cut.rs: Cutter"),
            "{c}"
        );
        assert!(
            c.contains("src/faults/mod.rs -> src/faults/link.rs: judge"),
            "{c}"
        );
        assert!(
            !c.contains("src/faults/link.rs -> src/faults/mod.rs"),
            "{c}"
        );
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_cycle_only_between_folders_is_reported_and_does_not_fail() {
        // servo/limits takes safety's Fault, safety takes params' error,
        // params takes servo/design's config: no cycle between files, one
        // between the servo folder and its two siblings.
        let dir = crate_of(
            "folders",
            &[
                (
                    "src/lib.rs",
                    "pub mod params;\npub mod safety;\npub mod servo;\n",
                ),
                ("src/servo/mod.rs", "pub mod design;\npub mod limits;\n"),
                ("src/servo/design.rs", "pub struct Config;\n"),
                ("src/servo/limits.rs", "use crate::safety::Fault;\n"),
                (
                    "src/safety.rs",
                    "use crate::params::ParamError;\npub struct Fault;\n",
                ),
                (
                    "src/params.rs",
                    "use crate::servo::design::Config;\npub struct ParamError;\n",
                ),
            ],
        );
        let r = check_crates(&dir, &["."]).unwrap();
        assert!(r.cycles.is_empty(), "{:?}", r.cycles);
        assert_eq!(r.folder_cycles.len(), 1, "{:?}", r.folder_cycles);
        let c = &r.folder_cycles[0];
        assert!(
            c.starts_with(
                "import cycle of 3 modules: src/params.rs, src/safety.rs, src/servo/mod.rs (and its modules)"
            ),
            "{c}"
        );
        assert!(
            c.contains("src/servo/limits.rs -> src/safety.rs: Fault"),
            "{c}"
        );
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn literals_and_lifetimes_are_not_paths() {
        let t = tokens("fn f<'a>(x: &'a str) -> char { let _ = r#\"crate::a\"#; 'x' } // crate::b");
        assert!(!t.contains(&Tok::Ident("crate".into())), "{t:?}");
        assert!(t.contains(&Tok::Ident("str".into())));
    }
}
