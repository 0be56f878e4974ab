extern crate std;

use super::*;
use crate::codes::{CODE_MAX, CODE_MIN};
use crate::hw::{BusError, EncoderSample, GaugeSample};
use crate::safety::{Device, Reaction};
use crate::spindle::EncoderConfig;
use crate::table::{CoeffTable, TableError};
use crate::units::SpindleAngle;
use crate::xpos::CountConfig;
use core::sync::atomic::Ordering;
use std::vec::Vec;

/// A gauge whose next reading the test sets.
struct Gauge(Result<GaugeSample, BusError>, u32);
impl Gauge {
    fn at(code: i32) -> Self {
        Self::of(Ok(GaugeSample {
            code,
            overrange: false,
        }))
    }
    fn of(r: Result<GaugeSample, BusError>) -> Self {
        Self(r, 0)
    }
    fn set(&mut self, code: i32) {
        self.0 = Ok(GaugeSample {
            code,
            overrange: false,
        });
    }
}
impl GaugeAdc for Gauge {
    /// The code, one code lower on every other read: a real 20-bit
    /// reading of a held slide moves by its noise (≥ 10 codes RMS), and
    /// one that does not is a frozen gauge (`servo::monitor`). A code on a
    /// rail stays there (a pinned gauge).
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        self.1 = self.1.wrapping_add(1);
        let mut r = self.0;
        if let Ok(s) = &mut r {
            if s.code > CODE_MIN + 1 && s.code < CODE_MAX {
                s.code -= (self.1 & 1) as i32 ^ 1;
            }
        }
        r
    }
}

#[derive(Default)]
struct Dac {
    writes: Vec<i32>,
    clamps: u32,
    releases: u32,
    fail_writes: bool,
    fail_clamps: u32,
}
impl AmplifierDac for Dac {
    fn write(&mut self, code: i32) -> Result<(), BusError> {
        if self.fail_writes {
            return Err(BusError);
        }
        self.writes.push(code);
        Ok(())
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        self.clamps += 1;
        if self.fail_clamps > 0 {
            self.fail_clamps -= 1;
            return Err(BusError);
        }
        Ok(())
    }
    fn release_clamp(&mut self) -> Result<(), BusError> {
        self.releases += 1;
        Ok(())
    }
}

#[test]
fn gauge_scale_is_one_volt_per_mil_over_20_bits() {
    // The gauge scale: code = round(V · 2¹⁹ / 10 V), 1 V per mil.
    assert_eq!(gauge_code_from_z(ZInches::from_f64(0.005)), 1 << 18);
    assert_eq!(gauge_code_from_z(ZInches::from_f64(-0.010)), CODE_MIN);
    assert_eq!(gauge_code_from_z(ZInches::from_f64(0.010)), CODE_MAX);
    assert_eq!(gauge_code_from_z(ZInches::from_f64(0.5)), CODE_MAX);
    // 1 µin = 52.4288 codes.
    assert_eq!(gauge_code_from_z(ZInches::from_f64(1e-6)), 52);
    assert_eq!(gauge_code_from_z(ZInches::from_f64(-1e-6)), -52);
}

#[test]
fn gauge_bus_error_latches_and_clamps_dac() {
    let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    g.0 = Err(BusError);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
    assert!(!fw.amplifier_enable());
    assert_eq!(d.clamps, 1);
    // The gauge recovers; the latch holds and the DAC stays untouched.
    g.set(5);
    for _ in 0..5 {
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    }
    assert_eq!(d.writes.len(), 1);
    assert_eq!(d.clamps, 1);
    assert_eq!(fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
    assert_eq!(fw.ticks(), 7);
}

#[test]
fn dac_bus_error_latches_and_retries_clamp_until_accepted() {
    let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    d.fail_writes = true;
    d.fail_clamps = 2;
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::Bus(Device::AmplifierDac)));
    assert!(!fw.dac_clamped());
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert!(fw.dac_clamped());
    assert_eq!(d.clamps, 3);
}

#[test]
fn gauge_pinned_at_either_rail_is_saturated_and_disables_amplifier() {
    // The AD4020's extreme codes, ±10 V (±0.010 in), without OV.
    for code in [(1 << 19) - 1, -(1 << 19)] {
        let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
        let mut g = Gauge::of(Ok(GaugeSample {
            code,
            overrange: false,
        }));
        let mut d = Dac::default();
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::GaugeSaturated));
        assert!(d.writes.is_empty());
        assert_eq!(d.clamps, 1);
        assert!(!fw.amplifier_enable());
    }
    // One code inside the rail is a reading like any other.
    let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
    let mut g = Gauge::of(Ok(GaugeSample {
        code: (1 << 19) - 2,
        overrange: false,
    }));
    let mut d = Dac::default();
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), None);
}

#[test]
fn overrange_gauge_disables_amplifier() {
    let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
    let mut g = Gauge::of(Ok(GaugeSample {
        code: CODE_MAX,
        overrange: true,
    }));
    let mut d = Dac::default();
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::GaugeRange));
    assert!(d.writes.is_empty());
    assert_eq!(d.clamps, 1);
}

/// The default loop without the commissioning sign check (the test
/// gauges here do not move when the DAC does).
fn no_check_cfg() -> ServoConfig {
    let mut d = crate::servo::ServoDesign::brief(20_000);
    d.sign_check_v = 0.0;
    d.config().unwrap()
}

fn armed_without_sign_check() -> Firmware {
    let mut fw = Firmware::new(no_check_cfg());
    fw.request(Request::Arm);
    fw
}

#[test]
fn ramp_to_null_fault_keeps_loop_closed_and_nulls_command() {
    let mut fw = armed_without_sign_check();
    let (mut g, mut d) = (Gauge::at(1000), Dac::default());
    fw.set_target_code(1000);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.command_code(), 1000);
    fw.trip(Fault::FollowingError);
    // Toward null at ≤ 2.6 codes/tick² (20 in/s²), never past it: a
    // 1000-code move takes 2·√(1000/2.6) ≈ 39 ticks.
    let mut prev = fw.command_code();
    let mut n = 0;
    while fw.command_code() != 0 {
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        let c = fw.command_code();
        assert!(c <= prev && c >= 0, "{prev} -> {c}");
        prev = c;
        n += 1;
        assert!(n < 60, "too slow");
    }
    assert!(n > 30, "{n} ticks: the acceleration limit is not in force");
    assert!(fw.amplifier_enable());
    // A more severe fault replaces it; a milder one does not.
    fw.trip(Fault::Watchdog);
    fw.trip(Fault::XGlitchStorm);
    assert_eq!(fw.fault(), Some(Fault::Watchdog));
}

#[test]
fn amplifier_stays_off_until_armed_and_engages_bumpless() {
    let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
    let (mut g, mut d) = (Gauge::at(-40_000), Dac::default());
    for _ in 0..1000 {
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    }
    assert!(!fw.amplifier_enable());
    assert!(d.writes.iter().all(|&c| c == 0));
    let mut fw = armed_without_sign_check();
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert!(fw.amplifier_enable());
    // The command starts where the slide is and sets off toward the
    // target (0) at the slew acceleration (20 in/s²: 2.6 codes/tick²).
    let c = fw.command_code();
    assert!((-40_000..=-39_997).contains(&c), "{c}");
}

#[test]
fn a_fault_is_cleared_only_when_its_cause_is_gone_and_needs_a_new_arm() {
    let mut fw = armed_without_sign_check();
    let mut d = Dac::default();
    let mut g = Gauge::of(Ok(GaugeSample {
        code: 1000,
        overrange: true,
    }));
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::GaugeRange));
    fw.request(Request::ClearFault);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::GaugeRange));
    assert_eq!(fw.loop_state().clear_refused(), Some(Fault::GaugeRange));
    g.set(1000);
    fw.request(Request::ClearFault);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), None);
    assert!(!fw.amplifier_enable(), "clearing must not re-arm");
    fw.request(Request::Arm);
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert!(fw.amplifier_enable());
}

// -------------------------------------------------------------------
// The integrated command path.

use crate::table::TableHeader;
use crate::xpos::legacy_output::LegacyFrame;
use crate::xpos::{half_mils_to_x, latch_word, XUpdate};
use crate::{DEFAULT_TABLE, LEGACY4_TABLE};
use std::boxed::Box;

/// Clock of the tests: 1 MHz; loop 20 kHz = 50 clock ticks.
const CLOCK_HZ: u32 = 1_000_000;
const TICK: u32 = 50;
/// 4000 counts per rev at 300 rpm: exactly one count per loop tick.
const CPR: u32 = 4000;

fn leak(v: Vec<u8>) -> &'static [u8] {
    Box::leak(v.into_boxed_slice())
}

fn enc_cfg() -> EncoderConfig {
    EncoderConfig {
        counts_per_rev: CPR,
        ticks_per_s: CLOCK_HZ,
        min_rpm: 30,
        max_rpm: 3000,
        index_tolerance_counts: 4,
        index_angle: SpindleAngle(0),
        edge_stamps: crate::spindle::EdgeStamps::Captured,
    }
}

fn fw_cfg(x: XMode, coefficient_output: bool) -> FirmwareConfig {
    FirmwareConfig {
        loop_cfg: no_check_cfg(),
        spindle: SpindleMode::Encoder(enc_cfg()),
        x,
        coefficient_output,
        gauge_reversed: false,
    }
}

fn legacy(table: &'static [u8], output: bool) -> Firmware {
    Firmware::with_table(table, fw_cfg(XMode::Legacy { clock_hz: CLOCK_HZ }, output)).unwrap()
}

/// Encoder reading `n` counts after the start, its edge at this tick.
fn enc(n: u32) -> TickInput {
    TickInput {
        now: n * TICK,
        spindle: SpindleReading::Encoder(EncoderSample {
            count: n,
            edge_ticks: n * TICK,
        }),
        x_count: 0,
        amplifier_fault: false,
    }
}

/// φ of count `n` after an index at count 0: n·2³²/CPR, rounded down.
fn phi_of(n: u32) -> SpindleAngle {
    let q = (u64::from(n % CPR) << 32) / u64::from(CPR);
    SpindleAngle(q as u32)
}

/// A recording quad DAC.
#[derive(Default)]
struct Quad {
    frames: Vec<LegacyFrame>,
    fail: bool,
}
impl CoefficientDac for Quad {
    fn output(&mut self, codes: &[u16; 4], update: u8) -> Result<(), BusError> {
        if self.fail {
            return Err(BusError);
        }
        self.frames.push(LegacyFrame {
            codes: *codes,
            update,
        });
        Ok(())
    }
}

/// The default table with its header and payload rewritten.
fn reencode(f: impl Fn(&mut TableHeader, &mut Vec<i32>)) -> &'static [u8] {
    let t = CoeffTable::parse(DEFAULT_TABLE).unwrap();
    let mut h = *t.header();
    let mut payload: Vec<i32> = (0..t.node_count())
        .flat_map(|n| (0..t.terms()).map(move |c| (n, c)))
        .map(|(n, c)| t.coeff_raw(n, c))
        .collect();
    f(&mut h, &mut payload);
    let mut out = std::vec![0u8; h.image_len()];
    h.encode(&payload, &mut out).unwrap();
    leak(out)
}

#[test]
fn refused_table_faults_with_the_parsers_reason_and_nulls() {
    let mut images: Vec<&'static [u8]> = std::vec![&[], &DEFAULT_TABLE[..63]];
    for at in [0usize, 9, 17, 70, 3000, DEFAULT_TABLE.len() - 1] {
        let mut v = DEFAULT_TABLE.to_vec();
        v[at] ^= 0x5A;
        images.push(leak(v));
    }
    for img in images {
        let expected = CoeffTable::parse(img).unwrap_err();
        let mut fw = legacy(img, true);
        assert_eq!(fw.fault(), Some(Fault::Table(expected)));
        assert!(fw.command_gen().is_none());
        // The entry points still run; armed, the command ramps to null
        // with the loop closed (RampToNull), from wherever the slide is.
        let (mut g, mut d) = (Gauge::at(3000), Dac::default());
        fw.request(Request::Arm);
        fw.index_event(0, 0);
        let mut quad = Quad::default();
        for hm in 100..110 {
            let _ = fw.x_event(latch_word(hm), hm * 1000, &mut quad);
        }
        for n in 0..100 {
            fw.loop_tick(&enc(n), &mut g, &mut d);
        }
        assert_eq!(fw.command_code(), 0);
        assert!(fw.amplifier_enable());
        assert!(quad.frames.is_empty());
    }
}

#[test]
fn sign_check_refuses_a_positive_command() {
    assert!(load_table(DEFAULT_TABLE).is_ok());
    assert!(load_table(LEGACY4_TABLE).is_ok());
    // The default table with every coefficient negated: a valid image
    // whose command is ≥ 0 (the wrong sign convention).
    let neg = reencode(|_, p| p.iter_mut().for_each(|v| *v = -*v));
    assert!(CoeffTable::parse(neg).is_ok());
    assert_eq!(load_table(neg).err(), Some(TableError::SignCheck));
    let fw = legacy(neg, false);
    assert_eq!(fw.fault(), Some(Fault::Table(TableError::SignCheck)));
    // A constant +2 µin offset in C00 (Z = 0 at X = 0 becomes +2 µin).
    let off = reencode(|h, p| {
        let t = usize::from(h.terms);
        p.iter_mut().step_by(t).for_each(|v| *v += 2148);
    });
    assert_eq!(load_table(off).err(), Some(TableError::SignCheck));
}

/// Every accepted X event hands the loop exactly the coefficients the
/// command path computes at that X (interval cache, no division:
/// bit-identical to `CommandGen::coefficients`), walking the whole table
/// up into the null zone and back.
#[test]
fn x_event_publishes_the_command_paths_coefficients() {
    let mut fw = legacy(DEFAULT_TABLE, false);
    let gen = *fw.command_gen().unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    let mut quad = NoCoefficientDac;
    let walk = (0..14_600u32).chain((14_000..14_599).rev());
    let mut now = 0u32;
    let mut accepted = 0;
    for hm in walk {
        now += 1000;
        let r = fw.x_event(latch_word(hm), now, &mut quad).unwrap();
        let XEvent::Update(u) = r else {
            panic!("event at {hm} ignored");
        };
        accepted += 1;
        assert_eq!(u.x, half_mils_to_x(hm));
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        // The tick takes X and the null flag, the handler below it the
        // values.
        assert_eq!(fw.loop_state().last_x(), Some(u.x));
        assert_eq!(fw.loop_state().command_null(), u.null, "hm {hm}");
        let got = fw.learn.ahead().coefficients();
        // The legacy null zone is the 8080's (X ≥ 7.2 in, xpos).
        assert_eq!(u.null, hm >= 14_400);
        assert_eq!(got.null, u.null, "hm {hm}");
        assert_eq!(got.x(), u.x);
        if !u.null {
            let want = gen.coefficients(u.x).unwrap();
            let n = usize::from(want.terms());
            assert_eq!(got.terms(), want.terms());
            assert_eq!(got.value[..n], want.value[..n], "hm {hm}");
        }
    }
    assert_eq!(fw.shared().x_accepted(), accepted);
    assert_eq!(fw.shared().coefficient_generation(), accepted);
    assert_eq!(fw.fault(), None);
}

/// The loop tick's command is the command path's Z at the X of the last
/// X event and the angle of the encoder count (closed form n·2³²/CPR
/// after the index), and its feedforward is ∂Z/∂φ·Δφ (checked against a
/// central difference of the command path's own Z).
#[test]
fn loop_tick_commands_z_at_the_encoder_angle_with_feedforward() {
    let mut fw = legacy(DEFAULT_TABLE, false);
    let gen = *fw.command_gen().unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    let mut quad = NoCoefficientDac;
    let hm = 6_283; // 3.1415 in
    fw.x_event(latch_word(hm), 10, &mut quad).unwrap();
    // Before the index the angle is unknown: null command.
    fw.loop_tick(&enc(0), &mut g, &mut d);
    assert_eq!(fw.table_code(), 0);
    fw.index_event(0, 0);
    let x = half_mils_to_x(hm);
    let codes = |phi: SpindleAngle| f64::from(gen.z(x, phi).unwrap().to_bits()) * 25.0 / 512.0;
    let mut worst_ff = 0f64;
    let mut largest_ff = 0f64;
    let (mut worst_acc, mut largest_acc) = (0f64, 0f64);
    let mut deepest = 0;
    for n in 1..=CPR + 10 {
        if n == CPR {
            fw.index_event(n * TICK, n);
        }
        fw.loop_tick(&enc(n), &mut g, &mut d);
        let phi = phi_of(n);
        if n == 1 {
            // The first tick with an angle: the handler below the tick
            // evaluates the command after it (`crate::handoff::ahead`), the
            // command starts on the next.
            assert_eq!(fw.table_code(), 0);
            continue;
        }
        let want = gauge_code_from_z(gen.z(x, phi).unwrap());
        assert!((fw.table_code() - want).abs() <= 1, "n {n}");
        deepest = deepest.min(fw.table_code());
        // The perfect slide: at the command.
        g.set(fw.command_code());
        if n >= 3 {
            let step = phi_of(1).0;
            let central = (codes(SpindleAngle(phi.0.wrapping_add(step)))
                - codes(SpindleAngle(phi.0.wrapping_sub(step))))
                / 2.0;
            let ff = fw.loop_state().feedforward_q16() as f64 / 65536.0;
            worst_ff = worst_ff.max((ff - central).abs());
            largest_ff = largest_ff.max(ff.abs());
            // Over ±10 steps, scaled back: the Q30 quantisation of Z
            // (0.05 code) would swamp a one-step second difference.
            let h = step.wrapping_mul(10);
            let second = (codes(SpindleAngle(phi.0.wrapping_add(h))) - 2.0 * codes(phi)
                + codes(SpindleAngle(phi.0.wrapping_sub(h))))
                / 100.0;
            let acc = fw.loop_state().accel_q16() as f64 / 65536.0;
            worst_acc = worst_acc.max((acc - second).abs());
            largest_acc = largest_acc.max(acc.abs());
        }
    }
    // Slopes up to ~150 codes/tick; the central difference's own error
    // at Δφ = 2π/4000 (third derivative · Δφ²/6) is ≈ 0.1 code.
    assert!(largest_ff > 50.0, "slope {largest_ff}");
    assert!(worst_ff < 0.5, "feedforward off by {worst_ff} codes/tick");
    // ∂²Z/∂φ²·Δφ² (~0.25 codes/tick² at most) against the second
    // difference, to 1 %.
    assert!(largest_acc > 0.1, "acceleration {largest_acc}");
    assert!(
        worst_acc < 0.01,
        "acceleration off by {worst_acc} codes/tick² (largest {largest_acc})"
    );
    assert_eq!(fw.fault(), None);
    // A real command at 3.14 in: tens of µin deep (1 µin = 52 codes).
    assert!(deepest < -5000, "deepest {deepest}");
}

/// The handler below the tick starved for longer than an expansion
/// lives (`ahead::MAX_AGE` ticks) after an X event: the tick then
/// evaluates the command itself with the values of the newest set
/// (which it copies only now: the X event's tick took its X alone),
/// exactly `gauge_code_from_z` of the command path's Z at that X and
/// the angle it reads, not the previous set's.
#[test]
fn starved_handler_below_the_tick_leaves_the_tick_evaluating_the_newest_set() {
    use crate::handoff::ahead::MAX_AGE;
    let mut fw = legacy(DEFAULT_TABLE, false);
    let gen = *fw.command_gen().unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    let mut quad = NoCoefficientDac;
    fw.x_event(latch_word(6_283), 1000, &mut quad).unwrap();
    fw.index_event(0, 0);
    for n in 1..=10 {
        fw.loop_tick(&enc(n), &mut g, &mut d);
        g.set(fw.command_code());
    }
    // 0.008 in further out (below the X-jump freeze), then the tick alone.
    let (old, new) = (half_mils_to_x(6_283), half_mils_to_x(6_299));
    for (k, hm) in (6_284..=6_299).enumerate() {
        let r = fw.x_event(latch_word(hm), 2000 + 1000 * k as u32, &mut quad);
        assert!(matches!(r, Ok(XEvent::Update(_))), "{r:?}");
    }
    let mut differ = 0;
    for n in 11..60 {
        fw.lp.loop_tick(&fw.shared, &enc(n), &mut g, &mut d);
        g.set(fw.command_code());
        if n <= 11 + MAX_AGE {
            // The last expansion (made for tick 11, at the old X) is
            // still fresh.
            continue;
        }
        let want = gauge_code_from_z(gen.z(new, phi_of(n)).unwrap());
        assert_eq!(fw.table_code(), want, "n {n}");
        if want != gauge_code_from_z(gen.z(old, phi_of(n)).unwrap()) {
            differ += 1;
        }
    }
    assert!(
        differ > 10,
        "the two sets' commands differ on {differ} ticks"
    );
    assert_eq!(fw.fault(), None);
}

#[test]
fn modern_x_reinterpolates_when_the_count_moves() {
    let cc = CountConfig {
        counts_per_inch: 100_000,
        zero_count: 0,
        max_step_counts: 1000,
    };
    let mut fw = Firmware::with_table(DEFAULT_TABLE, fw_cfg(XMode::Count(cc), false)).unwrap();
    let gen = *fw.command_gen().unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.index_event(0, 0);
    for n in 0..2000u32 {
        let count = 200_000 + n * 37; // from 2.0 in, 370 µin per tick
        let mut input = enc(n);
        input.x_count = count;
        fw.loop_tick(&input, &mut g, &mut d);
        g.set(fw.command_code());
        // The handler below the tick holds the set at this tick's count
        // (the X count handler published it after the tick).
        let c = fw.learn.ahead().coefficients();
        let exact = f64::from(count) / 100_000.0 * f64::from(1u32 << 24);
        assert!((f64::from(c.x().to_bits()) - exact).abs() <= 1.0);
        let want = gen.coefficients(c.x()).unwrap();
        assert_eq!(c.value[..5], want.value[..5]);
        let Some(x) = fw.loop_state().last_x() else {
            // The first count is published after the first tick.
            assert_eq!(n, 0);
            assert!(fw.loop_state().command_null());
            continue;
        };
        // The tick follows the previous tick's count.
        let exact = f64::from(count - 37) / 100_000.0 * f64::from(1u32 << 24);
        assert!((f64::from(x.to_bits()) - exact).abs() <= 1.0);
        let want = gauge_code_from_z(gen.z(x, phi_of(n)).unwrap());
        assert!((fw.table_code() - want).abs() <= 1, "n {n}");
    }
    assert_eq!(fw.fault(), None);
    // A jump beyond max_step_counts: glitch (latched at the next
    // tick), ramp to null.
    let mut input = enc(2000);
    input.x_count = 10;
    fw.loop_tick(&input, &mut g, &mut d);
    assert_eq!(fw.fault(), None);
    fw.loop_tick(&enc(2001), &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::XGlitchStorm));
}

/// The learning follows X while the feed moves the radius smoothly, and
/// freezes with `Freeze::XJump` for a second when X jumps by more than
/// 0.01 in (a restart elsewhere: the table belongs to another radius);
/// a null command freezes it with `Freeze::Null`.
#[test]
fn learning_freezes_when_x_jumps_and_runs_while_x_feeds() {
    use crate::servo::Freeze;
    let cc = CountConfig {
        counts_per_inch: 100_000,
        zero_count: 0,
        max_step_counts: 5_000,
    };
    let mut fw = Firmware::with_table(DEFAULT_TABLE, fw_cfg(XMode::Count(cc), false)).unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.request(Request::Arm);
    // 20 µin per tick of feed (an X count step of 2 every tick).
    let mut n = 0u32;
    let mut count = 300_000u32;
    while n < 20_000 {
        if n.is_multiple_of(CPR) {
            fw.index_event(n * TICK, n);
        }
        let mut input = enc(n);
        input.x_count = count;
        fw.loop_tick(&input, &mut g, &mut d);
        g.set(fw.command_code());
        n += 1;
        count += 2;
    }
    assert_eq!(fw.fault(), None);
    assert_eq!(fw.learning().frozen(), None, "learning runs while X feeds");
    // 0.03 in at once (within the count's step limit, beyond 0.01 in).
    count += 3_000;
    for _ in 0..10 {
        if n.is_multiple_of(CPR) {
            fw.index_event(n * TICK, n);
        }
        let mut input = enc(n);
        input.x_count = count;
        fw.loop_tick(&input, &mut g, &mut d);
        g.set(fw.command_code());
        n += 1;
    }
    assert_eq!(fw.fault(), None);
    assert_eq!(fw.learning().frozen(), Some(Freeze::XJump));
    // Into the null zone (beyond 7.2 in): the command is null.
    let mut fw2 = Firmware::with_table(DEFAULT_TABLE, fw_cfg(XMode::Count(cc), false)).unwrap();
    fw2.request(Request::Arm);
    for k in 0..3000u32 {
        if k.is_multiple_of(CPR) {
            fw2.index_event(k * TICK, k);
        }
        let mut input = enc(k);
        input.x_count = 760_000;
        fw2.loop_tick(&input, &mut g, &mut d);
    }
    assert_eq!(fw2.learning().frozen(), Some(Freeze::Null));
}

/// The modern X mode's cached re-interpolation equals the command path
/// bit for bit over the whole table: walking up and down through every
/// interval (crossings to both neighbours), jumps of several intervals,
/// every node exactly, the last node and the null zone.
#[test]
fn modern_x_cache_matches_the_command_path_over_the_table() {
    let cc = CountConfig {
        counts_per_inch: 1 << 24, // one count per X LSB: nodes exactly
        zero_count: 0,
        max_step_counts: u32::MAX,
    };
    let mut fw = Firmware::with_table(DEFAULT_TABLE, fw_cfg(XMode::Count(cc), false)).unwrap();
    let gen = *fw.command_gen().unwrap();
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    let t = gen.interpolator().table();
    let last = t.node_x(t.node_count() - 1).to_bits();
    let dx = t.node_x(1).to_bits() - t.node_x(0).to_bits();
    // Steps that are not a divisor of the grid, so every phase occurs.
    let up = (0..=last + dx).step_by(40_009);
    let down = (0..=last + dx).rev().step_by(33_331);
    let jumps = (0..400i64).map(|k| ((k * 7_919_993) % i64::from(last + dx)) as i32);
    let nodes = (0..t.node_count()).map(|n| t.node_x(n).to_bits());
    let mut checked = 0;
    for bits in up.chain(down).chain(jumps).chain(nodes) {
        let mut input = TickInput::NONE;
        input.x_count = bits as u32;
        // The count is published after the first tick, taken by the
        // second (the same count again publishes nothing).
        fw.loop_tick(&input, &mut g, &mut d);
        fw.loop_tick(&input, &mut g, &mut d);
        assert_eq!(fw.loop_state().last_x().map(|x| x.to_bits()), Some(bits));
        let got = fw.learn.ahead().coefficients();
        assert_eq!(fw.loop_state().command_null(), got.null);
        assert_eq!(got.x().to_bits(), bits);
        let want = gen.coefficients(got.x()).unwrap();
        assert_eq!(got.null, want.null, "x bits {bits}");
        if !want.null {
            let n = usize::from(want.terms());
            assert_eq!(got.terms(), want.terms());
            assert_eq!(got.value[..n], want.value[..n], "x bits {bits}");
            checked += 1;
        }
    }
    assert!(checked > 1000);
    assert_eq!(fw.fault(), None);
}

#[test]
fn debounce_ignores_repeats_without_publishing() {
    let mut fw = legacy(DEFAULT_TABLE, false);
    let mut quad = NoCoefficientDac;
    fw.x_event(latch_word(2000), 0, &mut quad).unwrap();
    fw.x_event(latch_word(2001), 5_000, &mut quad).unwrap();
    for k in 0..3 {
        // The same half-mil state again (a reversal across a boundary).
        let r = fw.x_event(latch_word(2001), 10_000 + k * 5_000, &mut quad);
        assert_eq!(r, Ok(XEvent::Ignored));
    }
    assert_eq!(fw.shared().x_accepted(), 2);
    assert_eq!(fw.shared().x_ignored(), 3);
    assert_eq!(fw.shared().coefficient_generation(), 2);
    assert_eq!(fw.fault(), None);
}

/// Runs `ticks` loop ticks on a perfect slide from tick `from`.
fn run(fw: &mut Firmware, g: &mut Gauge, d: &mut Dac, from: u32, ticks: u32) {
    for n in from..from + ticks {
        fw.loop_tick(&enc(n), g, d);
        g.set(fw.command_code());
    }
}

/// Engaged at X = 3.1415 in after an index, tracking.
fn cutting() -> (Firmware, Gauge, Dac) {
    let mut fw = legacy(DEFAULT_TABLE, false);
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.x_event(latch_word(6_283), 0, &mut NoCoefficientDac)
        .unwrap();
    fw.index_event(0, 0);
    fw.request(Request::Arm);
    run(&mut fw, &mut g, &mut d, 0, 100);
    assert_eq!(fw.fault(), None);
    assert!(fw.command_code() < -1000);
    (fw, g, d)
}

fn assert_ramps_to_null(fw: &mut Firmware, g: &mut Gauge, d: &mut Dac, from: u32, f: Fault) {
    assert_eq!(f.reaction(), Reaction::RampToNull);
    let slew = (fw.config().slew_q16 >> 16) as i32 + 1;
    let mut prev = fw.command_code();
    for n in from..from + 800 {
        fw.loop_tick(&enc(n), g, d);
        g.set(fw.command_code());
        let c = fw.command_code();
        // Never faster than the slew rate (it decelerates out of the
        // table's motion first, then ramps to null and stops there).
        assert!((c - prev).abs() <= slew, "{prev} -> {c}");
        prev = c;
    }
    assert_eq!(fw.fault(), Some(f));
    assert_eq!(fw.command_code(), 0);
    assert!(fw.amplifier_enable(), "the loop stays closed");
}

#[test]
fn x_glitch_storm_ramps_to_null() {
    let (mut fw, mut g, mut d) = cutting();
    let r = fw.x_event(latch_word(6_283 + 41), 100_000, &mut NoCoefficientDac);
    assert_eq!(r, Err(Fault::XGlitchStorm));
    assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::XGlitchStorm);
}

#[test]
fn bad_bcd_ramps_to_null() {
    let (mut fw, mut g, mut d) = cutting();
    let r = fw.x_event(XLatchWord(0x31A2), 100_000, &mut NoCoefficientDac);
    assert_eq!(r, Err(Fault::XBadBcd));
    assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::XBadBcd);
}

#[test]
fn x_below_the_table_ramps_to_null() {
    // The default grid moved to start at 1 in (null zone at 8.2 in).
    let img = reencode(|h, _| {
        h.x0_raw = 1 << 24;
        h.x_null_raw += 1 << 24;
    });
    let mut fw = legacy(img, false);
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.x_event(latch_word(2_100), 0, &mut NoCoefficientDac)
        .unwrap();
    fw.index_event(0, 0);
    fw.request(Request::Arm);
    run(&mut fw, &mut g, &mut d, 0, 100);
    assert_eq!(fw.fault(), None);
    let mut now = 0;
    let mut last = None;
    for hm in (1_990..2_100).rev() {
        now += 1000;
        if let Err(f) = fw.x_event(latch_word(hm), now, &mut NoCoefficientDac) {
            last = Some((hm, f));
            break;
        }
    }
    // 1.0 in = 2000 half-mils is the first node; 1999 is below it.
    assert_eq!(last, Some((1_999, Fault::XOutsideTable)));
    assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::XOutsideTable);
}

#[test]
fn two_index_pulses_in_one_loop_period_are_extra() {
    let (mut fw, mut g, mut d) = cutting();
    fw.index_event(4_000 * TICK, 4_000);
    fw.index_event(4_000 * TICK + 3, 4_000);
    assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::IndexExtra);
}

#[test]
fn early_index_is_extra_and_missing_index_is_missing() {
    let (mut fw, mut g, mut d) = cutting();
    // Half a turn after the last one.
    fw.index_event(2_000 * TICK, 2_000);
    assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::IndexExtra);

    let (mut fw, mut g, mut d) = cutting();
    // No index for more than a turn and the tolerance.
    run(&mut fw, &mut g, &mut d, 100, CPR);
    assert_eq!(fw.fault(), Some(Fault::IndexMissing));
    assert_ramps_to_null(&mut fw, &mut g, &mut d, 100 + CPR, Fault::IndexMissing);
}

#[test]
fn stalled_spindle_is_a_speed_fault() {
    let (mut fw, mut g, mut d) = cutting();
    // The count stops at 100 while time goes on.
    for n in 100..600 {
        let mut input = enc(100);
        input.now = n * TICK;
        fw.loop_tick(&input, &mut g, &mut d);
        g.set(fw.command_code());
    }
    assert_eq!(fw.fault(), Some(Fault::SpindleSpeed));
    assert_eq!(fw.command_code(), 0);
    assert!(fw.amplifier_enable());
}

/// Coefficient-output mode: every accepted event writes exactly the
/// frame of the command path's reference (`CommandGen::legacy_frame`)
/// with one strobe; a bus error disables the amplifier.
#[test]
fn coefficient_output_writes_the_legacy_frames() {
    let mut fw = legacy(LEGACY4_TABLE, true);
    let gen = *fw.command_gen().unwrap();
    let mut quad = Quad::default();
    let mut now = 0;
    let mut updates: Vec<XUpdate> = Vec::new();
    for hm in (13_900..14_500).chain((14_350..14_499).rev()) {
        now += 1000;
        if let XEvent::Update(u) = fw.x_event(latch_word(hm), now, &mut quad).unwrap() {
            updates.push(u);
        }
    }
    assert_eq!(updates.len(), 749);
    assert_eq!(quad.frames.len(), updates.len());
    for (f, u) in quad.frames.iter().zip(&updates) {
        assert_eq!(*f, gen.legacy_frame(u).unwrap(), "{u:?}");
    }
    let (mut g, mut d) = (Gauge::at(0), Dac::default());
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    quad.fail = true;
    let r = fw.x_event(latch_word(14_349), now + 1000, &mut quad);
    assert_eq!(r, Err(Fault::Bus(Device::CoefficientDac)));
    fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    assert_eq!(fw.fault(), Some(Fault::Bus(Device::CoefficientDac)));
    assert!(!fw.amplifier_enable());
    assert!(fw.dac_clamped());
}

/// The hand-off under real concurrency (host threads, stronger than the
/// board's preemption): every coefficient set the loop tick takes is one
/// complete published set, never a mix of two X positions.
#[test]
fn hand_off_never_tears_under_concurrency() {
    use std::sync::atomic::AtomicBool;
    let fw = legacy(DEFAULT_TABLE, false);
    let gen = *fw.command_gen().unwrap();
    let (mut lp, mut ev, _) = fw.into_parts();
    let shared = Shared::new();
    let stop = AtomicBool::new(false);
    /// Stops the writer however the reader leaves (a failed assert too).
    struct Stop<'a>(&'a AtomicBool);
    impl Drop for Stop<'_> {
        fn drop(&mut self) {
            self.0.store(true, Ordering::Relaxed);
        }
    }
    std::thread::scope(|s| {
        s.spawn(|| {
            let mut now = 0u32;
            'run: loop {
                for hm in (1..14_000).chain((1..13_999).rev()) {
                    if stop.load(Ordering::Relaxed) {
                        break 'run;
                    }
                    now = now.wrapping_add(1000);
                    let _ = ev.x_event(&shared, latch_word(hm), now, &mut NoCoefficientDac);
                }
            }
        });
        let _stop = Stop(&stop);
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        let mut checked = 0u32;
        let mut seen = 0u32;
        // The writer publishes a new generation every few microseconds; a
        // writer that stopped (or a generation that never moves) fails at
        // the deadline instead of looping forever.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        while checked < 20_000 {
            assert!(
                std::time::Instant::now() < deadline,
                "only {checked} of 20 000 new generations checked in 120 s"
            );
            lp.loop_tick(&shared, &TickInput::NONE, &mut g, &mut d);
            // The values as the tick's fallback copies them.
            let _ = shared
                .coefficients()
                .take(&mut lp.fallback_seen, &mut lp.fallback);
            let c = &lp.fallback;
            if !c.null && shared.coefficient_generation() != seen {
                seen = shared.coefficient_generation();
                let want = gen.coefficients(c.x()).unwrap();
                assert_eq!(c.value[..5], want.value[..5], "torn at {:?}", c.x());
                checked += 1;
            }
            d.writes.clear();
        }
    });
    assert_eq!(lp.fault(), None);
}

/// A gauge whose code stops changing while the loop is closed latches
/// `GaugeFrozen` (amplifier off) after `gauge_frozen_ms` (100 ticks at
/// 20 kHz) and the tick after the learning handler sees it, not before.
#[test]
fn a_frozen_gauge_disables_the_amplifier_after_its_ticks() {
    struct Stuck;
    impl GaugeAdc for Stuck {
        fn read(&mut self) -> Result<GaugeSample, BusError> {
            Ok(GaugeSample {
                code: 1000,
                overrange: false,
            })
        }
    }
    let mut fw = armed_without_sign_check();
    let (mut g, mut d) = (Gauge::at(1000), Dac::default());
    for _ in 0..500 {
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
    }
    assert_eq!(fw.fault(), None);
    let n = fw.config().monitor.gauge_frozen_ticks;
    let mut latched_at = None;
    for k in 0..3 * n {
        fw.loop_tick(&TickInput::NONE, &mut Stuck, &mut d);
        if fw.fault().is_some() {
            latched_at = Some(k);
            break;
        }
    }
    assert_eq!(fw.fault(), Some(Fault::GaugeFrozen));
    // The first stuck read may repeat the last live one; n repeats, then
    // one tick for the hand-off.
    let k = latched_at.unwrap();
    assert!((n - 1..=n + 1).contains(&k), "{k} against {n}");
    assert!(!fw.amplifier_enable());
}

/// The hole edges' contact chord follows the part program's depth of cut
/// (`depth_of_cut_uin`) under the loaded table's nose (0.125 in): the
/// closed form √(2 r_t d), 0.050 in at a 0.010 in roughing pass and
/// 0.00866 in at the 300 µin finishing pass, whatever the interruption
/// block (one without holes here).
#[test]
fn the_edges_contact_chord_is_root_2_r_d_of_the_depth_parameter_and_the_tables_nose() {
    let nose_in = CoeffTable::parse(crate::DEFAULT_TABLE)
        .unwrap()
        .header()
        .geometry
        .tool_radius_nin as f64
        * 1e-9;
    assert_eq!(nose_in, 0.125);
    for (depth_uin, want_uin) in [(10_000.0, 50_000), (300.0, 8_660)] {
        let mut d = crate::servo::ServoDesign::brief(20_000);
        d.depth_of_cut_uin = depth_uin;
        let mut cfg = fw_cfg(XMode::Legacy { clock_hz: CLOCK_HZ }, false);
        cfg.loop_cfg = d.config().unwrap();
        let mut fw = Firmware::with_table(crate::DEFAULT_TABLE, cfg).unwrap();
        let mut block = [0u8; 64];
        let n = crate::table::interrupt::Interruptions::encode(&[], &mut block).unwrap();
        fw.set_interruptions(&block[..n]).unwrap();
        let closed = (2.0 * nose_in * depth_uin * 1e-6).sqrt() * 1e6;
        let got = fw.edges().contact_inside_uin();
        assert_eq!(got, want_uin, "{depth_uin} µin deep");
        assert!((got as f64 - closed).abs() < 1.0, "{got} vs {closed}");
    }
}

/// A depth of cut outside [1, 10 000] µin is refused by the design, in
/// words that name the parameter and its value.
#[test]
fn a_depth_of_cut_beyond_the_gauge_range_is_refused_in_words() {
    for bad in [0.0, 10_001.0, f64::NAN] {
        let mut d = crate::servo::ServoDesign::brief(20_000);
        d.depth_of_cut_uin = bad;
        let e = d.config().unwrap_err();
        assert_eq!(e, crate::servo::DesignError::DepthOfCut);
        let m = std::format!("{}", d.refusal(e));
        assert!(
            m.starts_with(&std::format!(
                "depth_of_cut_uin = {bad} must be in [1, 10000]"
            )),
            "{m}"
        );
    }
}
