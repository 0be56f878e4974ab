//! `cargo xtask isr-cost [--json] [--variant V] [--profile R [--call N]]`:
//! instructions per interrupt handler of the QEMU image (Cortex-M4F),
//! counted from an execution trace.
//!
//! DWT CYCCNT reads 0 under QEMU, so the count comes from QEMU itself:
//! `-d exec,nochain` with one instruction per translation block logs every
//! executed instruction's PC, and `-d int` every exception entry and
//! return. A call of a measured function starts when the PC reaches its
//! first address; it ends when the PC is back in the function that was
//! running just before (its caller); a measured exception handler's call
//! ends at its exception return (also when the core tail-chains into the
//! next handler without running the interrupted code in between).
//! Everything in between is counted, callees included, except the
//! instructions of an exception that preempted it (the loop tick
//! preempting an X event counts for the loop tick only). Instruction
//! counts, not cycles: a Cortex-M4 needs about 1.2-1.5 cycles per
//! instruction on such code, plus 12 cycles of exception entry.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::time::Instant;

use crate::elf::{self, Symbol};
use crate::stack::{self, Depth, EXCEPTION_FRAME_BYTES};

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
const TARGETS: [(&str, &str, In); 10] = [
    // The firmware's entry points (monomorphised in the QEMU image): the
    // loop tick with its converter drivers, the legacy X event, the modern
    // X count event, the index, the learning (all its pending samples).
    ("loop_tick", "9LoopState9loop_tick", In::Both),
    ("x_event", "10EventState7x_event", In::Legacy),
    ("x_count_event", "10EventState13x_count_event", In::Modern),
    ("index_event", "10EventState11index_event", In::Both),
    ("learn", "10LearnState3run", In::Both),
    // The host link's part of the loop tick (zslide::link::tap), called by
    // the board right after loop_tick: not inside the loop_tick count.
    ("link_tap", "7TickTap10after_tick", In::Both),
    // The background's steps (thread mode, preempted by every handler;
    // each call counts its own instructions only): the host link's
    // station (`poll_with_store`, which `poll` calls with no store), every
    // call of the run (each monomorphisation: the checked
    // run's scripted host and the UART session), and the servo design a
    // parameter set runs inside it (measured at boot, `params::at_boot`).
    // The watchdog's timeout must hold the longest with the handlers' load
    // (docs/SAFETY.md, "Fault campaign").
    (
        "station_poll",
        "7station16Station$LT$_$GT$15poll_with_store",
        In::Both,
    ),
    ("servo_design", "11ServoDesign6config", In::Both),
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
const REPORTS: [&str; 18] = [
    "loop_tick",
    "x_event",
    "index_event",
    "link_tap",
    "learn",
    "station_poll",
    "servo_design",
    "TIMER0_handler_with_plant",
    "TIMER1_handler_with_machine",
    "loop_tick_modern",
    "x_count_event_modern",
    "index_event_modern",
    "link_tap_modern",
    "learn_modern",
    "station_poll_modern",
    "servo_design_modern",
    "TIMER0_handler_with_plant_modern",
    "TIMER1_handler_with_machine_modern",
];

pub fn run(args: &Args) -> Result<u8, String> {
    crate::require_for_qemu()?;
    let mut stats: BTreeMap<String, Stats> = BTreeMap::new();
    let mut depths: BTreeMap<String, Depth> = BTreeMap::new();
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
        let (s, d) = measure(name, suffix, args)?;
        stats.extend(s);
        depths.extend(d);
    }
    let sizes = elf::sizes(&crate::qemu_elf())?;

    // The stack entry: bytes, or null with the reason there is no bound.
    let stack_json = |name: &str| match depths.get(name) {
        Some(Depth::Bytes(b)) => format!("\"stack_bytes\": {b}"),
        Some(Depth::Recursion(f)) => {
            format!("\"stack_bytes\": null, \"stack\": \"recursion via {f}\"")
        }
        Some(Depth::Dynamic(f)) => {
            format!("\"stack_bytes\": null, \"stack\": \"SP set by a register in {f}\"")
        }
        None => "\"stack_bytes\": null".to_string(),
    };
    let stack_text = |name: &str| match depths.get(name) {
        Some(Depth::Bytes(b)) => format!("{b:6} B"),
        Some(Depth::Recursion(f)) => format!("unbounded (recursion via {f})"),
        Some(Depth::Dynamic(f)) => format!("unbounded (SP set by a register in {f})"),
        None => "?".to_string(),
    };
    if args.json {
        let mut out = String::from("{");
        for (i, (name, s)) in stats.iter().enumerate() {
            let mean = s.total.checked_div(s.calls).unwrap_or(0);
            out.push_str(&format!(
                "{}\"{name}\": {{\"max\": {}, \"mean\": {mean}, \"min\": {}, \"calls\": {}, {}}}",
                if i > 0 { ", " } else { "" },
                s.max,
                s.min,
                s.calls,
                stack_json(name)
            ));
        }
        out.push_str(&format!(
            ", \"image\": \"zslide-qemu (Cortex-M4F)\", \"unit\": \"instructions\", \
             \"flash_bytes\": {}, \"ram_bytes\": {}, \"exception_frame_bytes\": {}, \
             \"stack_method\": \"static: SP decrements of each function's code, worst path of the call graph\"}}",
            sizes.flash(),
            sizes.ram(),
            EXCEPTION_FRAME_BYTES
        ));
        println!("{out}");
    } else {
        println!(
            "instructions per call and worst-case stack depth (own frames and callees, from the code; \
             plus {EXCEPTION_FRAME_BYTES} B of exception frame for a handler), QEMU mps2-an386 image (Cortex-M4F):"
        );
        for (name, s) in &stats {
            let mean = s.total.checked_div(s.calls).unwrap_or(0);
            println!(
                "  {name:28} max {:6}  mean {:6}  min {:6}  calls {:5}  stack {}",
                s.max,
                mean,
                s.min,
                s.calls,
                stack_text(name)
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
/// Per report: instructions per call, and the worst-case stack depth.
type Measured = (BTreeMap<String, Stats>, Vec<(String, Depth)>);

fn measure(variant: &str, suffix: &str, args: &Args) -> Result<Measured, String> {
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
        // Every function matching (a generic one has a copy per
        // instantiation), into one report.
        let mut found = funcs
            .iter()
            .filter(|f| f.name == pattern || (pattern.len() > 8 && f.name.contains(pattern)))
            .peekable();
        if found.peek().is_none() {
            return Err(format!(
                "isr-cost: no function `{pattern}` in the {variant} image"
            ));
        }
        for f in found {
            targets.insert(f.addr, format!("{report}{suffix}"));
        }
    }
    // The worst-case stack depth of each entry point, from the code.
    let named: Vec<(String, &str)> = TARGETS
        .iter()
        .filter(|t| t.2 == In::Both || t.2 == holds)
        .map(|t| (format!("{}{suffix}", t.0), t.1))
        .collect();
    let depths = stack::depths(&elf::image(&elf_path)?, &named);

    let mut cmd = crate::qemu_command(&elf_path);
    if qemu_major() >= 8 {
        cmd.args(["-accel", "tcg,one-insn-per-tb=on"]);
    } else {
        cmd.arg("-singlestep");
    }
    // `int`: exception entries and returns, so that a handler's call ends
    // at its exception return even when the core tail-chains straight into
    // the next handler without running the interrupted code in between.
    cmd.args(["-d", "exec,nochain,int"])
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

    // `--profile <report>`: that report's count per call and its
    // executions per instruction address (to stderr), for finding where a
    // handler's budget goes; `--call <n>` limits the histogram to call n.
    let mut tracker = Tracker::new(&funcs, &targets, args.profile.clone(), args.call);
    for line in BufReader::new(trace).lines().map_while(Result::ok) {
        match parse_line(&line) {
            Some(Event::Pc(pc)) => {
                traced += 1;
                tracker.pc(pc);
            }
            Some(Event::ExceptionEntry) => tracker.exception_entry(),
            Some(Event::ExceptionReturn) => tracker.exception_return(),
            None => continue,
        }
        if traced.is_multiple_of(1 << 20) && last_report.elapsed().as_secs() >= 10 {
            last_report = Instant::now();
            let calls: u64 = tracker.stats.values().map(|s| s.calls).sum();
            eprintln!(
                "isr-cost: {variant} image: {:.0} M instructions traced, {calls} handler calls measured, {:.0} s",
                traced as f64 / 1e6,
                started.elapsed().as_secs_f64()
            );
        }
    }
    let (stats, histogram, profile) = (tracker.stats, tracker.histogram, tracker.profile);
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
    Ok((stats, depths))
}

/// What one line of QEMU's log says.
#[derive(Debug, PartialEq, Eq)]
enum Event {
    /// An instruction executed at this address (`-d exec`, one per block).
    Pc(u32),
    /// The core took an exception (normal entry or tail-chained, `-d int`).
    ExceptionEntry,
    /// An exception handler returned (`-d int`).
    ExceptionReturn,
}

fn parse_line(line: &str) -> Option<Event> {
    if line.starts_with("Trace ") {
        // "Trace 0: 0x7f.. [00800408/000024ae/00000110/ff020201] name"
        return line
            .split_once('[')
            .and_then(|(_, r)| r.split('/').nth(1))
            .and_then(|h| u32::from_str_radix(h, 16).ok())
            .map(Event::Pc);
    }
    if line.starts_with("...taking pending") && line.contains("exception") {
        return Some(Event::ExceptionEntry);
    }
    if line.starts_with("Exception return:") {
        return Some(Event::ExceptionReturn);
    }
    None
}

/// An open measurement: its report, the range of the function whose code
/// running again ends it (none for an exception handler: its exception
/// return does), and its count so far.
struct Open {
    report: String,
    caller: Option<(u32, u32)>,
    count: u64,
    handler: bool,
}

/// The measurement state machine over the trace: per report, instructions
/// per call. A call of a measured function starts when the PC reaches its
/// first address from another function and ends when that function runs
/// again; a measured exception handler's call ends at its exception return.
/// An exception counts for the handler it enters (and what it calls), not
/// for the code it preempted.
struct Tracker<'a> {
    funcs: &'a [Symbol],
    targets: &'a BTreeMap<u32, String>,
    open: Vec<Open>,
    /// `open.len()` at each exception entry not yet returned from.
    exceptions: Vec<usize>,
    /// An exception was just taken: the next PC is its handler's first.
    entering: bool,
    prev_pc: Option<u32>,
    stats: BTreeMap<String, Stats>,
    profile: Option<String>,
    call: Option<u64>,
    histogram: BTreeMap<u32, u64>,
}

impl<'a> Tracker<'a> {
    fn new(
        funcs: &'a [Symbol],
        targets: &'a BTreeMap<u32, String>,
        profile: Option<String>,
        call: Option<u64>,
    ) -> Self {
        Self {
            funcs,
            targets,
            open: Vec::new(),
            exceptions: Vec::new(),
            entering: false,
            prev_pc: None,
            stats: BTreeMap::new(),
            profile,
            call,
            histogram: BTreeMap::new(),
        }
    }

    fn close(&mut self, m: Open) {
        let s = self.stats.entry(m.report.clone()).or_default();
        if self.profile.as_deref() == Some(m.report.as_str()) {
            eprintln!("  call {} {}", s.calls, m.count);
        }
        s.calls += 1;
        s.total += m.count;
        s.max = s.max.max(m.count);
        s.min = if s.calls == 1 {
            m.count
        } else {
            s.min.min(m.count)
        };
    }

    fn exception_entry(&mut self) {
        self.exceptions.push(self.open.len());
        self.entering = true;
    }

    /// Everything opened since the returning exception's entry ends here.
    fn exception_return(&mut self) {
        let depth = self.exceptions.pop().unwrap_or(0);
        while self.open.len() > depth {
            if let Some(m) = self.open.pop() {
                self.close(m);
            }
        }
    }

    fn pc(&mut self, pc: u32) {
        // Close measurements whose caller is running again (innermost first).
        while let Some(m) = self.open.last() {
            match m.caller {
                Some((lo, hi)) if pc >= lo && pc < hi => {
                    if let Some(m) = self.open.pop() {
                        self.close(m);
                    }
                }
                _ => break,
            }
        }
        // Every measurement opened in the running context counts the
        // instruction (those below the innermost exception's entry belong
        // to the code it preempted), down to a measured handler.
        let floor = self.exceptions.last().copied().unwrap_or(0);
        for m in self.open.iter_mut().skip(floor).rev() {
            m.count += 1;
            if self.profile.as_deref() == Some(m.report.as_str()) {
                let call = self.stats.get(&m.report).map_or(0, |s| s.calls);
                if self.call.is_none_or(|c| c == call) {
                    *self.histogram.entry(pc).or_default() += 1;
                }
            }
            if m.handler {
                break;
            }
        }
        if let Some(report) = self.targets.get(&pc) {
            if self.entering {
                self.open.push(Open {
                    report: report.clone(),
                    caller: None,
                    count: 1,
                    handler: true,
                });
            } else if let Some(c) = self.prev_pc.and_then(|p| find(self.funcs, p)) {
                if !(pc >= c.addr && pc < c.addr + c.size) {
                    self.open.push(Open {
                        report: report.clone(),
                        caller: Some((c.addr, c.addr + c.size)),
                        count: 1,
                        handler: false,
                    });
                }
            }
        }
        self.entering = false;
        self.prev_pc = Some(pc);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sym(name: &str, addr: u32, size: u32) -> Symbol {
        Symbol {
            name: name.to_string(),
            addr,
            size,
        }
    }

    /// Tail-chaining: TIMER1 (calling the measured `work`) returns straight
    /// into TIMER0 (calling the measured `tick`), which returns to thread
    /// mode; and TIMER0 preempting `work` inside TIMER1. Each call counts
    /// its own instructions only, and every call ends.
    #[test]
    fn calls_end_at_their_exception_return_even_when_tail_chained() {
        let funcs = vec![
            sym("main", 0x100, 0x10),
            sym("TIMER0", 0x200, 0x10),
            sym("TIMER1", 0x300, 0x10),
            sym("tick", 0x400, 0x10),
            sym("work", 0x500, 0x10),
        ];
        let targets: BTreeMap<u32, String> = [
            (0x200, "T0"),
            (0x300, "T1"),
            (0x400, "tick"),
            (0x500, "work"),
        ]
        .into_iter()
        .map(|(a, r)| (a, r.to_string()))
        .collect();
        let mut t = Tracker::new(&funcs, &targets, None, None);
        use Event::*;
        let trace = [
            Pc(0x100),
            ExceptionEntry,
            Pc(0x300), // T1: 3 of its own + work 3 (none of T0's)
            Pc(0x302),
            Pc(0x500),
            Pc(0x502),
            ExceptionEntry,
            Pc(0x200), // T0 preempting work: 2 of its own + tick 2
            Pc(0x400),
            Pc(0x402),
            Pc(0x204),
            ExceptionReturn,
            Pc(0x504),
            Pc(0x306),
            ExceptionReturn, // tail-chained into T0 again
            ExceptionEntry,
            Pc(0x200),
            Pc(0x400),
            Pc(0x402),
            Pc(0x404),
            Pc(0x206),
            ExceptionReturn,
            Pc(0x102),
        ];
        for e in trace {
            match e {
                Pc(pc) => t.pc(pc),
                ExceptionEntry => t.exception_entry(),
                ExceptionReturn => t.exception_return(),
            }
        }
        assert!(t.open.is_empty());
        let s = |r: &str| {
            let s = &t.stats[r];
            (s.calls, s.max, s.min)
        };
        assert_eq!(s("T1"), (1, 6, 6));
        assert_eq!(s("work"), (1, 3, 3));
        assert_eq!(s("T0"), (2, 5, 4));
        assert_eq!(s("tick"), (2, 3, 2));
    }

    #[test]
    fn log_lines_are_parsed() {
        assert_eq!(
            parse_line("Trace 0: 0x7f30 [00800408/000024ae/00000110/ff020201] f"),
            Some(Event::Pc(0x24ae))
        );
        assert_eq!(
            parse_line("...taking pending nonsecure exception 25"),
            Some(Event::ExceptionEntry)
        );
        assert_eq!(
            parse_line("Exception return: magic PC ffffffe9 previous exception 24"),
            Some(Event::ExceptionReturn)
        );
        assert_eq!(parse_line("...tailchaining to pending exception"), None);
    }

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
