//! Scenario files: both standard files load, differ where they should, and
//! bad files are refused with the offending field named.

use host_sim::fwrig::{SpindleSensor, XInterface};
use host_sim::plant::{GaugeParams, ZSlideParams};
use host_sim::scenario::{load, parse};

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

#[test]
fn legacy_and_modern_load_and_differ_where_they_should() {
    let l = load("legacy-hw").unwrap();
    let m = load("modern-hw").unwrap();
    // same motor and slide: the Model 15 numbers of chapter 4
    let p = ZSlideParams::model15();
    for (a, b) in [
        (l.rig.slide.kf_lbf_per_a, 2.9),
        (l.rig.slide.kb_v_s_per_in, 4.002 / 12.0),
        (l.rig.slide.r_ohm, 1.4),
        (l.rig.slide.l_h, 0.26e-3 * 1.4),
        (l.rig.slide.mass_lbf_s2_per_in, 6.25 / 32.174 / 12.0),
        (l.rig.slide.b_lbf_s_per_in, 51.2 / 12.0),
        (l.rig.slide.mass_lbf_s2_per_in, p.mass_lbf_s2_per_in),
    ] {
        assert!(rel(a, b) < 1e-12, "{a} vs {b}");
    }
    assert_eq!(l.rig.slide, m.rig.slide);
    assert_eq!(l.rig.slide.mode, p.mode);
    assert_eq!(l.rig.amplifier, m.rig.amplifier);
    assert_eq!(l.loop_hz, 20_000);
    // legacy gauge: 10 µin RMS in total with a 5 µin-peak 120 Hz hum
    let g = &l.rig.gauge;
    let total = (g.white_rms_in.powi(2) + g.hum_amp_in.powi(2) / 2.0).sqrt();
    assert!((total - 10e-6).abs() < 1e-9, "{total}");
    assert_eq!(g.hum_hz, 120.0);
    assert!(rel(g.hum_amp_in, 5e-6) < 1e-12);
    assert!(rel(g.white_rms_in, GaugeParams::legacy().white_rms_in) < 1e-4);
    // modern gauge: low noise, no hum
    assert_eq!(m.rig.gauge.hum_amp_in, 0.0);
    assert!(m.rig.gauge.white_rms_in <= 0.2e-6);
    // interfaces
    assert!(matches!(l.machine.x, XInterface::LegacyBcd(_)));
    assert!(matches!(m.machine.x, XInterface::Quadrature(_)));
    assert_eq!(l.machine.sensor, SpindleSensor::TachIndex);
    assert_eq!(m.machine.sensor, SpindleSensor::EncoderIndex);
    // 300 rpm with sag; the spindle clock is the firmware clock
    assert_eq!(l.machine.spindle.rpm0, 300.0);
    assert!(l.machine.spindle.sag_rpm > 0.0);
    assert_eq!(l.machine.spindle.ticks_per_s, l.rig.clock_hz as f64);
    // 5 V at 300 rpm
    assert!((l.machine.spindle.tach_mv_per_rpm * 300.0 - 5000.0).abs() < 0.01);
}

#[test]
fn files_on_disk_are_the_built_in_ones_and_load_by_path() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/");
    for name in ["legacy-hw", "modern-hw"] {
        let by_path = load(&format!("{root}{name}.toml")).unwrap();
        assert_eq!(by_path, load(name).unwrap());
        assert_eq!(by_path.file.name, name);
    }
    let e = load("no-such-scenario").unwrap_err();
    assert!(format!("{e:#}").contains("no-such-scenario"));
}

fn legacy_text() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/legacy-hw.toml"
    ))
    .unwrap()
}

#[test]
fn unknown_fields_are_refused_by_name() {
    let t = legacy_text().replace("[gauge]", "[gauge]\nhum_freq = 60.0");
    let e = format!("{:#}", parse(&t, "test").unwrap_err());
    assert!(e.contains("hum_freq"), "{e}");
    let t = format!("rpm = 300\n{}", legacy_text());
    let e = format!("{:#}", parse(&t, "test").unwrap_err());
    assert!(e.contains("rpm"), "{e}");
    // a missing field is named too
    let t = legacy_text().replace("hum_hz = 120.0", "");
    let e = format!("{:#}", parse(&t, "test").unwrap_err());
    assert!(e.contains("hum_hz"), "{e}");
}

#[test]
fn out_of_range_values_are_refused_by_name() {
    for (from, to, field) in [
        ("rpm = 300.0", "rpm = -5.0", "spindle.rpm"),
        (
            "current_limit_a = 8.0",
            "current_limit_a = 0.0",
            "amplifier.current_limit_a",
        ),
        ("zero_hz = 2950.0", "zero_hz = 3500.0", "mode.zero_hz"),
        ("rate_hz = 20000", "rate_hz = 10", "loop.rate_hz"),
        ("ripple_prob = 0.01", "ripple_prob = 1.5", "x.ripple_prob"),
        (
            "interface = \"legacy-bcd\"",
            "interface = \"bcd\"",
            "x.interface",
        ),
        ("part_side = 1.0", "part_side = 0.5", "cutting.part_side"),
    ] {
        let t = legacy_text().replacen(from, to, 1);
        assert_ne!(t, legacy_text(), "{from}");
        let e = format!("{:#}", parse(&t, "test").unwrap_err());
        assert!(e.contains(field), "{field}: {e}");
    }
}

/// Follows from the spindle fuzz finding (a revolution at `min_rpm` longer
/// than the 32-bit clock is now a refused estimator configuration): the
/// loader must refuse such a file naming the field, not let the rig's
/// estimator construction panic.
#[test]
fn a_band_too_slow_for_the_clock_is_refused_by_name() {
    let t = legacy_text()
        .replacen("clock_hz = 100000000", "clock_hz = 4000000000", 1)
        .replacen("min_rpm = 100", "min_rpm = 55", 1);
    let e = format!("{:#}", parse(&t, "test").unwrap_err());
    assert!(
        e.contains("spindle.min_rpm = 55") && e.contains("min_rpm >= 56"),
        "{e}"
    );
    let t = legacy_text()
        .replacen("clock_hz = 100000000", "clock_hz = 4000000000", 1)
        .replacen("min_rpm = 100", "min_rpm = 56", 1);
    parse(&t, "test").unwrap();
}
