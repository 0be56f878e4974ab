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

mod graph;
mod lex;
mod report;
mod roots;
mod tree;

#[cfg(test)]
mod tests;

use std::path::Path;

pub use report::Report;
use roots::crate_roots;
use tree::Tree;

/// The crates' directories, from the repository root: the workspace's
/// `members` and its `exclude`d crates (each its own workspace). A test
/// (`every_crate_of_the_workspace_is_checked`) holds this list to the root
/// `Cargo.toml`, so a crate added there and not here fails it.
pub const CRATES: &[&str] = &[
    ".",
    "host-sim",
    "plant",
    "replay",
    "xtask",
    "zslide-host",
    "boards/qemu",
    "boards/nucleo-emu",
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
