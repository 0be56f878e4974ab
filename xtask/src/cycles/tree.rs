//! Reading a crate's module tree: `mod` declarations (files and inline
//! modules), the names each module defines, its `use`s and the paths in its
//! code; then every path resolved to an arrow between files (`graph`).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

use super::lex::{tokens, Tok};

/// One module: a file, or an inline module of a file.
#[derive(Debug)]
pub(super) struct Mod {
    /// Index into `Tree::mods`' files of the file it is in.
    pub(super) file: usize,
    pub(super) parent: Option<usize>,
    pub(super) children: BTreeMap<String, usize>,
    /// Names its items define.
    pub(super) defines: BTreeSet<String>,
    /// Names bound by its `use`s: name → absolute module path of the
    /// source plus the name there (`None`: the module itself).
    pub(super) imports: BTreeMap<String, (Vec<usize>, Option<String>)>,
    /// Modules whose names it glob-imports.
    pub(super) globs: Vec<usize>,
    /// Test code (`#[cfg(test)]`, or in a test): its arrows are not drawn.
    pub(super) test: bool,
}

/// A file of the tree.
#[derive(Debug)]
pub(super) struct FileNode {
    pub(super) file: PathBuf,
    /// The file whose module declares this one's.
    pub(super) parent: Option<usize>,
    pub(super) lines: usize,
    pub(super) test: bool,
}

/// An unresolved path met in a module: where, and its segments.
pub(super) struct RawPath {
    pub(super) module: usize,
    pub(super) segs: Vec<String>,
    /// From a `use`: what it binds (alias), or `*`.
    pub(super) bind: Option<String>,
}

pub(super) struct Tree {
    pub(super) mods: Vec<FileNode>,
    pub(super) modules: Vec<Mod>,
    /// Arrows between files with the names taken.
    pub(super) arrows: BTreeMap<(usize, usize), BTreeSet<String>>,
}

impl Tree {
    pub(super) fn read(root: &Path, test: bool) -> crate::Result<Tree> {
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
    pub(super) fn read_file(
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

    pub(super) fn new_mod(&mut self, file: usize, parent: Option<usize>, name: &str) -> usize {
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

    pub(super) fn read_tokens(
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
}

/// Flattens a `use` tree (the tokens after `use`) into (path, bound name).
pub(super) fn use_tree(
    toks: &[Tok],
    prefix: &mut Vec<String>,
    out: &mut Vec<(Vec<String>, String)>,
) {
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

pub(super) fn use_item(
    toks: &[Tok],
    prefix: &mut Vec<String>,
    out: &mut Vec<(Vec<String>, String)>,
) {
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
