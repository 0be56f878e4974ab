//! The QEMU image's decoded log against `boards/qemu/expected.log`.
//!
//! Every line is compared exactly (timestamps stripped) but for the
//! numbers that follow the emulated interleaving of the handlers: the
//! image runs under `-icount`, so which lower-priority handler runs between
//! two loop ticks follows the instruction count, and a change of code
//! size anywhere moves the gauge's sampled position by a code (git log of
//! expected.log: ticks 1600, 2400, 4000, 5601 and the tracking maximum
//! moved by one code in each re-bless for that reason alone). Those
//! numbers are compared within [`TOLERANCE`]; everything else (the
//! configuration, the table's identity, the scripted X, φ and table
//! command of each sampled tick, the event counts, the fault, PASS) must
//! match to the character. `--bless` rewrites the file and prints each
//! line it changes.

use std::fs;

use crate::{qemu_dir, Result};

/// The numbers the interleaving moves: (the line's prefix, the field's
/// label, the largest difference accepted). A sampled tick's position: ±2
/// codes (twice the one code seen; 0.04 µin). Its DAC code: the loop's
/// gains on that: kd ≈ 3.2 codes of DAC per code of position moved within
/// a tick, kp ≈ 0.06: ±8. The tracking maximum: the positions' ±2.
pub const TOLERANCE: [(&str, &str, i64); 3] = [
    ("INFO  tick ", "position", 2),
    ("INFO  tick ", "dac", 8),
    ("INFO  tracking: ", "=", 2),
];

/// A decoded log line without its timestamp (the first field).
pub fn strip_timestamp(line: &str) -> &str {
    match line.split_once(' ') {
        Some((t, rest)) if t.chars().all(|c| c.is_ascii_digit() || c == '.') => rest,
        _ => line,
    }
}

/// The integer after `label` in `line` (`label` followed by a space).
fn field(line: &str, label: &str) -> Option<(usize, i64)> {
    let at = line.find(&format!("{label} "))? + label.len() + 1;
    let rest = &line[at..];
    let end = rest
        .char_indices()
        .find(|&(i, c)| !(c.is_ascii_digit() || (i == 0 && c == '-')))
        .map_or(rest.len(), |(i, _)| i);
    Some((at, rest[..end].parse().ok()?))
}

/// `line` with the tolerated fields blanked, and those fields' values.
fn split(line: &str) -> (String, Vec<(&'static str, i64, i64)>) {
    let mut masked = line.to_string();
    let mut values = Vec::new();
    for (prefix, label, tol) in TOLERANCE {
        if !line.starts_with(prefix) {
            continue;
        }
        if let Some((at, v)) = field(&masked, label) {
            let len = v.to_string().len();
            masked.replace_range(at..at + len, "#");
            values.push((label, v, tol));
        }
    }
    (masked, values)
}

/// Why `got` does not match `want` (`None`: it does, within tolerance).
pub fn line_differs(want: &str, got: &str) -> Option<String> {
    if want == got {
        return None;
    }
    let ((w, wv), (g, gv)) = (split(want), split(got));
    if w != g || wv.len() != gv.len() {
        return Some("differs outside the tolerated fields".into());
    }
    let out: Vec<String> = wv
        .iter()
        .zip(&gv)
        .filter(|((_, a, tol), (_, b, _))| (a - b).abs() > *tol)
        .map(|((label, a, tol), (_, b, _))| format!("{label} {b} is {a} ± {tol}"))
        .collect();
    (!out.is_empty()).then(|| out.join(", "))
}

/// Every difference between the snapshot `want` and the log `got`, each
/// "line N: why\n  expected: ..\n  got: .." (empty: they match).
pub fn differences(want: &[&str], got: &[&str]) -> Vec<String> {
    let mut out = Vec::new();
    for (i, (w, g)) in want.iter().zip(got).enumerate() {
        if let Some(why) = line_differs(w, g) {
            out.push(format!(
                "line {}: {why}\n    expected: {w}\n    got:      {g}",
                i + 1
            ));
        }
    }
    if want.len() != got.len() {
        out.push(format!("expected {} lines, got {}", want.len(), got.len()));
    }
    out
}

/// The lines `--bless` changes, as a unified-style list ("-old", "+new").
fn changes(want: &[&str], got: &[&str]) -> Vec<String> {
    let mut out = Vec::new();
    for i in 0..want.len().max(got.len()) {
        let (w, g) = (want.get(i), got.get(i));
        if w != g {
            out.push(format!("line {}:", i + 1));
            if let Some(w) = w {
                out.push(format!("- {w}"));
            }
            if let Some(g) = g {
                out.push(format!("+ {g}"));
            }
        }
    }
    out
}

/// Checks the run's decoded `lines` against the snapshot, or with `bless`
/// rewrites it and prints what changed.
pub fn check(lines: &[String], bless: bool) -> Result<()> {
    let path = qemu_dir().join("expected.log");
    let got: Vec<&str> = lines.iter().map(|l| strip_timestamp(l)).collect();
    let text = got.join("\n") + "\n";
    let old = fs::read_to_string(&path).unwrap_or_default();
    let want: Vec<&str> = old.lines().collect();
    if bless {
        let changed = changes(&want, &got);
        if changed.is_empty() {
            eprintln!("{}: unchanged", path.display());
            return Ok(());
        }
        fs::write(&path, &text).map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("rewrote {}:", path.display());
        for c in changed {
            eprintln!("  {c}");
        }
        return Ok(());
    }
    if old.is_empty() {
        return Err(format!("{}: missing or empty", path.display()));
    }
    let diffs = differences(&want, &got);
    if diffs.is_empty() {
        eprintln!(
            "QEMU log matches {} ({} lines; sampled positions, DAC codes and the tracking maximum within {:?})",
            path.display(),
            got.len(),
            TOLERANCE.map(|(_, l, t)| format!("{l} ±{t}"))
        );
        return Ok(());
    }
    let mut msg = format!("QEMU log differs from {}:", path.display());
    for d in diffs {
        msg.push_str("\n  ");
        msg.push_str(&d);
    }
    msg.push_str(
        "\n  (if the change is intended: cargo xtask qemu --bless, which prints what it changes)",
    );
    Err(msg)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TICK: &str =
        "INFO  tick 2400: X 34200355 phi 1403414118 table -17447  command -17447  position -17483  dac 1181";
    const TRACK: &str = "INFO  tracking: max |command - position| = 469 codes over ticks 1001..=5600 (bound 500; 1 code = 0.019 uin); fault None";

    #[test]
    fn timestamps_are_stripped_only_when_present() {
        assert_eq!(strip_timestamp("0.200019 INFO  PASS"), "INFO  PASS");
        assert_eq!(strip_timestamp("INFO  tick 1: x"), "INFO  tick 1: x");
    }

    #[test]
    fn sampled_positions_and_dac_codes_match_within_their_tolerance_only() {
        assert_eq!(line_differs(TICK, TICK), None);
        let moved = TICK
            .replace("-17483", "-17485")
            .replace("dac 1181", "dac 1173");
        assert_eq!(line_differs(TICK, &moved), None);
        let too_far = TICK.replace("-17483", "-17486");
        assert_eq!(
            line_differs(TICK, &too_far).as_deref(),
            Some("position -17486 is -17483 ± 2")
        );
        let dac = TICK.replace("dac 1181", "dac 1190");
        assert!(line_differs(TICK, &dac).unwrap().contains("dac 1190"));
        // The scripted fields are exact.
        for (a, b) in [
            ("X 34200355", "X 34200356"),
            ("table -17447", "table -17446"),
            ("command -17447", "command -17448"),
        ] {
            assert!(line_differs(TICK, &TICK.replace(a, b)).is_some(), "{b}");
        }
    }

    #[test]
    fn the_tracking_maximum_is_tolerated_and_the_rest_of_its_line_is_exact() {
        assert_eq!(line_differs(TRACK, &TRACK.replace("469", "467")), None);
        assert!(line_differs(TRACK, &TRACK.replace("469", "472")).is_some());
        assert!(line_differs(TRACK, &TRACK.replace("bound 500", "bound 501")).is_some());
        assert!(line_differs(TRACK, &TRACK.replace("None", "Some(Panic)")).is_some());
    }

    #[test]
    fn structural_lines_are_exact_and_a_missing_line_is_reported() {
        let want = ["INFO  index events: 6 (scripted 6)", "INFO  PASS"];
        assert!(differences(&want, &want).is_empty());
        let got = ["INFO  index events: 7 (scripted 6)", "INFO  PASS"];
        assert_eq!(differences(&want, &got).len(), 1);
        let short = ["INFO  index events: 6 (scripted 6)"];
        assert_eq!(differences(&want, &short), ["expected 2 lines, got 1"]);
    }

    #[test]
    fn bless_lists_each_changed_line_old_and_new() {
        let c = changes(&["a", "b"], &["a", "c", "d"]);
        assert_eq!(c, ["line 2:", "- b", "+ c", "line 3:", "+ d"]);
    }
}
