//! Where a crate's module trees start: its `[lib]`/`[[bin]]`/`[[test]]`
//! paths, the default roots, `src/bin/*.rs`, `tests/*.rs` and
//! `tests/*/main.rs`.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

pub(super) struct Root {
    pub(super) path: PathBuf,
    /// An integration test (all of it is test code).
    pub(super) test: bool,
}

/// The roots of one crate's module trees.
pub(super) fn crate_roots(dir: &Path) -> crate::Result<Vec<Root>> {
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
        // Cargo's two target layouts: `sub/NAME.rs` and `sub/NAME/main.rs`.
        let mut files: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter_map(|p| {
                if p.extension().is_some_and(|x| x == "rs") {
                    Some(p)
                } else {
                    Some(p.join("main.rs")).filter(|m| m.is_file())
                }
            })
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
