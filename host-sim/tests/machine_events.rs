//! The firmware's X and spindle inputs through the scheduler: the machine
//! models behind the core's `hw` traits, interrupts at their exact
//! instants, interleaved with the loop tick in priority order.

use host_sim::fwrig::{machine_demo, FirmwareWorld};
use host_sim::machine::xslide::{FeedSegment, XSlideConfig};
use host_sim::machine::{MachineConfig, SpindleSensor, XInterface};
use host_sim::plant::zslide::st;
use host_sim::plant::RigConfig;
use host_sim::sched::{prio, OneShots};
use std::cell::RefCell;
use std::rc::Rc;

/// Everything observable at the end of a run, bit for bit.
fn fingerprint(w: &FirmwareWorld) -> Vec<u64> {
    let m = w.stats().unwrap();
    let mut v: Vec<u64> = w.rig.slide.x.iter().map(|x| x.to_bits()).collect();
    v.extend([
        w.fw.output_code() as u64,
        w.fw.position_code() as u64,
        w.rig.adc.state.borrow().code as u64,
        m.x_events,
        m.x_accepted,
        m.x_ignored,
        m.index_events,
        u64::from(m.angle.0),
        m.x.map_or(0, |x| x.0.to_bits() as u64),
    ]);
    v
}

fn glitchy_legacy(seed: u64) -> MachineConfig {
    let mut m = MachineConfig::legacy(seed);
    m.x = XInterface::LegacyBcd(XSlideConfig {
        x0_in: 1.000_2,
        feed: vec![FeedSegment {
            t_start_s: 0.0,
            feed_in_per_min: 1.0,
        }],
        vibration_uin: 3.0,
        vibration_hz: 1000.0,
        jitter_uin: 1.0,
        ripple_prob: 0.0,
        seed,
    });
    m.spindle.index_noise_per_rev = 0.0;
    // sample the 1 kHz vibration finely (10 points per period)
    m.x_step_ns = 100_000 / 10;
    m
}

fn run(seed: u64, t_ns: u64) -> FirmwareWorld {
    let (mut w, mut s) = machine_demo(RigConfig::legacy(seed), &glitchy_legacy(seed), 20_000);
    w.rig.slide.x[st::Z] = 0.0005;
    s.run_until(&mut w, t_ns);
    w
}

#[test]
fn scheduled_machine_run_is_bit_identical_per_seed() {
    let a = run(11, 250_000_000);
    let b = run(11, 250_000_000);
    let c = run(12, 250_000_000);
    assert_eq!(fingerprint(&a), fingerprint(&b));
    assert_ne!(fingerprint(&a), fingerprint(&c));
    // the run did exercise every source
    let m = a.stats().unwrap();
    assert!(m.x_events > 0 && m.index_events > 0, "{m:?}");
}

#[test]
fn half_mil_interrupts_match_the_x_motion_and_glitches_are_rejected() {
    // 1.0002 in at 1 in/min for 0.6 s: nominal 1.0102 in, so the half-mil
    // boundaries 1.0005 .. 1.0100 (20 of them) are crossed; the 3 µin,
    // 1 kHz vibration (18.8 mil/s peak against a 16.7 mil/s feed) reverses
    // the counter at boundaries: false interrupts with unchanged flags.
    let w = run(3, 600_000_000);
    let m = w.stats().unwrap();
    assert_eq!(m.x_accepted, 20, "{m:?}");
    assert!(m.x_ignored > 0, "the vibration must make false interrupts");
    assert_eq!(m.x_events, m.x_accepted + m.x_ignored);
    assert_eq!(m.x_faults, 0);
    // last accepted position: 1.0100 in = 2020 half-mils
    let x = m.x.unwrap().to_f64();
    assert!((x - 1.0100).abs() < 1e-7, "{x}");
    assert_eq!(w.fw.fault(), None);
}

#[test]
fn equal_time_events_run_loop_tick_then_x_then_index() {
    let (mut w, mut s) = machine_demo(RigConfig::legacy(1), &MachineConfig::legacy(1), 20_000);
    // (source, event time, plant time, loop ticks run so far)
    type Log = Rc<RefCell<Vec<(&'static str, u64, u64, u32)>>>;
    let log: Log = Rc::default();
    // Three events at the 10th loop tick (500 µs), registered in the
    // reverse of their priority order.
    for (name, p) in [
        ("index", prio::INDEX),
        ("x", prio::X_EVENT),
        ("after-tick", prio::LOOP_TICK - 1),
    ] {
        let mut o = OneShots::new(name, p);
        let l = log.clone();
        o.at(500_000, move |now, w: &mut FirmwareWorld| {
            l.borrow_mut().push((name, now, w.rig.t_ns, w.fw.ticks()));
        });
        s.add(o);
    }
    s.run_until(&mut w, 1_000_000);
    let log = log.borrow();
    let names: Vec<_> = log.iter().map(|e| e.0).collect();
    assert_eq!(names, ["after-tick", "x", "index"]);
    for e in log.iter() {
        assert_eq!(e.1, 500_000);
        assert_eq!(e.2, 500_000, "plant advanced exactly to the event");
        assert_eq!(e.3, 10, "the loop tick at the same instant ran first");
    }
}

#[test]
fn encoder_angle_follows_the_spindle_through_the_hw_traits() {
    let mut m = MachineConfig::modern(5);
    m.spindle.rpm0 = 300.0;
    let (mut w, mut s) = machine_demo(RigConfig::legacy(5), &m, 20_000);
    // an observer compares the firmware's angle with the model's truth
    let worst = Rc::new(RefCell::new(0.0f64));
    let w2 = worst.clone();
    s.on_event = Some(Box::new(move |t, k, w: &FirmwareWorld| {
        let st = w.stats().unwrap();
        if k == 0 && st.referenced {
            let m = w.machine.as_ref().unwrap();
            let truth = m.spindle.borrow_mut().turns_at(t).rem_euclid(1.0);
            let est = f64::from(st.angle.0) / 4294967296.0;
            let d = (est - truth + 0.5).rem_euclid(1.0) - 0.5;
            let mut b = w2.borrow_mut();
            *b = b.max(d.abs());
        }
    }));
    s.run_until(&mut w, 700_000_000);
    let st = w.stats().unwrap();
    assert!(st.referenced);
    assert_eq!(st.index_events, 3, "300 rpm: index at 0.2, 0.4, 0.6 s");
    assert_eq!(st.index_faults, 0, "{st:?}");
    // 10 000 counts/rev: the 1/T estimate is within a count of the truth
    let worst = *worst.borrow();
    assert!(worst < 1.0 / 10_000.0, "worst angle error {worst} turn");
    // modern X: the quadrature count at 0.2 in/min from 1 in
    let x = st.x.unwrap().to_f64();
    assert!((x - (1.0 + 0.2 / 60.0 * 0.7)).abs() < 2e-6, "{x}");
}

#[test]
fn tachometer_angle_is_phased_by_the_index() {
    let mut m = MachineConfig::legacy(6);
    m.sensor = SpindleSensor::TachIndex;
    let (mut w, mut s) = machine_demo(RigConfig::legacy(6), &m, 20_000);
    s.run_until(&mut w, 1_100_000_000);
    let st = w.stats().unwrap().clone();
    assert_eq!(st.index_events, 5);
    assert_eq!(st.index_faults, 0, "{st:?}");
    let truth = w
        .machine
        .as_ref()
        .unwrap()
        .spindle
        .borrow_mut()
        .turns_at(1_100_000_000)
        .rem_euclid(1.0);
    let est = f64::from(st.angle.0) / 4294967296.0;
    let d = (est - truth + 0.5).rem_euclid(1.0) - 0.5;
    // nominal tach gain, constant speed: integration from the last index
    assert!(d.abs() < 1e-3, "angle error {d} turn");
}

#[test]
fn bench_vcd_records_the_whole_machine_and_parses_back() {
    use host_sim::cmd::bench::write_vcd;
    use host_sim::vcd::machine::SIGNALS;
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let path = std::env::temp_dir().join(format!("zslide-vcd-{}.vcd", std::process::id()));
    let stats = write_vcd(&path, 20_000, &sc).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let mut parser = vcd::Parser::new(&bytes[..]);
    let header = parser.parse_header().expect("VCD header parses");
    let mut code = std::collections::HashMap::new();
    for (name, _) in SIGNALS {
        let v = header
            .find_var(&["zslide", name])
            .unwrap_or_else(|| panic!("{name} missing"));
        code.insert(v.code, name);
    }
    let mut changes: std::collections::HashMap<&str, usize> = Default::default();
    for c in parser {
        let c = c.expect("VCD body parses");
        let id = match c {
            vcd::Command::ChangeVector(id, _) | vcd::Command::ChangeScalar(id, _) => id,
            vcd::Command::ChangeReal(id, _) => id,
            _ => continue,
        };
        *changes.entry(code[&id]).or_default() += 1;
    }
    // 250 ms at 20 kHz: one toggle per loop tick (plus the initial value)
    assert!((5000..=5001).contains(&changes["loop_tick"]), "{changes:?}");
    // the index at 200 ms; X events from the counter dithering at 7.2500.
    // One toggle per handler run (plus the initial value), none for the
    // models' look-ahead wake-ups (every 5 ms).
    assert!(changes["index"] >= 2, "{changes:?}");
    assert!(changes["x_event"] >= 2, "{changes:?}");
    assert!(
        (stats.index_events..=stats.index_events + 1).contains(&(changes["index"] as u64)),
        "{changes:?} vs {stats:?}"
    );
    assert!(
        (stats.x_events..=stats.x_events + 1).contains(&(changes["x_event"] as u64)),
        "{changes:?} vs {stats:?}"
    );
    for name in [
        "slide_z_uin",
        "command_uin",
        "error_uin",
        "dac_code",
        "spindle_phi_deg",
    ] {
        assert!(changes[name] > 100, "{name}: {changes:?}");
    }
}
