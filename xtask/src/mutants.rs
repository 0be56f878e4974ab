//! `cargo xtask mutants [--module M]...`: cargo-mutants on the core's
//! safety-relevant code, each mutant tested by the core's own tests only
//! (`cargo test -p zslide --lib --tests`: its unit tests and the
//! integration tests in `tests/`). Not part of `cargo xtask test`: on two
//! cores one module takes tens of minutes. cargo-mutants is installed on
//! demand (`cargo install cargo-mutants --locked`), never built by the
//! normal build. The score per module and every surviving mutant, with
//! what was done about it: docs/RELIABILITY.md ("Mutation testing").

use std::path::PathBuf;
use std::process::Command;

use crate::{root, step, Result};

/// One scope: files (globs, so that a file moved into a folder is still
/// found) and, where only part of a file is safety-relevant, a regex over
/// the mutants' names (`file:line:col: replace Type::function ...`).
pub struct Module {
    pub name: &'static str,
    pub files: &'static [&'static str],
    pub re: Option<&'static str>,
    pub what: &'static str,
}

/// Most important first: `--module` picks among them; none runs them all.
pub const MODULES: [Module; 5] = [
    Module {
        name: "safety",
        files: &["**/safety.rs"],
        re: None,
        what: "faults, their reactions and severity order",
    },
    Module {
        name: "looptick",
        files: &["**/looptick.rs", "**/looptick/*.rs"],
        // Mutants are named `file:line:col: replace LoopState::f ...`, so a
        // function is matched by its path, not by `fn f` (which matched
        // nothing: the loop tick and its fault steps went unmutated).
        re: Some(
            "trip|clear_fault|amplifier_must_be_off|hold_safe|take_requests|amplifier_enable|LoopState::(loop_tick|sense_gauge|fault_checks|output) ",
        ),
        what: "the loop tick's fault reactions: latch, clamp, clear, arm",
    },
    Module {
        name: "limits",
        files: &["**/servo/limits.rs", "**/servo/limits/*.rs"],
        re: Some("FollowingError|CurrentLimit"),
        what: "the following-error and current-limit monitors",
    },
    Module {
        name: "table",
        files: &["**/table.rs", "**/table/*.rs"],
        re: Some("parse|crc32|node_x|x_null"),
        what: "the coefficient table's parser",
    },
    Module {
        name: "params",
        files: &["**/params.rs", "**/params/*.rs"],
        re: Some("load_region|at_boot|check|limits|[ :]set "),
        what: "the servo parameter block: parse, limits, design",
    },
];

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Only these modules (repeatable): safety, looptick, limits, table, params.
    #[arg(long = "module", value_name = "M")]
    pub modules: Vec<String>,
    /// Seconds a mutant's test run may take before it counts as a timeout.
    #[arg(long, default_value_t = 120)]
    pub timeout: u32,
    /// Parallel mutants (each builds in its own copy of the tree).
    #[arg(long, default_value_t = 1)]
    pub jobs: u32,
    /// List the mutants, run nothing.
    #[arg(long)]
    pub list: bool,
}

fn installed() -> bool {
    Command::new("cargo")
        .args(["mutants", "--version"])
        .output()
        .is_ok_and(|o| o.status.success())
}

fn install() -> Result<()> {
    if installed() {
        return Ok(());
    }
    step("cargo install cargo-mutants --locked");
    let ok = Command::new("cargo")
        .args(["install", "cargo-mutants", "--locked"])
        .status()
        .map_err(|e| format!("cannot run cargo install: {e}"))?
        .success();
    if !ok || !installed() {
        return Err(
            "cargo-mutants could not be installed (cargo install cargo-mutants --locked)".into(),
        );
    }
    Ok(())
}

/// The command for one module.
pub fn command(m: &Module, args: &Args, out: &std::path::Path) -> Command {
    let mut cmd = Command::new("cargo");
    cmd.current_dir(root())
        .args(["mutants", "--package", "zslide", "--test-package", "zslide"])
        .arg("--output")
        .arg(out)
        .args(["--timeout", &args.timeout.to_string()])
        .args(["--jobs", &args.jobs.to_string()])
        .arg("--no-shuffle");
    for f in m.files {
        cmd.args(["--file", f]);
    }
    if let Some(re) = m.re {
        cmd.args(["--re", re]);
    }
    if args.list {
        cmd.arg("--list");
    }
    // The core's unit and integration tests; no doctests, no other crate.
    cmd.args(["--", "--lib", "--tests"]);
    cmd
}

/// Counts of the outcome files cargo-mutants writes.
fn count(dir: &std::path::Path, file: &str) -> Vec<String> {
    std::fs::read_to_string(dir.join("mutants.out").join(file))
        .map(|t| t.lines().map(str::to_string).collect())
        .unwrap_or_default()
}

pub fn run(args: &Args) -> Result<u8> {
    let chosen: Vec<&Module> = if args.modules.is_empty() {
        MODULES.iter().collect()
    } else {
        args.modules
            .iter()
            .map(|n| {
                MODULES.iter().find(|m| m.name == n).ok_or_else(|| {
                    format!(
                        "--module {n}: not a module (one of: {})",
                        MODULES.map(|m| m.name).join(", ")
                    )
                })
            })
            .collect::<Result<_>>()?
    };
    install()?;
    let mut survivors = 0;
    for m in chosen {
        let out: PathBuf = root().join("target/mutants").join(m.name);
        std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
        step(&format!("mutants: {} ({})", m.name, m.what));
        let status = command(m, args, &out)
            .status()
            .map_err(|e| format!("cannot run cargo mutants: {e}"))?;
        if args.list {
            continue;
        }
        let (caught, missed, timeout, unviable) = (
            count(&out, "caught.txt"),
            count(&out, "missed.txt"),
            count(&out, "timeout.txt"),
            count(&out, "unviable.txt"),
        );
        let tested = caught.len() + missed.len() + timeout.len();
        let score = if tested == 0 {
            0.0
        } else {
            100.0 * (caught.len() + timeout.len()) as f64 / tested as f64
        };
        eprintln!(
            "{}: {} caught, {} missed, {} timeout, {} unviable: score {score:.1} % (cargo mutants exit {status})",
            m.name,
            caught.len(),
            missed.len(),
            timeout.len(),
            unviable.len()
        );
        for l in &missed {
            eprintln!("  survived: {l}");
        }
        survivors += missed.len();
    }
    Ok(u8::from(survivors > 0))
}
