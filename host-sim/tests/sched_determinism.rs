//! Scheduler ordering, exact plant advance between events, and
//! reproducibility: the same seed gives a bit-identical run.

use host_sim::cmd::bench::demo;
use host_sim::plant::RigConfig;
use host_sim::sched::{prio, OneShots, Periodic, Scheduler, World};
use host_sim::vcd::{SignalKind, VcdRecorder};
use std::cell::RefCell;
use std::rc::Rc;

#[derive(Default)]
struct Log {
    advanced: Vec<u64>,
    clock: u64,
    events: Vec<(u64, &'static str)>,
}
impl World for Log {
    fn advance_to(&mut self, t: u64) {
        assert!(
            self.advanced.last().is_none_or(|&l| l <= t),
            "time went backwards"
        );
        self.advanced.push(t);
    }
    fn set_time(&mut self, t: u64) {
        self.clock = t;
    }
}

#[test]
fn events_in_time_then_priority_order() {
    let mut s: Scheduler<Log> = Scheduler::new();
    s.add(Periodic::new(
        "x",
        prio::X_EVENT,
        0,
        30,
        |t, w: &mut Log| {
            assert_eq!(w.clock, t);
            w.events.push((t, "x"));
        },
    ));
    s.add(Periodic::new(
        "tick",
        prio::LOOP_TICK,
        0,
        50,
        |t, w: &mut Log| w.events.push((t, "tick")),
    ));
    let mut o = OneShots::new("oneshot", prio::BACKGROUND);
    o.at(100, |t, w: &mut Log| w.events.push((t, "a")));
    o.at(100, |t, w: &mut Log| w.events.push((t, "b")));
    o.at(40, |t, w: &mut Log| w.events.push((t, "c")));
    s.add(o);
    let mut w = Log::default();
    let n = s.run_until(&mut w, 150);
    let expect = vec![
        (0, "tick"),
        (0, "x"),
        (30, "x"),
        (40, "c"),
        (50, "tick"),
        (60, "x"),
        (90, "x"),
        (100, "tick"),
        (100, "a"),
        (100, "b"),
        (120, "x"),
        (150, "tick"),
        (150, "x"),
    ];
    assert_eq!(w.events, expect);
    assert_eq!(n, expect.len() as u64);
    // the world was advanced to every event time before it ran, and to the end
    for (t, _) in &expect {
        assert!(w.advanced.contains(t));
    }
    assert_eq!(w.advanced.last(), Some(&150));
    assert_eq!(s.fired, vec![6, 4, 3]);
}

#[derive(Clone, Default)]
struct SharedBuf(Rc<RefCell<Vec<u8>>>);
impl std::io::Write for SharedBuf {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A 50 ms closed-loop run with the stand-in loop on the legacy rig;
/// returns every bit that could differ.
type Run = (Vec<(u64, i32, i32)>, Vec<u64>, Vec<u8>);

fn run(seed: u64) -> Run {
    let (mut w, mut s) = demo(RigConfig::legacy(seed), 20_000, true);
    // start off null so the loop works; a cutting-force step at 20 ms
    w.rig.slide.x[2] = 0.002;
    let mut o = OneShots::new("force", prio::PLANT_INPUT);
    o.at(20_000_000, |_, w: &mut host_sim::cmd::bench::DemoWorld| {
        w.rig.set_force_lbf(-1.3)
    });
    s.add(o);
    let buf = SharedBuf::default();
    let rec = Rc::new(RefCell::new(Some(
        VcdRecorder::new(
            buf.clone(),
            "zslide",
            &[
                ("z_uin", SignalKind::Real),
                ("dac_code", SignalKind::Int(20)),
                ("amp_enabled", SignalKind::Bit),
            ],
        )
        .unwrap(),
    )));
    let rec2 = rec.clone();
    s.on_event = Some(Box::new(
        move |t, _, w: &host_sim::cmd::bench::DemoWorld| {
            let code = w.ctl.trace.last().map_or(0, |e| e.2);
            let en = if w.rig.amp.enabled() { 1.0 } else { 0.0 };
            if let Some(r) = rec2.borrow_mut().as_mut() {
                r.sample(t, &[w.rig.slide.position_in() * 1e6, f64::from(code), en])
                    .unwrap();
            }
        },
    ));
    s.run_until(&mut w, 50_000_000);
    if let Some(r) = rec.borrow_mut().take() {
        r.finish().unwrap();
    }
    let state: Vec<u64> = w.rig.slide.x.iter().map(|v| v.to_bits()).collect();
    let out = buf.0.borrow().clone();
    (w.ctl.trace, state, out)
}

#[test]
fn same_seed_bit_identical_different_seed_differs() {
    let a = run(11);
    let b = run(11);
    let c = run(12);
    assert_eq!(a.0.len(), 1000);
    assert_eq!(a, b);
    assert_ne!(a.0, c.0);
    assert_ne!(a.1, c.1);
    // the loop pulled the slide from 2 mil towards null (it works at all)
    let first = a.0[0].1;
    let before_force = a.0[399].1;
    assert!(
        first > 100_000 && before_force.abs() < first / 10,
        "{first} → {before_force}"
    );
    // the VCD is well formed
    let mut parser = vcd::Parser::new(&a.2[..]);
    let header = parser.parse_header().expect("VCD header parses");
    let dac = header
        .find_var(&["zslide", "dac_code"])
        .unwrap_or_else(|| panic!("{:?}", header.items))
        .code;
    // codes are real-valued variables holding whole 20-bit codes (so that
    // libsigrok, which stops at a multi-bit vector, still reads the wires)
    let codes: Vec<f64> = parser
        .filter_map(|c| match c {
            Ok(vcd::Command::ChangeReal(id, v)) if id == dac => Some(v),
            _ => None,
        })
        .collect();
    assert!(codes.len() >= 500, "{} code changes", codes.len());
    assert!(
        codes
            .iter()
            .all(|v| v.fract() == 0.0 && (-524_288.0..524_288.0).contains(v)),
        "a DAC code that is not a 20-bit integer"
    );
    let text = String::from_utf8(a.2).unwrap();
    assert!(
        text.contains("$timescale") && text.contains("$enddefinitions") && text.contains("#50000")
    );
}
