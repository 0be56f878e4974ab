//! `cargo xtask mutants [--module M]...`: cargo-mutants on the core's
//! safety-relevant code, each mutant tested by the core's own tests only:
//! its unit tests (`cargo test -p zslide --lib`), and for the loop tick
//! also the integration tests in `tests/` that drive it (`--tests`). The
//! test targets go to cargo-mutants as `--cargo-arg`s, so that its build
//! phase (`cargo test --no-run`, which never sees what follows `--`)
//! builds those alone, not every test target and the firmware binaries.
//! Not part of `cargo xtask test` (it runs for minutes, and cargo-mutants
//! is a heavy build): cargo-mutants is installed on demand (`cargo install
//! cargo-mutants --locked`), never built by the normal build. The score
//! per module and every surviving mutant, with what was done about it:
//! docs/RELIABILITY.md ("Mutation testing").

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
    /// The core's test targets that judge a mutant (cargo's `--lib`,
    /// `--tests`).
    pub tests: &'static [&'static str],
    /// With `--own-tests`: only the tests whose names contain one of these
    /// (libtest's filters) judge a mutant: the module's own tests, so a
    /// survivor says what the module's own tests miss.
    pub own: &'static [&'static str],
    pub what: &'static str,
}

/// Most important first: `--module` picks among them; none runs them all.
pub const MODULES: [Module; 12] = [
    Module {
        name: "safety",
        files: &["**/safety.rs"],
        re: None,
        tests: &["--lib"],
        own: &["safety::"],
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
        // `tests/fault_clear.rs` and `tests/fault_latch.rs` drive the tick.
        tests: &["--lib", "--tests"],
        own: &["firmware::", "fault"],
        what: "the loop tick's fault reactions: latch, clamp, clear, arm",
    },
    Module {
        name: "limits",
        files: &["**/servo/limits.rs", "**/servo/limits/*.rs"],
        re: Some("FollowingError|CurrentLimit"),
        tests: &["--lib"],
        own: &["servo::limits"],
        what: "the following-error and current-limit monitors",
    },
    Module {
        name: "table",
        files: &["**/table.rs", "**/table/*.rs"],
        re: Some("parse|crc32|node_x|x_null"),
        tests: &["--lib"],
        own: &["table::"],
        what: "the coefficient table's parser",
    },
    Module {
        name: "params",
        files: &["**/params.rs", "**/params/*.rs"],
        re: Some("load_region|at_boot|check|limits|[ :]set "),
        tests: &["--lib"],
        own: &["params::"],
        what: "the servo parameter block: parse, limits, design",
    },
    Module {
        name: "design",
        files: &["**/servo/design.rs"],
        re: None,
        // `tests/servo_gains.rs` holds the gains to the brief's design.
        tests: &["--lib", "--tests"],
        own: &["servo::design", "gain"],
        what: "the servo design: gains, observer poles, limits in codes",
    },
    Module {
        name: "observer",
        files: &["**/servo/observer.rs"],
        re: None,
        tests: &["--lib"],
        own: &["servo::observer"],
        what: "the force/velocity observer",
    },
    Module {
        name: "repetitive",
        files: &["**/servo/repetitive.rs", "**/firmware/learning.rs"],
        re: None,
        tests: &["--lib"],
        own: &["servo::repetitive", "learning"],
        what: "the learned correction and its clip",
    },
    Module {
        name: "xpos",
        files: &["**/xpos/mod.rs", "**/xpos/*.rs"],
        re: None,
        tests: &["--lib"],
        own: &["xpos::"],
        what: "the X position: BCD decode, debounce, glitch storm",
    },
    Module {
        name: "spindle",
        files: &["**/spindle/encoder.rs", "**/spindle/tach.rs", "**/spindle/mod.rs"],
        re: None,
        tests: &["--lib"],
        own: &["spindle::"],
        what: "the spindle angle, index and speed checks",
    },
    Module {
        name: "store",
        files: &["**/store/mod.rs", "**/store/boot.rs", "**/store/ram.rs", "**/store/ecc.rs"],
        re: None,
        tests: &["--lib"],
        own: &["store::"],
        what: "the parameter store, its boot order, unreadable words and the power-cut flash model",
    },
    Module {
        name: "handoff",
        files: &["**/handoff/*.rs"],
        re: None,
        tests: &["--lib"],
        own: &["handoff::", "preemption_tests"],
        what: "the lock-free hand-off between the handlers",
    },
];

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Only these modules (repeatable): safety, looptick, limits, table,
    /// params, design, observer, repetitive, xpos, spindle, store, handoff.
    #[arg(long = "module", value_name = "M")]
    pub modules: Vec<String>,
    /// Seconds a mutant's test run may take before it counts as a timeout.
    #[arg(long, default_value_t = 120)]
    pub timeout: u32,
    /// Parallel mutants (each builds in its own copy of the tree).
    #[arg(long, default_value_t = 1, conflicts_with = "in_place")]
    pub jobs: u32,
    /// Mutate this tree itself, one mutant at a time, instead of a copy:
    /// its own target/ stays warm, so a mutant costs an incremental
    /// build (seconds) and no run starts with a cold one. Each mutant is
    /// reverted after its test (and on Ctrl-C); run it in a scratch clone,
    /// not in a tree being edited.
    #[arg(long)]
    pub in_place: bool,
    /// Judge each mutant by the module's own tests only (its `own` name
    /// filters, passed to the test binaries): a test run of a fraction of
    /// a second instead of the whole library's 5 s, and a survivor names
    /// what the module's own tests miss.
    #[arg(long)]
    pub own_tests: bool,
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
        .arg("--no-shuffle")
        // No debug info in the mutants' builds: nothing reads it, and it
        // is most of their link time.
        .env("CARGO_PROFILE_DEV_DEBUG", "0")
        .env("CARGO_PROFILE_TEST_DEBUG", "0")
        // Every mutant judged on the baseline's property cases, and no
        // failure persisted into the tree: a property test that fails on
        // a new random case (one did, in `spindle`) would otherwise fail
        // every later mutant's run and count it caught.
        .env("PROPTEST_RNG_SEED", "22")
        .env("PROPTEST_DISABLE_FAILURE_PERSISTENCE", "1");
    if args.in_place {
        cmd.arg("--in-place");
    } else {
        cmd.args(["--jobs", &args.jobs.to_string()]);
    }
    for t in m.tests {
        cmd.args(["--cargo-arg", t]);
    }
    for f in m.files {
        cmd.args(["--file", f]);
    }
    if let Some(re) = m.re {
        cmd.args(["--re", re]);
    }
    if args.list {
        cmd.arg("--list");
    }
    if args.own_tests {
        // After `--` to cargo test, after the second to the test binaries.
        cmd.args(["--", "--"]).args(m.own);
    }
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
