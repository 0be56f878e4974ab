//! The board's timing as the simulator gives it to the firmware: input
//! captures on the free-running clock behind the input filter (encoder
//! edges and the index), the gauge's sampling instant, the handler's read
//! instant and its DAC frame. Each is checked against a closed form of the
//! instant the board would latch, so the simulator cannot hand the
//! firmware an earlier or finer time than the board's registers hold.

use host_sim::chips::SimTime;
use host_sim::fwrig::firmware_demo;
use host_sim::machine::hw::{SimSpindleEncoder, SpindleLink};
use host_sim::machine::spindle::SpindleConfig;
use host_sim::plant::zslide::st;
use host_sim::plant::{GaugeParams, RigConfig};
use host_sim::scenario::load;
use std::cell::{Cell, RefCell};
use std::rc::Rc;
use zslide::hw::Encoder;
use zslide::spindle::EdgeStamps;

const CLOCK_HZ: f64 = 200.0e6;
const DELAY_NS: u64 = 55;
const CPR: u32 = 10_000;
/// Not a multiple of anything: edges fall at every phase of the clock.
const RPM: f64 = 283.0;

fn spindle() -> SpindleConfig {
    SpindleConfig {
        rpm0: RPM,
        accel_rpm_per_s: 0.0,
        encoder_cpr: CPR,
        ticks_per_s: CLOCK_HZ,
        capture_delay_ns: DELAY_NS,
        ..SpindleConfig::default()
    }
}

/// Counts per ns at the constant speed.
fn counts_per_ns() -> f64 {
    RPM / 60.0 * f64::from(CPR) * 1e-9
}

/// `stamp` is ⌊x⌋ (up to the model's float error near an integer).
fn is_floor(stamp: u32, x: f64) -> bool {
    let s = f64::from(stamp);
    s <= x + 1e-6 && x < s + 1.0 + 1e-6
}

fn encoder(edges: EdgeStamps) -> (SimSpindleEncoder, SimTime) {
    let time: SimTime = Rc::new(Cell::new(0));
    let link = Rc::new(RefCell::new(SpindleLink::new(
        spindle(),
        250_000,
        5_000_000,
    )));
    (
        SimSpindleEncoder {
            link,
            time: time.clone(),
            edges,
            last: None,
        },
        time,
    )
}

#[test]
fn a_captured_count_changes_one_filter_delay_after_its_edge_stamped_with_the_clock_count_then() {
    let (mut enc, time) = encoder(EdgeStamps::Captured);
    let per_ns = counts_per_ns();
    let mut checked = 0;
    for k in (1000u64..1_000_000).step_by(7919) {
        // The true edge of count k (the angle is exactly linear in time).
        let t_edge = k as f64 / per_ns;
        // 20 ns after the edge the filter still holds the old count.
        time.set((t_edge + 20.0).ceil() as u64);
        let before = enc.sample();
        assert_eq!(before.count, k as u32 - 1, "count {k} 20 ns after its edge");
        // After the delay the new count reads with the edge's capture:
        // the clock's count when the filtered edge reached the timer.
        time.set((t_edge + DELAY_NS as f64 + 1.0).ceil() as u64);
        let after = enc.sample();
        assert_eq!(after.count, k as u32, "count {k} after the delay");
        let x = (t_edge + DELAY_NS as f64) * CLOCK_HZ * 1e-9;
        assert!(is_floor(after.edge_ticks, x), "{} vs {x}", after.edge_ticks);
        checked += 1;
    }
    assert!(checked > 100);
}

#[test]
fn an_at_read_count_is_stamped_with_the_clock_at_the_read_that_first_saw_it() {
    let (mut enc, time) = encoder(EdgeStamps::AtRead);
    let per_ns = counts_per_ns();
    let mut t = 10_000u64;
    let mut last: Option<(u32, u32)> = None;
    for _ in 0..2000 {
        t += 50_000;
        time.set(t);
        let s = enc.sample();
        let true_count = ((t - DELAY_NS) as f64 * per_ns).floor() as u32;
        assert_eq!(s.count, true_count);
        match last {
            Some((c, stamp)) if c == s.count => assert_eq!(s.edge_ticks, stamp),
            _ => assert!(is_floor(s.edge_ticks, t as f64 * CLOCK_HZ * 1e-9)),
        }
        last = Some((s.count, s.edge_ticks));
    }
}

#[test]
fn the_index_is_captured_with_the_encoder_count_at_its_edge() {
    let mut link = SpindleLink::new(spindle(), 250_000, 5_000_000);
    let rev_ns = 60.0e9 / RPM;
    let mut n = 0;
    while n < 5 {
        // Five index pulses are due within five revolutions: a model that
        // stopped raising them fails here instead of scanning forever.
        assert!(
            (link.scanned_to() as f64) < 6.0 * rev_ns,
            "{n} index pulses in six revolutions"
        );
        link.scan();
        while let Some(p) = link.pop_pulse() {
            n += 1;
            let t_edge = f64::from(n) * rev_ns;
            assert_eq!(p.count, n * CPR, "count at index {n}");
            let x = (t_edge + DELAY_NS as f64) * CLOCK_HZ * 1e-9;
            assert!(
                is_floor(p.edge_ticks, x),
                "index {n}: {} vs {x}",
                p.edge_ticks
            );
            // The interrupt is not raised before the capture exists.
            assert!(p.t_ns as f64 >= t_edge + DELAY_NS as f64);
        }
    }
}

fn quiet_timed(adc_sample_ns: u64) -> RigConfig {
    RigConfig {
        gauge: GaugeParams::noiseless(),
        clock_hz: 200_000_000,
        adc_sample_ns,
        handler_entry_ns: 1200,
        dac_latency_ns: 8500,
        ..RigConfig::legacy(1)
    }
}

#[test]
fn the_gauge_is_sampled_at_its_instant_and_the_dac_frame_ends_at_the_latency() {
    let period = 50_000u64;
    for sample_ns in [0u64, 1000] {
        let (mut w, mut s) = firmware_demo(quiet_timed(sample_ns), 20_000);
        // A coasting slide (amplifier off, current 0): z(t) = v0·τ·(1 − e^(−t/τ)).
        let v0 = 1.0;
        w.rig.slide.x[st::V] = v0;
        s.run_until(&mut w, period);
        let p = &w.rig.slide.params;
        let tau = p.mass_lbf_s2_per_in / p.b_lbf_s_per_in;
        let t = (period + sample_ns) as f64 * 1e-9;
        let z = v0 * tau * (1.0 - (-t / tau).exp());
        // 1 V/mil into ±10 V on 20 bits: 52 428.8 codes per mil.
        let want = z * 1000.0 / 10.0 * 524_288.0;
        let got = f64::from(w.fw.position_code());
        assert!(
            (got - want).abs() <= 1.0,
            "sample at +{sample_ns} ns: code {got} vs {want}"
        );
        // The disarmed firmware's first tick writes 0 V: its frame ends
        // `dac_latency_ns` after the loop event, not before.
        let change = w.rig.dac.state.borrow().changes.back().copied();
        assert_eq!(change.map(|c| c.0), Some(period + 8500));
    }
}

#[test]
fn both_scenarios_carry_the_nucleo_timing() {
    for name in ["legacy-hw", "modern-hw"] {
        let sc = load(name).unwrap();
        assert_eq!(sc.rig.clock_hz, 200_000_000, "{name}: TIM2 at 200 MHz");
        assert_eq!(sc.rig.adc_sample_ns, 0, "{name}: CNV from the timer");
        assert_eq!(sc.rig.handler_entry_ns, 1200, "{name}");
        assert!(sc.rig.dac_latency_ns >= 8500, "{name}");
        assert_eq!(sc.machine.spindle.capture_delay_ns, 55, "{name}");
        assert_eq!(sc.machine.spindle.ticks_per_s, 200.0e6, "{name}");
        assert_eq!(sc.machine.encoder_edges, EdgeStamps::Captured, "{name}");
    }
}

#[test]
fn the_firmware_angle_is_the_angle_at_the_handler_read_instant() {
    use host_sim::fwrig::machine_demo;
    use host_sim::machine::MachineConfig;
    let mut m = MachineConfig::modern(3);
    m.encoder_edges = EdgeStamps::Captured;
    m.spindle = SpindleConfig {
        seed: m.spindle.seed,
        ..spindle()
    };
    let (mut w, mut s) = machine_demo(quiet_timed(0), &m, 20_000);
    let period = 50_000u64;
    // Two index pulses: referenced, and a count interval measured.
    let mut t = 500_000_000u64;
    s.run_until(&mut w, t);
    let (mut at_read, mut at_event, mut n) = (0.0, 0.0, 0.0);
    for _ in 0..400 {
        t += period;
        s.run_until(&mut w, t);
        let st = w.stats().unwrap();
        assert!(st.referenced);
        let fw = f64::from(st.angle.0) / 4_294_967_296.0;
        let link = &w.machine.as_ref().unwrap().spindle;
        let (event, read) = {
            let mut l = link.borrow_mut();
            let e = l.turns_at(t);
            (e, l.turns_at(t + 1200))
        };
        let counts = |truth: f64| {
            let d = (fw - truth).rem_euclid(1.0);
            (if d > 0.5 { d - 1.0 } else { d }).abs() * f64::from(CPR)
        };
        at_read += counts(read);
        at_event += counts(event);
        n += 1.0;
    }
    // 1.2 µs at 283 rpm is 0.057 count; the capture's own error is the
    // filter's 55 ns (0.003 count) and the clock's 5 ns.
    let (at_read, at_event) = (at_read / n, at_event / n);
    assert!(
        at_read < 0.01,
        "mean error at the read instant {at_read} count"
    );
    assert!(
        at_event > 0.04,
        "mean error at the loop event {at_event} count"
    );
}
