//! The firmware's codes in the user's units and words: gauge codes in µin,
//! DAC codes in volts, X in inches, φ in degrees, phases and triggers.

use zslide::link::proto::{FaultRecord, LoopPhase, Status, Trigger};

/// Gauge codes per µin (20 bits over ±0.010 in: 2¹⁹ / 10 000 µin).
pub const CODES_PER_UIN: f64 = zslide::codes::GAUGE_CODES_PER_INCH / 1e6;
/// Volts per DAC code (±10 V over 20 bits).
pub const V_PER_CODE: f64 = 10.0 / 524_288.0;

pub fn inch(bits: i32) -> f64 {
    f64::from(bits) / f64::from(1u32 << 24)
}
pub fn deg(phi: u32) -> f64 {
    f64::from(phi) * 360.0 / 4_294_967_296.0
}
pub fn uin(codes: i32) -> f64 {
    f64::from(codes) / CODES_PER_UIN
}

/// A parameter's value as a person writes it: at most 6 significant
/// digits, no trailing zeros. The firmware holds its parameters as f32
/// (`params::ParamValue`), so `0.3335` comes back as 0.33349999999999996
/// in f64; the seventh digit and beyond say nothing.
pub fn value(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = 6 - 1 - v.abs().log10().floor() as i32;
    let s = if (0..=12).contains(&digits) {
        format!("{v:.*}", digits as usize)
    } else {
        return format!("{v:.5e}");
    };
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A trigger as the user typed it: the following-error level in µin (the
/// wire carries gauge codes).
pub fn trigger(t: Trigger) -> String {
    match t {
        Trigger::Immediate => "immediate".into(),
        Trigger::Fault => "on the next fault".into(),
        // The level is whole codes (0.019 µin each): a typed 3 µin is 157
        // codes, 2.9945 µin, shown as the 3.0 typed.
        Trigger::FollowingError { level } => {
            let v = f64::from(level) / CODES_PER_UIN;
            let digits = if v < 1.0 { 2 } else { 1 };
            format!("|following error| ≥ {v:.digits$} µin")
        }
        Trigger::AtTick { tick } => format!("at loop tick {tick}"),
    }
}

pub fn phase(p: LoopPhase) -> &'static str {
    match p {
        LoopPhase::Disarmed => "disarmed",
        LoopPhase::SignCheck => "armed, sign check running",
        LoopPhase::Engaging => "armed, engaging",
        LoopPhase::Engaged => "armed, engaged",
        LoopPhase::Disarming => "disarming (ramping to null)",
    }
}

pub fn status_text(s: &Status) -> String {
    let mut t = String::new();
    let secs = f64::from(s.state.ticks) / f64::from(s.loop_hz.max(1));
    t += &format!(
        "loop: {} ({}), {} Hz, tick {} ({secs:.3} s); X from {:?}, spindle from {:?}\n",
        phase(s.state.phase),
        if s.state.amplifier_enabled {
            "amplifier enabled"
        } else {
            "amplifier off"
        },
        s.loop_hz,
        s.state.ticks,
        s.x_source,
        s.spindle_source
    );
    t += &match s.state.fault {
        Some(f) => format!("fault: {f} ({:?})\n", f.reaction()),
        None => "fault: none\n".into(),
    };
    if let Some(f) = s.state.clear_refused {
        t += &format!("last clear refused: {f}\n");
    }
    let x = s.state.x_bits.map_or("unknown (no X yet)".into(), |b| {
        format!("{:.6} in", inch(b))
    });
    let phi = s
        .state
        .phi
        .map_or("not referenced (no index yet)".into(), |p| {
            format!("{:.3} deg", deg(p))
        });
    let rpm = s.state.phi_step_q8.map_or("unknown".into(), |q| {
        let turns_per_tick = q as f64 / 256.0 / 4_294_967_296.0;
        format!("{:.2} rpm", turns_per_tick * f64::from(s.loop_hz) * 60.0)
    });
    t += &format!(
        "X {x}{}; phi {phi}; spindle {rpm}\n",
        if s.state.null_command {
            " (command null)"
        } else {
            ""
        }
    );
    t += &format!(
        "command {:.3} uin ({} codes), position {:.3} uin, error {:.3} uin, table command {:.3} uin, output {:.5} V\n",
        uin(s.state.command),
        s.state.command,
        uin(s.state.position),
        uin(s.state.command.saturating_sub(s.state.position)),
        uin(s.state.table_command),
        f64::from(s.state.output) * V_PER_CODE
    );
    t += &match s.table {
        Ok(id) => format!("table: {id}\n"),
        Err(e) => format!("table: REFUSED: {e}\n"),
    };
    t += &format!("servo parameters: {}\n", s.params);
    t += &format!(
        "counters: X events {} accepted / {} ignored, coefficient sets {}, index events {}, faults logged {}\n",
        s.x_accepted, s.x_ignored, s.coefficient_sets, s.index_events, s.faults_logged
    );
    let f = s.frames;
    t += &format!(
        "link frames: {} ok, {} empty; refused: {} oversize, {} bad COBS, {} bad CRC, {} other version, {} unknown command, {} malformed\n",
        f.ok, f.empty, f.oversize, f.bad_cobs, f.bad_crc, f.bad_version, f.unknown_command, f.malformed
    );
    let c = s.capture;
    t += &format!(
        "capture: {:?}, {} samples ({} before the trigger), trigger {}; holds up to {}\n",
        c.state,
        c.samples,
        c.pre,
        trigger(c.trigger),
        c.capacity
    );
    t
}

pub fn record_text(r: &FaultRecord, loop_hz: u32) -> String {
    format!(
        "t = {:>10.5} s (tick {:>9}): {} {}",
        f64::from(r.tick) / f64::from(loop_hz.max(1)),
        r.tick,
        if r.cleared { "cleared" } else { "LATCHED" },
        r.fault
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Six significant digits of the f32 the firmware holds: 0.3335 in f32
    /// is 0.33349999785…, which f64 prints to 17 digits.
    #[test]
    fn values_are_printed_to_the_precision_the_firmware_holds() {
        assert_eq!(value(f64::from(0.3335f32)), "0.3335");
        assert_eq!(value(0.33349999999999996), "0.3335");
        assert_eq!(value(0.000001), "0.000001");
        assert_eq!(value(20.0), "20");
        assert_eq!(value(1000.0), "1000");
        assert_eq!(value(-2.5), "-2.5");
        assert_eq!(value(0.0), "0");
        assert_eq!(value(123456789.0), "1.23457e8");
    }

    /// The level goes out in codes (52.4288 per µin) and comes back in µin
    /// as typed: 5 µin is 262 codes, 3 µin 157, 0.5 µin 26.
    #[test]
    fn a_following_error_trigger_reads_in_micro_inches() {
        assert_eq!(
            trigger(Trigger::FollowingError { level: 262 }),
            "|following error| ≥ 5.0 µin"
        );
        assert_eq!(
            trigger(Trigger::FollowingError { level: 524 }),
            "|following error| ≥ 10.0 µin"
        );
        assert_eq!(
            trigger(Trigger::FollowingError { level: 157 }),
            "|following error| ≥ 3.0 µin"
        );
        assert_eq!(
            trigger(Trigger::FollowingError { level: 26 }),
            "|following error| ≥ 0.50 µin"
        );
    }
}
