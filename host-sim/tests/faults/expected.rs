//! What each row must end in, written by hand from docs/SAFETY.md, and
//! when its detection is due.

use super::*;

/// A fault a row may latch, the reaction SAFETY.md gives it, and words its
/// reason must hold.
pub(crate) type FaultRule = (fn(Fault) -> bool, Reaction, &'static str);

/// What docs/SAFETY.md's fault table says a row must end in, written here
/// by hand (not read from `Fault::reaction`, `Fault::reason` or
/// `Case::expects`, the code under test).
pub(crate) struct Expected {
    /// The faults the row may latch: each with the reaction SAFETY.md gives
    /// it and words its reason must hold. Empty: nothing may latch.
    pub(crate) faults: &'static [FaultRule],
    /// Detected by the board's model (watchdog, panic handler), not the core.
    pub(crate) board_model: bool,
    /// What detects it, for the deadline of [`detection_deadline_ms`].
    pub(crate) detect: Detect,
}

/// The mechanism that detects a row's fault (SAFETY.md, "detection").
#[derive(Clone, Copy, Debug)]
pub(crate) enum Detect {
    /// At boot, before the arm: the table's CRC.
    Boot,
    /// At the arm: the sign check's open-loop doublet.
    Arm,
    /// The tick after the one that sees it (the frame in flight, or the
    /// interrupt's latch read by the next tick).
    NextTick,
    /// `storm_count` anomalies 50 µs apart (the injected storm's spacing).
    Storm,
    /// The X count crossing below the table's first node at the feed.
    XCross,
    /// No index within a revolution and its tolerance.
    IndexMissing,
    /// The first spurious index pulse (20 a revolution, at random).
    IndexExtra,
    /// The coast-down crossing the speed floor.
    Coast,
    /// |reference − gauge| beyond `following_error_in` for
    /// `following_error_ms` (or the gauge's range, the more severe).
    FollowingError,
    /// The current estimate at its limit for `current_limit_ms`.
    CurrentLimit,
    /// IWDG1: 40 counts of 125 µs after the last feed.
    Watchdog,
    /// The panic handler, run at the injection: the enable written low
    /// first, seen by the amplifier at the next tick's instant.
    Handler,
    /// Nothing is detected (refused frames).
    Nothing,
    /// Contour monitoring's windows (`servo::monitor`): the process rows,
    /// timed by `faults_process.rs`, not here.
    Monitor,
}

pub(crate) fn expected(case: Case) -> Expected {
    use zslide::safety::Device;
    use zslide::table::TableError;
    use Reaction::{DisableAmplifier as Off, RampToNull as Null, Retract as Back};
    let (faults, detect): (&'static [FaultRule], Detect) = match case {
        Case::CorruptTable => (
            &[(
                |f| matches!(f, Fault::Table(TableError::PayloadCrc { .. })),
                Null,
                "coefficient table",
            )],
            Detect::Boot,
        ),
        Case::XOutsideTable => (
            &[(|f| f == Fault::XOutsideTable, Null, "x outside")],
            Detect::XCross,
        ),
        Case::XGlitchStorm => (
            &[(|f| f == Fault::XGlitchStorm, Null, "glitch storm")],
            Detect::Storm,
        ),
        Case::XBadBcd => (
            &[(|f| f == Fault::XBadBcd, Null, "not bcd")],
            Detect::NextTick,
        ),
        Case::IndexMissing => (
            &[(|f| f == Fault::IndexMissing, Null, "index pulse missing")],
            Detect::IndexMissing,
        ),
        Case::IndexExtra => (
            &[(|f| f == Fault::IndexExtra, Null, "extra spindle index")],
            Detect::IndexExtra,
        ),
        Case::SpindleSpeed => (
            &[(|f| f == Fault::SpindleSpeed, Null, "spindle speed")],
            Detect::Coast,
        ),
        // The gauge's rail is the ADC's full scale: the OV flag.
        Case::GaugeSaturation => (
            &[(|f| f == Fault::GaugeRange, Off, "overrange")],
            Detect::NextTick,
        ),
        Case::AdcBusError => (
            &[(|f| f == Fault::Bus(Device::GaugeAdc), Off, "gauge adc bus")],
            Detect::NextTick,
        ),
        Case::DacBusError => (
            &[(
                |f| f == Fault::Bus(Device::AmplifierDac),
                Off,
                "amplifier dac bus",
            )],
            Detect::NextTick,
        ),
        // The push stays under the following-error limit where the loop
        // is stiff (modern-hw); its rebound into the stock, or the ring,
        // is contour monitoring's (SAFETY.md, "Contour monitoring").
        Case::FollowingError => (
            &[
                (|f| f == Fault::FollowingError, Null, "following error"),
                (|f| f == Fault::DepthGuard, Back, "depth guard"),
                (|f| f == Fault::Oscillation, Back, "oscillation"),
            ],
            Detect::FollowingError,
        ),
        // A slide lost fast crosses from the following-error limit to
        // the gauge's range within the monitor's persistence: the more
        // severe GaugeRange may hold the latch.
        Case::FollowingErrorFast => (
            &[
                (|f| f == Fault::FollowingError, Null, "following error"),
                (|f| f == Fault::GaugeRange, Off, "overrange"),
            ],
            Detect::FollowingError,
        ),
        Case::CurrentLimit => (
            &[(|f| f == Fault::CurrentLimit, Off, "coil current")],
            Detect::CurrentLimit,
        ),
        Case::AmplifierTrip => (
            &[(|f| f == Fault::AmplifierTrip, Off, "amplifier tripped")],
            Detect::NextTick,
        ),
        // The arm's sign check, not the table's load-time one
        // (`Table(SignCheck)`).
        Case::ReversedGauge => (
            &[(|f| f == Fault::SignCheck, Off, "sign check")],
            Detect::Arm,
        ),
        // A chip reset: the outputs off through the reset.
        Case::StalledLoop => (
            &[(|f| f == Fault::Watchdog, Off, "watchdog")],
            Detect::Watchdog,
        ),
        // Outputs off first, in the handler.
        Case::Panic => (&[(|f| f == Fault::Panic, Off, "panic")], Detect::Handler),
        Case::MalformedHostFrame => (&[], Detect::Nothing),
        // The process rows (`Case::PROCESS`): `faults_process.rs` runs and
        // times them against contour monitoring's windows.
        Case::EdgeForceX2 => (&[], Detect::Monitor),
        Case::EdgeForceX4 => (
            &[
                (|f| f == Fault::Oscillation, Back, "oscillation"),
                (|f| f == Fault::DepthGuard, Back, "depth guard"),
            ],
            Detect::Monitor,
        ),
        Case::GaugeFrozen => (
            &[(|f| f == Fault::GaugeFrozen, Off, "gauge frozen")],
            Detect::Monitor,
        ),
        Case::XCountStopped => (
            &[(|f| f == Fault::XStalled, Back, "x stalled")],
            Detect::Monitor,
        ),
        // Nothing may latch: an engagement is no fault.
        Case::EngageRunning => (&[], Detect::Nothing),
    };
    Expected {
        faults,
        board_model: matches!(case, Case::StalledLoop | Case::Panic),
        detect,
    }
}

/// A row's detection deadline from the injection, ms, from its mechanism;
/// `None` for a row with nothing to detect. The loop period is the
/// design's; one period more for the sample that shows the latch.
pub(crate) fn detection_deadline_ms(
    spec: &host_sim::cut::CutSpec,
    d: Detect,
    o: &host_sim::faults::Outcome,
) -> Option<f64> {
    let design = &spec.scenario.servo_design;
    let tick_ms = 1e3 / f64::from(design.rate_hz);
    let rev_ms = 60e3 / spec.rpm;
    let spindle = &spec.scenario.file.spindle;
    let slowest_rev_ms = 60e3 / (spec.rpm - spindle.sag_rpm - spindle.ripple_rpm);
    Some(match d {
        Detect::Nothing | Detect::Monitor => return None,
        // Refused at boot: latched before the first sample of the run.
        Detect::Boot => tick_ms,
        // The doublet: sign_check_ms each way, judged at its end.
        Detect::Arm => 2.0 * design.sign_check_ms + 2.0 * tick_ms,
        Detect::NextTick => 2.0 * tick_ms,
        // The firmware's storm: `LegacyConfig`'s 16 anomalies; the
        // injection's interrupts come 50 µs apart, each an anomaly.
        Detect::Storm => 15.0 * 0.050 + 2.0 * tick_ms,
        // The tool centre is 0.2 µin above the axis at the injection and
        // moves at the feed; the interferometer's count (1 µin) reads X
        // plus the slide's vibration and jitter (the scenario's X slide),
        // so it is below zero for certain once X is below −(A + J + 1 µin),
        // read at the next tick.
        Detect::XCross => {
            use host_sim::machine::XInterface;
            let (XInterface::LegacyBcd(c) | XInterface::Quadrature(c)) = &spec.scenario.machine.x;
            let feed_in_per_ms = spec.feed_per_rev_in / rev_ms;
            let margin_in = (c.vibration_uin + c.jitter_uin + 1.0) * 1e-6;
            (0.2e-6 + margin_in) / feed_in_per_ms + 2.0 * tick_ms
        }
        // The last index came at most a revolution before the injection;
        // the check allows the next CPR + tolerance counts (host-sim's
        // firmware wiring, `fwrig/world.rs`: 2 counts of an encoder, 2 %
        // of a tachometer's revolution: at most 2 %), at the spindle's
        // slowest: its set point less the cut's sag and its ripple.
        Detect::IndexMissing => slowest_rev_ms * 1.02 + 2.0 * tick_ms,
        // 20 spurious pulses a revolution at random: the first comes
        // within half a revolution but for a chance of e^−10 (4.5·10⁻⁵).
        Detect::IndexExtra => slowest_rev_ms / 2.0 + 2.0 * tick_ms,
        // Coasting at accel from rpm to the floor (encoder: 4/5·min_rpm per
        // count; tachometer: min_rpm/2; SAFETY.md), then one count (one
        // revolution of a tachometer's index) at the floor.
        Detect::Coast => {
            use host_sim::machine::SpindleSensor;
            let m = &spec.scenario.machine;
            let (floor, last) = match m.sensor {
                // The per-count check sees the floor; the index check's
                // revolution average (below min_rpm) is its backstop, a
                // revolution at the floor later. (modern-hw's per-count
                // detection comes 11.5 ms after the coast line's crossing
                // of the floor, unexplained: the backstop holds it.)
                SpindleSensor::EncoderIndex => {
                    let floor = 0.8 * f64::from(m.min_rpm);
                    (floor, 60e3 / floor)
                }
                SpindleSensor::TachIndex => {
                    let floor = 0.5 * f64::from(m.min_rpm);
                    (floor, 60e3 / floor)
                }
            };
            // The once-per-revolution ripple can hold the speed up to
            // ripple_rpm above the coast line.
            (spec.rpm + spindle.ripple_rpm - floor) / spindle.accel_rpm_per_s * 1e3
                + last
                + 2.0 * tick_ms
        }
        // From the first tick the slide is beyond the limit off its
        // reference (the plant's truth; the gauge's filter adds at most a
        // tick), the persistence; or the gauge's range, the next tick.
        Detect::FollowingError => {
            let t_inj = o.trace.iter().map(|x| x.t_ns).min()?;
            let t_inj = t_inj.max((o.row.injected_at_s? * 1e9).round() as u64);
            let first = |pred: &dyn Fn(&host_sim::faults::Sample) -> bool| {
                o.trace
                    .iter()
                    .find(|x| x.t_ns >= t_inj && pred(x))
                    .map(|x| (x.t_ns - t_inj) as f64 * 1e-6)
            };
            let fe = first(&|x| (x.reference_in - x.z_in).abs() > design.following_error_in)
                .map(|t| t + design.following_error_ms + 3.0 * tick_ms);
            let range = first(&|x| x.z_in.abs() > GAUGE_RANGE_IN).map(|t| t + 2.0 * tick_ms);
            fe.into_iter().chain(range).fold(f64::INFINITY, f64::min)
        }
        // From the first tick the coil current reaches the limit (the
        // estimate is held there by the DAC clamp), the persistence.
        Detect::CurrentLimit => {
            let t_inj = (o.row.injected_at_s? * 1e9).round() as u64;
            let at = o
                .trace
                .iter()
                .find(|x| {
                    x.t_ns >= t_inj
                        && x.current_a.abs() >= CURRENT_AT_LIMIT * design.current_limit_a
                })
                .map(|x| (x.t_ns - t_inj) as f64 * 1e-6)?;
            at + design.current_limit_ms + 2.0 * tick_ms
        }
        // 40 counts of 125 µs after the last feed (a loop period before),
        // the count that sees no feed at most one count late, the reset
        // seen at the next tick.
        Detect::Watchdog => 5.0 + 0.125 + 2.0 * tick_ms,
        Detect::Handler => tick_ms,
    })
}

/// The gauge's range, in (±0.010 in: the AD4020's full scale).
pub(crate) const GAUGE_RANGE_IN: f64 = 0.010;
/// The true coil current the limit's estimate holds, as a fraction of the
/// limit (the estimate i ≈ (G·V − Kb·v)/R leads or lags the coil's L/R).
pub(crate) const CURRENT_AT_LIMIT: f64 = 0.9;

/// When the row's fault showed, ms from the injection: the first sample
/// with a fault latched (the board model's rows: with the amplifier off).
pub(crate) fn detected_ms(case: Case, o: &host_sim::faults::Outcome) -> Option<f64> {
    let t_inj = (o.row.injected_at_s? * 1e9).round() as u64;
    let seen = |x: &host_sim::faults::Sample| {
        if expected(case).board_model {
            !x.amp_enabled
        } else {
            x.fault
        }
    };
    let x = o.trace.iter().find(|x| x.t_ns >= t_inj && seen(x))?;
    Some((x.t_ns - t_inj) as f64 * 1e-6)
}
