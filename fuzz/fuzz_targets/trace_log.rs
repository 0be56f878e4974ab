//! host-sim's trace-log decoder (`host_sim::vcd::target::convert`, behind
//! `host-sim trace2vcd`: a board's decoded defmt log → VCD), from arbitrary
//! bytes: a mode byte, then the log as it is (0), or a log made of a
//! clock line, ordinary messages and `ev` lines built from the input (1),
//! so that long valid traces are common.
//!
//! Properties, against an independent reading of the format the module
//! documents (lines as `BufRead::lines` gives them; `trace clock <hz> Hz`
//! anywhere in a line; `ev <code> <value> <clock>` as one of the first
//! three tokens; the codes and values of `zslide::trace::Event`, its 20-bit
//! converter codes, its 0/1 flags and its valueless handler marks):
//!
//! * the verdict: a log is refused exactly when the reading finds a bad
//!   line (the message names the first), or no event at all;
//! * an accepted log's summary: events, clock, handler runs, the longest
//!   entry-to-exit time and the span, from the unwrapped clock (each
//!   clock taken nearest the previous event's, the events then in time
//!   order: a handler preempted between its clock read and its log line
//!   logs an earlier time after a later one);
//! * its VCD: it parses; its timestamps strictly increase and each is an
//!   event's time; every change changes its value (only changes are
//!   written); each numeric signal ends at the value of its last event,
//!   in its documented unit (µin of 2¹⁹ codes per 0.010 in, inches of
//!   2²⁴, degrees of 2³² per turn).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::collections::HashMap;
use zslide::trace::{Event, Signal};

enum Verdict {
    /// The first bad line (1-based), or 0: no event.
    Refused(usize),
    Accepted(Model),
}

#[derive(Default)]
struct Model {
    events: u64,
    clock_hz: u32,
    times: Vec<u64>,
    runs: [u64; 3],
    longest_us: [f64; 3],
    /// Last value per numeric signal name, in its unit.
    last: HashMap<&'static str, f64>,
}

/// Lines as `BufRead::lines` yields them.
fn lines(b: &[u8]) -> Vec<&[u8]> {
    let mut v: Vec<&[u8]> = b.split(|&c| c == b'\n').collect();
    if b.is_empty() || b.ends_with(b"\n") {
        v.pop();
    }
    v.into_iter()
        .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
        .collect()
}

/// The event's fields exactly as the trace module defines them: a code it
/// knows, and a value it would itself send (handler marks carry 0, flags
/// 0 or 1, converter codes 20 bits).
fn event(code: u8, value: i32) -> Option<Event> {
    let e = Event::decode(code, value)?;
    if e.code() != code || e.value() != value {
        return None;
    }
    if let Event::Adc(c) | Event::Dac(c) = e {
        if !(-(1 << 19)..1 << 19).contains(&c) {
            return None;
        }
    }
    Some(e)
}

fn read(log: &[u8]) -> Verdict {
    let mut m = Model::default();
    let mut hz: Option<u32> = None;
    // Each clock unwrapped to the count nearest the previous event's
    // (a step back of less than half a wrap is an earlier event).
    let mut last = None::<(i64, u32)>;
    let mut evs: Vec<(i64, Event)> = Vec::new();
    let mut entered = [None::<u64>; 3];
    for (k, raw) in lines(log).into_iter().enumerate() {
        let n = k + 1;
        let Ok(line) = std::str::from_utf8(raw) else {
            return Verdict::Refused(n);
        };
        if let Some(at) = line.find("trace clock ") {
            let rest = &line[at + 12..];
            let h = rest.strip_suffix(" Hz").unwrap_or(rest).trim();
            match h.parse::<u32>() {
                Ok(h) if h > 0 && hz.is_none_or(|x| x == h) => hz = Some(h),
                _ => return Verdict::Refused(n),
            }
            continue;
        }
        let t: Vec<&str> = line.split_whitespace().collect();
        let Some(at) = t.iter().take(3).position(|&x| x == "ev") else {
            continue;
        };
        let f = &t[at + 1..];
        if f.len() != 3 {
            return Verdict::Refused(n);
        }
        let (Ok(code), Ok(value), Ok(clock)) =
            (f[0].parse::<u8>(), f[1].parse::<i32>(), f[2].parse::<u32>())
        else {
            return Verdict::Refused(n);
        };
        let Some(e) = event(code, value) else {
            return Verdict::Refused(n);
        };
        if hz.is_none() {
            return Verdict::Refused(n);
        }
        let ticks = match last {
            None => i64::from(clock),
            Some((t, c)) => t + i64::from(clock.wrapping_sub(c) as i32),
        };
        last = Some((ticks, clock));
        evs.push((ticks, e));
    }
    if evs.is_empty() {
        return Verdict::Refused(0);
    }
    let h = hz.unwrap_or(1);
    m.clock_hz = h;
    // In time order, equal times in the log's order.
    evs.sort_by_key(|&(t, _)| t);
    let origin = evs[0].0.min(0);
    for (ticks, e) in evs {
        let t_ns = ((ticks - origin) as u128 * 1_000_000_000 / u128::from(h)) as u64;
        m.events += 1;
        m.times.push(t_ns);
        let handler = |e: Event| match e {
            Event::LoopEnter | Event::LoopExit => Some(0),
            Event::XEnter | Event::XExit => Some(1),
            Event::IndexEnter | Event::IndexExit => Some(2),
            _ => None,
        };
        match e {
            Event::LoopEnter | Event::XEnter | Event::IndexEnter => {
                let k = handler(e).unwrap();
                m.runs[k] += 1;
                entered[k] = Some(t_ns);
            }
            Event::LoopExit | Event::XExit | Event::IndexExit => {
                let k = handler(e).unwrap();
                if let Some(t0) = entered[k].take() {
                    m.longest_us[k] = m.longest_us[k].max((t_ns - t0) as f64 / 1000.0);
                }
            }
            Event::Adc(c) => {
                m.last.insert(Signal::AdcCode.name(), f64::from(c));
            }
            Event::Dac(c) => {
                m.last.insert(Signal::DacCode.name(), f64::from(c));
            }
            Event::Command(c) => {
                m.last
                    .insert(Signal::Command.name(), f64::from(c) * 0.010e6 / 524_288.0);
            }
            Event::Error(c) => {
                m.last
                    .insert(Signal::Error.name(), f64::from(c) * 0.010e6 / 524_288.0);
            }
            Event::X(b) => {
                m.last
                    .insert(Signal::XFirmware.name(), f64::from(b) / 16_777_216.0);
            }
            Event::Angle(a) => {
                m.last.insert(
                    Signal::AngleFirmware.name(),
                    f64::from(a) * 360.0 / 4_294_967_296.0,
                );
            }
            _ => {}
        }
    }
    Verdict::Accepted(m)
}

/// A log from the input: each 10-byte chunk is a line.
fn structured(b: &[u8]) -> Vec<u8> {
    let mut s =
        String::from("0.000000 INFO  zslide on QEMU\n0.000000 INFO  trace clock 25000000 Hz\n");
    let mut clock = 1000u32;
    for c in b.chunks_exact(10) {
        let code = c[0] % 17;
        let v = i32::from_le_bytes(c[1..5].try_into().unwrap());
        let value = match code {
            0..=5 => 0,
            6 | 7 => v >> 12,
            10..=12 => v & 1,
            _ => v,
        };
        clock = clock.wrapping_add(u32::from_le_bytes(c[5..9].try_into().unwrap()) >> (c[9] % 32));
        if c[9] & 0x80 != 0 {
            s.push_str("0.000100 INFO  tick report: ev 3 ignored\n");
        }
        s.push_str(&format!("0.000100 TRACE ev {code} {value} {clock}\n"));
    }
    s.into_bytes()
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let log = if mode % 2 == 0 {
        rest.to_vec()
    } else {
        structured(rest)
    };
    let mut out = Vec::new();
    let got = host_sim::vcd::target::convert(log.as_slice(), &mut out);
    let m = match (read(&log), got) {
        (Verdict::Refused(n), Err(e)) => {
            let msg = format!("{e:#}");
            if n == 0 {
                assert!(msg.contains("no trace events"), "{msg}");
            } else {
                assert!(msg.contains(&format!("line {n}")), "line {n}: {msg}");
            }
            return;
        }
        (Verdict::Refused(n), Ok(s)) => panic!("accepted, but line {n} is bad: {s:?}"),
        (Verdict::Accepted(_), Err(e)) => panic!("refused a sound log: {e:#}"),
        (Verdict::Accepted(m), Ok(s)) => {
            assert_eq!(s.events, m.events);
            assert_eq!(s.clock_hz, m.clock_hz);
            assert_eq!(s.runs, m.runs);
            for k in 0..3 {
                assert!(
                    (s.longest_us[k] - m.longest_us[k]).abs() <= 1e-9 * m.longest_us[k].max(1.0)
                );
            }
            let span = (m.times.last().unwrap() - m.times[0]) as f64 * 1e-9;
            assert!((s.span_s - span).abs() <= 1e-12 * span.max(1.0));
            m
        }
    };
    // The VCD.
    let mut p = vcd::Parser::new(out.as_slice());
    let h = p.parse_header().expect("the VCD's header parses");
    let mut names: HashMap<vcd::IdCode, &'static str> = HashMap::new();
    for s in Signal::ALL {
        let v = h
            .find_var(&["zslide", s.name()])
            .expect("every signal declared");
        names.insert(v.code, s.name());
    }
    let mut last_t: Option<u64> = None;
    let mut value: HashMap<&str, f64> = HashMap::new();
    for c in p {
        match c.expect("the VCD parses") {
            vcd::Command::Timestamp(t) => {
                assert!(last_t.is_none_or(|l| t > l), "time went {last_t:?} -> {t}");
                assert!(
                    m.times.binary_search(&t).is_ok(),
                    "{t} ns is no event's time"
                );
                last_t = Some(t);
            }
            vcd::Command::ChangeReal(id, v) => {
                let n = names[&id];
                if let Some(old) = value.insert(n, v) {
                    assert_ne!(
                        old.to_bits(),
                        v.to_bits(),
                        "{n}: a change to the same value"
                    );
                }
            }
            vcd::Command::ChangeScalar(id, v) => {
                let n = names[&id];
                let v = if v == vcd::Value::V1 { 1.0 } else { 0.0 };
                if let Some(old) = value.insert(n, v) {
                    assert_ne!(old, v, "{n}: a change to the same value");
                }
            }
            _ => {}
        }
    }
    for (name, want) in &m.last {
        let got = value.get(name).copied().unwrap_or(0.0);
        assert!(
            got == *want || (got - want).abs() <= 1e-12 * want.abs(),
            "{name}: VCD ends at {got}, the last event says {want}"
        );
    }
});
