//! The host tests of `cargo xtask test`: `cargo nextest run --workspace`
//! (each test in its own process under the deadline of
//! `.config/nextest.toml`, scheduled across every test binary at once),
//! then the doc tests, which nextest does not run (`cargo test --doc`).
//! cargo-nextest is installed when missing (`cargo install cargo-nextest
//! --locked`).

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use crate::{cargo, root, step, Result};

/// (passed, failed, skipped) of every host test.
pub fn host_tests() -> Result<(u64, u64, u64)> {
    ensure_nextest()?;
    step("host tests: cargo nextest run --workspace (.config/nextest.toml)");
    let mut cmd = cargo();
    cmd.current_dir(root())
        .args(["nextest", "run", "--workspace", "--no-tests=fail"]);
    let (status, counts) = tally(&mut cmd, parse_nextest_summary)?;
    let Some((passed, failed, skipped)) = counts else {
        return Err(format!(
            "cargo nextest run ({status}): no summary line (\"N tests run: ...\")"
        ));
    };
    if !status.success() {
        return Err(format!(
            "cargo nextest run --workspace: {failed} failed ({status})"
        ));
    }
    step("doc tests: cargo test --workspace --doc");
    let mut cmd = cargo();
    cmd.current_dir(root())
        .args(["test", "--workspace", "--doc"]);
    let (status, doc) = tally(&mut cmd, parse_test_result)?;
    if !status.success() {
        return Err(format!("cargo test --workspace --doc failed ({status})"));
    }
    let (dp, df, di) = doc.unwrap_or((0, 0, 0));
    Ok((passed + dp, failed + df, skipped + di))
}

fn ensure_nextest() -> Result<()> {
    let works = |c: &mut Command| c.output().is_ok_and(|o| o.status.success());
    if works(cargo().args(["nextest", "--version"])) {
        return Ok(());
    }
    step("installing cargo-nextest (cargo install)");
    let ok = cargo()
        .args(["install", "cargo-nextest", "--locked"])
        .status()
        .is_ok_and(|s| s.success());
    if ok && works(cargo().args(["nextest", "--version"])) {
        Ok(())
    } else {
        Err("cargo-nextest: not installed and `cargo install cargo-nextest --locked` failed".into())
    }
}

/// Runs `cmd` with its stdout and stderr shown as they come, and sums what
/// `parse` reads from their lines (`None`: no line parsed).
/// (passed, failed, skipped).
type Counts = (u64, u64, u64);

fn tally(
    cmd: &mut Command,
    parse: fn(&str) -> Option<Counts>,
) -> Result<(std::process::ExitStatus, Option<Counts>)> {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start {cmd:?}: {e}"))?;
    let err = child.stderr.take().ok_or("no stderr")?;
    // nextest reports on stderr, libtest on stdout: both are read, each on
    // its own thread so that neither pipe fills and stalls the run.
    let err_thread = std::thread::spawn(move || {
        let mut sum = None;
        for line in BufReader::new(err)
            .lines()
            .map_while(std::result::Result::ok)
        {
            eprintln!("{line}");
            add(&mut sum, parse(&line));
        }
        sum
    });
    let mut sum = None;
    let out = child.stdout.take().ok_or("no stdout")?;
    for line in BufReader::new(out)
        .lines()
        .map_while(std::result::Result::ok)
    {
        println!("{line}");
        add(&mut sum, parse(&line));
    }
    let status = child.wait().map_err(|e| format!("{cmd:?}: {e}"))?;
    add(
        &mut sum,
        err_thread.join().map_err(|_| "stderr reader panicked")?,
    );
    Ok((status, sum))
}

fn add(sum: &mut Option<Counts>, x: Option<Counts>) {
    if let Some((p, f, i)) = x {
        let s = sum.get_or_insert((0, 0, 0));
        *s = (s.0 + p, s.1 + f, s.2 + i);
    }
}

/// (passed, failed, skipped) of nextest's closing line, "Summary [ 1.2s]
/// 12 tests run: 10 passed, 1 failed, 1 timed out, 3 skipped" (a test that
/// timed out, crashed or leaked counts as failed).
pub fn parse_nextest_summary(line: &str) -> Option<(u64, u64, u64)> {
    let rest = line.trim_start().strip_prefix("Summary [")?;
    let (_, counts) = rest.split_once(" run: ")?;
    let (mut passed, mut failed, mut skipped) = (0, 0, 0);
    for part in counts.split(',') {
        let mut words = part.split_whitespace();
        let (Some(n), Some(what)) = (words.next(), words.next()) else {
            continue;
        };
        let Ok(n) = n.parse::<u64>() else { continue };
        match what {
            "passed" => passed += n,
            "skipped" => skipped += n,
            // "flaky" is among the passed already.
            "failed" | "timed" | "exec" | "leaky" => failed += n,
            _ => {}
        }
    }
    Some((passed, failed, skipped))
}

/// (passed, failed, ignored) of a libtest summary line,
/// "test result: ok. 11 passed; 0 failed; 0 ignored; 0 measured; ...".
pub fn parse_test_result(line: &str) -> Option<(u64, u64, u64)> {
    let rest = line.strip_prefix("test result: ")?;
    let (mut passed, mut failed, mut ignored) = (0, 0, 0);
    for part in rest.split(';') {
        let mut words = part.split_whitespace().rev();
        let (Some(what), Some(n)) = (words.next(), words.next()) else {
            continue;
        };
        let Ok(n) = n.parse::<u64>() else { continue };
        match what {
            "passed" => passed = n,
            "failed" => failed = n,
            "ignored" => ignored = n,
            _ => {}
        }
    }
    Some((passed, failed, ignored))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn test_result_lines_are_summed_by_field() {
        let l = "test result: FAILED. 11 passed; 2 failed; 3 ignored; 0 measured; 0 filtered out";
        assert_eq!(parse_test_result(l), Some((11, 2, 3)));
        assert_eq!(parse_test_result("running 3 tests"), None);
    }

    #[test]
    fn nextest_summaries_count_timeouts_and_crashes_as_failed() {
        let ok = "     Summary [  61.021s] 412 tests run: 412 passed, 3 skipped";
        assert_eq!(parse_nextest_summary(ok), Some((412, 0, 3)));
        let bad = "     Summary [ 480.5s] 12 tests run: 8 passed (1 slow), 2 failed, 1 timed out, 1 exec failed, 0 skipped";
        assert_eq!(parse_nextest_summary(bad), Some((8, 4, 0)));
        assert_eq!(parse_nextest_summary("        PASS [   0.1s] x"), None);
    }
}
