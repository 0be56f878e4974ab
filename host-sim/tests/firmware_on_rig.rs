//! The firmware's own loop tick (`zslide::firmware`) on the simulated rig:
//! bumpless engagement from off null, and the safe reaction to converter
//! bus errors injected in the simulated chips.

use host_sim::chips::BusFault;
use host_sim::cmd::bench::firmware_demo;
use host_sim::plant::amplifier::AmpRegime;
use host_sim::plant::zslide::st;
use host_sim::plant::{GaugeParams, RigConfig};
use zslide::firmware::Request;
use zslide::safety::{Device, Fault};

fn quiet() -> RigConfig {
    RigConfig {
        gauge: GaugeParams::noiseless(),
        ..RigConfig::legacy(1)
    }
}

#[test]
fn engages_bumpless_off_null_and_holds_null() {
    let (mut w, mut s) = firmware_demo(quiet(), 20_000);
    w.rig.slide.x[st::Z] = 0.002; // 2 mil off null, as the 1983 slide often was
    s.run_until(&mut w, 50_000_000);
    assert!(
        !w.rig.amp.enabled(),
        "the amplifier never enables on its own"
    );
    w.request(Request::Arm);
    s.run_until(&mut w, 300_000_000);
    assert_eq!(w.fw.fault(), None);
    assert!(w.rig.amp.enabled());
    assert_eq!(w.rig.amp.trips, 0, "engagement must not trip the amplifier");
    assert!(
        w.rig.slide.position_in().abs() < 1e-6,
        "z = {}",
        w.rig.slide.position_in()
    );
    // the first tick engaged where the slide was: no current spike
    assert!(w.rig.amp.limit_entries == 0);
}

#[test]
fn gauge_bus_error_opens_the_loop_safely() {
    for fault in [BusFault::Error, BusFault::StuckHigh, BusFault::StuckLow] {
        let (mut w, mut s) = firmware_demo(quiet(), 20_000);
        w.request(Request::Arm);
        s.run_until(&mut w, 10_000_000);
        assert!(w.rig.amp.enabled());
        w.rig.adc.state.borrow_mut().faults.inject(fault, 1);
        s.run_until(&mut w, 20_000_000);
        assert_eq!(
            w.fw.fault(),
            Some(Fault::Bus(Device::GaugeAdc)),
            "{fault:?}"
        );
        // DAC clamped to ground (0 V at the amplifier), amplifier disabled
        assert_eq!(w.rig.dac.state.borrow().output_volts(), 0.0);
        assert!(w.fw.dac_clamped());
        assert_eq!(w.rig.amp.regime(), AmpRegime::Off);
        assert_eq!(w.rig.slide.current_a(), 0.0);
    }
}

/// After a disabling fault the converter is clamped to ground; once the
/// cause is gone, a clear and an arm must engage the loop again through
/// the simulated AD5791 (its control register released at zero volts),
/// not leave the output clamped so that the sign check fails.
#[test]
fn the_loop_engages_again_after_a_disabling_fault_is_cleared() {
    let (mut w, mut s) = firmware_demo(quiet(), 20_000);
    w.request(Request::Arm);
    s.run_until(&mut w, 10_000_000);
    w.rig
        .adc
        .state
        .borrow_mut()
        .faults
        .inject(BusFault::Error, 1);
    s.run_until(&mut w, 20_000_000);
    assert_eq!(w.fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
    assert!(w.fw.dac_clamped());
    w.request(Request::Disarm);
    s.run_until(&mut w, 30_000_000);
    w.request(Request::ClearFault);
    s.run_until(&mut w, 40_000_000);
    assert_eq!(w.fw.fault(), None);
    assert!(!w.fw.dac_clamped(), "the clamp is released after the clear");
    // Released at zero volts: the amplifier input does not step.
    assert_eq!(w.rig.dac.state.borrow().output_volts(), 0.0);
    w.rig.slide.x[st::Z] = 0.001; // the slide drifted while off
    w.request(Request::Arm);
    s.run_until(&mut w, 300_000_000);
    assert_eq!(w.fw.fault(), None, "re-arm passes the sign check");
    assert!(w.rig.amp.enabled());
    assert!(
        w.rig.slide.position_in().abs() < 1e-6,
        "z = {}",
        w.rig.slide.position_in()
    );
}

#[test]
fn amplifier_dac_bus_error_opens_the_loop_safely() {
    let (mut w, mut s) = firmware_demo(quiet(), 20_000);
    w.request(Request::Arm);
    s.run_until(&mut w, 10_000_000);
    w.rig
        .dac
        .state
        .borrow_mut()
        .faults
        .inject(BusFault::Error, 1);
    s.run_until(&mut w, 20_000_000);
    assert_eq!(w.fw.fault(), Some(Fault::Bus(Device::AmplifierDac)));
    assert_eq!(w.rig.dac.state.borrow().output_volts(), 0.0);
    assert_eq!(w.rig.amp.regime(), AmpRegime::Off);
}

#[test]
fn fit_sine_is_exact_off_the_period_grid() {
    let w = std::f64::consts::TAU * 37.3;
    let s: Vec<(f64, f64)> = (0..777)
        .map(|k| {
            let t = k as f64 * 5e-5;
            (t, 0.7 * (w * t).sin() - 0.2 * (w * t).cos() + 3.0)
        })
        .collect();
    let h = host_sim::analyser::fit_sine(&s, w);
    assert!(
        (h.re - 0.7).abs() < 1e-12 && (h.im + 0.2).abs() < 1e-12,
        "{h}"
    );
}

/// The digital loop's sensitivities on legacy-hw, measured through the
/// chips with a sinusoid injected into the gauge's reading: margins a
/// servo engineer accepts (measured: crossover 94.5 Hz, phase margin 40°,
/// gain margin 10.5 dB at 268 Hz, peak |S| 6.0 dB with the board's 8.5 µs
/// DAC latency); the 120 Hz hum notch on
/// the feedback makes T at 120 Hz very small (the loop does not drive
/// the slide with hum); S → 1 far above the loop.
#[test]
fn digital_loop_margins_and_sensitivities_on_legacy_hw() {
    use host_sim::analyser::log_freqs;
    use host_sim::cmd::response::{margins, measure_digital};
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let pts: Vec<_> = log_freqs(1.0, 2000.0, 40)
        .into_iter()
        .map(|f| measure_digital(&sc, f, 20e-6, false))
        .collect();
    let m = margins(&pts);
    assert!(m.phase_margin_deg.unwrap() > 30.0, "{m:?}");
    assert!(m.gain_margin_db.unwrap() > 6.0, "{m:?}");
    assert!(m.peak_sensitivity_db < 6.0, "{m:?}");
    let hum = measure_digital(&sc, 120.0, 20e-6, false);
    assert!(hum.t.norm() < 0.01, "T(120 Hz) = {}", hum.t.norm());
    let high = measure_digital(&sc, 1000.0, 20e-6, false);
    assert!((high.s.norm() - 1.0).abs() < 0.01);
}

/// The margin finder against a closed form: L = 2/(s(s+1)(s+2)) crosses
/// −180° at √2 rad/s where |L| = 1/3 (gain margin 9.54 dB); its gain
/// crossover is where |L| = 1 (0.749 rad/s, phase margin 32.6°).
#[test]
fn margins_of_a_closed_form_loop() {
    use host_sim::cmd::response::{margins, LoopPoint};
    use nalgebra::Complex;
    let pts: Vec<LoopPoint> = host_sim::analyser::log_freqs(0.01, 10.0, 400)
        .into_iter()
        .map(|f| {
            let s = Complex::new(0.0, std::f64::consts::TAU * f);
            let l = Complex::new(2.0, 0.0) / (s * (s + 1.0) * (s + 2.0));
            LoopPoint {
                f_hz: f,
                s: 1.0 / (1.0 + l),
                t: l / (1.0 + l),
            }
        })
        .collect();
    let m = margins(&pts);
    assert!((m.gain_margin_db.unwrap() - 9.542).abs() < 0.05, "{m:?}");
    assert!((m.phase_crossover_hz.unwrap() * std::f64::consts::TAU - 2f64.sqrt()).abs() < 0.01);
    assert!((m.phase_margin_deg.unwrap() - 32.6).abs() < 0.3, "{m:?}");
}

#[test]
fn core_dac_driver_init_runs_on_the_simulated_chip() {
    // The core driver's init: zero code, control = RBUF (two's complement,
    // clamp and tristate released), read back in a second frame. The
    // simulated chip must end in exactly that state, with every frame valid.
    let (w, _) = firmware_demo(quiet(), 20_000);
    let st = w.rig.dac.state.borrow();
    assert_eq!(st.ctrl, host_sim::chips::ad5791::CTRL_RBUF);
    assert_eq!(st.bad_frames, 0);
    assert_eq!(st.frames, 4, "DAC, control, read request, no-op");
    assert_eq!(w.fw.fault(), None);
}

#[test]
fn dac_init_on_a_stuck_bus_is_a_bus_fault() {
    use host_sim::fwrig::FirmwareWorld;
    use host_sim::plant::Rig;
    use zslide::drivers::ad5791::Ad5791;
    use zslide::servo::ServoConfig;
    // The read-back of a bus stuck high (all ones: clamp and tristate
    // bits set) or low (all zero: RBUF missing) cannot match.
    for fault in [BusFault::StuckHigh, BusFault::StuckLow, BusFault::Error] {
        let rig = Rig::new(quiet());
        rig.dac.state.borrow_mut().faults.inject(fault, 4);
        let mut dac = Ad5791::new(rig.devices().amp_dac);
        assert!(dac.init().is_err(), "{fault:?}");
        // and the world built on such a bus starts latched, amplifier off
        let mut cfg = quiet();
        cfg.seed = 2;
        let w =
            FirmwareWorld::new_with_dac_faults(cfg, ServoConfig::at_rate(20_000).unwrap(), fault);
        assert_eq!(w.fw.fault(), Some(Fault::Bus(Device::AmplifierDac)));
        assert!(!w.fw.amplifier_enable());
    }
}
