//! `cargo xtask isr-cost [--json] [--variant V] [--profile R [--call N]]`: instructions per interrupt handler of the
//! QEMU image (Cortex-M4F), counted from an execution trace.
//!
//! DWT CYCCNT reads 0 under QEMU, so the count comes from QEMU itself:
//! `-d exec,nochain` with one instruction per translation block logs every
//! executed instruction's PC. A call of a measured function starts when the
//! PC reaches its first address; it ends when the PC is back in the function
//! that was running just before (the caller, or for an exception handler the
//! interrupted code). Everything in between is counted, callees included,
//! except the instructions of a measured exception handler that preempted
//! it (the loop tick preempting an X event counts for the loop tick only). Instruction counts, not cycles: a Cortex-M4 needs about 1.2-1.5
//! cycles per instruction on such code, plus 12 cycles of exception entry.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::time::Instant;

use crate::elf::{self, Symbol};

/// Which image variants hold an entry point.
#[derive(Clone, Copy, PartialEq, Eq)]
enum In {
    Both,
    /// The plain image only (legacy X events).
    Legacy,
    /// The `modern-x` image only (X count events).
    Modern,
}

/// What to measure: report name, a predicate on symbol names, and the
/// variants that must hold it.
const TARGETS: [(&str, &str, In); 7] = [
    // The firmware's entry points (monomorphised in the QEMU image): the
    // loop tick with its converter drivers, the legacy X event, the modern
    // X count event, the index, the learning (all its pending samples).
    ("loop_tick", "9LoopState9loop_tick", In::Both),
    ("x_event", "10EventState7x_event", In::Legacy),
    ("x_count_event", "10EventState13x_count_event", In::Modern),
    ("index_event", "10EventState11index_event", In::Both),
    ("learn", "10LearnState3run", In::Both),
    // The whole timer handlers: timer 0 = loop tick plus the slide model's
    // step (the simulated world, not firmware) and the board glue; timer 1 =
    // the synthetic machine's event playback around the X and index events.
    ("TIMER0_handler_with_plant", "TIMER0", In::Both),
    ("TIMER1_handler_with_machine", "TIMER1", In::Both),
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

/// Image variants measured: the `boards/qemu` cargo features, the suffix
/// of their report names and which targets they hold. The modern X mode (X
/// count re-interpolated by the X handler) first, so the plain (legacy X)
/// image is the one left built.
const VARIANTS: [(Option<&str>, &str, In); 2] = [
    (Some("modern-x"), "_modern", In::Modern),
    (None, "", In::Legacy),
];

#[derive(clap::Args, Debug)]
pub struct Args {
    /// One JSON object on stdout instead of the table.
    #[arg(long)]
    json: bool,
    /// Trace one image only: `legacy` (legacy X) or `modern` (modern X).
    #[arg(long, value_name = "V", value_parser = ["legacy", "modern"])]
    variant: Option<String>,
    /// Also print this report's count per call and its executions per
    /// instruction address (stderr), e.g. `x_event`.
    #[arg(long, value_name = "REPORT", value_parser = clap::builder::PossibleValuesParser::new(REPORTS))]
    profile: Option<String>,
    /// With --profile: the per-address histogram of call N only (from 0).
    #[arg(long, value_name = "N", requires = "profile")]
    call: Option<u64>,
}

/// Report names `--profile` accepts: each target in each variant that
/// holds it.
const REPORTS: [&str; 12] = [
    "loop_tick",
    "x_event",
    "index_event",
    "learn",
    "TIMER0_handler_with_plant",
    "TIMER1_handler_with_machine",
    "loop_tick_modern",
    "x_count_event_modern",
    "index_event_modern",
    "learn_modern",
    "TIMER0_handler_with_plant_modern",
    "TIMER1_handler_with_machine_modern",
];

pub fn run(args: &Args) -> Result<u8, String> {
    crate::require_for_qemu()?;
    let mut stats: BTreeMap<String, Stats> = BTreeMap::new();
    for (features, suffix, _) in VARIANTS {
        let name = if suffix.is_empty() {
            "legacy"
        } else {
            "modern"
        };
        if args.variant.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        match features {
            Some(f) => crate::build_qemu_image_with(f)?,
            None => crate::build_qemu_image()?,
        }
        stats.extend(measure(name, suffix, args)?);
    }
    let sizes = elf::sizes(&crate::qemu_elf())?;

    if args.json {
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

/// Runs the image built last under an execution trace; reports named with
/// `suffix` appended.
fn measure(variant: &str, suffix: &str, args: &Args) -> Result<BTreeMap<String, Stats>, String> {
    let elf_path = crate::qemu_elf();
    let mut funcs: Vec<Symbol> = elf::functions(&elf_path)?
        .into_iter()
        .filter(|f| f.size > 0)
        .collect();
    funcs.sort_by_key(|f| f.addr);
    funcs.dedup_by_key(|f| f.addr);
    let mut targets: BTreeMap<u32, String> = BTreeMap::new();
    let holds = VARIANTS
        .iter()
        .find(|v| v.1 == suffix)
        .map_or(In::Both, |v| v.2);
    for (report, pattern, only) in TARGETS {
        if only != In::Both && only != holds {
            continue;
        }
        let found = funcs
            .iter()
            .find(|f| f.name == pattern || (pattern.len() > 8 && f.name.contains(pattern)));
        let Some(f) = found else {
            return Err(format!(
                "isr-cost: no function `{pattern}` in the {variant} image"
            ));
        };
        targets.insert(f.addr, format!("{report}{suffix}"));
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
    eprintln!(
        "isr-cost: {variant} image: running under QEMU with an instruction trace \
         (about a minute; progress every 10 s)"
    );
    let started = Instant::now();
    let mut last_report = started;
    let mut traced: u64 = 0;
    let mut child = cmd
        .spawn()
        .map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    let trace = child.stderr.take().ok_or("no QEMU stderr")?;

    let mut stats: BTreeMap<String, Stats> = BTreeMap::new();
    // Open measurements: (report, caller range start, caller range end, count).
    let mut open: Vec<(&str, u32, u32, u64)> = Vec::new();
    let mut prev_pc: Option<u32> = None;
    // `--profile <report>`: that report's count per call and its
    // executions per instruction address (to stderr), for finding where a
    // handler's budget goes; `--call <n>` limits the histogram to call n.
    let profile = args.profile.clone();
    let mut histogram: BTreeMap<u32, u64> = BTreeMap::new();
    for line in BufReader::new(trace).lines().map_while(Result::ok) {
        // "Trace 0: 0x7f.. [00800408/000024ae/00000110/ff020201] name"
        let Some(pc) = line
            .split_once('[')
            .and_then(|(_, r)| r.split('/').nth(1))
            .and_then(|h| u32::from_str_radix(h, 16).ok())
        else {
            continue;
        };
        traced += 1;
        if traced.is_multiple_of(1 << 20) && last_report.elapsed().as_secs() >= 10 {
            last_report = Instant::now();
            let calls: u64 = stats.values().map(|s| s.calls).sum();
            eprintln!(
                "isr-cost: {variant} image: {:.0} M instructions traced, {calls} handler calls measured, {:.0} s",
                traced as f64 / 1e6,
                started.elapsed().as_secs_f64()
            );
        }
        // Close measurements whose caller is running again (innermost first).
        while let Some(&(report, lo, hi, n)) = open.last() {
            if pc >= lo && pc < hi {
                open.pop();
                let s = stats.entry(report.to_string()).or_default();
                if profile.as_deref() == Some(report) {
                    eprintln!("  call {} {n}", s.calls);
                }
                s.calls += 1;
                s.total += n;
                s.max = s.max.max(n);
                s.min = if s.calls == 1 { n } else { s.min.min(n) };
            } else {
                break;
            }
        }
        // Every open measurement counts the instruction, down to (and
        // including) the innermost exception handler: a handler that
        // preempted a measured function is not that function's cost.
        for m in open.iter_mut().rev() {
            m.3 += 1;
            if profile.as_deref() == Some(m.0) {
                let call = stats.get(m.0).map_or(0, |s| s.calls);
                if args.call.is_none_or(|c| c == call) {
                    *histogram.entry(pc).or_default() += 1;
                }
            }
            if m.0.starts_with("TIMER") {
                break;
            }
        }
        if let Some(report) = targets.get(&pc) {
            let caller = prev_pc.and_then(|p| find(&funcs, p));
            if let Some(c) = caller {
                if !(pc >= c.addr && pc < c.addr + c.size) {
                    open.push((report.as_str(), c.addr, c.addr + c.size, 1));
                }
            }
        }
        prev_pc = Some(pc);
    }
    let status = child.wait().map_err(|e| format!("qemu: {e}"))?;
    eprintln!(
        "isr-cost: {variant} image: done, {:.0} M instructions traced in {:.0} s",
        traced as f64 / 1e6,
        started.elapsed().as_secs_f64()
    );
    if !status.success() {
        return Err(format!("the QEMU image failed under tracing ({status})"));
    }
    if let Some(p) = &profile {
        // With --call the histogram holds that one call: no averaging.
        let calls = match args.call {
            Some(_) => 1,
            None => stats.get(p.as_str()).map_or(1, |s| s.calls.max(1)),
        };
        eprintln!(
            "isr-cost profile of {p} ({}): address, executions per call, function",
            match args.call {
                Some(n) => format!("call {n}"),
                None => format!("{calls} calls"),
            }
        );
        for (pc, n) in &histogram {
            let f = find(&funcs, *pc).map_or("?", |f| f.name.as_str());
            eprintln!("  {pc:#010x} {:8.2}  {f}", *n as f64 / calls as f64);
        }
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_reports_are_every_target_in_every_variant() {
        let mut want: Vec<String> = VARIANTS
            .iter()
            .flat_map(|&(_, suffix, holds)| {
                TARGETS
                    .iter()
                    .filter(move |t| t.2 == In::Both || t.2 == holds)
                    .map(move |(r, _, _)| format!("{r}{suffix}"))
            })
            .collect();
        let mut got: Vec<String> = REPORTS.iter().map(|r| r.to_string()).collect();
        want.sort();
        got.sort();
        assert_eq!(got, want);
    }
}
