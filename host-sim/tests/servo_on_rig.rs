//! The servo alone on the simulated rig (the core's `Servo` between the
//! real AD4020/AD5791 drivers and the exact plant), with a synthetic
//! spindle at 300 rpm: the noise and tracking figures of issue 8.
use embedded_hal::digital::OutputPin;
use host_sim::plant::{Rig, RigConfig};
use zslide::drivers::ad4020::Ad4020;
use zslide::drivers::ad5791::Ad5791;
use zslide::hw::{AmplifierDac, GaugeAdc};
use zslide::servo::{Reference, Servo, ServoDesign, ServoInput};
use zslide::units::SpindleAngle;

fn run(design: ServoDesign, cfg: RigConfig, amp_in: f64, freq: f64, secs: f64) -> (f64, f64, f64) {
    let mut rig = Rig::new(cfg);
    let dev = rig.devices();
    let mut adc = Ad4020::new(dev.gauge_adc);
    let mut dac = Ad5791::new(dev.amp_dac);
    dac.init().unwrap();
    let mut en = dev.amp_enable;
    let mut servo = Servo::new(design.config().unwrap());
    servo.arm();
    let fs = design.rate_hz as f64;
    let h_ns = (1e9 / fs) as u64;
    let rpm = 300.0;
    let turn = 4294967296.0;
    let dphi = (rpm / 60.0 / fs * turn) as u32;
    let k = (freq / (rpm / 60.0)).round().max(1.0);
    let cpi = 524288.0 / 0.010;
    let mut phi: u32 = 0;
    let n = (secs * fs) as u64;
    let (mut s2, mut peak, mut cnt, mut cur2) = (0.0, 0.0f64, 0.0, 0.0);
    let mut sum = 0.0;
    let mut enabled = false;
    for i in 1..=n {
        let t = i * h_ns;
        rig.time.set(t);
        rig.advance_to(t);
        rig.cnv();
        let y = adc.read().unwrap().code;
        phi = phi.wrapping_add(dphi);
        let th = phi as f64 / turn * std::f64::consts::TAU;
        let w = std::f64::consts::TAU * dphi as f64 / turn; // rad/tick
        let r = amp_in * ((k * th).sin() - 1.0);
        let v = amp_in * k * w * (k * th).cos();
        let a = -amp_in * k * k * w * w * (k * th).sin();
        let reference = Reference {
            code: (r * cpi).round() as i32,
            velocity_q16: (v * cpi * 65536.0) as i64,
            accel_q16: (a * cpi * 65536.0) as i64,
        };
        let out = servo.update(&ServoInput {
            gauge_code: y,
            reference,
            angle: Some((SpindleAngle(phi), dphi as i32)),
            freeze: None,
            amplifier_tripped: rig.amp.tripped(),
        });
        if std::env::var("TRACE").is_ok() && (i < 200 || i % 100 == 0) && i < 3000 {
            let e = servo.estimate();
            eprintln!(
                "{i} {:?} y={y} u={} z^={} v^={} d^={} cmd={} en={}",
                servo.phase(),
                out.dac_code,
                e.z_q16 >> 16,
                e.v_q16 as f64 / 65536.0,
                e.d_q16 >> 16,
                servo.command_code(),
                out.enable
            );
        }
        if let Some(f) = out.fault {
            panic!("fault {f:?} at tick {i}");
        }
        dac.write(out.dac_code).unwrap();
        if out.enable != enabled {
            enabled = out.enable;
            if enabled {
                en.set_high().unwrap()
            } else {
                en.set_low().unwrap()
            }
        }
        if std::env::var("REV").is_ok() && i % 4000 == 0 {
            eprintln!(
                "rev {} table peak {} frozen {:?} err {:.2}",
                i / 4000,
                servo.learning().peak_code(),
                servo.learning().frozen(),
                (rig.slide.position_in() - r) * 1e6
            );
        }
        if i > n / 2 {
            let e = rig.slide.position_in() - r;
            s2 += e * e;
            sum += e;
            peak = peak.max(e.abs());
            cnt += 1.0;
            cur2 += rig.slide.current_a().powi(2);
        }
    }
    let mean = sum / cnt;
    (
        (s2 / cnt - mean * mean).sqrt() * 1e6,
        peak * 1e6,
        (cur2 / cnt).sqrt(),
    )
}

/// Brief §6 / issue 8: at null, on the legacy-hw gauge (9.35 µin broadband
/// with a 5 µin 120 Hz hum), the slide's true motion from gauge noise is
/// at most 1 µin RMS with the learning running (measured 0.92 µin over the
/// last 4 s of 8 s).
#[test]
fn gauge_noise_moves_the_slide_less_than_one_microinch_rms_at_null() {
    let (rms, _, _) = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        0.0,
        10.0,
        8.0,
    );
    assert!(rms <= 1.0, "{rms} µin RMS");
}

/// The 1979 plan's dynamic-error goal: a 10 Hz × 0.004 in spindle-synchronous
/// command followed within 10 µin peak (true slide position from the plant
/// minus the exact command) after 20 revolutions of learning, on the
/// legacy-hw noise (measured 7.0 µin peak, 1.9 µin RMS).
#[test]
fn ten_hz_command_is_followed_within_ten_microinch_peak_after_learning() {
    let (rms, peak, _) = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        0.004,
        10.0,
        8.0,
    );
    assert!(peak <= 10.0, "{peak} µin peak, {rms} RMS");
}
