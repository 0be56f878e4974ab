//! Tuning harness: the servo alone on the rig (temporary).
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
            eprintln!("fault {f:?} at {i}");
            return (f64::NAN, f64::NAN, f64::NAN);
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

#[test]
fn tune() {
    let base = ServoDesign::brief(20_000);
    for (kl, qs, lead) in [(0.2, 2, 3), (0.15, 2, 3)] {
        for bw in [16.0, 18.0] {
            let mut d = base;
            d.bandwidth_hz = bw;
            d.observer_hz = 40.0;
            d.learning_gain = kl;
            d.learning_q_shift = qs;
            d.learning_lead_bins = lead;
            eprint!("bw {bw} ");
            eprintln!(
                "kl {kl} q {qs} lead {lead}: null rc {:?} track {:?}",
                run(d, RigConfig::legacy(7), 0.0, 10.0, 8.0),
                run(d, RigConfig::legacy(7), 0.004, 10.0, 8.0)
            );
        }
    }
    let d = ServoDesign::brief(20_000);
    let (rms, pk, i) = run(d, RigConfig::legacy(7), 0.0, 10.0, 6.0);
    eprintln!("null legacy: rms {rms:.3} uin, peak {pk:.3}, current {i:.4} A");
    let (rms, pk, i) = run(d, RigConfig::legacy(7), 0.004, 10.0, 6.0);
    eprintln!("track 10 Hz: rms {rms:.3} uin, peak {pk:.3}, current {i:.4} A");
    eprintln!("vel noise gain {:?}", d.velocity_noise_gain());
}
