//! Faults and their reactions. Every fault the machine can detect has a name
//! here, a defined reaction, and leaves the slide in a safe state.

use crate::table::TableError;

/// A converter chip on a bus, for bus-error faults.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Device {
    AmplifierDac,
    GaugeAdc,
    CoefficientDac,
}

/// Everything that stops a cut. Readable: `Debug`/`defmt` name the cause.
/// (Serialisable: the host link carries faults as they are, and the host
/// prints [`Fault::reason`] and the detail's words, `docs/BOARD.md`.)
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Fault {
    /// The coefficient table was refused by the parser.
    Table(TableError),
    /// The servo parameter block in flash was refused (`params`): the loop
    /// is not run on parameters the machinist did not write.
    Parameters(ParamError),
    /// X left the range the table covers (below the first node).
    XOutsideTable,
    /// Too many X events that changed nothing or jumped: a glitching counter.
    XGlitchStorm,
    /// A latched BCD digit was not a decimal digit.
    XBadBcd,
    /// No index pulse within the expected window.
    IndexMissing,
    /// An index pulse well before the expected one.
    IndexExtra,
    /// Spindle speed outside the configured band.
    SpindleSpeed,
    /// Gauge reading outside its range, or pinned at full scale.
    GaugeRange,
    GaugeSaturated,
    /// A converter did not answer or answered nonsense.
    Bus(Device),
    /// |command − position| beyond the configured limit.
    FollowingError,
    /// The estimated coil current sat at its limit for longer than allowed.
    CurrentLimit,
    /// The amplifier's fault line: it tripped (its own current limit).
    AmplifierTrip,
    /// Command and response disagree in sign (reversed gauge or wiring).
    SignCheck,
    Watchdog,
    Panic,
    /// Centring: the rotary table is not turning (no encoder edge or no
    /// index within the time the slowest table speed allows), or it turns
    /// too fast to sample every angle bin.
    CentringTableStopped,
    /// Centring: the transducer reached the end of its ±0.5 in travel; the
    /// part is too far off centre to measure. Place it closer by hand.
    CentringOutOfRange,
    /// Centring: a correction cycle left the part further off centre than
    /// before (reversed slide wiring, a slipping part, or a residual already
    /// at the machine's mechanical limit: raise the level detector).
    CentringWorse,
    /// Centring: the level was not reached in the allowed number of cycles.
    CentringNoConvergence,
    /// Centring: a slide did not settle in the allowed time (jammed slide,
    /// open motor or tachometer).
    CentringSlideTimeout,
    /// Contour monitoring (`servo::monitor`): the tool went below the
    /// commanded surface, into the stock, by more than the depth guard.
    DepthGuard,
    /// Contour monitoring: the following error oscillates (its windowed
    /// RMS about its slow mean above the limit): the loop rings against
    /// the process (a blunt edge, another material) or the slide.
    Oscillation,
    /// Contour monitoring: the gauge's 20-bit code has not changed for
    /// longer than a driven slide's noise allows.
    GaugeFrozen,
    /// Contour monitoring: no new X for too many revolutions while the
    /// table command is live (the X count stopped while X feeds).
    XStalled,
}

/// What the machine does about a fault.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Reaction {
    /// Keep the loop closed, ramp the command to null, hold there.
    RampToNull,
    /// Keep the loop closed and take the tool out of the stock: the
    /// command ramps at the slew limit to the retract position
    /// (`retract_z_in`, away from the stock), and holds there.
    Retract,
    /// Open the loop: DAC to zero volts, amplifier disabled.
    DisableAmplifier,
}

impl Fault {
    /// The defined reaction. The loop stays closed (and holds the slide at
    /// null) whenever its own sensing and actuation are still trustworthy;
    /// otherwise the amplifier is disabled, because a loop on a bad gauge or
    /// a bad DAC would drive the tool uncontrolled.
    pub const fn reaction(self) -> Reaction {
        match self {
            Fault::Table(_)
            | Fault::XOutsideTable
            | Fault::XGlitchStorm
            | Fault::XBadBcd
            | Fault::IndexMissing
            | Fault::IndexExtra
            | Fault::SpindleSpeed
            | Fault::FollowingError => Reaction::RampToNull,
            Fault::GaugeRange
            | Fault::GaugeSaturated
            | Fault::Bus(_)
            | Fault::CurrentLimit
            | Fault::AmplifierTrip
            | Fault::SignCheck
            | Fault::Watchdog
            | Fault::Panic => Reaction::DisableAmplifier,
            // A loop on parameters nobody wrote could be unstable on this
            // slide: the amplifier stays off until a good block is flashed.
            Fault::Parameters(_) => Reaction::DisableAmplifier,
            // The centring slides have no null to ramp to: they stop where
            // they are (motor voltage zero), which is safe for the part.
            Fault::CentringTableStopped
            | Fault::CentringOutOfRange
            | Fault::CentringWorse
            | Fault::CentringNoConvergence
            | Fault::CentringSlideTimeout => Reaction::DisableAmplifier,
            // The loop's sensing and actuation are sound but the tool is
            // where it must not be (or the command is for another radius):
            // out of the stock is the only place the tool is safe, and a
            // loop ringing against the process spring stops ringing once
            // the spring is gone.
            Fault::DepthGuard | Fault::Oscillation | Fault::XStalled => Reaction::Retract,
            // A loop on a reading that no longer follows the slide drives
            // it blind: amplifier off, and the cutting force (the part
            // pushes the tool away from itself) takes the tool out.
            Fault::GaugeFrozen => Reaction::DisableAmplifier,
        }
    }

    /// The cause in words, for logs and the fault table.
    pub const fn reason(self) -> &'static str {
        match self {
            Fault::Table(TableError::Missing) => "no coefficient table in flash",
            Fault::Table(_) => "coefficient table refused (format, CRC or sign check at load)",
            Fault::Parameters(_) => "servo parameter block refused (format, CRC or a value outside its limits)",
            Fault::XOutsideTable => "X outside the range the coefficient table covers",
            Fault::XGlitchStorm => "X counter glitch storm (too many events that changed nothing or jumped)",
            Fault::XBadBcd => "X latch held a digit that is not BCD",
            Fault::IndexMissing => "spindle index pulse missing",
            Fault::IndexExtra => "extra spindle index pulse",
            Fault::SpindleSpeed => "spindle speed outside the accepted band",
            Fault::GaugeRange => "gauge out of range (overrange flag)",
            Fault::GaugeSaturated => "gauge reading pinned at full scale",
            Fault::Bus(Device::AmplifierDac) => "amplifier DAC bus error",
            Fault::Bus(Device::GaugeAdc) => "gauge ADC bus error",
            Fault::Bus(Device::CoefficientDac) => "coefficient DAC bus error",
            Fault::FollowingError => "following error beyond its limit",
            Fault::CurrentLimit => "estimated coil current held at its limit too long",
            Fault::AmplifierTrip => "amplifier tripped (its fault line is set)",
            Fault::SignCheck => "sign check failed: the slide did not move as commanded (reversed sign, dead amplifier or stuck slide)",
            Fault::Watchdog => "watchdog: a handler stopped making progress",
            Fault::Panic => "firmware panic",
            Fault::CentringTableStopped => {
                "centring: the rotary table is not turning (or not within 1-25 rpm): no encoder edge or index when one was due"
            }
            Fault::CentringOutOfRange => {
                "centring: the transducer is at the end of its +/-0.5 in travel: the part is too far off centre to measure"
            }
            Fault::CentringWorse => {
                "centring: a correction cycle left the part further off centre than before (mechanical limit reached, or a slide or its wiring is reversed)"
            }
            Fault::CentringNoConvergence => "centring: the level was not reached in the allowed number of cycles",
            Fault::CentringSlideTimeout => "centring: a slide did not come to rest in the allowed time",
            Fault::DepthGuard => "depth guard: the tool went into the stock below the commanded surface by more than the guard",
            Fault::Oscillation => "sustained oscillation of the following error (windowed RMS above its limit): the loop rings against the process or the slide",
            Fault::GaugeFrozen => "gauge frozen: its code has not changed for longer than a driven slide's noise allows",
            Fault::XStalled => "X stalled: no new X for too many revolutions while the table command is live",
        }
    }
}

/// When a latched fault may be cleared (`Request::ClearFault`, always
/// with the loop disarmed; a clear never re-arms).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Clearing {
    /// Disarmed: the cause is an event, not a state that lasts.
    Disarmed,
    /// Disarmed and the last gauge sample good.
    GaugeGood,
    /// Disarmed and the amplifier's fault line low.
    AmplifierLineLow,
    /// Never: a refused table or parameter block stays refused until a good
    /// one is read at the next boot.
    NextBoot,
}

impl Fault {
    /// One fault of each kind, in declaration order (the refused table
    /// twice: `Missing` has words of its own): the fault table of
    /// docs/SAFETY.md is generated from it (`cargo xtask figures`).
    pub const EACH: [Fault; 30] = [
        Fault::Table(TableError::Missing),
        Fault::Table(TableError::Truncated { needed: 64, got: 3 }),
        Fault::Parameters(ParamError::BlockMagic),
        Fault::XOutsideTable,
        Fault::XGlitchStorm,
        Fault::XBadBcd,
        Fault::IndexMissing,
        Fault::IndexExtra,
        Fault::SpindleSpeed,
        Fault::GaugeRange,
        Fault::GaugeSaturated,
        Fault::Bus(Device::AmplifierDac),
        Fault::Bus(Device::GaugeAdc),
        Fault::Bus(Device::CoefficientDac),
        Fault::FollowingError,
        Fault::CurrentLimit,
        Fault::AmplifierTrip,
        Fault::SignCheck,
        Fault::Watchdog,
        Fault::Panic,
        Fault::CentringTableStopped,
        Fault::CentringOutOfRange,
        Fault::CentringWorse,
        Fault::CentringNoConvergence,
        Fault::CentringSlideTimeout,
        Fault::Parameters(ParamError::BlockCrc {
            stored: 1,
            computed: 2,
        }),
        Fault::DepthGuard,
        Fault::Oscillation,
        Fault::GaugeFrozen,
        Fault::XStalled,
    ];

    /// When the fault may be cleared (`LoopState::clear_fault` applies it).
    pub const fn clearing(self) -> Clearing {
        match self {
            Fault::GaugeRange | Fault::GaugeSaturated | Fault::Bus(Device::GaugeAdc) => {
                Clearing::GaugeGood
            }
            Fault::AmplifierTrip => Clearing::AmplifierLineLow,
            Fault::Table(_) | Fault::Parameters(_) => Clearing::NextBoot,
            _ => Clearing::Disarmed,
        }
    }

    /// What detects the fault, in words (the fault table's column).
    pub const fn detection(self) -> &'static str {
        match self {
            Fault::Table(TableError::Missing) => "the table region is erased (`CoeffTable::parse_region`)",
            Fault::Table(_) => "the table parser (`CoeffTable::parse_region`: format, CRC, geometry, grid) and the load-time sign check (Z ≤ 0 at every node, 16 angles) in `Firmware::with_table_region`",
            Fault::Parameters(_) => "`params::load_region` on the block the boot reads (`store::boot`), or a store that cannot be read",
            Fault::XOutsideTable => "the X handler: X below the table's first node",
            Fault::XGlitchStorm => "`xpos`: too many X events that change nothing or jump beyond `max_jump`",
            Fault::XBadBcd => "`xpos::decode`: a latched BCD nibble above 9",
            Fault::IndexMissing => "`spindle`: no index within a revolution's counts and the tolerance",
            Fault::IndexExtra => "`spindle`: an index well before the expected count, or two within one loop period",
            Fault::SpindleSpeed => "`spindle`: a revolution's period, or an encoder count's, outside `min_rpm..max_rpm`",
            Fault::GaugeRange => "the AD4020 frame's overrange bit",
            Fault::GaugeSaturated => "a gauge code on either rail without the overrange bit",
            Fault::Bus(Device::AmplifierDac) => "an AD5791 write error; its read-back at boot",
            Fault::Bus(Device::GaugeAdc) => "an AD4020 frame failing its 0b010 pattern, or an SPI error",
            Fault::Bus(Device::CoefficientDac) => "an AD5686 or LDAC error in the X handler (coefficient output)",
            Fault::FollowingError => "`servo::limits`: |reference − gauge| above `following_error_in` for longer than `following_error_ms`",
            Fault::CurrentLimit => "`servo::limits`: the estimated coil current, (G·V − Kb·v)/R, held at `current_limit_a` longer than `current_limit_ms`",
            Fault::AmplifierTrip => "the amplifier's fault line (NUCLEO PG9)",
            Fault::SignCheck => "`servo::engage`: at every arm, an open-loop DAC doublet (`sign_check_v`, `sign_check_ms`) must move the gauge the model's way within ×3",
            Fault::Watchdog => "IWDG1 (5 ms), fed by the background only when the loop tick ran since the last feed (`watchdog::FeedGate`)",
            Fault::Panic => "the panic handler (and HardFault)",
            Fault::CentringTableStopped => "`centring::cycle`: no table encoder edge or index when one was due, or an empty angle bin",
            Fault::CentringOutOfRange => "`centring::estimate`: a transducer reading within 0.5 mil of its ±0.5 in stop",
            Fault::CentringWorse => "`centring::cycle`: the off-centre larger than the previous cycle's",
            Fault::CentringNoConvergence => "`centring::cycle`: more than `max_cycles` corrections",
            Fault::CentringSlideTimeout => "`centring::cycle`: a correction not settled within `max_correction_ticks`",
            Fault::DepthGuard => "`servo::monitor` (learning handler, on the tick's samples): command − gauge toward the stock (opposite `retract_z_in`) beyond the depth guard (`depth_of_cut_uin` less the retract's stop, `ServoDesign::depth_guard_uin`) on 3 consecutive ticks, not over the part's holes nor in their edges' transient, from 2 revolutions of live command after the engagement (`SETTLE_REVS`: the spindle angle's first index correction)",
            Fault::Oscillation => "`servo::monitor`: the error's mean square about its 50 Hz mean (exponential windows of 2⁸ and 2⁶ ticks) above `oscillation_uin`² for a whole window (12.8 ms), not over the part's holes nor in their edges' transient, from 2 revolutions of live command after the engagement",
            Fault::GaugeFrozen => "`servo::monitor`: the gauge's 20-bit code identical for `gauge_frozen_ms` while the loop is closed, watched also while another fault's reaction runs",
            Fault::XStalled => "`servo::monitor`: `x_stall_revs` revolutions (0 = off) with the table command live and no new coefficient set",
        }
    }
}

/// The cause in words with its detail (a refused table or parameter block
/// says what is wrong with it): what the host link and the logs print.
impl core::fmt::Display for Fault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Fault::Table(TableError::Missing) => {
                write!(f, "{}: {}", self.reason(), TableError::Missing)
            }
            Fault::Table(e) => write!(f, "{}: {e}", self.reason()),
            Fault::Parameters(e) => write!(f, "{}: {e}", self.reason()),
            _ => f.write_str(self.reason()),
        }
    }
}

// What a refused configuration carries (`Fault::Parameters`), defined here
// below the modules that refuse it (`params`, `servo::design`), so that the
// faults depend on nothing above them. Their words are with them:
// `ParamError`'s `Display` in `params`, `DesignError::reason` in
// `servo::design`.

/// An `f64` carried by its bits, so that errors holding one stay `Eq`.
#[derive(Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Value(pub u64);

// defmt sends the f64 and the host formats it: no float formatting code in
// the image (`core::fmt` of an f64 costs about 20 KiB of flash).
#[cfg(target_os = "none")]
impl defmt::Format for Value {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=f64}", self.get())
    }
}

impl Value {
    pub fn new(v: f64) -> Self {
        Self(v.to_bits())
    }
    pub fn get(self) -> f64 {
        f64::from_bits(self.0)
    }
}

impl core::fmt::Debug for Value {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}", self.get())
    }
}

/// Why a parameter, or a parameter block, is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ParamError {
    /// No parameter has this id.
    Unknown(u16),
    /// The value lies outside the parameter's limits (or is not finite).
    OutOfRange {
        id: u16,
        value: Value,
    },
    /// A whole-number parameter given a fraction.
    NotInteger {
        id: u16,
        value: Value,
    },
    /// Each value is within its limits but the design refuses them
    /// together (its reason names the fields and the rule).
    Design(DesignError),
    /// The block is shorter than its header or its entries.
    BlockTruncated {
        needed: u32,
        got: u32,
    },
    BlockMagic,
    BlockVersion(u16),
    BlockReserved,
    /// More entries than there are parameters.
    BlockTooMany(u16),
    BlockCrc {
        stored: u32,
        computed: u32,
    },
    /// The same parameter twice in one block.
    BlockDuplicate(u16),
    /// The parameter store (`store`) could not be read: it is corrupt or
    /// its flash failed; its last saved block is unknown.
    StoreUnreadable,
}

/// A design parameter out of its range (named for the `[servo]` field).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum DesignError {
    Rate,
    Slide,
    Bandwidth,
    Damping,
    Observer,
    ObserverFast,
    GainRange,
    HumNotch,
    ModeNotch,
    Learning,
    Slew,
    CommandLimit,
    CurrentLimit,
    FollowingError,
    SignCheck,
    /// Last, so that the variants before keep their wire numbers.
    BandwidthFast,
    /// A contour-monitoring parameter out of its range (the depth guard,
    /// `oscillation_uin`, `gauge_frozen_ms`, `x_stall_revs`,
    /// `retract_z_in`).
    Monitor,
    /// The part program's depth of cut (`depth_of_cut_uin`) out of its
    /// range.
    DepthOfCut,
    /// `edge_feedforward` neither 0 nor 1.
    EdgeFeedforward,
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::format;
    use std::string::ToString;

    const ALL: [Fault; 30] = Fault::EACH;

    /// Each cause has words of its own (the host prints them, and a
    /// machinist acts on them): none empty, no two faults alike (the two
    /// refused blocks share theirs; their detail tells them apart).
    /// Found by cargo-mutants: `reason` returning "" or "xyzzy" survived.
    #[test]
    fn every_fault_names_its_own_cause_in_words() {
        for (i, a) in ALL.iter().enumerate() {
            assert!(a.reason().len() > 10, "{a:?}: {:?}", a.reason());
            for b in &ALL[i + 1..] {
                if !matches!((a, b), (Fault::Parameters(_), Fault::Parameters(_))) {
                    assert_ne!(a.reason(), b.reason(), "{a:?} and {b:?}");
                }
            }
        }
    }

    /// A refused table or parameter block is printed with its detail
    /// (what is wrong with it), every other fault by its cause alone.
    #[test]
    fn a_refused_table_or_block_is_printed_with_its_detail() {
        for f in ALL {
            let shown = f.to_string();
            let detail = match f {
                Fault::Table(e) => Some(e.to_string()),
                Fault::Parameters(e) => Some(e.to_string()),
                _ => None,
            };
            match detail {
                Some(d) => assert_eq!(shown, format!("{}: {d}", f.reason()), "{f:?}"),
                None => assert_eq!(shown, f.reason(), "{f:?}"),
            }
        }
    }

    /// An `f64` carried by its bits comes back as itself and prints as one.
    #[test]
    fn a_value_carries_its_f64_exactly() {
        for v in [1.5, -0.004, 0.0, 7.25e-9] {
            assert_eq!(Value::new(v).get().to_bits(), v.to_bits());
            assert_eq!(format!("{:?}", Value::new(v)), format!("{v}"));
        }
    }
}
