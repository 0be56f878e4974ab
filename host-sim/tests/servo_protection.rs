//! Every run-time protection of the servo, driven through the firmware on
//! the simulated rig (`fwrig`: the real drivers on the simulated chips, the
//! exact plant, the amplifier with its own limit and trip): what trips it,
//! the reaction, and the state the machine is left in.

use host_sim::cmd::bench::firmware_demo;
use host_sim::fwrig::FirmwareWorld;
use host_sim::plant::amplifier::AmpRegime;
use host_sim::plant::{GaugeParams, RigConfig};
use host_sim::sched::Scheduler;
use zslide::firmware::Request;
use zslide::safety::{Fault, Reaction};
use zslide::servo::Phase;
use zslide::units::ZInches;

const MS: u64 = 1_000_000;

fn quiet() -> RigConfig {
    RigConfig {
        gauge: GaugeParams::noiseless(),
        ..RigConfig::legacy(1)
    }
}

fn armed(cfg: RigConfig) -> (FirmwareWorld, Scheduler<FirmwareWorld>) {
    let (mut w, mut s) = firmware_demo(cfg, 20_000);
    w.request(Request::Arm);
    s.run_until(&mut w, 100 * MS);
    assert_eq!(w.fw.fault(), None);
    assert_eq!(w.fw.servo().phase(), Phase::Engaged);
    (w, s)
}

/// Chapter 5's first part was cut with the command sign reversed. A gauge
/// wired reversed (the firmware not told) fails the commissioning doublet:
/// `Fault::SignCheck`, amplifier disabled, before the loop ever closes; the
/// slide moved only by the doublet (< 500 µin).
#[test]
fn reversed_gauge_fails_the_sign_check_before_the_loop_closes() {
    let mut cfg = quiet();
    cfg.gauge.reversed = true;
    let (mut w, mut s) = firmware_demo(cfg, 20_000);
    w.request(Request::Arm);
    s.run_until(&mut w, 50 * MS);
    assert_eq!(w.fw.fault(), Some(Fault::SignCheck));
    assert!(!w.fw.amplifier_enable());
    assert_eq!(w.rig.amp.regime(), AmpRegime::Off);
    let r = w.fw.servo().last_sign_check().unwrap();
    assert!(r.moved_code < 0 && r.expected_code > 0, "{r:?}");
    assert!(w.rig.slide.position_in().abs() < 500e-6);
    assert!(Fault::SignCheck.reason().contains("sign check"));
}

/// A push the loop cannot hold within its estimated current (20 lbf against
/// 6 A × 2.9 lbf/A = 17.4 lbf) saturates the output; held past the limit
/// time (5 ms here, before the slide leaves the gauge's range) it is
/// `Fault::CurrentLimit`: amplifier disabled, and the amplifier itself
/// never reached its own 8 A limit or tripped.
#[test]
fn a_push_beyond_the_current_limit_opens_the_loop_before_the_amplifier_trips() {
    let mut d = zslide::servo::ServoDesign::brief(20_000);
    d.current_limit_ms = 5.0;
    let (mut w, mut s) = host_sim::fwrig::firmware_with(quiet(), 20_000, d.config().unwrap());
    w.request(Request::Arm);
    s.run_until(&mut w, 100 * MS);
    w.rig.set_force_lbf(20.0);
    s.run_until(&mut w, 200 * MS);
    assert_eq!(w.fw.fault(), Some(Fault::CurrentLimit));
    assert_eq!(Fault::CurrentLimit.reaction(), Reaction::DisableAmplifier);
    assert!(!w.fw.amplifier_enable());
    assert_eq!(w.rig.amp.trips, 0);
    assert_eq!(w.rig.amp.limit_entries, 0);
}

/// A weak amplifier (4 A) against a 16 lbf push: the loop asks for 5.5 A
/// (inside its own estimate limit) and cannot get it; the slide is pushed
/// away and |reference − gauge| > 0.004 in for 2 ms is
/// `Fault::FollowingError`: the loop stays closed and ramps to null.
#[test]
fn following_error_beyond_its_limit_ramps_to_null_with_the_loop_closed() {
    let mut cfg = quiet();
    cfg.amplifier.current_limit_a = 4.0;
    cfg.amplifier.trip_after_s = 10.0;
    let (mut w, mut s) = armed(cfg);
    w.rig.set_force_lbf(16.0);
    let mut t = 100 * MS;
    while w.fw.fault().is_none() && t < 400 * MS {
        t += MS;
        s.run_until(&mut w, t);
    }
    assert_eq!(w.fw.fault(), Some(Fault::FollowingError));
    assert!(w.fw.amplifier_enable(), "RampToNull keeps the loop closed");
    s.run_until(&mut w, t + 50 * MS);
    assert_eq!(w.fw.command_code(), 0);
}

/// The amplifier's own trip (its fault line) is `Fault::AmplifierTrip`:
/// the loop opens. A 2 A amplifier against a 10 lbf push trips after 2 ms
/// in its limit.
#[test]
fn amplifier_trip_seen_on_its_fault_line_opens_the_loop() {
    let mut cfg = quiet();
    cfg.amplifier.current_limit_a = 2.0;
    let (mut w, mut s) = armed(cfg);
    w.rig.set_force_lbf(10.0);
    s.run_until(&mut w, 150 * MS);
    assert!(w.rig.amp.trips >= 1);
    assert_eq!(w.fw.fault(), Some(Fault::AmplifierTrip));
    assert!(!w.fw.amplifier_enable());
}

/// Slew and range: a 0.012 in target step is approached at ≤ 20 in/s² up
/// to 0.25 in/s (0.25 in/s is reached after 12.5 ms, 1560 µin) and the
/// command stops at its limit, 0.0095 in, inside the gauge's ±0.010 in;
/// the slide settles there without leaving the gauge's range.
#[test]
fn command_slews_at_its_limit_and_stops_at_its_range() {
    // The quietest real gauge (modern-hw's 0.2 µin RMS): a noiseless one
    // held at the range's end repeats its code, which is `GaugeFrozen`.
    let (mut w, mut s) = armed(RigConfig {
        gauge: GaugeParams::modern(),
        ..RigConfig::legacy(1)
    });
    let start = w.fw.command_code();
    w.fw.set_target(ZInches::from_f64(0.012));
    s.run_until(&mut w, 100 * MS + 10 * MS);
    // ½·20 in/s²·(10 ms)² = 1000 µin = 52 429 codes.
    let moved = w.fw.command_code() - start;
    assert!((51_000..=53_000).contains(&moved), "{moved}");
    s.run_until(&mut w, 100 * MS + 30 * MS);
    let moved = w.fw.command_code() - start;
    // 1560 µin of acceleration, then 17.5 ms at 0.25 in/s: 5940 µin.
    assert!((305_000..=318_000).contains(&moved), "{moved}");
    s.run_until(&mut w, 400 * MS);
    assert_eq!(
        w.fw.command_code(),
        (0.0095 * 524_288.0 / 0.010) as i32,
        "command limit"
    );
    let z = w.rig.slide.position_in();
    assert!((z - 0.0095).abs() < 2e-6, "{z}");
    assert_eq!(w.fw.fault(), None);
}

/// The gauge out of its range while the loop runs (a weak amplifier loses
/// the slide to a push past +0.010 in; the AD4020 flags overrange) is
/// `Fault::GaugeRange`: the loop cannot see the slide, so the amplifier is
/// disabled. (A rail reading without the flag, `GaugeSaturated`, is tested
/// on the core.)
#[test]
fn gauge_out_of_range_while_running_disables_the_amplifier() {
    let mut cfg = quiet();
    cfg.amplifier.current_limit_a = 1.0;
    cfg.amplifier.trip_after_s = 10.0;
    let (mut w, mut s) = armed(cfg);
    w.rig.set_force_lbf(8.0);
    s.run_until(&mut w, 400 * MS);
    assert_eq!(w.fw.fault(), Some(Fault::GaugeRange));
    assert!(!w.fw.amplifier_enable());
}
