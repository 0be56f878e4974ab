//! Contour monitoring against hand-made error and gauge sequences: each
//! fault at its threshold and not below it.
#![allow(clippy::unwrap_used, clippy::panic)]

use super::*;
use crate::servo::repetitive::LearnRequests;
use crate::servo::ServoDesign;
use crate::units::SpindleAngle;

/// Gauge codes per inch: 2¹⁹ codes over 0.010 in (the gauge's ±10 V).
const CPI: f64 = 524_288.0 / 0.010;

fn cfg() -> MonitorConfig {
    ServoDesign::brief(20_000).config().unwrap().monitor
}

fn uin_q8(uin: f64) -> i32 {
    (uin * 1e-6 * CPI * 256.0).round() as i32
}

/// A live sample: error (µin, + toward −Z), gauge code, angle.
fn live(error_q8: i32, gauge: i32, phi: u32) -> LearnSample {
    LearnSample::new(
        error_q8,
        Some((SpindleAngle(phi), 1 << 20)),
        None,
        LearnRequests::NONE,
    )
    .with_gauge(gauge)
}

/// Feeds `m` the live revolutions after the engagement that the depth and
/// oscillation checks wait for: a quarter turn a sample, no error, the
/// gauge moving.
fn settle(m: &mut Monitor) {
    let mut gauge = 1_000_000;
    for _ in 0..SETTLE_REVS {
        for phi in [0, 1 << 30, 2 << 30, 3 << 30] {
            gauge += 3;
            assert_eq!(m.sample(&live(0, gauge, phi), false), None, "settling");
        }
    }
    gauge += 3;
    assert_eq!(m.sample(&live(0, gauge, 0), false), None, "settling");
}

/// A monitor past its settling revolutions.
fn settled(c: MonitorConfig) -> Monitor {
    let mut m = Monitor::new(c);
    settle(&mut m);
    m
}

/// Until [`SETTLE_REVS`] live revolutions have passed since the
/// engagement (the spindle angle's first index correction), an error deep
/// toward the stock or ringing raises nothing; one revolution fewer is
/// still settling, and once settled three deep ticks latch the guard.
#[test]
fn the_depth_and_ring_checks_wait_for_the_settling_revolutions() {
    let c = cfg();
    let g = c.depth_guard_q8 + 1;
    let mut m = Monitor::new(c);
    let mut k = 0;
    // SETTLE_REVS turns of samples (SETTLE_REVS − 1 wraps), deep and
    // ringing (±10 guards) at every sample.
    for rev in 0..SETTLE_REVS {
        for q in 0..(4 << OSC_SHIFT) {
            let phi = (q as u32) << (32 - 2 - OSC_SHIFT);
            let e = if q % 2 == 0 { 10 * g } else { -10 * g };
            k += 1;
            assert_eq!(
                m.sample(&live(e, k, phi), false),
                None,
                "rev {rev}, sample {q}"
            );
        }
    }
    // The wrap that completes the last settling revolution: from it on
    // the depth is judged.
    assert_eq!(m.sample(&live(g, k + 1, 0), false), None);
    assert_eq!(m.sample(&live(g, k + 2, 0), false), None);
    assert_eq!(m.sample(&live(g, k + 3, 0), false), Some(Fault::DepthGuard));
}

/// The brief's limits in the monitor's units, from the parameter
/// defaults by hand: the depth guard 300 µin less the stop
/// √2·40·(1 + 2π·45 Hz·4 ticks/20 kHz) = 59.7674 µin, i.e. 240.2326 µin Q8;
/// (40 µin)² in codes², 5 ms at 20 kHz.
#[test]
fn the_defaults_convert_to_codes_and_ticks() {
    let c = cfg();
    assert_eq!(c.depth_guard_q8, uin_q8(240.2326));
    let osc = 40e-6 * CPI;
    assert_eq!(c.oscillation_sq, (osc * osc).round() as u64);
    assert_eq!(c.gauge_frozen_ticks, 100);
    assert_eq!(
        c.x_stall_revs, 0,
        "off unless the part program says X feeds"
    );
    assert_eq!(c.retract_code, (0.009 * CPI).round() as i32);
}

/// Three ticks beyond the guard toward the stock latch it; two, or the
/// guard itself, or any depth on the retract's side, do not.
#[test]
fn the_depth_guard_needs_three_ticks_beyond_it_toward_the_stock() {
    let c = cfg();
    let mut m = settled(c);
    let g = c.depth_guard_q8;
    let mut gauge = 0;
    let mut next = |m: &mut Monitor, e: i32| {
        gauge += 17;
        m.sample(&live(e, gauge, 0), false)
    };
    for _ in 0..50 {
        assert_eq!(next(&mut m, g), None, "the guard itself");
    }
    assert_eq!(next(&mut m, g + 1), None);
    assert_eq!(next(&mut m, g + 1), None);
    assert_eq!(next(&mut m, 0), None);
    assert_eq!(next(&mut m, g + 1), None);
    assert_eq!(next(&mut m, g + 1), None);
    assert_eq!(next(&mut m, g + 1), Some(Fault::DepthGuard));
    // Raised once.
    assert_eq!(next(&mut m, g + 1), None);
    let mut m = settled(c);
    for k in 0..50 {
        assert_eq!(
            m.sample(&live(-10 * g, k, 0), false),
            None,
            "out of the stock"
        );
    }
}

/// With the retract toward −Z the stock lies toward +Z: the guard
/// watches negative errors.
#[test]
fn a_retract_toward_minus_z_turns_the_guard_around() {
    let mut c = cfg();
    c.retract_code = -c.retract_code;
    let g = c.depth_guard_q8;
    let mut m = settled(c);
    for k in 0..10 {
        assert_eq!(m.sample(&live(10 * g, k, 0), false), None);
    }
    let mut m = settled(c);
    assert_eq!(m.sample(&live(-g - 1, 1, 0), false), None);
    assert_eq!(m.sample(&live(-g - 1, 2, 0), false), None);
    assert_eq!(
        m.sample(&live(-g - 1, 3, 0), false),
        Some(Fault::DepthGuard)
    );
}

/// A sine's RMS is its amplitude over √2: at 1.2 × the limit's amplitude
/// it trips within a few windows, at 0.8 × never in 40 windows, and a
/// steady offset of 3 × the limit (under the depth guard) is no ring, nor
/// a step of the error by 3 × the limit.
#[test]
fn oscillation_trips_above_its_rms_and_not_below_nor_on_an_offset() {
    let c = cfg();
    let limit_uin = 40.0;
    let run = |amp_uin: f64, offset_uin: f64, ticks: u32| {
        let mut m = settled(c);
        for k in 0..ticks {
            // 400 Hz at 20 kHz: a loop ring.
            let e =
                offset_uin + amp_uin * (core::f64::consts::TAU * 400.0 * f64::from(k) / 20e3).sin();
            if let Some(f) = m.sample(&live(uin_q8(e), k as i32, 0), false) {
                return Some((f, k));
            }
        }
        None
    };
    let (f, k) = run(1.2 * limit_uin * 2f64.sqrt(), 0.0, 40 << OSC_SHIFT).unwrap();
    assert_eq!(f, Fault::Oscillation);
    // The window's mean square reaches (1/1.2)² of its final value after
    // ln(1/(1 − 1/1.44)) = 1.19 windows, and must stay above for one.
    assert!(k < 3 << OSC_SHIFT, "{k}");
    assert_eq!(
        run(0.8 * limit_uin * 2f64.sqrt(), 0.0, 40 << OSC_SHIFT),
        None
    );
    assert_eq!(run(0.0, 3.0 * limit_uin, 40 << OSC_SHIFT), None);
    let mut m = settled(c);
    for k in 0..40 << OSC_SHIFT {
        let e = if k < 1000 { 0.0 } else { 3.0 * limit_uin };
        assert_eq!(
            m.sample(&live(uin_q8(e), k, 0), false),
            None,
            "step at 1000, tick {k}"
        );
    }
}

/// The gauge's code unchanged for the configured ticks is a frozen gauge;
/// one tick fewer, or a code that moves by one, is not.
#[test]
fn a_gauge_code_held_for_its_ticks_is_frozen_and_one_less_is_not() {
    let c = cfg();
    let n = c.gauge_frozen_ticks;
    let mut m = Monitor::new(c);
    // The first sample sets the code; n more identical ones trip.
    assert_eq!(m.sample(&live(0, 1234, 0), false), None);
    for _ in 0..n - 1 {
        assert_eq!(m.sample(&live(0, 1234, 0), false), None);
    }
    assert_eq!(
        m.sample(&live(0, 1235, 0), false),
        None,
        "moved by one code"
    );
    for _ in 0..n - 1 {
        assert_eq!(m.sample(&live(0, 1235, 0), false), None);
    }
    assert_eq!(m.sample(&live(0, 1235, 0), false), Some(Fault::GaugeFrozen));
}

/// Revolutions (the angle wrapping forward) with the command live and no
/// new X: the configured count trips; a new X starts the count again; a
/// null command counts nothing; 0 turns the check off.
#[test]
fn x_stalls_after_its_revolutions_of_live_command_without_a_new_x() {
    let mut c = cfg();
    c.x_stall_revs = 20;
    let revs = c.x_stall_revs;
    let turn = |m: &mut Monitor, g: &mut i32, freeze: Option<Freeze>| {
        let mut out = None;
        for q in 0..4u32 {
            *g += 1;
            let s = LearnSample::new(
                0,
                Some((SpindleAngle(q << 30), 1 << 30)),
                freeze,
                LearnRequests::NONE,
            )
            .with_gauge(*g);
            out = out.or(m.sample(&s, false));
        }
        out
    };
    let mut g = 0;
    let mut m = Monitor::new(c);
    for _ in 0..revs - 1 {
        assert_eq!(turn(&mut m, &mut g, None), None);
    }
    m.new_x();
    for _ in 0..revs - 1 {
        assert_eq!(turn(&mut m, &mut g, None), None);
    }
    for _ in 0..3 * revs {
        assert_eq!(turn(&mut m, &mut g, Some(Freeze::Null)), None, "null");
    }
    // The first live quarter after the null turns starts afresh: one
    // wrap is one revolution more.
    assert_eq!(m.revs_since_x(), revs - 1);
    assert_eq!(turn(&mut m, &mut g, None), None);
    assert_eq!(turn(&mut m, &mut g, None), Some(Fault::XStalled));

    let mut off = c;
    off.x_stall_revs = 0;
    let mut m = Monitor::new(off);
    for _ in 0..10 * revs {
        assert_eq!(turn(&mut m, &mut g, None), None);
    }
}

/// While a fault is latched the contour checks rest (its reaction
/// drives the tool) but a frozen gauge is still raised; a new arming
/// raises a fault raised before again.
#[test]
fn a_latched_fault_rests_the_contour_checks_but_not_the_frozen_gauge() {
    let c = cfg();
    let g = c.depth_guard_q8 + 1;
    let mut m = settled(c);
    let deep = |m: &mut Monitor, k: i32| m.sample(&live(g, k, 0), false);
    assert_eq!(deep(&mut m, 1), None);
    assert_eq!(deep(&mut m, 2), None);
    assert_eq!(deep(&mut m, 3), Some(Fault::DepthGuard));
    assert_eq!(deep(&mut m, 4), None);
    let latched = |k: i32| {
        LearnSample::new(10 * g, None, Some(Freeze::Fault), LearnRequests::NONE).with_gauge(k)
    };
    for k in 0..c.gauge_frozen_ticks {
        assert_eq!(
            m.sample(&latched(k as i32), false),
            None,
            "moving gauge, deep"
        );
    }
    // The first sets the code; n repeats of it trip.
    for _ in 0..c.gauge_frozen_ticks {
        assert_eq!(m.sample(&latched(7), false), None);
    }
    assert_eq!(m.sample(&latched(7), false), Some(Fault::GaugeFrozen));
    let mut arm = LearnRequests::NONE;
    arm.clear();
    assert_eq!(
        m.sample(&LearnSample::new(g, None, None, arm).with_gauge(8), false),
        None
    );
    // Armed again: the settling revolutions, then three deep ticks.
    settle(&mut m);
    assert_eq!(deep(&mut m, 9), None);
    assert_eq!(deep(&mut m, 10), None);
    assert_eq!(deep(&mut m, 11), Some(Fault::DepthGuard));
}

/// While the loop engages (or disarms) the command is a slew profile, not
/// the surface: an error deep toward the stock raises nothing, and the
/// engaged loop's depth guard starts afresh (three engaged ticks). A
/// frozen gauge is still raised.
#[test]
fn the_contour_checks_wait_for_the_engagement_but_the_frozen_gauge_does_not() {
    let c = cfg();
    let g = c.depth_guard_q8 + 1;
    let engaging = |e: i32, k: i32| {
        LearnSample::new(e, None, Some(Freeze::NotEngaged), LearnRequests::NONE).with_gauge(k)
    };
    let mut m = Monitor::new(c);
    // Deep and ringing (±10 guards, far above the oscillation limit)
    // for longer than the oscillation window.
    for k in 0..(4 << OSC_SHIFT) {
        let e = if k % 2 == 0 { 10 * g } else { -10 * g };
        assert_eq!(m.sample(&engaging(e, k), false), None, "engaging, tick {k}");
    }
    settle(&mut m);
    assert_eq!(m.sample(&live(g, 1, 0), false), None);
    assert_eq!(m.sample(&live(g, 2, 0), false), None);
    assert_eq!(m.sample(&live(g, 3, 0), false), Some(Fault::DepthGuard));
    let mut m = Monitor::new(c);
    for _ in 0..c.gauge_frozen_ticks {
        assert_eq!(m.sample(&engaging(0, 7), false), None);
    }
    assert_eq!(m.sample(&engaging(0, 7), false), Some(Fault::GaugeFrozen));
}

/// Over a hole (and for `edge_settle_ticks` after it) an error deep
/// toward the stock and ringing raises nothing, whatever its size; the
/// tick after that window, three deep ticks latch the guard again, and a
/// frozen gauge is raised over the hole too.
#[test]
fn over_a_hole_and_its_edges_transient_the_depth_and_ring_checks_stand_down() {
    let c = cfg();
    assert!(c.edge_settle_ticks > 0);
    let g = c.depth_guard_q8 + 1;
    let mut m = settled(c);
    let mut k = 0;
    // Two windows of ±10 guards over the hole.
    for q in 0..(2 << OSC_SHIFT) {
        k += 1;
        let e = if q % 2 == 0 { 10 * g } else { -10 * g };
        assert_eq!(m.sample(&live(e, k, 0), true), None, "over the hole, {q}");
    }
    // Deep through the edges' transient after it.
    for q in 0..c.edge_settle_ticks {
        k += 1;
        assert_eq!(m.sample(&live(10 * g, k, 0), false), None, "transient, {q}");
    }
    k += 1;
    assert_eq!(m.sample(&live(g, k, 0), false), None);
    k += 1;
    assert_eq!(m.sample(&live(g, k, 0), false), None);
    k += 1;
    assert_eq!(m.sample(&live(g, k, 0), false), Some(Fault::DepthGuard));
    // The gauge frozen over a hole: the first sets the code, n repeats
    // of it trip.
    for _ in 0..c.gauge_frozen_ticks {
        assert_eq!(m.sample(&live(0, 5, 0), true), None);
    }
    assert_eq!(m.sample(&live(0, 5, 0), true), Some(Fault::GaugeFrozen));
}
