//! `cargo xtask isr-cost [--json]`: instructions per interrupt handler of the
//! QEMU image (Cortex-M4F), counted from an execution trace.
//!
//! DWT CYCCNT reads 0 under QEMU, so the count comes from QEMU itself:
//! `-d exec,nochain` with one instruction per translation block logs every
//! executed instruction's PC. A call of a measured function starts when the
//! PC reaches its first address; it ends when the PC is back in the function
//! that was running just before (the caller, or for an exception handler the
//! interrupted thread code). Everything in between is counted, callees
//! included. Instruction counts, not cycles: a Cortex-M4 needs about 1.2-1.5
//! cycles per instruction on such code, plus 12 cycles of exception entry.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::process::Stdio;

use crate::elf::{self, Symbol};

/// What to measure: report name, and a predicate on symbol names.
const TARGETS: [(&str, &str); 2] = [
    // The firmware's loop tick (monomorphised in the QEMU image).
    ("loop_tick", "8firmware8Firmware9loop_tick"),
    // The whole timer-0 handler: loop tick plus the slide model's step
    // (the simulated world, not firmware) and the board glue.
    ("TIMER0_handler_with_plant", "TIMER0"),
];

#[derive(Default)]
struct Stats {
    calls: u64,
    total: u64,
    max: u64,
    min: u64,
}

fn find(funcs: &[Symbol], pc: u32) -> Option<&Symbol> {
    // `funcs` is sorted by address; the last one starting at or below pc.
    let i = funcs.partition_point(|f| f.addr <= pc);
    let f = funcs.get(i.checked_sub(1)?)?;
    (pc < f.addr + f.size.max(2)).then_some(f)
}

fn qemu_major() -> u32 {
    crate::output_of("qemu-system-arm", &["--version"])
        .and_then(|v| {
            v.split("version ")
                .nth(1)
                .and_then(|r| r.split('.').next())
                .and_then(|m| m.trim().parse().ok())
        })
        .unwrap_or(0)
}

pub fn run(json: bool) -> Result<u8, String> {
    crate::require_for_qemu()?;
    crate::build_qemu_image()?;
    let elf_path = crate::qemu_elf();
    let mut funcs: Vec<Symbol> = elf::functions(&elf_path)?
        .into_iter()
        .filter(|f| f.size > 0)
        .collect();
    funcs.sort_by_key(|f| f.addr);
    funcs.dedup_by_key(|f| f.addr);
    let mut targets: BTreeMap<u32, &str> = BTreeMap::new();
    for (report, pattern) in TARGETS {
        let f = funcs
            .iter()
            .find(|f| f.name == pattern || (pattern.len() > 8 && f.name.contains(pattern)))
            .ok_or_else(|| format!("isr-cost: no function `{pattern}` in the image"))?;
        targets.insert(f.addr, report);
    }

    let mut cmd = crate::qemu_command(&elf_path);
    if qemu_major() >= 8 {
        cmd.args(["-accel", "tcg,one-insn-per-tb=on"]);
    } else {
        cmd.arg("-singlestep");
    }
    cmd.args(["-d", "exec,nochain"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    eprintln!("isr-cost: running the QEMU image with an execution trace");
    let mut child = cmd
        .spawn()
        .map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    let trace = child.stderr.take().ok_or("no QEMU stderr")?;

    let mut stats: BTreeMap<&str, Stats> = BTreeMap::new();
    // Open measurements: (report, caller range start, caller range end, count).
    let mut open: Vec<(&str, u32, u32, u64)> = Vec::new();
    let mut prev_pc: Option<u32> = None;
    for line in BufReader::new(trace).lines().map_while(Result::ok) {
        // "Trace 0: 0x7f.. [00800408/000024ae/00000110/ff020201] name"
        let Some(pc) = line
            .split_once('[')
            .and_then(|(_, r)| r.split('/').nth(1))
            .and_then(|h| u32::from_str_radix(h, 16).ok())
        else {
            continue;
        };
        // Close measurements whose caller is running again (innermost first).
        while let Some(&(report, lo, hi, n)) = open.last() {
            if pc >= lo && pc < hi {
                open.pop();
                let s = stats.entry(report).or_default();
                s.calls += 1;
                s.total += n;
                s.max = s.max.max(n);
                s.min = if s.calls == 1 { n } else { s.min.min(n) };
            } else {
                break;
            }
        }
        for m in open.iter_mut() {
            m.3 += 1;
        }
        if let Some(&report) = targets.get(&pc) {
            let caller = prev_pc.and_then(|p| find(&funcs, p));
            if let Some(c) = caller {
                if !(pc >= c.addr && pc < c.addr + c.size) {
                    open.push((report, c.addr, c.addr + c.size, 1));
                }
            }
        }
        prev_pc = Some(pc);
    }
    let status = child.wait().map_err(|e| format!("qemu: {e}"))?;
    if !status.success() {
        return Err(format!("the QEMU image failed under tracing ({status})"));
    }
    let sizes = elf::sizes(&elf_path)?;

    if json {
        let mut out = String::from("{");
        for (i, (name, s)) in stats.iter().enumerate() {
            let mean = s.total.checked_div(s.calls).unwrap_or(0);
            out.push_str(&format!(
                "{}\"{name}\": {{\"max\": {}, \"mean\": {mean}, \"min\": {}, \"calls\": {}}}",
                if i > 0 { ", " } else { "" },
                s.max,
                s.min,
                s.calls
            ));
        }
        out.push_str(&format!(
            ", \"image\": \"zslide-qemu (Cortex-M4F)\", \"unit\": \"instructions\", \
             \"flash_bytes\": {}, \"ram_bytes\": {}}}",
            sizes.flash(),
            sizes.ram()
        ));
        println!("{out}");
    } else {
        println!("instructions per call, QEMU mps2-an386 image (Cortex-M4F):");
        for (name, s) in &stats {
            let mean = s.total.checked_div(s.calls).unwrap_or(0);
            println!(
                "  {name:28} max {:6}  mean {:6}  min {:6}  calls {}",
                s.max, mean, s.min, s.calls
            );
        }
        println!(
            "image: flash {} B, static RAM {} B",
            sizes.flash(),
            sizes.ram()
        );
    }
    Ok(0)
}
