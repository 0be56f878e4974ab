//! Clearing a latched fault through the firmware (`Request::ClearFault`):
//! refused while the loop is armed, refused while the cause is still seen
//! (an amplifier trip whose line is still high), never for a refused table
//! or parameter block (only a new one, at the next boot); a clear never
//! re-arms. The parameter block's refusal is latched the way both boards
//! latch it at boot (`params::at_boot`, then `trip(Fault::Parameters)`),
//! and its reaction, DisableAmplifier, is checked on the DAC and the
//! enable line.

mod common;

use common::{Dac, Gauge};
use zslide::firmware::{Firmware, FirmwareConfig, Request, SpindleMode, TickInput, XMode};
use zslide::params::{self, ParamError, ParamSource};
use zslide::safety::{Fault, Reaction};
use zslide::servo::{Phase, ServoConfig, ServoDesign};
use zslide::table::TableError;

fn design() -> ServoDesign {
    let mut d = ServoDesign::brief(20_000);
    // The test's gauge does not move with the DAC: no sign check.
    d.sign_check_v = 0.0;
    d
}

fn cfg() -> ServoConfig {
    design().config().unwrap()
}

fn bench_config(loop_cfg: ServoConfig) -> FirmwareConfig {
    FirmwareConfig {
        loop_cfg,
        spindle: SpindleMode::None,
        x: XMode::None,
        coefficient_output: false,
        gauge_reversed: false,
    }
}

fn tick(fw: &mut Firmware, g: &mut Gauge, d: &mut Dac, line_high: bool) {
    let input = TickInput {
        amplifier_fault: line_high,
        ..TickInput::NONE
    };
    fw.loop_tick(&input, g, d);
}

/// Posts `r` and runs the tick that takes it.
fn request(fw: &mut Firmware, r: Request, g: &mut Gauge, d: &mut Dac, line_high: bool) {
    fw.request(r);
    tick(fw, g, d, line_high);
}

#[test]
fn a_refused_table_is_never_cleared() {
    let mut img = zslide::DEFAULT_TABLE.to_vec();
    let k = img.len() / 2;
    img[k] ^= 0x10;
    let img: &'static [u8] = Box::leak(img.into_boxed_slice());
    let mut fw = Firmware::with_table(img, bench_config(cfg())).unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    let f = fw.fault();
    assert!(
        matches!(f, Some(Fault::Table(TableError::PayloadCrc { .. }))),
        "{f:?}"
    );
    for _ in 0..3 {
        request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
        assert_eq!(fw.fault(), f, "a clear must not forget a refused table");
        assert_eq!(fw.loop_state().clear_refused(), f);
    }
    // Armed on it (RampToNull: the loop holds null), still not cleared.
    request(&mut fw, Request::Arm, &mut g, &mut d, false);
    assert!(fw.amplifier_enable());
    request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
    assert_eq!(fw.fault(), f);
    assert_eq!(fw.command_code(), 0);
}

/// The boards' boot path for a corrupt parameter block: the built-in
/// design runs the loop, the refusal is latched, the amplifier stays off,
/// the DAC clamped; an arm is refused; a clear is refused, disarmed or not.
#[test]
fn a_refused_parameter_block_keeps_the_amplifier_off_and_is_never_cleared() {
    let base = design();
    let mut block = vec![0u8; params::HEADER_LEN + params::ENTRY_LEN];
    let setting = (params::by_name("following_error_in").unwrap().id, 0.002);
    let n = params::encode_block(&[setting], &base, &mut block).unwrap();
    block.truncate(n);
    // The good block is taken...
    let (_, _, src) = params::at_boot(&block, &base).unwrap();
    assert!(
        matches!(src, ParamSource::Block { entries: 1, .. }),
        "{src:?}"
    );
    // ... one flipped bit in its value is not.
    block[n - 1] ^= 0x01;
    let (_, loop_cfg, src) = params::at_boot(&block, &base).unwrap();
    let ParamSource::Refused(e) = src else {
        panic!("a corrupt block was taken: {src:?}")
    };
    assert!(matches!(e, ParamError::BlockCrc { .. }), "{e:?}");
    assert_eq!(loop_cfg, base.config().unwrap(), "the built-in design runs");

    let mut fw = Firmware::with_table(zslide::DEFAULT_TABLE, bench_config(loop_cfg)).unwrap();
    fw.trip(Fault::Parameters(e));
    let f = Some(Fault::Parameters(e));
    assert_eq!(Fault::Parameters(e).reaction(), Reaction::DisableAmplifier);
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    tick(&mut fw, &mut g, &mut d, false);
    assert!(d.clamped, "DisableAmplifier clamps the DAC");
    request(&mut fw, Request::Arm, &mut g, &mut d, false);
    for _ in 0..100 {
        tick(&mut fw, &mut g, &mut d, false);
        assert!(!fw.amplifier_enable(), "armed on a refused parameter block");
    }
    assert_eq!(fw.servo().phase(), Phase::Disarmed);
    assert_eq!(d.writes, 0, "the DAC was driven");
    assert!(d.clamped);
    request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
    assert_eq!(fw.fault(), f);
    assert_eq!(fw.loop_state().clear_refused(), f);
    assert!(d.clamped && d.releases == 0, "the clamp was released");
}

/// A RampToNull fault keeps the loop armed: a clear is refused until the
/// operator disarms, then taken, and the loop stays disarmed.
#[test]
fn a_clear_while_armed_is_refused_and_taken_after_a_disarm() {
    let mut fw = Firmware::new(cfg());
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    request(&mut fw, Request::Arm, &mut g, &mut d, false);
    assert!(fw.amplifier_enable());
    fw.trip(Fault::FollowingError);
    for _ in 0..10 {
        tick(&mut fw, &mut g, &mut d, false);
    }
    request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
    assert_eq!(
        fw.fault(),
        Some(Fault::FollowingError),
        "cleared while armed"
    );
    assert_eq!(fw.loop_state().clear_refused(), Some(Fault::FollowingError));
    assert!(fw.amplifier_enable());
    request(&mut fw, Request::Disarm, &mut g, &mut d, false);
    // Disarming ramps the command to null first (here it is there).
    for _ in 0..200 {
        tick(&mut fw, &mut g, &mut d, false);
    }
    assert_eq!(fw.servo().phase(), Phase::Disarmed);
    request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
    assert_eq!(fw.fault(), None);
    assert_eq!(fw.loop_state().clear_refused(), None);
    assert!(!fw.amplifier_enable(), "a clear re-armed the loop");
}

/// An amplifier trip: refused while its fault line is still high, taken
/// once it is low; the clamp is released at code 0, the loop not re-armed.
#[test]
fn an_amplifier_trip_is_not_cleared_while_its_line_is_high() {
    let mut fw = Firmware::new(cfg());
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    request(&mut fw, Request::Arm, &mut g, &mut d, false);
    assert!(fw.amplifier_enable());
    tick(&mut fw, &mut g, &mut d, true);
    assert_eq!(fw.fault(), Some(Fault::AmplifierTrip));
    assert!(!fw.amplifier_enable() && d.clamped);
    assert_eq!(fw.servo().phase(), Phase::Disarmed);
    for _ in 0..3 {
        request(&mut fw, Request::ClearFault, &mut g, &mut d, true);
        assert_eq!(
            fw.fault(),
            Some(Fault::AmplifierTrip),
            "cleared with the line high"
        );
        assert_eq!(fw.loop_state().clear_refused(), Some(Fault::AmplifierTrip));
        assert!(d.clamped);
    }
    request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
    assert_eq!(fw.fault(), None);
    assert!(
        !d.clamped,
        "the clamp is released once the fault is cleared"
    );
    assert_eq!(d.last, 0);
    assert!(!fw.amplifier_enable(), "a clear re-armed the loop");
    request(&mut fw, Request::Arm, &mut g, &mut d, false);
    assert!(fw.amplifier_enable());
}

/// Only a clear request clears: an arm or a disarm request leaves a
/// latched fault latched, even one whose cause is gone and that a clear
/// would take at once (a following error, disarmed).
#[test]
fn an_arm_or_disarm_request_never_clears_a_fault() {
    let mut fw = Firmware::new(cfg());
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.trip(Fault::FollowingError);
    tick(&mut fw, &mut g, &mut d, false);
    for r in [Request::Disarm, Request::Arm, Request::Disarm] {
        request(&mut fw, r, &mut g, &mut d, false);
        assert_eq!(fw.fault(), Some(Fault::FollowingError), "{r:?} cleared it");
        for _ in 0..200 {
            tick(&mut fw, &mut g, &mut d, false);
        }
    }
    assert_eq!(fw.servo().phase(), Phase::Disarmed);
    request(&mut fw, Request::ClearFault, &mut g, &mut d, false);
    assert_eq!(fw.fault(), None, "the clear itself is taken");
}
