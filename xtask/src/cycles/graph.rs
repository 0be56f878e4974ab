//! The import graph of a module tree: paths resolved to modules (through
//! `use`s and re-exports), arrows between files or between folders, and
//! its strongly connected sets of two modules or more.

use std::collections::BTreeMap;

use super::tree::Tree;

impl Tree {
    /// The module path from the root, as module indices.
    pub(super) fn abs(&self, m: usize) -> Vec<usize> {
        let mut v = vec![m];
        let mut c = m;
        while let Some(p) = self.modules[c].parent {
            v.push(p);
            c = p;
        }
        v.reverse();
        v
    }

    pub(super) fn root(&self) -> usize {
        0
    }

    /// The deepest module `segs` names from module `at`, and the name after
    /// it (an item, or `None` when the path ends at the module).
    pub(super) fn resolve_prefix(
        &self,
        at: usize,
        segs: &[String],
    ) -> Option<(usize, Option<String>)> {
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
    pub(super) fn follow(
        &self,
        m: usize,
        name: Option<String>,
        hops: usize,
    ) -> (usize, Option<String>) {
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
    pub(super) fn chain(&self, f: usize) -> Vec<usize> {
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
    pub(super) fn edges(&self, folders: bool) -> BTreeMap<(Node, Node), Vec<(usize, usize)>> {
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
    pub(super) fn cycles(&self, folders: bool) -> Vec<Cycle> {
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
}

/// `Node::level` of the graph between files.
pub(super) const FILES: usize = usize::MAX;

/// The modules of one cycle and the file arrows between them.
pub(super) type Cycle = (Vec<Node>, Vec<(usize, usize)>);

/// A module in the graph of one level: `file` (a module with its
/// descendants, or `level` itself alone) among the children of `level`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Node {
    pub(super) level: usize,
    pub(super) file: usize,
}
