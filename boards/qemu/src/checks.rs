//! The checks after the run (the crate docs list them), on what the
//! loop-tick handler summarised, the counters in `SHARED` and the host
//! link's capture; each logs its figures, and a failed one its reason.

use core::sync::atomic::Ordering;

use zslide::link::proto::{CaptureState, Reply, Request as HostRequest};
use zslide::link::station::Station;
use zslide::safety::{Device, Fault};
use zslide::xpos::{half_mils_to_x, CountX};

use crate::plant::Dac;
use crate::scenario::{
    index_pulses, x_count_at, x_events, x_script, DUPLICATES, INJECT_AT, START_CODE, TICKS,
    TRACK_FROM, X_COUNT_CFG,
};
use crate::tick::{Summary, ISR_COUNT};
use crate::{link, BOOT_DAC_WRITES, SHARED};

/// Tracking bound: 500 gauge codes = 9.5 µin (measured: 469,
/// `expected.log`; 156 with the coil inductance set to nil, measured when
/// the figure was 448 and not since: most of the error is the 0.26 ms electrical
/// lag the servo's feedforward does not invert, 7.5° at 80 Hz). The servo
/// follows the table here mostly on its plant-inverse feedforward and 45 Hz
/// feedback (at 1200 rpm the part's harmonics are at 40-80 Hz; the
/// learning acts a revolution later and is not what this short run
/// measures), and the plant (host-sim's model: coil inductance, 3150 Hz
/// mode, 8.5 µs DAC latency, modern gauge noise of 0.2 µin RMS = 10 codes
/// in the position read here) is not the rigid model the feedforward
/// inverts. The host-sim tests hold the servo to its real figures; this
/// run proves the same loop closes on the target with the same plant.
pub(crate) const TRACK_BOUND: u32 = 500;
/// The bound grows with the command beyond that: the part of the error the
/// feedforward leaves is proportional to the command (a linear mismatch of
/// a linear plant), so a table of another part is held to the same 2 % of
/// its swing (the default table: 469 codes = 2.0 % of 23 135, under the
/// 500-code floor; a 160 in
/// focal length at 1200 rpm swings 89 705 codes).
pub(crate) const TRACK_BOUND_OF_SWING_PERCENT: u32 = 2;
/// The command must swing at least this much (codes; 1 µin = 52.4 codes).
pub(crate) const MIN_SWING: i32 = 5_000;

/// Runs every check on the run's summary `s`, asking the capture through
/// `station` as the scripted `host`; whether all passed (then logs PASS).
pub(crate) fn report(
    s: &Summary,
    station: &mut Station<{ link::CAPTURE }>,
    host: &mut link::Script,
) -> bool {
    for t in s.trace.iter() {
        defmt::info!(
            "tick {=u32}: X {=i32} phi {=u32} table {=i32}  command {=i32}  position {=i32}  dac {=i32}",
            t.tick,
            t.x_bits,
            t.phi,
            t.table,
            t.command,
            t.position,
            t.output
        );
    }
    let mut ok = true;
    // A refused (or missing) table: the checks become "held at null".
    let refused = matches!(s.fault_before, Some(Fault::Table(_)));
    // A refused parameter block: the amplifier is never enabled and the
    // DAC never written; the slide stays where it rests.
    let params_refused = matches!(s.fault_before, Some(Fault::Parameters(_)));

    let swing = s.table_max.saturating_sub(s.table_min);
    let bound = TRACK_BOUND.max(swing.unsigned_abs() / 100 * TRACK_BOUND_OF_SWING_PERCENT);
    defmt::info!(
        "tracking: max |command - position| = {=u32} codes over ticks {=u32}..={=u32} (bound {=u32}; 1 code = 0.019 uin); table command {=i32}..{=i32} codes (swing bound {=i32}); fault {}",
        s.track_max_error,
        TRACK_FROM,
        INJECT_AT,
        bound,
        s.table_min,
        s.table_max,
        MIN_SWING,
        s.fault_before
    );
    if params_refused {
        // Undriven, the slide stays at rest: the modern gauge's noise is
        // 10 codes RMS, a driven move is thousands (the table swings 23 135).
        const AT_REST: u32 = 500;
        let moved = s
            .trace
            .iter()
            .map(|t| t.position.abs_diff(START_CODE))
            .max()
            .unwrap_or(u32::MAX);
        let loop_writes = Dac::writes().wrapping_sub(BOOT_DAC_WRITES.load(Ordering::Relaxed));
        let off = loop_writes == 0 && s.dac_clamped && !s.amplifier_enable && moved <= AT_REST;
        defmt::info!(
            "refused parameters: fault {}, DAC writes by the loop {=u32}, DAC clamped {=bool}, amplifier enable {=bool}, slide moved at most {=u32} codes from rest",
            s.fault_before,
            loop_writes,
            s.dac_clamped,
            s.amplifier_enable,
            moved
        );
        if !off {
            defmt::error!("FAIL: the amplifier was driven with the parameter block refused");
            ok = false;
        }
    } else if refused {
        let held = s.table_min == 0 && s.table_max == 0 && s.track_max_error <= TRACK_BOUND;
        defmt::info!(
            "refused table: table command {=i32}..{=i32}, slide within {=u32} codes of the null command (bound {=u32})",
            s.table_min,
            s.table_max,
            s.track_max_error,
            TRACK_BOUND
        );
        if !held {
            defmt::error!("FAIL: the slide was not held at null with the table refused");
            ok = false;
        }
    } else if s.fault_before.is_some() || s.track_max_error > bound || swing < MIN_SWING {
        defmt::error!("FAIL: the loop did not follow the table's command");
        ok = false;
    }

    let scheduled = x_events();
    let dups = DUPLICATES.iter().filter(|&&i| i < scheduled).count() as u32;
    let last_x = match (scheduled.checked_sub(1), CountX::new(X_COUNT_CFG)) {
        (Some(last), _) => half_mils_to_x(x_script(last)),
        (None, Some(cx)) => cx.x(x_count_at(INJECT_AT)),
        (None, None) => zslide::units::XInches::ZERO,
    };
    let (accepted, ignored) = (SHARED.x_accepted(), SHARED.x_ignored());
    defmt::info!(
        "X events: {=u32} accepted, {=u32} ignored (scripted {=u32} + {=u32} duplicates); {=u32} coefficient sets published; loop coefficients at {} (last X {}), null {=bool}",
        accepted,
        ignored,
        scheduled,
        dups,
        SHARED.coefficient_generation(),
        zslide::units::XInches::from_bits(s.coeff_x_bits),
        last_x,
        s.coeff_null
    );
    // Modern X publishes a set per count instead of per X event.
    let sets_ok = if cfg!(feature = "modern-x") {
        SHARED.coefficient_generation() > 0
    } else {
        SHARED.coefficient_generation() == scheduled
    };
    if accepted != scheduled
        || ignored != dups
        || !sets_ok
        || (!refused && (s.coeff_x_bits != last_x.to_bits() || s.coeff_null))
    {
        defmt::error!("FAIL: X events not handled as scripted");
        ok = false;
    }
    let pulses = index_pulses();
    defmt::info!(
        "index events: {=u32} (scripted {=u32})",
        SHARED.index_events(),
        pulses
    );
    if SHARED.index_events() != pulses {
        defmt::error!("FAIL: index pulses lost");
        ok = false;
    }

    let writes_after = s.writes_at_end.wrapping_sub(s.writes_at_inject);
    defmt::info!(
        "gauge bus error after tick {=u32}: fault {}, DAC clamped {=bool}, amplifier enable {=bool}, DAC writes since {=u32}",
        INJECT_AT,
        s.fault_after,
        s.dac_clamped,
        s.amplifier_enable,
        writes_after
    );
    // With the parameter block refused, the more severe fault is already
    // latched (same reaction) and holds.
    let expected_after = if params_refused {
        s.fault_before
    } else {
        Some(Fault::Bus(Device::GaugeAdc))
    };
    let reacted = s.fault_after == expected_after
        && s.dac_clamped
        && !s.amplifier_enable
        && writes_after == 0;
    if !reacted {
        defmt::error!("FAIL: wrong reaction to the gauge bus error");
        ok = false;
    }
    // 5. The capture holds what the loop did: at a traced tick inside it,
    // the recorded command, output, X and φ are the traced ones.
    let mut ask = |r: HostRequest| {
        host.send(&r);
        (0..100).find_map(|_| {
            station.poll(&link::TAP, &SHARED, host);
            host.reply()
        })
    };
    let captured = match ask(HostRequest::CaptureInfo) {
        Some(Reply::Capture(c)) if c.state == CaptureState::Done => Some(c),
        _ => None,
    };
    let probe = s.trace.iter().find(|t| t.tick == 800);
    let same = match (captured, probe) {
        (Some(c), Some(t)) => {
            match ask(HostRequest::CaptureRead {
                from: (t.tick - c.trigger_tick) as u16,
            }) {
                Some(Reply::Samples { samples, .. }) => samples.first().is_some_and(|x| {
                    (x.command, x.output, x.x_bits, x.phi) == (t.command, t.output, t.x_bits, t.phi)
                }),
                _ => false,
            }
        }
        _ => false,
    };
    defmt::info!(
        "capture: {=u16} loop ticks from tick {=u32} recorded while the loop ran; at tick 800 it holds the traced command, output, X and phi: {=bool}",
        captured.map_or(0, |c| c.recorded),
        captured.map_or(0, |c| c.trigger_tick),
        same
    );
    if !same || captured.map(|c| c.recorded) != Some(link::CAPTURE as u16) {
        defmt::error!("FAIL: the capture does not hold the loop's samples");
        ok = false;
    }

    let isr = ISR_COUNT.load(Ordering::Relaxed);
    defmt::info!(
        "loop-tick interrupt ran {=u32} times, firmware counted {=u32} (expected {=u32})",
        isr,
        s.fw_ticks,
        TICKS
    );
    if isr != TICKS || s.fw_ticks != TICKS {
        defmt::error!("FAIL: wrong tick count");
        ok = false;
    }
    if s.plant_missing_steps != 0 {
        defmt::error!(
            "FAIL: the plant skipped {=u64} steps (no generated discretisation)",
            s.plant_missing_steps
        );
        ok = false;
    }
    if ok {
        defmt::info!("PASS");
    }
    ok
}
