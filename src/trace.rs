//! Trace events: what a board reports of its handlers and outputs so that a
//! run on the target can be laid beside a simulated one, signal for signal.
//!
//! A board puts each [`Event`] on its defmt log with [`emit`]: one line
//! carrying the event's [`Event::code`], its value and the board's clock at
//! the moment it happened. Only builds with this crate's `trace` feature
//! have the lines (the boards' own `trace` features turn it on: `cargo
//! xtask qemu --vcd`, `cargo fw --features trace`); otherwise [`emit`] and
//! [`Outputs`] are empty and cost nothing. The host side
//! (`host-sim trace2vcd`) turns a decoded log into a VCD whose signal names
//! are [`Signal::name`], the same names the simulator's machine trace uses
//! for the same quantities (`host-sim/src/vcd/machine.rs`).
//!
//! The wire form is three integers, so the decoder needs no knowledge of
//! defmt's encoding: `ev <code> <value> <clock>`.

/// 2¹⁹: the gauge ADC's and the amplifier DAC's codes are 20-bit two's
/// complement, −2¹⁹ ..= 2¹⁹ − 1.
const CONVERTER_FULL_SCALE: i32 = 1 << 19;

/// What happened. The value each carries is given per variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// The loop-tick handler started / finished (value 0).
    LoopEnter,
    LoopExit,
    /// The X-event handler started / finished (value 0).
    XEnter,
    XExit,
    /// The index handler started / finished (value 0).
    IndexEnter,
    IndexExit,
    /// The gauge ADC code the tick read (20-bit two's complement).
    Adc(i32),
    /// The amplifier DAC code the tick wrote (20-bit two's complement).
    Dac(i32),
    /// The position command, gauge codes.
    Command(i32),
    /// Command − position estimate, gauge codes.
    Error(i32),
    /// Amplifier enable (0 or 1).
    Enable(bool),
    /// A fault is latched (1) or none (0); its reason is logged in words
    /// on its own line.
    Fault(bool),
    /// The loop is armed (1) or disarmed (0).
    Armed(bool),
    /// A new coefficient set was published (value: its generation).
    Coefficients(u32),
    /// X as the firmware has it, `XInches` bits (I8F24 in).
    X(i32),
    /// The spindle angle as the firmware has it, binary angle bits.
    Angle(u32),
}

impl Event {
    /// The event's number on the wire.
    pub const fn code(self) -> u8 {
        match self {
            Event::LoopEnter => 0,
            Event::LoopExit => 1,
            Event::XEnter => 2,
            Event::XExit => 3,
            Event::IndexEnter => 4,
            Event::IndexExit => 5,
            Event::Adc(_) => 6,
            Event::Dac(_) => 7,
            Event::Command(_) => 8,
            Event::Error(_) => 9,
            Event::Enable(_) => 10,
            Event::Fault(_) => 11,
            Event::Armed(_) => 12,
            Event::Coefficients(_) => 13,
            Event::X(_) => 14,
            Event::Angle(_) => 15,
        }
    }

    /// The event's value on the wire (unsigned quantities as their bits).
    pub const fn value(self) -> i32 {
        match self {
            Event::LoopEnter
            | Event::LoopExit
            | Event::XEnter
            | Event::XExit
            | Event::IndexEnter
            | Event::IndexExit => 0,
            Event::Adc(v) | Event::Dac(v) | Event::Command(v) | Event::Error(v) | Event::X(v) => v,
            Event::Enable(b) | Event::Fault(b) | Event::Armed(b) => b as i32,
            Event::Coefficients(g) => g as i32,
            Event::Angle(a) => a as i32,
        }
    }

    /// The event back from its wire form; `None` for an unknown code or a
    /// value the event never carries: a handler mark with a value other
    /// than 0, a converter code beyond 20 bits, a flag that is neither 0
    /// nor 1 (a corrupt line is refused, not guessed: none of these is
    /// dropped or clipped to what it might have been).
    pub const fn decode(code: u8, value: i32) -> Option<Event> {
        let flag = match value {
            0 => Some(false),
            1 => Some(true),
            _ => None,
        };
        let mark = value == 0;
        let converter = -CONVERTER_FULL_SCALE <= value && value < CONVERTER_FULL_SCALE;
        Some(match code {
            0..=5 if !mark => return None,
            6 | 7 if !converter => return None,
            0 => Event::LoopEnter,
            1 => Event::LoopExit,
            2 => Event::XEnter,
            3 => Event::XExit,
            4 => Event::IndexEnter,
            5 => Event::IndexExit,
            6 => Event::Adc(value),
            7 => Event::Dac(value),
            8 => Event::Command(value),
            9 => Event::Error(value),
            10 => match flag {
                Some(b) => Event::Enable(b),
                None => return None,
            },
            11 => match flag {
                Some(b) => Event::Fault(b),
                None => return None,
            },
            12 => match flag {
                Some(b) => Event::Armed(b),
                None => return None,
            },
            13 => Event::Coefficients(value as u32),
            14 => Event::X(value),
            15 => Event::Angle(value as u32),
            _ => return None,
        })
    }

    /// The signal the event drives.
    pub const fn signal(self) -> Signal {
        match self {
            Event::LoopEnter => Signal::LoopTick,
            Event::XEnter => Signal::XEvent,
            Event::IndexEnter => Signal::Index,
            Event::LoopExit => Signal::LoopBusy,
            Event::XExit => Signal::XBusy,
            Event::IndexExit => Signal::IndexBusy,
            Event::Adc(_) => Signal::AdcCode,
            Event::Dac(_) => Signal::DacCode,
            Event::Command(_) => Signal::Command,
            Event::Error(_) => Signal::Error,
            Event::Enable(_) => Signal::AmpEnabled,
            Event::Fault(_) => Signal::Fault,
            Event::Armed(_) => Signal::Armed,
            Event::Coefficients(_) => Signal::CoeffUpdate,
            Event::X(_) => Signal::XFirmware,
            Event::Angle(_) => Signal::AngleFirmware,
        }
    }
}

/// A signal the firmware itself knows, named as in every VCD of the project.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// Toggles once per loop-tick handler run.
    LoopTick,
    /// Toggles once per X-event handler run.
    XEvent,
    /// Toggles once per index handler run.
    Index,
    /// High while the loop-tick handler runs (entry to exit; a handler that
    /// preempts it does not lower it). Only a target trace has these three:
    /// the simulator runs a handler in zero simulated time.
    LoopBusy,
    XBusy,
    IndexBusy,
    AdcCode,
    DacCode,
    /// Position command, µin.
    Command,
    /// Command − position, µin.
    Error,
    AmpEnabled,
    Fault,
    Armed,
    /// Toggles once per coefficient set published.
    CoeffUpdate,
    /// X, inches.
    XFirmware,
    /// Spindle angle, degrees.
    AngleFirmware,
}

impl Signal {
    /// Every signal, in the order a VCD declares them.
    pub const ALL: [Signal; 16] = [
        Signal::Command,
        Signal::Error,
        Signal::AdcCode,
        Signal::DacCode,
        Signal::AmpEnabled,
        Signal::XFirmware,
        Signal::AngleFirmware,
        Signal::LoopTick,
        Signal::XEvent,
        Signal::Index,
        Signal::LoopBusy,
        Signal::XBusy,
        Signal::IndexBusy,
        Signal::CoeffUpdate,
        Signal::Armed,
        Signal::Fault,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            Signal::LoopTick => "loop_tick",
            Signal::XEvent => "x_event",
            Signal::Index => "index",
            Signal::LoopBusy => "loop_tick_busy",
            Signal::XBusy => "x_event_busy",
            Signal::IndexBusy => "index_busy",
            Signal::AdcCode => "adc_code",
            Signal::DacCode => "dac_code",
            Signal::Command => "command_uin",
            Signal::Error => "error_uin",
            Signal::AmpEnabled => "amp_enabled",
            Signal::Fault => "fault",
            Signal::Armed => "armed",
            Signal::CoeffUpdate => "coeff_update",
            Signal::XFirmware => "x_fw_in",
            Signal::AngleFirmware => "spindle_phi_fw_deg",
        }
    }

    /// A one-bit line (activity toggles and flags); the others are numbers.
    pub const fn is_bit(self) -> bool {
        matches!(
            self,
            Signal::LoopTick
                | Signal::XEvent
                | Signal::Index
                | Signal::LoopBusy
                | Signal::XBusy
                | Signal::IndexBusy
                | Signal::AmpEnabled
                | Signal::Fault
                | Signal::Armed
                | Signal::CoeffUpdate
        )
    }

    /// A handler's activity line: it toggles at each entry.
    pub const fn toggles(self) -> bool {
        matches!(
            self,
            Signal::LoopTick | Signal::XEvent | Signal::Index | Signal::CoeffUpdate
        )
    }
}

/// What changed in the loop's outputs since the last tick, as events: the
/// boards call [`LoopTrace::after_tick`] after each `loop_tick` (in builds
/// with their `trace` feature) and put each event on their log with their
/// clock. Only changes are emitted, so a quiet loop costs little log.
#[derive(Clone, Debug, Default)]
pub struct LoopTrace {
    last: [Option<i32>; 9],
}

impl LoopTrace {
    pub const fn new() -> Self {
        Self { last: [None; 9] }
    }

    /// The events of this tick's outputs that differ from the last tick's.
    pub fn after_tick(
        &mut self,
        lp: &crate::firmware::looptick::LoopState,
        mut emit: impl FnMut(Event),
    ) {
        let command = lp.command_code();
        let position = lp.position_code();
        let now = [
            Event::Adc(position),
            Event::Dac(lp.output_code()),
            Event::Command(command),
            Event::Error(command.saturating_sub(position)),
            Event::Enable(lp.amplifier_enable()),
            Event::Fault(lp.fault().is_some()),
            Event::Armed(lp.servo().phase() != crate::servo::Phase::Disarmed),
            Event::X(lp.last_x().map_or(i32::MIN, |x| x.to_bits())),
            Event::Angle(lp.setpoint_state().angle().map_or(0, |a| a.0)),
        ];
        for (last, e) in self.last.iter_mut().zip(now) {
            // An unknown X or angle is not traced (the VCD keeps "unknown").
            let unknown = matches!(e, Event::X(i32::MIN))
                || (matches!(e, Event::Angle(_)) && lp.setpoint_state().angle().is_none());
            if unknown || *last == Some(e.value()) {
                continue;
            }
            *last = Some(e.value());
            emit(e);
        }
    }
}

/// Puts `e` on the log, stamped `clock` (the board's trace clock, named
/// once at boot by [`announce_clock`]), in `trace` builds on a target.
#[inline(always)]
pub fn emit(e: Event, clock: u32) {
    #[cfg(all(target_os = "none", feature = "trace"))]
    defmt::info!("ev {=u8} {=i32} {=u32}", e.code(), e.value(), clock);
    #[cfg(not(all(target_os = "none", feature = "trace")))]
    let _ = (e, clock);
}

/// Names the trace clock's rate (the decoder needs it before any event).
#[inline(always)]
pub fn announce_clock(hz: u32) {
    #[cfg(all(target_os = "none", feature = "trace"))]
    defmt::info!("trace clock {=u32} Hz", hz);
    #[cfg(not(all(target_os = "none", feature = "trace")))]
    let _ = hz;
}

/// The loop's outputs as the boards trace them: [`LoopTrace`] in `trace`
/// builds, nothing at all otherwise.
#[derive(Clone, Debug, Default)]
pub struct Outputs {
    #[cfg(feature = "trace")]
    last: LoopTrace,
}

impl Outputs {
    pub const fn new() -> Self {
        Self {
            #[cfg(feature = "trace")]
            last: LoopTrace::new(),
        }
    }

    /// After a loop tick: the outputs that changed, stamped by `clock`.
    #[inline(always)]
    pub fn after_tick(
        &mut self,
        lp: &crate::firmware::looptick::LoopState,
        clock: impl Fn() -> u32,
    ) {
        #[cfg(feature = "trace")]
        self.last.after_tick(lp, |e| emit(e, clock()));
        #[cfg(not(feature = "trace"))]
        let _ = (lp, clock);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn every_event_survives_its_wire_form() {
        let events = [
            Event::LoopEnter,
            Event::LoopExit,
            Event::XEnter,
            Event::XExit,
            Event::IndexEnter,
            Event::IndexExit,
            Event::Adc(-524_288),
            Event::Dac(524_287),
            Event::Command(-1),
            Event::Error(7),
            Event::Enable(true),
            Event::Fault(false),
            Event::Armed(true),
            Event::Coefficients(u32::MAX),
            Event::X(0x7000_0000),
            Event::Angle(0xFFFF_FFFF),
        ];
        let mut codes = [false; 16];
        for e in events {
            assert_eq!(Event::decode(e.code(), e.value()), Some(e));
            codes[usize::from(e.code())] = true;
        }
        assert!(codes.iter().all(|&c| c), "every code used once");
    }

    #[test]
    fn unknown_codes_and_values_no_event_carries_are_refused() {
        assert_eq!(Event::decode(16, 0), None);
        assert_eq!(Event::decode(255, 0), None);
        assert_eq!(Event::decode(Event::Enable(true).code(), 2), None);
        assert_eq!(Event::decode(Event::Fault(true).code(), -1), None);
        // Handler marks carry 0 (found by the trace_log fuzz target: an
        // index exit with a gauge code's value was taken as a mark).
        for code in 0..=5 {
            assert!(Event::decode(code, 0).is_some(), "{code}");
            for v in [1, -1, -41_534, i32::MIN, i32::MAX] {
                assert_eq!(Event::decode(code, v), None, "{code} {v}");
            }
        }
        // Converter codes are 20-bit two's complement: −2¹⁹ ..= 2¹⁹ − 1.
        for code in [6, 7] {
            assert!(Event::decode(code, -524_288).is_some());
            assert!(Event::decode(code, 524_287).is_some());
            for v in [524_288, -524_289, i32::MAX, i32::MIN] {
                assert_eq!(Event::decode(code, v), None, "{code} {v}");
            }
        }
        // The other quantities use all 32 bits.
        for code in [8, 9, 13, 14, 15] {
            assert!(Event::decode(code, i32::MIN).is_some(), "{code}");
            assert!(Event::decode(code, i32::MAX).is_some(), "{code}");
        }
    }

    #[test]
    fn loop_trace_emits_what_changed_and_nothing_else() {
        let cfg = crate::servo::ServoConfig::at_rate(20_000).unwrap();
        let mut fw = crate::firmware::Firmware::new(cfg);
        let mut tr = LoopTrace::new();
        let mut got = heapless::Vec::<Event, 16>::new();
        tr.after_tick(fw.loop_state(), |e| got.push(e).unwrap());
        // a loop that never ran: codes 0, amplifier off, no fault,
        // disarmed; X and the angle are unknown and not traced
        assert_eq!(
            got.as_slice(),
            &[
                Event::Adc(0),
                Event::Dac(0),
                Event::Command(0),
                Event::Error(0),
                Event::Enable(false),
                Event::Fault(false),
                Event::Armed(false),
            ]
        );
        got.clear();
        tr.after_tick(fw.loop_state(), |e| got.push(e).unwrap());
        assert!(got.is_empty(), "{got:?}");
        fw.trip(crate::safety::Fault::GaugeRange);
        tr.after_tick(fw.loop_state(), |e| got.push(e).unwrap());
        assert_eq!(got.as_slice(), &[Event::Fault(true)]);
    }

    #[test]
    fn signal_names_are_distinct() {
        for (i, a) in Signal::ALL.iter().enumerate() {
            for b in &Signal::ALL[i + 1..] {
                assert_ne!(a.name(), b.name());
            }
        }
    }
}
