//! `cargo xtask fuzz --seconds N [--target T]`: builds the cargo-fuzz
//! targets of `fuzz/` once, runs each for N seconds, and prints per target
//! the executions, coverage (libFuzzer's `cov` edges and `ft` features) and
//! corpus size. A finding (crash, failed property, leak, timeout) fails the
//! command and names the reproducer libFuzzer wrote.
//!
//! Each run starts from the committed corpus `fuzz/corpus/<target>` (read
//! only) and writes what it discovers to `target/fuzz-corpus/<target>`, so a
//! run never changes tracked files; the full libFuzzer log of each target is
//! kept in `target/fuzz-logs/<target>.log`.

use std::fs;
use std::path::PathBuf;
use std::process::Stdio;
use std::time::Instant;

use std::process::Command;

use crate::{cargo, root, step, Result};

/// The targets, in the order they run: the `[[bin]]` names of
/// `fuzz/Cargo.toml` (a test checks the two lists agree).
pub const TARGETS: [&str; 10] = [
    "table_parse",
    "xpos",
    "spindle",
    "scenario",
    "geometry",
    "link_frame",
    "param_block",
    "interrupt_block",
    "replay_recording",
    "trace_log",
];

/// Seconds per target in `cargo xtask test`: enough to replay the corpus and
/// mutate a few thousand inputs, small against the rest of the run.
pub const TEST_SECONDS: u32 = 3;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Seconds each target runs (after its build).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    seconds: u32,
    /// Run only this target.
    #[arg(long, value_name = "T", value_parser = clap::builder::PossibleValuesParser::new(TARGETS))]
    target: Option<String>,
}

/// What one target's run reported.
#[derive(Debug, Default, PartialEq)]
pub struct RunStats {
    pub execs: u64,
    pub cov: u64,
    pub ft: u64,
    pub corpus: u64,
    pub execs_per_s: u64,
}

/// `cargo +nightly …` through the rustup proxy: the `CARGO` that runs xtask
/// is the stable toolchain's own binary, which knows no `+toolchain`.
fn nightly_cargo() -> Command {
    let mut cmd = Command::new("cargo");
    cmd.env_remove("CARGO")
        .env_remove("RUSTUP_TOOLCHAIN")
        .arg("+nightly");
    cmd
}

pub fn fuzz_dir() -> PathBuf {
    root().join("fuzz")
}

/// What is missing to fuzz, each with its remedy (empty: ready). Installs
/// cargo-fuzz when the nightly toolchain is there; never installs a
/// toolchain itself (`.ci/run` does that on CI).
pub fn missing_tools() -> Vec<String> {
    if !crate::works("rustup", &["run", "nightly", "rustc", "--version"]) {
        return vec!["the nightly toolchain (cargo-fuzz needs it): run \
             `rustup toolchain install nightly --profile minimal`"
            .into()];
    }
    let fuzz_runs = || {
        nightly_cargo()
            .args(["fuzz", "--version"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if fuzz_runs() {
        return Vec::new();
    }
    step("installing cargo-fuzz (cargo install)");
    let installed = crate::run(
        cargo().args(["install", "cargo-fuzz", "--locked"]),
        "cargo install cargo-fuzz",
    );
    match installed {
        Ok(()) if fuzz_runs() => Vec::new(),
        Ok(()) => vec![
            "cargo-fuzz: installed but `cargo +nightly fuzz` does not run; \
                        add ~/.cargo/bin to PATH"
                .into(),
        ],
        Err(e) => vec![format!(
            "cargo-fuzz ({e}); run `cargo install cargo-fuzz --locked`"
        )],
    }
}

pub fn run(args: &Args) -> Result<Vec<(String, RunStats)>> {
    let missing = missing_tools();
    if !missing.is_empty() {
        return Err(format!("cannot fuzz, missing: {}", missing.join("; ")));
    }
    let targets: Vec<&str> = match &args.target {
        Some(t) => vec![t.as_str()],
        None => TARGETS.to_vec(),
    };
    run_targets(&targets, args.seconds)
}

/// Builds once, then runs each target for `seconds`.
pub fn run_targets(targets: &[&str], seconds: u32) -> Result<Vec<(String, RunStats)>> {
    step("fuzz targets: cargo +nightly fuzz build (fuzz/)");
    crate::run(
        nightly_cargo()
            .current_dir(fuzz_dir())
            .args(["fuzz", "build"]),
        "cargo fuzz build",
    )?;
    let target_dir = crate::target_dir();
    let logs = target_dir.join("fuzz-logs");
    fs::create_dir_all(&logs).map_err(|e| format!("{}: {e}", logs.display()))?;
    let mut results = Vec::new();
    let mut failures = Vec::new();
    for &t in targets {
        let work = target_dir.join("fuzz-corpus").join(t);
        fs::create_dir_all(&work).map_err(|e| format!("{}: {e}", work.display()))?;
        let seeds = fuzz_dir().join("corpus").join(t);
        let log_path = logs.join(format!("{t}.log"));
        let log =
            fs::File::create(&log_path).map_err(|e| format!("{}: {e}", log_path.display()))?;
        eprintln!(
            "fuzz: {t}: running {seconds} s (log: {})",
            log_path.display()
        );
        let started = Instant::now();
        let status = nightly_cargo()
            .current_dir(fuzz_dir())
            .args(["fuzz", "run", t])
            .arg(&work)
            .arg(&seeds)
            .args([
                "--",
                &format!("-max_total_time={seconds}"),
                // A single input running this long is a hang: a finding.
                "-timeout=10",
                "-print_final_stats=1",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log)
            .status()
            .map_err(|e| format!("cannot start cargo fuzz run {t}: {e}"))?;
        let text = fs::read_to_string(&log_path).unwrap_or_default();
        let stats = parse_stats(&text);
        if status.success() {
            eprintln!(
                "fuzz: {t:12} {:>10} execs ({:>6}/s)  cov {:>5}  ft {:>6}  corpus {:>5}  [{:.0} s]",
                stats.execs,
                stats.execs_per_s,
                stats.cov,
                stats.ft,
                stats.corpus,
                started.elapsed().as_secs_f64()
            );
        } else {
            let artifact = text
                .lines()
                .rev()
                .find_map(|l| l.split_once("Test unit written to "))
                .map(|(_, p)| p.trim().to_string());
            // The failed property or the sanitizer's report, not the
            // backtrace of cargo-fuzz itself.
            let lines: Vec<&str> = text.lines().collect();
            let at = lines
                .iter()
                .position(|l| {
                    l.contains("panicked at")
                        || l.starts_with("==")
                        || l.contains("ERROR: libFuzzer")
                })
                .unwrap_or(lines.len().saturating_sub(30));
            eprintln!("fuzz: {t}: FINDING ({status}):");
            for l in lines.iter().skip(at).take(12) {
                eprintln!("  {l}");
            }
            failures.push(match artifact {
                Some(a) => format!(
                    "{t}: reproducer {a} (replay: cd fuzz && cargo +nightly fuzz run {t} {a})"
                ),
                None => format!("{t}: failed ({status}), see {}", log_path.display()),
            });
        }
        results.push((t.to_string(), stats));
    }
    if failures.is_empty() {
        Ok(results)
    } else {
        Err(format!("fuzzing found:\n  {}", failures.join("\n  ")))
    }
}

/// The figures of a libFuzzer log: the last status line's `cov`, `ft` and
/// `corp`, and the final stats' executions and rate.
pub fn parse_stats(log: &str) -> RunStats {
    let mut s = RunStats::default();
    let field = |line: &str, key: &str| -> Option<u64> {
        let rest = line.split(key).nth(1)?;
        let num: String = rest
            .trim_start()
            .chars()
            .take_while(char::is_ascii_digit)
            .collect();
        num.parse().ok()
    };
    for line in log.lines() {
        if line.starts_with('#') && line.contains(" cov: ") {
            s.cov = field(line, " cov:").unwrap_or(s.cov);
            s.ft = field(line, " ft:").unwrap_or(s.ft);
            s.corpus = field(line, " corp:").unwrap_or(s.corpus);
        } else if let Some(v) = line.strip_prefix("stat::number_of_executed_units:") {
            s.execs = v.trim().parse().unwrap_or(0);
        } else if let Some(v) = line.strip_prefix("stat::average_exec_per_sec:") {
            s.execs_per_s = v.trim().parse().unwrap_or(0);
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_list_matches_the_fuzz_crate() {
        let manifest = fs::read_to_string(fuzz_dir().join("Cargo.toml")).unwrap();
        let bins: Vec<&str> = manifest
            .split("[[bin]]")
            .skip(1)
            .filter_map(|b| b.lines().find_map(|l| l.strip_prefix("name = ")))
            .map(|n| n.trim().trim_matches('"'))
            .collect();
        assert_eq!(bins, TARGETS);
        for t in TARGETS {
            let seeds = fuzz_dir().join("corpus").join(t);
            let n = fs::read_dir(&seeds).map(|d| d.count()).unwrap_or(0);
            assert!(n > 0, "no committed seed corpus in {}", seeds.display());
        }
    }

    #[test]
    fn libfuzzer_figures_are_read_from_the_last_status_line() {
        let log = "INFO: seed corpus: files: 4\n\
                   #2\tINITED cov: 120 ft: 130 corp: 4/9Kb exec/s: 0 rss: 40Mb\n\
                   #4096\tpulse  cov: 311 ft: 902 corp: 57/3312b lim: 43 exec/s: 2048 rss: 45Mb\n\
                   #9001\tDONE   cov: 312 ft: 915 corp: 60/3400b lim: 43 exec/s: 3000 rss: 45Mb\n\
                   Done 9001 runs in 3 second(s)\n\
                   stat::number_of_executed_units: 9001\n\
                   stat::average_exec_per_sec:     3000\n";
        assert_eq!(
            parse_stats(log),
            RunStats {
                execs: 9001,
                cov: 312,
                ft: 915,
                corpus: 60,
                execs_per_s: 3000
            }
        );
    }
}
