//! Traces as VCD, and the viewers' check of every VCD the project writes.
//!
//! * `zslide trace2vcd LOG --out FILE` (the user's command, host-sim's
//!   `trace2vcd`): a board's decoded defmt log with trace events → VCD
//!   (`host_sim::vcd::target`, the one decoder; the signal names are
//!   `zslide::trace::Signal`'s, the simulator's own).
//! * `cargo xtask qemu --vcd FILE`: the QEMU run built with its `trace`
//!   feature, which must pass the image's own checks (tracking, events,
//!   the injected fault), converted. Its numbers are not the snapshot's to
//!   the last code: the trace output is work in the loop-tick handler, so
//!   the event handler runs at other phases of the tick and a coefficient
//!   set can reach the loop a tick apart, as a probe's reads would shift a
//!   board's handlers.
//! * [`check_viewers`]: GTKWave's own converter (`vcd2fst`) reads the
//!   file, and libsigrok (`sigrok-cli -I vcd`, what PulseView uses) decodes
//!   its 1-bit lines with one `loop_tick` edge per loop-tick run. `cargo
//!   xtask test` runs it on the QEMU trace and on a host-sim machine VCD.

use crate::{
    cargo, default_table_path, qemu_dir, run_qemu_elf_echo, step, target_dir, QemuRegions, Result,
    TARGET,
};
use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

fn describe(vcd: &Path, s: &host_sim::vcd::target::TraceSummary) -> String {
    let names = ["loop tick", "X event", "index"];
    let mut out = format!(
        "{}: {} events over {:.6} s (clock {} Hz)",
        vcd.display(),
        s.events,
        s.span_s,
        s.clock_hz
    );
    for (k, name) in names.iter().enumerate() {
        if s.runs[k] > 0 {
            out.push_str(&format!(
                "; {name}: {} runs, longest {:.2} µs entry to exit",
                s.runs[k], s.longest_us[k]
            ));
        }
    }
    out
}

/// The log file → the VCD file.
pub fn convert(log: &Path, vcd: &Path) -> Result<host_sim::vcd::target::TraceSummary> {
    let input = File::open(log).map_err(|e| format!("{}: {e}", log.display()))?;
    let out = File::create(vcd).map_err(|e| format!("{}: {e}", vcd.display()))?;
    let mut w = BufWriter::new(out);
    let s = host_sim::vcd::target::convert(BufReader::new(input), &mut w)
        .map_err(|e| format!("trace {}: {e:#}", log.display()))?;
    w.flush().map_err(|e| format!("{}: {e}", vcd.display()))?;
    Ok(s)
}

/// Where the traced QEMU image is built (apart from the checked one, so
/// that neither build overwrites the other).
fn trace_target_dir() -> PathBuf {
    target_dir().join("qemu-trace")
}

/// Builds and runs the traced QEMU image, checks its log, writes the VCD
/// (and the decoded log beside it, `.log`). Returns a summary line and
/// what the trace held.
pub fn qemu_vcd(vcd: &Path) -> Result<(String, host_sim::vcd::target::TraceSummary)> {
    step("QEMU trace image: cargo build --release --features trace (boards/qemu)");
    let status = cargo()
        .current_dir(qemu_dir())
        .env("CARGO_TARGET_DIR", trace_target_dir())
        .args(["build", "--release", "--features", "trace"])
        .status()
        .map_err(|e| format!("cannot start cargo: {e}"))?;
    if !status.success() {
        return Err(format!("QEMU trace image build failed ({status})"));
    }
    let elf = trace_target_dir().join(TARGET).join("release/zslide-qemu");
    let table = default_table_path();
    let regions = QemuRegions {
        table: Some(&table),
        params: None,
    };
    step("QEMU run with trace events");
    let (code, lines) = run_qemu_elf_echo(&elf, &regions, &[], false)?;
    if code != 0 {
        return Err(format!("the traced QEMU image exited with status {code}"));
    }
    if !lines.iter().any(|l| l.ends_with("INFO  PASS")) {
        return Err("the traced QEMU image did not report PASS".into());
    }
    let log = vcd.with_extension("log");
    std::fs::write(&log, lines.join("\n") + "\n").map_err(|e| format!("{}: {e}", log.display()))?;
    let s = convert(&log, vcd)?;
    Ok((describe(vcd, &s), s))
}

/// What a viewer check found.
#[derive(Debug)]
pub struct ViewerReport {
    /// The 1-bit channels libsigrok decoded and their level changes.
    pub sigrok_edges: Vec<(String, usize)>,
}

impl ViewerReport {
    pub fn edges(&self, name: &str) -> Option<usize> {
        self.sigrok_edges
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, e)| *e)
    }
}

/// `vcd2fst` converts the file, and `sigrok-cli -I vcd` decodes its 1-bit
/// lines (sampled at 1 MHz); the edges per channel.
pub fn check_viewers(vcd: &Path) -> Result<ViewerReport> {
    let fst = vcd.with_extension("fst");
    let out = Command::new("vcd2fst")
        .arg(vcd)
        .arg(&fst)
        .output()
        .map_err(|e| format!("cannot start vcd2fst (Debian package gtkwave): {e}"))?;
    let len = std::fs::metadata(&fst).map_or(0, |m| m.len());
    let _ = std::fs::remove_file(&fst);
    if !out.status.success() || len == 0 {
        return Err(format!(
            "GTKWave's vcd2fst refused {}: {}{}",
            vcd.display(),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let out = Command::new("sigrok-cli")
        .args(["-I", "vcd:downsample=1000", "-i"])
        .arg(vcd)
        .args(["-O", "csv"])
        .output()
        .map_err(|e| format!("cannot start sigrok-cli (Debian package sigrok-cli): {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "sigrok-cli failed on {}: {}",
            vcd.display(),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(ViewerReport {
        sigrok_edges: csv_edges(&String::from_utf8_lossy(&out.stdout)),
    })
}

/// Level changes per channel of sigrok-cli's CSV output.
fn csv_edges(text: &str) -> Vec<(String, usize)> {
    let mut names: Vec<String> = Vec::new();
    let mut edges: Vec<usize> = Vec::new();
    let mut last: Option<Vec<&str>> = None;
    for line in text.lines() {
        if let Some(ch) = line.strip_prefix("; Channels") {
            let list = ch.split_once(':').map_or("", |(_, l)| l);
            names = list.split(',').map(|n| n.trim().to_string()).collect();
            edges = vec![0; names.len()];
            continue;
        }
        if line.starts_with(';') || line.starts_with("META") || line.starts_with("logic") {
            continue;
        }
        let row: Vec<&str> = line.split(',').collect();
        if let Some(prev) = &last {
            for (k, (a, b)) in prev.iter().zip(&row).enumerate() {
                if a != b {
                    if let Some(e) = edges.get_mut(k) {
                        *e += 1;
                    }
                }
            }
        }
        last = Some(row);
    }
    names.into_iter().zip(edges).collect()
}

/// The viewer check on both kinds of VCD: the QEMU run's trace (`vcd`,
/// with its loop-tick runs) and a host-sim machine VCD written here.
/// Returns a summary line; an error names the file and the viewer.
pub fn check_both(qemu_vcd: &Path, loop_runs: u64) -> Result<String> {
    step("VCD viewers: vcd2fst (GTKWave) and sigrok-cli (PulseView) on the QEMU and host-sim VCDs");
    let q = check_viewers(qemu_vcd)?;
    let qe = q.edges("loop_tick").unwrap_or(0) as u64;
    // one toggle per run; the first run's toggle is the first sample
    if qe + 1 < loop_runs || qe > loop_runs {
        return Err(format!(
            "{}: sigrok decoded {qe} loop_tick edges for {loop_runs} loop-tick runs",
            qemu_vcd.display()
        ));
    }
    let sim = qemu_vcd.with_file_name("host-sim-machine.vcd");
    let sc = host_sim::scenario::load("legacy-hw").map_err(|e| format!("{e:#}"))?;
    host_sim::cmd::bench::write_vcd(&sim, 20_000, &sc).map_err(|e| format!("{e:#}"))?;
    let h = check_viewers(&sim)?;
    // 250 ms at 20 kHz
    let he = h.edges("loop_tick").unwrap_or(0);
    if !(4998..=5000).contains(&he) {
        return Err(format!(
            "{}: sigrok decoded {he} loop_tick edges for 5000 loop ticks",
            sim.display()
        ));
    }
    Ok(format!(
        "GTKWave's vcd2fst reads both; sigrok-cli decodes {} 1-bit lines of the QEMU trace ({qe} loop_tick edges for {loop_runs} runs) and {} of host-sim's ({he} for 5000)",
        q.sigrok_edges.len(),
        h.sigrok_edges.len()
    ))
}
