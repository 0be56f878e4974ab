//! The firmware application: controller state and the interrupt entry points
//! the boards call. Both boards (`src/main.rs` on the NUCLEO-H743ZI2 and
//! `boards/qemu`) and `host-sim` drive the same [`Firmware`]; a board only
//! supplies the converters and the amplifier-enable pin.
//!
//! # The loop (a placeholder until the servo issue)
//!
//! A fixed-point PID position loop on the gauge code with velocity
//! feedforward from the command slope:
//!
//! ```text
//! c[n]  = c[n-1] moved toward the target by at most `slew_per_tick`
//! e[n]  = c[n] - y[n]                               (gauge codes)
//! I[n]  = clamp(I[n-1] + ki·e[n], ±output_limit)
//! u[n]  = clamp(kp·e[n] + I[n] - kd·(y[n] - y[n-1]) + kff·(c[n] - c[n-1]),
//!               ±output_limit)                      (DAC codes)
//! ```
//!
//! The derivative acts on the measurement, not the error, so command steps
//! do not kick the output. Gains are `I8F24`; products are formed in `i64`
//! (no overflow is possible: |e| < 2²¹, gains < 2³¹ raw) and the sum is
//! rounded to the nearest DAC code, then saturated. Gauge and DAC codes share
//! a scale (2¹⁹ = 10 V), so `kp` is in volts per gauge volt.
//!
//! # Safety
//!
//! Nothing here can panic or allocate. The first gauge read at engagement
//! sets the command to where the slide is (bumpless), and the command then
//! ramps to the target. Faults latch ([`Firmware::fault`]); a fault whose
//! reaction is [`Reaction::DisableAmplifier`] clamps the DAC to ground (retried
//! every tick until the DAC accepts it), stops all DAC writes and drops
//! [`Firmware::amplifier_enable`]; a [`Reaction::RampToNull`] fault keeps the
//! loop closed and ramps the command to zero. Only a more severe fault replaces
//! a latched one; nothing clears a latch but a new [`Firmware`].

use fixed::types::I8F24;

use crate::hw::{AmplifierDac, GaugeAdc};
use crate::safety::{Device, Fault, Reaction};
use crate::units::ZInches;

/// Largest 20-bit two's complement code (gauge ADC and amplifier DAC).
pub const CODE_MAX: i32 = (1 << 19) - 1;
/// Smallest 20-bit two's complement code.
pub const CODE_MIN: i32 = -(1 << 19);

/// The gauge code that reads `z` (gauge 1 V/mil, ±10 V = ±0.010 in over
/// ±2¹⁹ codes), rounded to nearest and clamped to the converter range.
///
/// `code = z · 2¹⁹ / 0.010 in = z_bits · 2¹⁹ / (0.010 · 2³⁰) = z_bits · 25 / 512`,
/// exact in integers.
pub const fn gauge_code_from_z(z: ZInches) -> i32 {
    let scaled = z.to_bits() as i64 * 25;
    let code = (scaled + 256) >> 9;
    if code > CODE_MAX as i64 {
        CODE_MAX
    } else if code < CODE_MIN as i64 {
        CODE_MIN
    } else {
        code as i32
    }
}

/// Loop gains and limits, in per-tick units (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct LoopConfig {
    /// DAC codes per gauge code of position error, `I8F24` bits.
    pub kp_bits: i32,
    /// DAC codes per gauge code of error per tick (integral), `I8F24` bits.
    pub ki_bits: i32,
    /// DAC codes per gauge code per tick of measured velocity, `I8F24` bits.
    pub kd_bits: i32,
    /// DAC codes per gauge code per tick of command velocity, `I8F24` bits.
    pub kff_bits: i32,
    /// |DAC code| never exceeds this (≤ [`CODE_MAX`]).
    pub output_limit: i32,
    /// Largest command step per tick, gauge codes (> 0).
    pub slew_per_tick: i32,
}

impl LoopConfig {
    /// Proportional gain, volts per gauge volt, `I8F24` bits (0.4).
    const KP_Q24: i64 = 6_710_886;
    /// Derivative gain as a time: 655 µs (volts per gauge volt per second).
    const KD_NS: i64 = 655_000;
    /// Velocity feedforward as a time: 239.3 µs. The brief's slide (Model 15
    /// motor through the ×10 amplifier, B = 51.2 lbf·s/ft plus back-EMF
    /// damping) moves at 4.178 in/s per DAC volt; the gauge gives 1000 V/in,
    /// so one volt of DAC per 4178 gauge volts per second holds a ramp.
    const KFF_NS: i64 = 239_300;
    /// Integral gain: 80 volts per gauge volt·second.
    const KI_PER_S: i64 = 80;
    /// Command slew: 0.25 in/s, the brief's worst-case Z speed, in gauge
    /// codes per second (0.25 in/s · 2¹⁹ codes / 0.010 in).
    const SLEW_CODES_PER_S: i64 = 13_107_200;

    /// Gains for the brief's slide sampled at `rate_hz` (clamped to
    /// 1 Hz..1 MHz). Design, continuous time, plant
    /// P(s) = 1.281e6 / (s (s + 306.6)) gauge V per DAC V: kp = 0.4 and
    /// kd = 655 µs place the poles at ωn = 716 rad/s, ζ = 0.8; the integral
    /// zero sits at 200 rad/s and only removes offsets (amplifier, gravity).
    pub const fn at_rate(rate_hz: u32) -> Self {
        let rate = if rate_hz == 0 {
            1
        } else if rate_hz > 1_000_000 {
            1_000_000
        } else {
            rate_hz as i64
        };
        let q24 = 1i64 << 24;
        let slew = Self::SLEW_CODES_PER_S / rate;
        Self {
            kp_bits: Self::KP_Q24 as i32,
            ki_bits: ((Self::KI_PER_S * q24 + rate / 2) / rate) as i32,
            kd_bits: time_gain_per_tick(Self::KD_NS, rate),
            kff_bits: time_gain_per_tick(Self::KFF_NS, rate),
            output_limit: CODE_MAX,
            slew_per_tick: if slew < 1 { 1 } else { slew as i32 },
        }
    }

    /// `kp` as a fixed-point number, for reports.
    pub fn kp(&self) -> I8F24 {
        I8F24::from_bits(self.kp_bits)
    }
}

/// Controller state and the interrupt entry points.
#[derive(Clone, Debug)]
pub struct Firmware {
    cfg: LoopConfig,
    /// Where the slide should go, gauge codes.
    target: i32,
    /// The slew-limited command the loop follows, gauge codes.
    command: i32,
    /// Integral term, DAC codes in `I8F24` bits, clamped to the output limit.
    integral: i64,
    /// Gauge code of the previous tick.
    position: i32,
    engaged: bool,
    ticks: u32,
    output: i32,
    fault: Option<Fault>,
    dac_clamped: bool,
}

impl Firmware {
    pub const fn new(cfg: LoopConfig) -> Self {
        let limit = if cfg.output_limit < 0 {
            0
        } else if cfg.output_limit > CODE_MAX {
            CODE_MAX
        } else {
            cfg.output_limit
        };
        let slew = if cfg.slew_per_tick < 1 {
            1
        } else {
            cfg.slew_per_tick
        };
        Self {
            cfg: LoopConfig {
                output_limit: limit,
                slew_per_tick: slew,
                ..cfg
            },
            target: 0,
            command: 0,
            integral: 0,
            position: 0,
            engaged: false,
            ticks: 0,
            output: 0,
            fault: None,
            dac_clamped: false,
        }
    }

    /// Sets where the slide should go; the command ramps there at the slew
    /// limit. Clamped to the gauge range.
    pub fn set_target_code(&mut self, code: i32) {
        self.target = code.clamp(CODE_MIN, CODE_MAX);
    }

    /// [`Self::set_target_code`] for a Z position (gauge sign: +volts = +Z).
    pub fn set_target(&mut self, z: ZInches) {
        self.set_target_code(gauge_code_from_z(z));
    }

    /// Latches `fault` unless a fault with an equally or more severe reaction
    /// is already latched (the first cause stays readable).
    pub fn trip(&mut self, fault: Fault) {
        match self.fault {
            Some(f) if f.reaction() >= fault.reaction() => {}
            _ => self.fault = Some(fault),
        }
    }

    /// The loop-tick interrupt: one gauge sample in, one DAC code out.
    ///
    /// Never inlined, so that `cargo xtask isr-cost` finds it in the image
    /// and counts its instructions apart from the board's glue (one call and
    /// return, a few cycles).
    #[inline(never)]
    pub fn loop_tick(&mut self, gauge: &mut impl GaugeAdc, dac: &mut impl AmplifierDac) {
        self.ticks = self.ticks.wrapping_add(1);
        if self.amplifier_must_be_off() {
            self.hold_safe(dac);
            return;
        }
        let sample = match gauge.read() {
            Ok(s) => s,
            Err(_) => {
                self.trip(Fault::Bus(Device::GaugeAdc));
                self.hold_safe(dac);
                return;
            }
        };
        if sample.overrange {
            self.trip(Fault::GaugeRange);
            self.hold_safe(dac);
            return;
        }
        let y = sample.code.clamp(CODE_MIN, CODE_MAX);
        if !self.engaged {
            // Bumpless: start from wherever the slide is.
            self.command = y;
            self.position = y;
            self.integral = 0;
            self.engaged = true;
        }
        let goal = if self.fault.is_some() { 0 } else { self.target };
        let previous_command = self.command;
        self.command = step_toward(self.command, goal, self.cfg.slew_per_tick);

        let error = i64::from(self.command) - i64::from(y);
        let velocity = i64::from(y) - i64::from(self.position);
        let command_step = i64::from(self.command) - i64::from(previous_command);
        self.position = y;

        let limit_q24 = i64::from(self.cfg.output_limit) << 24;
        self.integral = self
            .integral
            .saturating_add(i64::from(self.cfg.ki_bits) * error)
            .clamp(-limit_q24, limit_q24);
        let sum = (i64::from(self.cfg.kp_bits) * error)
            .saturating_add(self.integral)
            .saturating_sub(i64::from(self.cfg.kd_bits) * velocity)
            .saturating_add(i64::from(self.cfg.kff_bits) * command_step);
        let rounded = sum.saturating_add(1 << 23) >> 24;
        let limit = i64::from(self.cfg.output_limit);
        // The clamp bounds the value to ±2¹⁹, so the cast is exact.
        let u = rounded.clamp(-limit, limit) as i32;

        match dac.write(u) {
            Ok(()) => self.output = u,
            Err(_) => {
                self.trip(Fault::Bus(Device::AmplifierDac));
                self.hold_safe(dac);
            }
        }
    }

    fn amplifier_must_be_off(&self) -> bool {
        matches!(self.fault, Some(f) if f.reaction() == Reaction::DisableAmplifier)
    }

    fn hold_safe(&mut self, dac: &mut impl AmplifierDac) {
        self.output = 0;
        self.integral = 0;
        if !self.dac_clamped && dac.clamp_to_ground().is_ok() {
            self.dac_clamped = true;
        }
    }

    /// Whether the board may drive the amplifier-enable line high: the loop
    /// has engaged on a good gauge sample and no fault demands it off.
    pub fn amplifier_enable(&self) -> bool {
        self.engaged && !self.amplifier_must_be_off()
    }

    /// Loop ticks run so far (wrapping), faulted ticks included.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }
    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }
    /// The command the loop followed on the last tick, gauge codes.
    pub fn command_code(&self) -> i32 {
        self.command
    }
    /// The target the command ramps to, gauge codes.
    pub fn target_code(&self) -> i32 {
        self.target
    }
    /// The gauge code of the last good sample.
    pub fn position_code(&self) -> i32 {
        self.position
    }
    /// The DAC code written on the last tick (0 when held safe).
    pub fn output_code(&self) -> i32 {
        self.output
    }
    /// Whether the DAC has acknowledged its clamp to ground.
    pub fn dac_clamped(&self) -> bool {
        self.dac_clamped
    }
    pub fn config(&self) -> &LoopConfig {
        &self.cfg
    }
}

/// A gain given as a time in ns (volts per volt/second) as `I8F24` bits per
/// tick at `rate` Hz, rounded; saturates at `i32::MAX` (a 655 µs gain at
/// 1 MHz would need 2⁴⁰). `i128`: ns · rate · 2²⁴ exceeds `i64` at 1 MHz.
const fn time_gain_per_tick(ns: i64, rate: i64) -> i32 {
    let bits = (ns as i128 * rate as i128 * (1 << 24) + 500_000_000) / 1_000_000_000;
    if bits > i32::MAX as i128 {
        i32::MAX
    } else {
        bits as i32
    }
}

const fn step_toward(from: i32, to: i32, max_step: i32) -> i32 {
    if to > from {
        if to - from > max_step {
            from + max_step
        } else {
            to
        }
    } else if from - to > max_step {
        from - max_step
    } else {
        to
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::hw::{BusError, GaugeSample};
    use core::cell::Cell;
    use std::vec::Vec;

    const Q24: i32 = 1 << 24;

    /// A gauge whose next reading the test sets.
    struct Gauge(Result<GaugeSample, BusError>);
    impl Gauge {
        fn at(code: i32) -> Self {
            Self(Ok(GaugeSample {
                code,
                overrange: false,
            }))
        }
        fn set(&mut self, code: i32) {
            self.0 = Ok(GaugeSample {
                code,
                overrange: false,
            });
        }
    }
    impl GaugeAdc for Gauge {
        fn read(&mut self) -> Result<GaugeSample, BusError> {
            self.0
        }
    }

    #[derive(Default)]
    struct Dac {
        writes: Vec<i32>,
        clamps: u32,
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
    }

    fn cfg(kp: i32, ki: i32, kd: i32) -> LoopConfig {
        LoopConfig {
            kp_bits: kp,
            ki_bits: ki,
            kd_bits: kd,
            kff_bits: 0,
            output_limit: CODE_MAX,
            slew_per_tick: CODE_MAX,
        }
    }

    #[test]
    fn gauge_scale_is_one_volt_per_mil_over_20_bits() {
        // Brief: code = round(V · 2¹⁹ / 10 V), 1 V per mil.
        assert_eq!(gauge_code_from_z(ZInches::from_f64(0.005)), 1 << 18);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(-0.010)), CODE_MIN);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(0.010)), CODE_MAX);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(0.5)), CODE_MAX);
        // 1 µin = 52.4288 codes.
        assert_eq!(gauge_code_from_z(ZInches::from_f64(1e-6)), 52);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(-1e-6)), -52);
    }

    #[test]
    fn first_tick_is_bumpless() {
        let mut fw = Firmware::new(cfg(Q24, Q24 / 4, Q24));
        let (mut g, mut d) = (Gauge::at(12_345), Dac::default());
        fw.set_target_code(12_345);
        assert!(!fw.amplifier_enable());
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(d.writes, [0]);
        assert_eq!(fw.command_code(), 12_345);
        assert!(fw.amplifier_enable());
    }

    #[test]
    fn proportional_integral_and_derivative_terms() {
        // kp = 0.5, ki = 0.25, kd = 2: hand-computed outputs.
        let mut fw = Firmware::new(cfg(Q24 / 2, Q24 / 4, 2 * Q24));
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.loop_tick(&mut g, &mut d); // engages at 0, target 0
        fw.set_target_code(1000);
        fw.loop_tick(&mut g, &mut d); // e = 1000: 500 + 250
        g.set(10);
        fw.loop_tick(&mut g, &mut d); // e = 990: 495 + (250 + 247.5) - 20
        assert_eq!(d.writes, [0, 750, 973]);
    }

    #[test]
    fn output_saturates_and_integral_does_not_wind_up() {
        let limit = 100_000;
        let mut c = cfg(100 * Q24, Q24, 0);
        c.output_limit = limit;
        let mut fw = Firmware::new(c);
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.set_target_code(200_000);
        for _ in 0..10_000 {
            fw.loop_tick(&mut g, &mut d);
        }
        assert!(d.writes.iter().skip(1).all(|&u| u == limit));
        // At zero error the output is the integral alone: at most the limit,
        // so the loop leaves saturation at once when the error reverses.
        g.set(200_000);
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(d.writes.last(), Some(&limit));
        g.set(200_001);
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(d.writes.last(), Some(&(limit - 101)));
    }

    #[test]
    fn command_slews_to_target() {
        let mut c = cfg(0, 0, 0);
        c.slew_per_tick = 100;
        let mut fw = Firmware::new(c);
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.set_target_code(1050);
        let mut seen = Vec::new();
        for _ in 0..12 {
            fw.loop_tick(&mut g, &mut d);
            seen.push(fw.command_code());
        }
        assert_eq!(
            seen,
            [100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1050, 1050]
        );
    }

    /// A discrete integrator plant y[n+1] = y[n] + u[n] under P control:
    /// e[n+1] = (1 - kp) e[n], closed form e[n] = e0 (1 - kp)^n.
    #[test]
    fn p_loop_on_integrator_follows_closed_form() {
        struct Plant<'a>(&'a Cell<i32>);
        impl GaugeAdc for Plant<'_> {
            fn read(&mut self) -> Result<GaugeSample, BusError> {
                Ok(GaugeSample {
                    code: self.0.get(),
                    overrange: false,
                })
            }
        }
        impl AmplifierDac for Plant<'_> {
            fn write(&mut self, code: i32) -> Result<(), BusError> {
                self.0.set(self.0.get() + code);
                Ok(())
            }
            fn clamp_to_ground(&mut self) -> Result<(), BusError> {
                Ok(())
            }
        }
        let y = Cell::new(0);
        let mut fw = Firmware::new(cfg(Q24 / 2, 0, 0));
        fw.loop_tick(&mut Plant(&y), &mut Plant(&y));
        fw.set_target_code(1 << 16);
        let mut errors = Vec::new();
        for _ in 0..17 {
            errors.push(fw.target_code() - y.get());
            fw.loop_tick(&mut Plant(&y), &mut Plant(&y));
        }
        let expected: Vec<i32> = (0..17).map(|n| (1 << 16) >> n).collect();
        assert_eq!(errors, expected);
    }

    #[test]
    fn gauge_bus_error_latches_and_clamps_dac() {
        let mut fw = Firmware::new(LoopConfig::at_rate(20_000));
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.loop_tick(&mut g, &mut d);
        g.0 = Err(BusError);
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
        assert!(!fw.amplifier_enable());
        assert_eq!(d.clamps, 1);
        // The gauge recovers; the latch holds and the DAC stays untouched.
        g.set(5);
        for _ in 0..5 {
            fw.loop_tick(&mut g, &mut d);
        }
        assert_eq!(d.writes.len(), 1);
        assert_eq!(d.clamps, 1);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
        assert_eq!(fw.ticks(), 7);
    }

    #[test]
    fn dac_bus_error_latches_and_retries_clamp_until_accepted() {
        let mut fw = Firmware::new(LoopConfig::at_rate(20_000));
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        d.fail_writes = true;
        d.fail_clamps = 2;
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::AmplifierDac)));
        assert!(!fw.dac_clamped());
        fw.loop_tick(&mut g, &mut d);
        fw.loop_tick(&mut g, &mut d);
        fw.loop_tick(&mut g, &mut d);
        assert!(fw.dac_clamped());
        assert_eq!(d.clamps, 3);
    }

    #[test]
    fn overrange_gauge_disables_amplifier() {
        let mut fw = Firmware::new(LoopConfig::at_rate(20_000));
        let mut g = Gauge(Ok(GaugeSample {
            code: CODE_MAX,
            overrange: true,
        }));
        let mut d = Dac::default();
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::GaugeRange));
        assert!(d.writes.is_empty());
        assert_eq!(d.clamps, 1);
    }

    #[test]
    fn ramp_to_null_fault_keeps_loop_closed_and_nulls_command() {
        let mut c = cfg(0, 0, 0);
        c.slew_per_tick = 250;
        let mut fw = Firmware::new(c);
        let (mut g, mut d) = (Gauge::at(1000), Dac::default());
        fw.set_target_code(1000);
        fw.loop_tick(&mut g, &mut d);
        fw.trip(Fault::FollowingError);
        for _ in 0..3 {
            fw.loop_tick(&mut g, &mut d);
        }
        assert_eq!(fw.command_code(), 250);
        fw.loop_tick(&mut g, &mut d);
        fw.loop_tick(&mut g, &mut d);
        assert_eq!(fw.command_code(), 0);
        assert!(fw.amplifier_enable());
        // A more severe fault replaces it; a milder one does not.
        fw.trip(Fault::Watchdog);
        fw.trip(Fault::XGlitchStorm);
        assert_eq!(fw.fault(), Some(Fault::Watchdog));
    }

    #[test]
    fn default_gains_match_their_continuous_design() {
        let c = LoopConfig::at_rate(20_000);
        let q = f64::from(Q24);
        assert!((f64::from(c.kp_bits) / q - 0.4).abs() < 1e-6);
        assert!((f64::from(c.kd_bits) / q - 655e-6 * 20_000.0).abs() < 1e-6);
        assert!((f64::from(c.kff_bits) / q - 239.3e-6 * 20_000.0).abs() < 1e-6);
        assert!((f64::from(c.ki_bits) / q - 80.0 / 20_000.0).abs() < 1e-7);
        // 0.25 in/s at 20 kHz: 12.5 µin per tick = 655.36 codes.
        assert_eq!(c.slew_per_tick, 655);
        assert_eq!(LoopConfig::at_rate(0).slew_per_tick, 13_107_200);
        // The extremes of the allowed rates neither overflow nor wrap.
        let fast = LoopConfig::at_rate(u32::MAX);
        assert_eq!(fast.kd_bits, i32::MAX);
        assert_eq!(fast.slew_per_tick, 13);
        assert!(fast.ki_bits > 0);
    }
}
