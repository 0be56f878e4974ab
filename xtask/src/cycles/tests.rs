//! The check on synthetic crates (each written to a temporary folder).

use std::fs;
use std::path::PathBuf;

use super::check_crates;
use super::lex::{tokens, Tok};

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

/// The quoted strings of the root manifest's `[workspace]` array `key`.
fn workspace_list(toml: &str, key: &str) -> Vec<String> {
    let start = toml
        .find(&format!("\n{key} = ["))
        .unwrap_or_else(|| panic!("no {key} in the root Cargo.toml"));
    let body = &toml[start..];
    let body = &body[..body.find(']').unwrap()];
    body.split('"')
        .skip(1)
        .step_by(2)
        .map(String::from)
        .collect()
}

#[test]
fn every_crate_of_the_workspace_is_checked() {
    let toml = fs::read_to_string(crate::root().join("Cargo.toml")).unwrap();
    let mut want = workspace_list(&toml, "members");
    want.extend(workspace_list(&toml, "exclude"));
    want.sort();
    let mut have: Vec<String> = super::CRATES.iter().map(|c| c.to_string()).collect();
    have.sort();
    assert_eq!(
        have, want,
        "cycles::CRATES against the workspace's members and exclude"
    );
}
