//! The table-region runs of `cargo xtask test`: the QEMU image with other
//! tables in its region (QEMU's `-device loader`): a second part gives
//! other commands, each the host's own computation from that file; a
//! corrupt table and a missing one are refused in words, slide at null.

use std::fs;
use std::path::{Path, PathBuf};

use zslide::table::CoeffTable;

use crate::link::CODES_PER_UIN;
use crate::regions::{check_table_file, QEMU};
use crate::Result;

/// (tick, X bits, φ, table command) of the image's trace lines.
fn traced(lines: &[String]) -> Vec<(u32, i32, u32, i32)> {
    lines
        .iter()
        .filter_map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let at = w.iter().position(|&x| x == "tick")?;
            let n = |k: usize| w.get(at + k);
            if n(2) != Some(&"X") || n(4) != Some(&"phi") || n(6) != Some(&"table") {
                return None;
            }
            Some((
                n(1)?.trim_end_matches(':').parse().ok()?,
                n(3)?.parse().ok()?,
                n(5)?.parse().ok()?,
                n(7)?.parse().ok()?,
            ))
        })
        .collect()
}

/// Each traced table command against the host's computation from `file`
/// (the same fixed-point command path): within one code.
fn recompute(file: &Path, trace: &[(u32, i32, u32, i32)]) -> Result<()> {
    let bytes = fs::read(file).map_err(|e| e.to_string())?;
    let t = CoeffTable::parse(&bytes).map_err(|e| e.to_string())?;
    let gen = zslide::command::CommandGen::new(t);
    for &(tick, x, phi, code) in trace {
        if phi == 0 && code == 0 {
            continue; // before the first index: null command
        }
        let z = gen
            .z(
                zslide::units::XInches::from_bits(x),
                zslide::units::SpindleAngle(phi),
            )
            .map_err(|f| format!("tick {tick}: {f}"))?;
        let want = zslide::firmware::gauge_code_from_z(z);
        if (want - code).abs() > 1 {
            return Err(format!(
                "{}: tick {tick}: the image commanded {code} codes, the host computes {want} from this table",
                file.display()
            ));
        }
    }
    Ok(())
}

/// The table-region runs of `cargo xtask test`; `default_log` is the log
/// of the plain run (the default table). Returns the checks passed.
pub fn qemu_table_checks(default_log: &[String]) -> Result<u32> {
    crate::step("QEMU table region: a second part, a corrupt table, no table");
    let default = crate::default_table_path();
    let other = crate::root().join("tables/short-focus.zsct");
    let mut passed = 0;

    let a = traced(default_log);
    recompute(&default, &a)?;
    let (code, log) = crate::run_qemu_with(Some(&other))?;
    if code != 0 {
        return Err(format!(
            "the QEMU image with {} exited {code}",
            other.display()
        ));
    }
    let b = traced(&log);
    recompute(&other, &b)?;
    let id = check_table_file(&other, &QEMU)?;
    if !log
        .iter()
        .any(|l| l.contains(&format!("CRC {:#010x}", id.crc)) && l.contains("table:"))
    {
        return Err("the QEMU image did not report the second table's CRC".into());
    }
    // Same ticks, same X and φ (the same synthetic machine), other commands.
    let mut largest = 0;
    for (p, q) in a.iter().zip(&b) {
        if (p.0, p.1, p.2) != (q.0, q.1, q.2) {
            return Err(format!("the two runs traced other points: {p:?} / {q:?}"));
        }
        largest = largest.max((p.3 - q.3).abs());
    }
    if a.len() < 10 || largest < 10_000 {
        return Err(format!(
            "the two tables' commands differ by at most {largest} codes over {} points",
            a.len()
        ));
    }
    eprintln!(
        "table swap: {} traced commands of each table as the host computes them from its file; they differ by up to {largest} codes ({:.0} µin)",
        a.len(),
        f64::from(largest) / CODES_PER_UIN
    );
    passed += 3;

    let dir = crate::root().join("target/table-checks");
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let mut bad = fs::read(&default).map_err(|e| e.to_string())?;
    bad[3000] ^= 0x5A;
    let corrupt = dir.join("corrupt.zsct");
    fs::write(&corrupt, &bad).map_err(|e| e.to_string())?;
    let host = check_table_file(&corrupt, &QEMU).unwrap_err();
    if !host.contains("corrupt.zsct: table refused: the coefficients are corrupt") {
        return Err(format!("host refusal lacks the file or the words: {host}"));
    }
    for (table, words) in [
        (
            Some(&corrupt),
            "the coefficients are corrupt: their CRC says",
        ),
        (None, "no coefficient table in the table region"),
    ] {
        let (code, log) = crate::run_qemu_with(table.map(PathBuf::as_path))?;
        let said = log.iter().any(|l| {
            l.contains("coefficient table refused, slide held at null") && l.contains(words)
        });
        let held = log
            .iter()
            .any(|l| l.contains("refused table: table command 0..0"));
        if code != 0 || !said || !held {
            return Err(format!(
                "QEMU with {}: exit {code}, reason in words {said}, slide held at null {held}",
                table.map_or("no table".into(), |t| t.display().to_string())
            ));
        }
        eprintln!(
            "{}: refused in words, slide held at null",
            table.map_or("no table".into(), |t| t.display().to_string())
        );
        passed += 1;
    }
    Ok(passed + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trace_lines_are_read_by_field() {
        let l = vec![
            "INFO  tick 100: X 33571209 phi 114923929 table -813  command -30160  position -36674  dac 1054".to_string(),
            "INFO  something else".into(),
        ];
        assert_eq!(traced(&l), vec![(100, 33_571_209, 114_923_929, -813)]);
    }
}
