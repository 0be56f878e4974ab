//! The firmware's own loop tick (`zslide::firmware`) on the simulated rig:
//! bumpless engagement from off null, and the safe reaction to converter
//! bus errors injected in the simulated chips.

use host_sim::chips::BusFault;
use host_sim::cmd::bench::firmware_demo;
use host_sim::plant::amplifier::AmpRegime;
use host_sim::plant::zslide::st;
use host_sim::plant::{GaugeParams, RigConfig};
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
    s.run_until(&mut w, 200_000_000);
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

#[test]
fn amplifier_dac_bus_error_opens_the_loop_safely() {
    let (mut w, mut s) = firmware_demo(quiet(), 20_000);
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
