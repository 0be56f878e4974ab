//! The servo alone on the simulated rig: the core's `Servo` between the real
//! AD4020/AD5791 drivers and the exact plant (`host_sim::plant::Rig`, with
//! the coil inductance, the 3150 Hz mode, the amplifier's limit and trip,
//! and the scenario's gauge noise and hum), with a synthetic spindle whose
//! speed profile each test sets. The figures of issue 8 on `legacy-hw`.

use embedded_hal::digital::OutputPin;
use host_sim::plant::{Rig, RigConfig};
use zslide::drivers::ad4020::Ad4020;
use zslide::drivers::ad5791::Ad5791;
use zslide::hw::{AmplifierDac, GaugeAdc};
use zslide::safety::Fault;
use zslide::servo::{LearnedTable, Learner, Reference, Servo, ServoDesign, ServoInput};
use zslide::units::SpindleAngle;

const TURN: f64 = 4_294_967_296.0;
const CODES_PER_IN: f64 = 524_288.0 / 0.010;

struct Run {
    /// Command amplitude (in) and harmonic per revolution: Z = A(sin kθ − 1).
    amp_in: f64,
    k: f64,
    /// Spindle speed (rev/s) at angle θ (revolutions).
    speed: Box<dyn Fn(f64) -> f64>,
    /// External force on the slide along +Z (lbf) at time t and angle θ.
    force: Box<dyn Fn(f64, f64) -> f64>,
    secs: f64,
    /// Measurement window start, s.
    from_s: f64,
    /// What the firmware tells the learning (`Freeze::Null` at null).
    freeze: Option<zslide::servo::Freeze>,
}

#[derive(Debug)]
struct Result {
    rms_uin: f64,
    peak_uin: f64,
    current_peak_a: f64,
    amp_trips: u32,
    fault: Option<Fault>,
    /// Largest |disturbance estimate| (the loop's integrator), DAC codes.
    d_peak_codes: f64,
    /// |slide position − command| at the end, µin.
    final_error_uin: f64,
}

fn run(design: ServoDesign, rig_cfg: RigConfig, r: Run) -> Result {
    let mut rig = Rig::new(rig_cfg);
    let dev = rig.devices();
    let mut adc = Ad4020::new(dev.gauge_adc);
    let mut dac = Ad5791::new(dev.amp_dac);
    dac.init().unwrap();
    let mut en = dev.amp_enable;
    let cfg = design.config().unwrap();
    let mut servo = Servo::new(cfg);
    // The learning runs after every tick, as below the loop tick on a board.
    let (mut learner, learned) = (Learner::new(&cfg), LearnedTable::new());
    servo.arm();
    let fs = f64::from(design.rate_hz);
    let h_ns = (1e9 / fs) as u64;
    let n = (r.secs * fs) as u64;
    let mut theta = 0.0f64; // revolutions
    let (mut s2, mut sum, mut cnt, mut peak, mut ipk) = (0.0, 0.0, 0.0, 0.0f64, 0.0f64);
    let mut enabled = false;
    let mut fault = None;
    let mut d_peak = 0.0f64;
    let mut last_err = 0.0;
    for i in 1..=n {
        let t = i * h_ns;
        let ts = t as f64 * 1e-9;
        rig.time.set(t);
        rig.advance_to(t);
        let rev_per_tick = (r.speed)(theta) / fs;
        theta += rev_per_tick;
        rig.set_force_lbf((r.force)(ts, theta));
        rig.cnv();
        let y = adc.read().unwrap().code;
        let th = theta * std::f64::consts::TAU;
        let w = std::f64::consts::TAU * rev_per_tick; // rad per tick
        let k = r.k;
        let z = r.amp_in * ((k * th).sin() - 1.0);
        let v = r.amp_in * k * w * (k * th).cos();
        let a = -r.amp_in * k * k * w * w * (k * th).sin();
        let phi = SpindleAngle(((theta.fract()) * TURN) as u32);
        let dphi = (rev_per_tick * TURN) as i32;
        let out = servo.update(
            &ServoInput {
                gauge_code: y,
                reference: Reference {
                    code: (z * CODES_PER_IN).round() as i32,
                    velocity_q16: (v * CODES_PER_IN * 65536.0) as i32,
                    accel_q16: (a * CODES_PER_IN * 65536.0) as i32,
                },
                angle: Some((phi, dphi)),
                freeze: r.freeze,
                amplifier_tripped: rig.amp.tripped(),
                correction_ahead: None,
                edge_q8: None,
            },
            &learned,
        );
        if let Some(s) = &out.learn {
            learner.apply(s, &learned);
        }
        if fault.is_none() {
            fault = out.fault;
        }
        d_peak = d_peak.max((f64::from(servo.estimate().d_q8) / 256.0).abs());
        last_err = rig.slide.position_in() - z;
        dac.write(out.dac_code).unwrap();
        if out.enable != enabled {
            enabled = out.enable;
            if enabled {
                en.set_high().unwrap()
            } else {
                en.set_low().unwrap()
            }
        }
        if ts >= r.from_s {
            let e = rig.slide.position_in() - z;
            s2 += e * e;
            sum += e;
            cnt += 1.0;
            peak = peak.max(e.abs());
            ipk = ipk.max(rig.slide.current_a().abs());
        }
    }
    let mean = sum / cnt;
    Result {
        rms_uin: (s2 / cnt - mean * mean).max(0.0).sqrt() * 1e6,
        peak_uin: peak * 1e6,
        current_peak_a: ipk,
        amp_trips: rig.amp.trips,
        fault,
        d_peak_codes: d_peak,
        final_error_uin: last_err.abs() * 1e6,
    }
}

fn steady(rps: f64) -> Box<dyn Fn(f64) -> f64> {
    Box::new(move |_| rps)
}

fn no_force() -> Box<dyn Fn(f64, f64) -> f64> {
    Box::new(|_, _| 0.0)
}

/// 10 Hz × 0.004 in at 300 rpm (2 per revolution), 12 s, measured over
/// the last 4 s (20 revolutions) after 40 of learning.
fn track_10hz() -> Run {
    Run {
        amp_in: 0.004,
        k: 2.0,
        speed: steady(5.0),
        force: no_force(),
        secs: 12.0,
        from_s: 8.0,
        freeze: None,
    }
}

/// At null, on the legacy-hw gauge (9.35 µin broadband with a 5 µin
/// 120 Hz hum, ≈ 10 µin RMS), the slide's true motion from gauge noise is
/// at most a quarter of the gauge's RMS (measured 2.0 µin). The loop is
/// fast enough to hold the cut's process spring (45 Hz error dynamics,
/// 250 Hz observer), so it passes more noise than a slow loop would (the
/// 16 Hz / 40 Hz design passed 0.88 µin but rang under the cut:
/// docs/TUNING.md). At null the firmware freezes the learning
/// (`Freeze::Null`: the table's command is null).
#[test]
fn gauge_noise_moves_the_slide_less_than_a_quarter_of_its_rms_at_null() {
    let r = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        Run {
            amp_in: 0.0,
            freeze: Some(zslide::servo::Freeze::Null),
            ..track_10hz()
        },
    );
    eprintln!("at null: {r:?}");
    assert!(r.rms_uin <= 0.25 * 10.0, "{r:?}");
}

/// The 1979 plan's dynamic-error goal: a 10 Hz × 0.004 in spindle-synchronous
/// command followed within 10 µin peak (true slide position from the plant
/// minus the exact command) after learning (`host-sim track` on legacy-hw:
/// 7.8 µin peak, gauge noise through the 45 Hz loop).
#[test]
fn ten_hz_command_is_followed_within_ten_microinch_peak_after_learning() {
    let r = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        track_10hz(),
    );
    assert!(r.peak_uin <= 10.0 && r.fault.is_none(), "{r:?}");
}

/// Issue 8: stable and within 2× of its nominal tracking with the plant's
/// gain ±20 % (force constant), moving mass ±10 % and mode frequency ±10 %,
/// every combination, while the firmware's model stays nominal.
#[test]
fn tracking_holds_within_twice_nominal_over_plant_variations() {
    let nominal = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        track_10hz(),
    );
    let mut worst: (f64, String) = (0.0, String::new());
    for g in [0.8, 1.2] {
        for m in [0.9, 1.1] {
            for f in [0.9, 1.1] {
                let mut cfg = RigConfig::legacy(7);
                cfg.slide.kf_lbf_per_a *= g;
                cfg.slide.mass_lbf_s2_per_in *= m;
                if let Some(mode) = cfg.slide.mode.as_mut() {
                    mode.pole_hz *= f;
                    mode.zero_hz *= f;
                }
                let r = run(ServoDesign::brief(20_000), cfg, track_10hz());
                eprintln!("gain {g} mass {m} mode {f}: {r:?}");
                assert!(
                    r.fault.is_none() && r.amp_trips == 0,
                    "gain {g} mass {m} mode {f}: {r:?}"
                );
                if r.peak_uin > worst.0 {
                    worst = (r.peak_uin, format!("gain {g} mass {m} mode {f}: {r:?}"));
                }
            }
        }
    }
    eprintln!(
        "worst / nominal peak: {:.2} ({}; nominal {nominal:?})",
        worst.0 / nominal.peak_uin,
        worst.1
    );
    assert!(
        worst.0 <= 2.0 * nominal.peak_uin,
        "nominal {:?}; worst {}",
        nominal,
        worst.1
    );
}

/// Issue 8 / chapter 5: the tool leaving a bolt hole, a 10 lbf (3.5 A at
/// 2.9 lbf/A) thrust released within 3° of spindle angle at 300 rpm, does
/// not trip the amplifier nor fault the loop (the following-error limit is
/// 0.004 in); the spike stays below 3000 µin (measured 2030 µin; 1983:
/// several hundred, from an analog loop that passed 20 µin of gauge noise
/// to the amplifier). The limit is the gauge-only sensing: the loop keeps
/// its 250 Hz observer (`ServoDesign::brief`: `observer_hz`) and switches to
/// the 800 Hz one (`observer_fast_hz`) only once the innovation exceeds
/// 150 µin (`observer_switch_uin`); in a cut the holes repeat every
/// revolution and the learning takes them out.
#[test]
fn sudden_loss_of_cutting_force_does_not_trip_and_the_spike_is_bounded() {
    let r = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(3),
        Run {
            amp_in: 0.0,
            k: 2.0,
            speed: steady(5.0),
            force: Box::new(|t, _| {
                let f = 10.0;
                if t < 0.2 {
                    0.0
                } else if t < 0.3 {
                    -f * (t - 0.2) / 0.1
                } else if t < 1.0 {
                    -f
                } else {
                    -f * (1.0 - ((t - 1.0) / 1.67e-3).min(1.0))
                }
            }),
            secs: 1.3,
            from_s: 1.0,
            freeze: None,
        },
    );
    eprintln!("bolt-hole release: {r:?}");
    assert!(r.amp_trips == 0 && r.fault.is_none(), "{r:?}");
    assert!(r.peak_uin < 3000.0, "{r:?}");
    // The coil current stays within the servo's 6 A estimate limit, well
    // below the amplifier's 8 A.
    assert!(r.current_peak_a < 6.0, "{r:?}");
}

/// Issue 8: the spindle sagging 5 % within a revolution (300 → 285 rpm and
/// back, once per revolution, under a cutting torque that follows the
/// part) does not make the angle-indexed learning diverge: the tracking
/// after learning stays within 2× of the steady-speed figure.
#[test]
fn five_percent_sag_within_a_revolution_does_not_make_learning_diverge() {
    let steady_run = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        track_10hz(),
    );
    let sag = run(
        ServoDesign::brief(20_000),
        RigConfig::legacy(7),
        Run {
            speed: Box::new(|th| 5.0 * (1.0 - 0.025 * (1.0 - (std::f64::consts::TAU * th).cos()))),
            ..track_10hz()
        },
    );
    assert!(sag.fault.is_none(), "{sag:?}");
    assert!(
        sag.peak_uin <= 2.0 * steady_run.peak_uin.max(5.0),
        "steady {steady_run:?}, sag {sag:?}"
    );
}

/// Anti-windup: the loop's integrator is the observer's disturbance state,
/// which integrates the gauge's disagreement with the model driven by the
/// DAC code actually written (after the current limit), not by what the
/// loop wanted. A 20 lbf push (ramped over 20 ms, held 10 ms) saturates the output at the 6 A
/// estimate (17.4 lbf): the disturbance estimate rises to the push's
/// equivalent, 20 lbf / (Kf/R · G) = 0.966 V = 50 600 DAC codes, and no
/// further (its clamp is 2²⁰ codes), and after the release the slide is
/// back within 2 µin of null 330 ms later, without a fault.
#[test]
fn integrator_does_not_wind_up_while_the_output_is_current_limited() {
    // Noiseless gauge: the test is about the integrator, not the noise; the
    // following-error check at its widest (the push moves the slide by
    // physics: 2.6 lbf beyond the limit accelerate it freely).
    let mut d = ServoDesign::brief(20_000);
    d.following_error_in = 0.010;
    // The push holds the current at its limit for ≈ 40 ms; the current
    // fault (its own test) would end the run before the release.
    d.current_limit_ms = 200.0;
    let cfg = RigConfig {
        gauge: host_sim::plant::GaugeParams::noiseless(),
        ..RigConfig::legacy(5)
    };
    let r = run(
        d,
        cfg,
        Run {
            amp_in: 0.0,
            k: 2.0,
            speed: steady(5.0),
            force: Box::new(|t, _| {
                // up over 20 ms, 10 ms held, down over 20 ms
                let u = ((t - 0.3) / 0.02).clamp(0.0, 1.0) - ((t - 0.33) / 0.02).clamp(0.0, 1.0);
                20.0 * u
            }),
            secs: 0.7,
            from_s: 0.3,
            freeze: Some(zslide::servo::Freeze::Null),
        },
    );
    eprintln!("{r:?}");
    assert!(r.fault.is_none() && r.amp_trips == 0, "{r:?}");
    assert!(r.d_peak_codes < 1.3 * 50_600.0, "wound up: {r:?}");
    assert!(
        r.current_peak_a > 5.5,
        "the push must saturate the output: {r:?}"
    );
    assert!(r.final_error_uin < 2.0, "{r:?}");
}
