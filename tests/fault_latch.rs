//! A latched fault, or a lost spindle angle, stops the learned correction
//! at once: the servo's reference is its slew-limited command, nothing
//! added, for the revolution after. (The defect this guards: a learning
//! that had taken in a hard spot's push kept adding its correction while
//! the loop ramped to null and drove the tool 415 µin into the part one
//! revolution later; docs/SAFETY.md, "Following error".)

mod common;

use common::{Dac, Gauge};
use zslide::firmware::{
    Firmware, FirmwareConfig, Request, SpindleMode, SpindleReading, TickInput, XMode,
};
use zslide::hw::EncoderSample;
use zslide::safety::{Fault, Reaction};
use zslide::servo::{Freeze, Phase, ServoDesign};
use zslide::spindle::{EdgeStamps, EncoderConfig};
use zslide::units::SpindleAngle;
use zslide::xpos::CountConfig;

/// Firmware clock 1 MHz; loop 20 kHz = 50 clock ticks; 4000 counts a
/// turn at 300 rpm: one count a loop tick, a revolution 4000 ticks.
const TICK: u32 = 50;
const CPR: u32 = 4000;
/// X = 3.0 in on a count of 100 000 per inch.
const X_COUNT: u32 = 300_000;
/// The periodic error the slide makes and the learning must take out:
/// 2/rev, 2000 codes (38 µin).
const DISTURBANCE_CODES: f64 = 2000.0;

fn firmware() -> Firmware {
    let mut d = ServoDesign::brief(20_000);
    // The test's slide is a gauge the test sets: no sign check to pass.
    d.sign_check_v = 0.0;
    let cfg = FirmwareConfig {
        loop_cfg: d.config().unwrap(),
        spindle: SpindleMode::Encoder(EncoderConfig {
            counts_per_rev: CPR,
            ticks_per_s: 1_000_000,
            min_rpm: 30,
            max_rpm: 3000,
            index_tolerance_counts: 4,
            index_angle: SpindleAngle(0),
            edge_stamps: EdgeStamps::Captured,
        }),
        x: XMode::Count(CountConfig {
            counts_per_inch: 100_000,
            zero_count: 0,
            max_step_counts: 5_000,
        }),
        coefficient_output: false,
        gauge_reversed: false,
    };
    Firmware::with_table(zslide::DEFAULT_TABLE, cfg).unwrap()
}

fn input(n: u32, angle: bool) -> TickInput {
    TickInput {
        now: n * TICK,
        spindle: if angle {
            SpindleReading::Encoder(EncoderSample {
                count: n,
                edge_ticks: n * TICK,
            })
        } else {
            SpindleReading::None
        },
        x_count: X_COUNT,
        amplifier_fault: false,
    }
}

/// A slide that follows the servo's reference exactly but for a 2/rev
/// error: the gauge reads the reference less the disturbance.
struct Cut {
    fw: Firmware,
    g: Gauge,
    d: Dac,
    n: u32,
}

impl Cut {
    fn tick(&mut self, angle: bool) {
        if angle && self.n.is_multiple_of(CPR) {
            self.fw.index_event(self.n * TICK, self.n);
        }
        self.fw
            .loop_tick(&input(self.n, angle), &mut self.g, &mut self.d);
        let turns = f64::from(self.n % CPR) / f64::from(CPR);
        let dist = DISTURBANCE_CODES * (2.0 * std::f64::consts::TAU * turns).sin();
        let reference = f64::from(self.fw.servo().reference_q8()) / 256.0;
        self.g.set((reference - dist).round() as i32);
        self.n += 1;
    }

    /// |reference − command| in gauge codes Q8 on the last tick. The
    /// command is only public rounded to a code, so a reference equal to
    /// the Q8 command is within ½ code (128 Q8) of it.
    fn added_q8(&self) -> i32 {
        (self.fw.servo().reference_q8() - (self.fw.command_code() << 8)).abs()
    }
}

/// Engaged, settled and learning for 30 revolutions: the learned
/// correction is a large part of the reference.
fn learned() -> Cut {
    let mut c = Cut {
        fw: firmware(),
        g: Gauge::at(0),
        d: Dac::default(),
        n: 0,
    };
    c.fw.request(Request::Arm);
    for _ in 0..30 * CPR {
        c.tick(true);
    }
    assert_eq!(c.fw.fault(), None);
    assert_eq!(c.fw.servo().phase(), Phase::Engaged);
    assert_eq!(c.fw.learning().frozen(), None);
    // The learning has taken in most of the 2000-code disturbance: over
    // the last revolution the correction reaches at least half of it.
    let mut most = 0;
    for _ in 0..CPR {
        c.tick(true);
        most = most.max(c.added_q8());
    }
    assert!(
        most > (DISTURBANCE_CODES as i32 / 2) << 8,
        "learned correction at most {} codes",
        most >> 8
    );
    c
}

/// The reference is the command, nothing added, on every tick of the
/// revolution after `stop` (½ code: the command's rounding).
fn assert_no_correction_for_a_revolution(c: &mut Cut, angle: bool, what: &str) {
    for k in 0..CPR {
        c.tick(angle);
        let added = c.added_q8();
        assert!(
            added <= 128,
            "{what}: tick {k} after: the reference is {} codes (Q8 {added}) off the command",
            f64::from(added) / 256.0
        );
    }
}

#[test]
fn a_latched_ramp_to_null_fault_stops_the_learned_correction_for_the_revolution_after() {
    let mut c = learned();
    let f = Fault::FollowingError;
    assert_eq!(f.reaction(), Reaction::RampToNull);
    c.fw.trip(f);
    assert_no_correction_for_a_revolution(&mut c, true, "latched FollowingError");
    assert_eq!(c.fw.fault(), Some(f));
    assert!(c.fw.amplifier_enable(), "RampToNull keeps the loop closed");
    assert_eq!(c.fw.learning().frozen(), Some(Freeze::Fault));
    // And the command did go to null (the ramp ran).
    assert_eq!(c.fw.command_code(), 0);
}

#[test]
fn a_lost_spindle_angle_stops_the_learned_correction_for_the_revolution_after() {
    let mut c = learned();
    // The encoder's readings stop arriving (no angle); no fault is raised
    // by that alone, so only the missing angle may stop the correction.
    assert_no_correction_for_a_revolution(&mut c, false, "no angle");
    assert_eq!(c.fw.fault(), None);
    assert_eq!(c.fw.servo().phase(), Phase::Engaged);
}
