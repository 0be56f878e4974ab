//! What the check found, in words: the report over all crates and the
//! text of one cycle.

use std::path::Path;

use super::graph::{Cycle, Node, FILES};
use super::tree::Tree;

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

impl Tree {
    pub(super) fn describe(&self, cycle: &Cycle, root: &Path) -> String {
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
