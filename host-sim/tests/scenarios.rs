//! Scenario files: both standard files load, differ where they should, and
//! bad files are refused with the offending field named.

use host_sim::machine::{SpindleSensor, XInterface};
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
    let t = legacy_text().replace("handler_entry_ns = 1200", "");
    let e = format!("{:#}", parse(&t, "test").unwrap_err());
    assert!(e.contains("handler_entry_ns"), "{e}");
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
        ("part_side = -1.0", "part_side = 0.5", "cutting.part_side"),
        // The board's timing: the gauge sampled after the handler read it,
        // a conversion not done by then, a handler entered after the next
        // tick, a DAC frame ending before the handler's reads.
        (
            "adc_sample_ns = 0",
            "adc_sample_ns = 1500",
            "loop.adc_sample_ns",
        ),
        (
            "adc_conversion_ns = 320",
            "adc_conversion_ns = 1300",
            "loop.adc_conversion_ns",
        ),
        (
            "handler_entry_ns = 1200",
            "handler_entry_ns = 60000",
            "loop.handler_entry_ns",
        ),
        (
            "dac_latency_ns = 8500",
            "dac_latency_ns = 1000",
            "loop.dac_latency_ns",
        ),
        (
            "capture_delay_ns = 55",
            "capture_delay_ns = 200000",
            "loop.capture_delay_ns",
        ),
        (
            "encoder_edges = \"captured\"",
            "encoder_edges = \"every\"",
            "spindle.encoder_edges",
        ),
    ] {
        let t = legacy_text().replacen(from, to, 1);
        assert_ne!(t, legacy_text(), "{from}");
        let e = format!("{:#}", parse(&t, "test").unwrap_err());
        assert!(e.contains(field), "{field}: {e}");
    }
}

#[test]
fn servo_section_sets_the_loop_and_refuses_a_bad_field_by_name() {
    use host_sim::scenario::parse;
    let text = include_str!("../../scenarios/legacy-hw.toml");
    let sc = parse(text, "legacy-hw").unwrap();
    assert_eq!(sc.servo_design.bandwidth_hz, 45.0);
    assert_eq!(sc.servo, sc.servo_design.config().unwrap());
    let faster = text.replace("bandwidth_hz = 45.0", "bandwidth_hz = 60.0");
    let sc30 = parse(&faster, "x").unwrap();
    assert!(sc30.servo.kp_q24 > sc.servo.kp_q24);
    let bad = text.replace("bandwidth_hz = 45.0", "bandwidth_hz = 5000.0");
    let e = format!("{:#}", parse(&bad, "bad").unwrap_err());
    assert!(e.contains("servo.bandwidth_hz = 5000"), "{e}");
    // Below rate_hz / 20 but above the fast bandwidth (150 Hz): that
    // relation and both values are named, not the rate's.
    let above_fast = text.replace("bandwidth_hz = 45.0", "bandwidth_hz = 160.0");
    let e = format!("{:#}", parse(&above_fast, "bad").unwrap_err());
    assert!(
        e.contains("bandwidth_fast_hz = 150") && e.contains("bandwidth_hz = 160"),
        "{e}"
    );
    let unknown = text.replace("damping = 0.9", "dampng = 0.9");
    let e = format!("{:#}", parse(&unknown, "typo").unwrap_err());
    assert!(e.contains("dampng"), "{e}");
}

/// Every field of `[servo]` reaches the design (none is accepted and then
/// dropped): each is set to a value off its default and read back.
#[test]
fn every_servo_field_reaches_the_design() {
    use host_sim::scenario::parse;
    let text = include_str!("../../scenarios/legacy-hw.toml");
    let head = &text[..text.find("[servo]").unwrap()];
    let fields: [(&str, f64); 24] = [
        ("bandwidth_hz", 17.0),
        ("damping", 0.85),
        ("bandwidth_fast_hz", 90.0),
        ("observer_hz", 45.0),
        ("observer_fast_hz", 410.0),
        ("observer_switch_uin", 140.0),
        ("observer_hold_ms", 19.0),
        ("hum_notch_hz", 121.0),
        ("hum_notch_q", 2.5),
        ("mode_notch_hz", 3100.0),
        ("mode_notch_q", 0.8),
        ("learning_gain", 0.35),
        ("learning_lead_bins", 4.0),
        ("learning_q_shift", 3.0),
        ("slew_in_per_s", 0.2),
        ("slew_accel_in_per_s2", 25.0),
        ("command_limit_in", 0.009),
        ("current_limit_a", 5.5),
        ("current_limit_ms", 21.0),
        ("following_error_in", 0.003),
        ("following_error_ms", 2.5),
        ("sign_check_v", 0.3),
        ("sign_check_ms", 1.5),
        ("learning_clip_uin", 210.0),
    ];
    let mut servo = String::from("[servo]\n");
    for (k, v) in &fields {
        if k.ends_with("bins") || k.ends_with("shift") {
            servo.push_str(&format!("{k} = {}\n", *v as u32));
        } else {
            servo.push_str(&format!("{k} = {v:?}\n"));
        }
    }
    let sc = parse(&format!("{head}{servo}"), "all-fields").unwrap();
    let d = sc.servo_design;
    let got = [
        d.bandwidth_hz,
        d.damping,
        d.bandwidth_fast_hz,
        d.observer_hz,
        d.observer_fast_hz,
        d.observer_switch_uin,
        d.observer_hold_ms,
        d.hum_notch_hz,
        d.hum_notch_q,
        d.mode_notch_hz,
        d.mode_notch_q,
        d.learning_gain,
        f64::from(d.learning_lead_bins),
        f64::from(d.learning_q_shift),
        d.slew_in_per_s,
        d.slew_accel_in_per_s2,
        d.command_limit_in,
        d.current_limit_a,
        d.current_limit_ms,
        d.following_error_in,
        d.following_error_ms,
        d.sign_check_v,
        d.sign_check_ms,
        d.learning_clip_uin,
    ];
    for ((k, want), got) in fields.iter().zip(got) {
        assert_eq!(*want, got, "{k}");
    }
}

/// Follows from the spindle fuzz finding (a revolution at `min_rpm` longer
/// than the 32-bit clock is now a refused estimator configuration): the
/// loader must refuse such a file naming the field, not let the rig's
/// estimator construction panic.
#[test]
fn a_band_too_slow_for_the_clock_is_refused_by_name() {
    let t = legacy_text()
        .replacen("clock_hz = 200000000", "clock_hz = 4000000000", 1)
        .replacen("min_rpm = 100", "min_rpm = 55", 1);
    let e = format!("{:#}", parse(&t, "test").unwrap_err());
    assert!(
        e.contains("spindle.min_rpm = 55") && e.contains("min_rpm >= 56"),
        "{e}"
    );
    let t = legacy_text()
        .replacen("clock_hz = 200000000", "clock_hz = 4000000000", 1)
        .replacen("min_rpm = 100", "min_rpm = 56", 1);
    parse(&t, "test").unwrap();
}
